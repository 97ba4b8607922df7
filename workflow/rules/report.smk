# Reconstructed Table 1 and the study's report.
# The report reads exactly its declared inputs: the configured sweeps and their diagrams, the
# point sets, the catalogue (plane cells), each plane's cells and numerical audit, Table 1, the
# continuation's located points and curves and, when the repository has it, the calibration
# record docs/calibration.json (produced offline by `gearsim calibrate`, a long search that is
# not part of the workflow). Its planes, sweeps and points come from the config.
CALIBRATION = Path(workflow.basedir, "docs/calibration.json")


rule table1:
    input:
        config["standard_parameters"],
    output:
        md="results/table1.md",
        csv="results/table1.csv",
    log:
        "logs/report/table1.log",
    conda:
        GEARSIM_ENV
    shell:
        "gearsim table1 --params {input} --md {output.md} --csv {output.csv} > {log} 2>&1"


rule report:
    input:
        sweeps=lambda wildcards: SWEEP_FILES,
        catalogue=lambda wildcards: rules.catalogue.output.build,
        cells=lambda wildcards: CELL_FILES,
        audits=lambda wildcards: AUDIT_FILES,
        calibration=[str(CALIBRATION)] if CALIBRATION.is_file() else [],
        table1=rules.table1.output.md,
        # the sweeps' bifurcation diagrams the report links
        diagrams=lambda wildcards: [f for f in DIAGRAM_FILES if f.endswith(".png")],
        points=lambda wildcards: POINT_FILES,
        orbits=lambda wildcards: ORBIT_REPORT_INPUTS,
        # the plane atlas: boundary edges by mechanism, the cascade (workflow/rules/atlas.smk)
        atlas=lambda wildcards: ATLAS_REPORT_INPUTS,
        config=CONFIG,
    output:
        report="results/report.md",
    log:
        "logs/report/report.log",
    conda:
        GEARSIM_ENV
    params:
        calibration=lambda wildcards, input: input.calibration or "",
        sweep_dir=lambda wildcards: Path(rules.sweep.output.table).parent,
        results=lambda wildcards, output: Path(output.report).parent,
        code_version=CODE_VERSION["presentation"],
    shell:
        "gearsim report --sweeps {params.sweep_dir} --catalogue {input.catalogue} "
        "--results {params.results} --calibration {params.calibration:q} "
        "--configfile {input.config} --out {output.report} > {log} 2>&1"


TARGETS_REPORT = [*rules.table1.output, rules.report.output.report]
