# Named points of the figures (phase portraits, spectra): each point reached by a forward ramp in
# w and from rest, with a recorded trajectory. One job per point set.


rule points:
    input:
        compiled=COMPILED,
        config=CONFIG,
    output:
        table="results/points/{fig}.parquet",
    log:
        "logs/points/{fig}.log",
    benchmark:
        "logs/benchmarks/points/{fig}.tsv"
    conda:
        GEARSIM_ENV
    threads: 1
    params:
        config=point_params,
        code_version=CODE_VERSION["tiles"],
    shell:
        "gearsim sweep --points {wildcards.fig} --configfile {input.config} "
        "--out {output.table} > {log} 2>&1"


POINT_FILES = expand(rules.points.output.table, fig=POINT_SETS)
ALL_TARGETS += POINT_FILES
