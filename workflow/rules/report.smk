# Reconstructed Table 1 and the study's report.
# The report reads exactly its declared inputs: the configured sweeps and their diagrams, the
# point sets, the catalogue (plane cells), each plane's cells and numerical audit, Table 1 and,
# when the repository has it, the calibration record docs/calibration.json (produced offline by
# `gearsim calibrate`, a long search that is not part of the workflow). Its planes, sweeps and
# points come from the config.
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
        sweeps=expand("results/sweeps/{sweep}.parquet", sweep=SWEEPS),
        catalogue=CATALOGUE,
        cells=expand("results/{plane}/cells.parquet", plane=PLANES),
        audits=expand("results/{plane}/audit.parquet", plane=PLANES) if AUDIT else [],
        calibration=[str(CALIBRATION)] if CALIBRATION.is_file() else [],
        table1="results/table1.md",
        # the sweeps' bifurcation diagrams the report links (workflow/rules/figures.smk)
        diagrams=expand("results/figures/sweeps/{sweep}.png", sweep=SWEEPS),
        points=expand("results/points/{points}.parquet", points=POINT_SETS),
        # exact landmarks by continuation (workflow/rules/orbits.smk)
        orbits=globals().get("ORBIT_REPORT_INPUTS", []),
        config=CONFIG,
    output:
        "results/report.md",
    log:
        "logs/report/report.log",
    conda:
        GEARSIM_ENV
    params:
        calibration=lambda wildcards, input: input.calibration or "",
        code_version=CODE_VERSION["presentation"],
    shell:
        "gearsim report --sweeps results/sweeps --catalogue {input.catalogue} "
        "--results results --calibration {params.calibration:q} --configfile {input.config} "
        "--out {output} > {log} 2>&1"


ALL_TARGETS += ["results/table1.md", "results/table1.csv", "results/report.md"]
