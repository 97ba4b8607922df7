# Periodic orbits (docs/orbits.md).
#
# In the default run (`all`), unless config `orbits: {continuation: false, curves: false}`:
#  * standard_continuation: the continuation of the standard sweep's parameter set along w
#    (Newton-Floquet, branch switching at period doublings): the exact landmarks of the report,
#    Fig 4's unstable branches and exact marks, Fig 23; ~2-3 CPU-minutes.
#  * bifurcation_curves: per plane, the plane atlas: every boundary of the plane's pattern map
#    seeds a bifurcation curve (fold, period doubling of every period to 16, grazing of both
#    flanks) located by Newton-Floquet and followed across the plane, and the codimension-2
#    points where curves end or meet: Figs 21, 22 and the catalogue tables bifurcation_points /
#    bifurcation_curves. Two processes per job; progress in logs/orbits/{plane}_curves.log.
# On demand only (not in `all`: ~60 ms per periodic cell, hours on a 400 x 400 plane):
#   snakemake --cores 2 results/wb/orbits.parquet


rule refine_orbits:
    input:
        cells=of_plane(lambda: rules.plane_cells.output.cells),
        config=CONFIG,
    output:
        orbits="results/{plane}/orbits.parquet",
    log:
        "logs/{plane}/orbits.log",
    benchmark:
        "logs/benchmarks/{plane}/orbits.tsv"
    conda:
        GEARSIM_ENV
    params:
        config=plane_params,
        code_version=CODE_VERSION["analysis"],
    shell:
        "gearsim refine-orbits --plane {wildcards.plane} --cells {input.cells} "
        "--configfile {input.config} --out {output.orbits} > {log} 2>&1"

# Exact landmarks of the standard sweep: continuation over the sweep's range from its start.
rule standard_continuation:
    input:
        sweep=lambda wildcards: expand(rules.sweep.output.table, sweep="standard"),
        config=CONFIG,
    output:
        branches="results/orbits/standard.parquet",
        points="results/orbits/standard_points.parquet",
        landmarks="results/orbits/standard_landmarks.parquet",
        figure="results/orbits/standard.png",
    log:
        "logs/orbits/standard.log",
    benchmark:
        "logs/benchmarks/orbits/standard.tsv"
    conda:
        GEARSIM_ENV
    params:
        start=config["sweeps"]["standard"]["min"] if ORBITS_STANDARD else 0,
        stop=config["sweeps"]["standard"]["max"] if ORBITS_STANDARD else 0,
        code_version=CODE_VERSION["analysis"],
    shell:
        "gearsim continue --configfile {input.config} --of-sweep standard --name w "
        "--from {params.start} --to {params.stop} --period 1 --sweep {input.sweep} "
        "--out {output.branches} "
        "--figure {output.figure} > {log} 2>&1"

# The plane atlas: bifurcation curves seeded from the boundaries of a plane's pattern map.
rule bifurcation_curves:
    input:
        cells=of_plane(lambda: rules.plane_cells.output.cells),
        config=CONFIG,
    output:
        curves="results/orbits/{plane}_curves.parquet",
        points="results/orbits/{plane}_curves_points.parquet",
        branches="results/orbits/{plane}_curves_branches.parquet",
        codim2="results/orbits/{plane}_codim2.parquet",
        figure="results/orbits/{plane}_curves.png",
    log:
        "logs/orbits/{plane}_curves.log",
    benchmark:
        "logs/benchmarks/orbits/{plane}_curves.tsv"
    conda:
        GEARSIM_ENV
    threads: 2
    params:
        config=plane_params,
        code_version=CODE_VERSION["analysis"],
    shell:
        "gearsim bifurcation-curves --plane {wildcards.plane} --cells {input.cells} "
        "--workers {threads} --configfile {input.config} "
        "--out {output.curves} > {log} 2>&1"

# the continuation tables by the names the figures read (figures.registry, `Inputs.orbits`)
ORBIT_FILES = (
    {"standard": rules.standard_continuation.output.branches} if ORBITS_STANDARD else {}
)
ORBIT_FILES.update(
    {
        f"{plane}_curves": expand(rules.bifurcation_curves.output.curves, plane=plane)[
            0
        ]
        for plane in CURVE_PLANES
    }
)
# what the catalogue loads (bifurcation_points, bifurcation_curves)
ORBIT_CATALOGUE_FILES = [
    f
    for plane in CURVE_PLANES
    for f in expand(
        [
            rules.bifurcation_curves.output.points,
            rules.bifurcation_curves.output.curves,
        ],
        plane=plane,
    )
]
# what the report reads: the located points of the standard continuation, and each plane's
# curves (the report says which planes' curves were skipped or cut)
ORBIT_REPORT_INPUTS = (
    [rules.standard_continuation.output.points] if ORBITS_STANDARD else []
) + expand(rules.bifurcation_curves.output.curves, plane=CURVE_PLANES)
# the codimension-2 points of each plane's curves (docs/orbits.md, "The plane atlas")
ORBIT_CODIM2_FILES = expand(rules.bifurcation_curves.output.codim2, plane=CURVE_PLANES)
TARGETS_ORBITS = ORBIT_CATALOGUE_FILES + ORBIT_REPORT_INPUTS + ORBIT_CODIM2_FILES
