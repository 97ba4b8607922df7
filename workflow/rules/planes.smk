# Planes: tiles (one job each, rows mapped over dask) -> cells.parquet per plane -> audit ->
# the SQLite catalogue (the only writer of results/catalogue.sqlite).
#
# Snakemake deletes a job's declared outputs before the job starts. The catalogue rule therefore
# declares results/catalogue.d/build.sqlite and publishes it as results/catalogue.sqlite (hard
# link renamed into place): readers of results/catalogue.sqlite never see it missing or partial,
# and a failed rebuild keeps the last good one (docs/pipeline.md, Guarantees).
CATALOGUE = "results/catalogue.d/build.sqlite"
PUBLISHED_CATALOGUE = "results/catalogue.sqlite"


rule compile:
    output:
        COMPILED_STAMP,
    log:
        "logs/compile.log",
    conda:
        GEARSIM_ENV
    priority: 10  # the planes wait for it
    shell:
        "gearsim compile --stamp {output} > {log} 2>&1"


rule simulate_tile:
    input:
        compiled=COMPILED,
        config=CONFIG,
    output:
        "results/{plane}/tiles/{tile}.parquet",
    log:
        "logs/{plane}/tile_{tile}.log",
    benchmark:
        "logs/benchmarks/{plane}/tile_{tile}.tsv"
    conda:
        GEARSIM_ENV
    # one process per job, Snakemake runs --cores of them at once: no LocalCluster start-up per
    # job (~7 s of a tile job's wall on 2 idle cores; benchmarks/README.md (k)). With
    # cluster.scheduler_address set, each job still sends its tasks to that scheduler.
    threads: 1
    # the planes' chain (tiles -> cells -> audit -> catalogue) is the longest: start it first,
    # the sweeps, points and figures fill the other core
    priority: 10
    params:
        config=plane_params,
        code_version=CODE_VERSION["tiles"],
    shell:
        "gearsim simulate-tile --plane {wildcards.plane} --tile {wildcards.tile} "
        "--configfile {input.config} --workers {threads} --out {output} > {log} 2>&1"


rule plane_cells:
    input:
        tiles=tiles_of_plane,
        config=CONFIG,
    output:
        "results/{plane}/cells.parquet",
    log:
        "logs/{plane}/cells.log",
    conda:
        GEARSIM_ENV
    priority: 10
    params:
        config=plane_params,
        code_version=CODE_VERSION["tiles"],
    shell:
        "gearsim catalogue cells --plane {wildcards.plane} --tiles {input.tiles} "
        "--configfile {input.config} --out {output} > {log} 2>&1"


rule audit:
    input:
        cells="results/{plane}/cells.parquet",
        config=CONFIG,
    output:
        "results/{plane}/audit.parquet",
    log:
        "logs/{plane}/audit.log",
    benchmark:
        "logs/benchmarks/{plane}/audit.tsv"
    conda:
        GEARSIM_ENV
    priority: 10
    params:
        config=audit_params,
        code_version=CODE_VERSION["tiles"],
    shell:
        "gearsim catalogue audit --plane {wildcards.plane} --cells {input.cells} "
        "--configfile {input.config} --out {output} > {log} 2>&1"


rule catalogue:
    input:
        cells=expand("results/{plane}/cells.parquet", plane=PLANES),
        sweeps=expand("results/sweeps/{sweep}.parquet", sweep=SWEEPS),
        audits=expand("results/{plane}/audit.parquet", plane=PLANES) if AUDIT else [],
        attractors=ATTRACTOR_FILES,
        # bifurcation points / curves (workflow/rules/orbits.smk, included later)
        orbits=lambda wildcards: globals().get("ORBIT_CATALOGUE_FILES", []),
    output:
        CATALOGUE,
    log:
        "logs/catalogue.log",
    conda:
        GEARSIM_ENV
    shell:
        "gearsim catalogue build --cells {input.cells} --sweeps {input.sweeps} "
        "--audits {input.audits} --attractors {input.attractors} --orbits {input.orbits} "
        "--out {output} --publish results/catalogue.sqlite "
        "> {log} 2>&1"


# The file users query as a target of its own (`snakemake results/catalogue.sqlite`): the build
# above publishes it; this job only asks for that build and publishes again (idempotent).
# update(): Snakemake does not delete the published file before the job, and a failed build
# never reaches this job, so the last good catalogue stays in place, untouched.
rule published_catalogue:
    input:
        CATALOGUE,
    output:
        update(PUBLISHED_CATALOGUE),
    log:
        "logs/catalogue_publish.log",
    conda:
        GEARSIM_ENV
    shell:
        "gearsim catalogue publish --from {input} --to {output} > {log} 2>&1"


ALL_TARGETS += expand("results/{plane}/cells.parquet", plane=PLANES)
ALL_TARGETS += [CATALOGUE]
