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
