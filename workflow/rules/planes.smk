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


# On a GPU (execution.device cuda or auto) the same tile of every plane is one job: one call of
# the chain driver, both planes' chains in one launch (a plane's 400 chains alone leave the GPU
# nearly idle; README, "On a GPU"). Each plane's tile file is the one rule simulate_tile writes.
TOGETHER = GPU_JOBS and len(PLANES) > 1 and len({len(TILES[p]) for p in PLANES}) == 1


if TOGETHER:

    ruleorder: simulate_tiles_together > simulate_tile

    rule simulate_tiles_together:
        input:
            compiled=COMPILED,
            config=CONFIG,
        output:
            tiles=expand("results/{plane}/tiles/{{tile}}.parquet", plane=PLANES),
        log:
            "logs/tiles_together_{tile}.log",
        benchmark:
            "logs/benchmarks/tiles_together_{tile}.tsv"
        priority: 10
        conda:
            GEARSIM_ENV
        threads: 1
        resources:
            gpu=GPU_JOBS,
        params:
            config=planes_params,
            code_version=CODE_VERSION["tiles"],
            planes=" ".join(f"--plane {p}" for p in PLANES),
            outs=lambda wildcards, output: " ".join(f"--out {o}" for o in output.tiles),
        shell:
            "gearsim simulate-tile {params.planes} --tile {wildcards.tile} "
            "--configfile {input.config} {params.outs} > {log} 2>&1"
