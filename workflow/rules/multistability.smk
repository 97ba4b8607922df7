# Coexisting attractors of the planes that set `multistability: {starts, seed}`
# (docs/multistability.md): one job per tile, after the plane's simulated tile (its
# forward-continuation states seed the finder), into the catalogue's `attractors` table.
MULTISTABLE_PLANES = [p for p in PLANES if config["planes"][p].get("multistability")]
# the finder's source decides the attractor tiles too (CODE_VERSION covers the simulation)
import gearsim.analysis.attractors as _ga

ATTRACTOR_CODE = hashlib.sha256(
    b"".join(p.read_bytes() for p in sorted(Path(_ga.__file__).parent.glob("*.py")))
).hexdigest()[:16]
ATTRACTOR_FILES = [
    f"results/{plane}/attractors/{tile}.parquet"
    for plane in MULTISTABLE_PLANES
    for tile in TILES[plane]
]


rule attractor_tile:
    input:
        compiled=COMPILED,
        config=CONFIG,
        tile="results/{plane}/tiles/{tile}.parquet",
    output:
        "results/{plane}/attractors/{tile}.parquet",
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
    params:
        config=plane_params,
        code_version=CODE_VERSION["analysis"],
        attractor_code=ATTRACTOR_CODE,
    shell:
        "gearsim attractor-tile --plane {wildcards.plane} --tile {wildcards.tile} "
        "--tile-file {input.tile} --configfile {input.config} --workers {threads} "
        "--out {output} > {log} 2>&1"


ALL_TARGETS += ATTRACTOR_FILES


rule attractor_maps:
    input:
        attractors=lambda wc: expand(
            "results/{plane}/attractors/{tile}.parquet", plane=wc.plane, tile=TILES[wc.plane]
        ),
        config=CONFIG,
    output:
        "results/figures/planes/{plane}-coexistence.png",
        "results/figures/planes/{plane}-forward-basin.png",
    log:
        "logs/{plane}/attractor_maps.log",
    conda:
        GEARSIM_ENV
    shell:
        "gearsim attractor-maps --plane {wildcards.plane} --attractors {input.attractors} "
        "--configfile {input.config} --out-dir results/figures/planes > {log} 2>&1"


ALL_TARGETS += expand(
    "results/figures/planes/{plane}-{kind}.png",
    plane=MULTISTABLE_PLANES,
    kind=("coexistence", "forward-basin"),
)
