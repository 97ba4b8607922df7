# Periodic orbits (docs/orbits.md): Newton refinement of every periodic cell of a plane.
# On demand only (not in `all`: ~60 ms per periodic cell, hours on a 400 x 400 plane):
#   snakemake --cores 2 results/wb/orbits.parquet


rule refine_orbits:
    input:
        cells="results/{plane}/cells.parquet",
        config=CONFIG,
    output:
        "results/{plane}/orbits.parquet",
    log:
        "logs/{plane}/orbits.log",
    benchmark:
        "logs/benchmarks/{plane}/orbits.tsv"
    conda:
        GEARSIM_ENV
    params:
        config=plane_params,
        code_version=CODE_VERSION,
    shell:
        "gearsim refine-orbits --plane {wildcards.plane} --cells {input.cells} "
        "--configfile {input.config} --out {output} > {log} 2>&1"


# Exact landmarks of the standard sweep (continuation from w = 0.1 to 2.5; the report lists them
# beside the grid-read ones when results/orbits/standard_points.parquet exists). On demand.
rule standard_continuation:
    input:
        sweep="results/sweeps/standard.parquet",
        config=CONFIG,
    output:
        branches="results/orbits/standard.parquet",
        points="results/orbits/standard_points.parquet",
        landmarks="results/orbits/standard_landmarks.parquet",
        figure="results/orbits/standard.png",
    log:
        "logs/orbits/standard.log",
    conda:
        GEARSIM_ENV
    params:
        code_version=CODE_VERSION,
    shell:
        "gearsim continue --name w --from 0.1 --to 2.5 --period 1 --sweep {input.sweep} "
        "--out {output.branches} --figure {output.figure} > {log} 2>&1"


# Two-parameter bifurcation curves over a plane's pattern map. On demand.
rule bifurcation_curves:
    input:
        cells="results/{plane}/cells.parquet",
        config=CONFIG,
    output:
        curves="results/orbits/{plane}_curves.parquet",
        points="results/orbits/{plane}_curves_points.parquet",
        branches="results/orbits/{plane}_curves_branches.parquet",
        figure="results/orbits/{plane}_curves.png",
    log:
        "logs/orbits/{plane}_curves.log",
    benchmark:
        "logs/benchmarks/orbits/{plane}_curves.tsv"
    conda:
        GEARSIM_ENV
    params:
        config=plane_params,
        code_version=CODE_VERSION,
    shell:
        "gearsim bifurcation-curves --plane {wildcards.plane} --cells {input.cells} "
        "--configfile {input.config} --out {output.curves} > {log} 2>&1"
