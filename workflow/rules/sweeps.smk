# One-parameter sweeps (bifurcation diagrams): one job per sweep, a single continuation chain.


rule sweep:
    input:
        compiled=COMPILED,
        config=CONFIG,
    output:
        table="results/sweeps/{sweep}.parquet",
    log:
        "logs/sweeps/{sweep}.log",
    benchmark:
        "logs/benchmarks/sweeps/{sweep}.tsv"
    conda:
        GEARSIM_ENV
    threads: 1
    params:
        config=sweep_params,
        code_version=CODE_VERSION["tiles"],
    shell:
        "gearsim sweep --name {wildcards.sweep} --configfile {input.config} "
        "--out {output.table} > {log} 2>&1"


SWEEP_FILES = expand(rules.sweep.output.table, sweep=SWEEPS)
TARGETS_SWEEPS = SWEEP_FILES
