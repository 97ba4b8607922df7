# Planes: tiles (one job each, rows mapped over dask) -> cells.parquet per plane -> audit.


rule simulate_tile:
    input:
        compiled=COMPILED,
        config=CONFIG,
    output:
        tile="results/{plane}/tiles/{tile}.parquet",
    log:
        "logs/{plane}/tile_{tile}.log",
    benchmark:
        "logs/benchmarks/{plane}/tile_{tile}.tsv"
    # the planes' chain (tiles -> cells -> audit -> catalogue) is the longest: start it first,
    # the sweeps, points and figures fill the other core
    priority: 10
    conda:
        GEARSIM_ENV
    # one process per job, Snakemake runs --cores of them at once: no LocalCluster start-up per
    # job (~7 s of a tile job's wall on 2 idle cores; benchmarks/README.md (k)). With
    # cluster.scheduler_address set, each job still sends its tasks to that scheduler.
    threads: 1
    resources:
        gpu=GPU_JOBS,
    params:
        config=plane_params,
        code_version=CODE_VERSION["tiles"],
    shell:
        "gearsim simulate-tile --plane {wildcards.plane} --tile {wildcards.tile} "
        "--configfile {input.config} --workers {threads} --out {output.tile} > {log} 2>&1"


rule plane_cells:
    input:
        tiles=tiles_of_plane,
        config=CONFIG,
    output:
        cells="results/{plane}/cells.parquet",
    log:
        "logs/{plane}/cells.log",
    priority: 10
    conda:
        GEARSIM_ENV
    params:
        config=plane_params,
        code_version=CODE_VERSION["tiles"],
    shell:
        "gearsim catalogue cells --plane {wildcards.plane} --tiles {input.tiles} "
        "--configfile {input.config} --out {output.cells} > {log} 2>&1"


rule audit:
    input:
        cells=rules.plane_cells.output.cells,
        config=CONFIG,
    output:
        audit="results/{plane}/audit.parquet",
    log:
        "logs/{plane}/audit.log",
    benchmark:
        "logs/benchmarks/{plane}/audit.tsv"
    priority: 10
    conda:
        GEARSIM_ENV
    params:
        config=audit_params,
        code_version=CODE_VERSION["tiles"],
    shell:
        "gearsim catalogue audit --plane {wildcards.plane} --cells {input.cells} "
        "--configfile {input.config} --out {output.audit} > {log} 2>&1"


CELL_FILES = expand(rules.plane_cells.output.cells, plane=PLANES)
AUDIT_FILES = expand(rules.audit.output.audit, plane=PLANES) if AUDIT else []
TARGETS_PLANES = CELL_FILES
