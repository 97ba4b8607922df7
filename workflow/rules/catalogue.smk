# The SQLite catalogue, the only writer of the published catalogue: every plane's cells and
# audit, every sweep, the attractor tiles and the bifurcation points and curves. It builds
# CATALOGUE_BUILD and publishes it as PUBLISHED_CATALOGUE (workflow/rules/common.smk).


rule catalogue:
    input:
        cells=lambda wildcards: CELL_FILES,
        sweeps=lambda wildcards: SWEEP_FILES,
        audits=lambda wildcards: AUDIT_FILES,
        attractors=lambda wildcards: ATTRACTOR_FILES,
        # the bifurcation points and curves, and the codimension-2 points (codim2_points)
        orbits=lambda wildcards: ORBIT_CATALOGUE_FILES + ORBIT_CODIM2_FILES,
    output:
        build=CATALOGUE_BUILD,
    log:
        "logs/catalogue.log",
    conda:
        GEARSIM_ENV
    params:
        published=PUBLISHED_CATALOGUE,
        code_version=CODE_VERSION["catalogue"],
    shell:
        "gearsim catalogue build --cells {input.cells} --sweeps {input.sweeps} "
        "--audits {input.audits} --attractors {input.attractors} --orbits {input.orbits} "
        "--out {output.build} --publish {params.published} > {log} 2>&1"


# The file users query as a target of its own (`snakemake results/catalogue.sqlite`): the build
# above publishes it; this job only asks for that build and publishes again (idempotent).
# update(): Snakemake does not delete the published file before the job, and a failed build
# never reaches this job, so the last good catalogue stays in place, untouched.
rule published_catalogue:
    input:
        rules.catalogue.output.build,
    output:
        update(PUBLISHED_CATALOGUE),
    log:
        "logs/catalogue_publish.log",
    conda:
        GEARSIM_ENV
    shell:
        "gearsim catalogue publish --from {input} --to {output} > {log} 2>&1"


TARGETS_CATALOGUE = [rules.catalogue.output.build]


# A lab's database (config `publish: {url, study}`; docs/pipeline.md, "A lab's database"): the
# catalogue published there as one study after each build, swapped in atomically. Its output is
# the command's line (the URL with its password hidden). Without `publish`, no such rule.
if config.get("publish"):
    PUBLISH_URL, PUBLISH_STUDY = publish_target()

    rule publish_server:
        input:
            rules.catalogue.output.build,
        output:
            f"results/catalogue.d/server-{PUBLISH_STUDY}.txt",
        log:
            "logs/catalogue_server.log",
        conda:
            GEARSIM_ENV
        params:
            url=PUBLISH_URL,
            study=PUBLISH_STUDY,
        shell:
            "gearsim catalogue publish --from {input} --to {params.url:q} "
            "--study {params.study} > {log} 2>&1 && cp {log} {output}"

    TARGETS_CATALOGUE.append(rules.publish_server.output[0])
