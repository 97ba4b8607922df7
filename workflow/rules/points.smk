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
TARGETS_POINTS = POINT_FILES


# What the figures draw that is simulated (Fig 2's motions, Figs 9-11's attractor search, the
# basins of Figs 19 and 20): one job per table, from the sweeps it starts from; the figure jobs
# only read it (gearsim.study.figure_tables names the tables and what each reads).
rule figure_data:
    input:
        unpack(figure_data_sweeps),
        compiled=COMPILED,
        config=CONFIG,
    output:
        table="results/figure_data/{name}.parquet",
    log:
        "logs/figure_data/{name}.log",
    benchmark:
        "logs/benchmarks/figure_data/{name}.tsv"
    wildcard_constraints:
        name=_alternatives(FIGURE_DATA_TABLES),
    conda:
        GEARSIM_ENV
    threads: 1
    params:
        sweeps=lambda wildcards, input: " ".join(
            f"--sweep {n}={input[n]}" for n in gfd.FIGURE_DATA[wildcards.name].sweeps
        ),
        study=gprov.canonical_json(
            {
                "parameters": STUDY.parameters().model.to_dict(),
                "integration": STUDY.settings.to_dict(),
                "points": config.get("points", {}),
            }
        ),
        code_version=CODE_VERSION["analysis"],
    shell:
        "gearsim figure-data --name {wildcards.name} {params.sweeps} "
        "--configfile {input.config} --out {output.table} > {log} 2>&1"


FIGURE_DATA_FILES = dict(
    zip(FIGURE_DATA_TABLES, expand(rules.figure_data.output.table, name=FIGURE_DATA_TABLES))
)
