# The plane atlas (docs/atlas.md).
#
# For every plane with bifurcation curves (config `orbits: {curves: true}`, the default):
# each boundary edge of the pattern map classified by the located curve, fold band or chaotic
# band that explains it (a table reading, ~seconds), the cascade's doublings located along one
# line of the plane (a short continuation to period 16, ~20-60 CPU-s), and the paper's
# mechanisms measured on the whole plane. The report reads the summaries and links the
# unexplained edges.


rule atlas:
    input:
        cells=of_plane(lambda: rules.plane_cells.output.cells),
        curves=of_plane(lambda: rules.bifurcation_curves.output.curves),
        config=CONFIG,
    output:
        summary="results/atlas/{plane}.json",
        edges="results/atlas/{plane}_edges.parquet",
        unexplained="results/atlas/{plane}_unexplained.csv",
    log:
        "logs/atlas/{plane}.log",
    benchmark:
        "logs/benchmarks/atlas/{plane}.tsv"
    conda:
        GEARSIM_ENV
    params:
        config=plane_params,
        code_version=CODE_VERSION["analysis"],
    shell:
        "gearsim atlas --plane {wildcards.plane} --cells {input.cells} "
        "--curves {input.curves} --configfile {input.config} "
        "--out {output.summary} > {log} 2>&1"


# what the report reads (and links: the unexplained edges)
ATLAS_REPORT_INPUTS = expand(
    [rules.atlas.output.summary, rules.atlas.output.unexplained], plane=CURVE_PLANES
)
TARGETS_ATLAS = ATLAS_REPORT_INPUTS
