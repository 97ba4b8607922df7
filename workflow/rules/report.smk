# Reconstructed Table 1 and the reproduction report (calibration + report owner).
# Inputs: the sweeps, the catalogue (plane cells) and the standard-parameter file; the
# calibration record docs/calibration.json is read when present (it is produced offline by
# `gearsim calibrate`, a long search that is not part of the workflow).


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
        table1="results/table1.md",
    output:
        "results/report.md",
    log:
        "logs/report/report.log",
    conda:
        GEARSIM_ENV
    params:
        code_version=CODE_VERSION,
    shell:
        "gearsim report --sweeps results/sweeps --catalogue {input.catalogue} "
        "--results results --out {output} > {log} 2>&1"


ALL_TARGETS += ["results/table1.md", "results/table1.csv", "results/report.md"]
