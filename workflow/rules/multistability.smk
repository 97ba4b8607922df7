# Coexisting attractors of the planes that set `multistability: {starts, seed}`
# (docs/multistability.md): one job per tile, after the plane's simulated tile (its
# forward-continuation states seed the finder), into the catalogue's `attractors` table.


rule attractor_tile:
    input:
        compiled=COMPILED,
        config=CONFIG,
        tile=lambda wildcards: expand(
            rules.simulate_tile.output.tile, plane=wildcards.plane, tile=wildcards.tile
        ),
    output:
        attractors="results/{plane}/attractors/{tile}.parquet",
    log:
        "logs/{plane}/attractors_{tile}.log",
    benchmark:
        "logs/benchmarks/{plane}/attractors_{tile}.tsv"
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
        code_version=CODE_VERSION["attractors"],
    shell:
        "gearsim attractor-tile --plane {wildcards.plane} --tile {wildcards.tile} "
        "--tile-file {input.tile} --configfile {input.config} --workers {threads} "
        "--out {output.attractors} > {log} 2>&1"


ATTRACTOR_FILES = [
    f
    for plane in MULTISTABLE_PLANES
    for f in expand(
        rules.attractor_tile.output.attractors, plane=plane, tile=TILES[plane]
    )
]


rule attractor_maps:
    input:
        attractors=attractors_of_plane,
        config=CONFIG,
    output:
        coexistence="results/figures/planes/{plane}-coexistence.png",
        forward_basin="results/figures/planes/{plane}-forward-basin.png",
    log:
        "logs/{plane}/attractor_maps.log",
    conda:
        GEARSIM_ENV
    params:
        out_dir=lambda wildcards, output: Path(output.coexistence).parent,
        code_version=CODE_VERSION["presentation"],
    shell:
        "gearsim attractor-maps --plane {wildcards.plane} --attractors {input.attractors} "
        "--configfile {input.config} --out-dir {params.out_dir} > {log} 2>&1"


TARGETS_MULTISTABILITY = ATTRACTOR_FILES + expand(
    rules.attractor_maps.output, plane=MULTISTABLE_PLANES
)
