# Figures of the study. One rule per figure group, generated from the one figure table
# gearsim.presentation.figures.registry.FIGURES (inputs, CLI arguments, outputs, captions); a
# figure whose tables are not made for this config is left out. Every plane, whatever its axes,
# also gets its maps (pattern, DC, Kmax, and any registered later) from rule plane_maps.
# Outputs: results/figures/figNN.{png,pdf,json}, results/figures/planes/<plane>-<kind>.*, and
# the index results/figures/README.md (the figure table names them: presentation.figures.rules).
from gearsim.presentation.figures import rules as gfr

FIGURE_PARAMS = gfr.figure_params(STUDY)
# the tables a figure can read, by kind and name (what the figure groups are planned from; the
# files: table_files(), common.smk)
TABLE_NAMES = {
    "sweeps": SWEEPS,
    "planes": PLANES,
    "points": POINT_SETS,
    "orbits": ORBIT_TABLES,
    "figure_data": FIGURE_DATA_TABLES,
}
FIGURE_GROUPS = gfr.groups({kind: dict.fromkeys(names) for kind, names in TABLE_NAMES.items()})


for _spec in FIGURE_GROUPS:

    rule:
        name:
            gfr.rule_name(_spec)
        input:
            unpack(lambda wildcards, spec=_spec: gfr.input_paths(spec, table_files())),
            config=CONFIG,
        output:
            *[
                report(p, caption=f"../report/{c}", category="Figures")
                for p, c in zip(gfr.outputs(_spec)["png"], gfr.report_captions(_spec))
            ],
            *gfr.outputs(_spec)["other"],
        log:
            f"logs/figures/{gfr.rule_name(_spec)}.log",
        conda:
            GEARSIM_ENV
        threads: 1
        params:
            args=lambda wildcards, spec=_spec: gfr.cli_args(spec, table_files()),
            caption=gfr.caption_params(_spec),
            figure=FIGURE_PARAMS,
            outdir=lambda wildcards, output: Path(output[0]).parent,
            code_version=CODE_VERSION["presentation"],
        shell:
            "gearsim figures {params.args} --configfile {input.config} "
            "--outdir {params.outdir} > {log} 2>&1"


FIGURE_FILES = [f for g in FIGURE_GROUPS for fs in gfr.outputs(g).values() for f in fs]


rule plane_maps:
    input:
        cells=of_plane(lambda: rules.plane_cells.output.cells),
        config=CONFIG,
    output:
        [
            (
                report(p, caption="../report/plane_map.rst", category="Plane maps")
                if p.endswith(".png")
                else p
            )
            for p in gfr.map_outputs("{plane}")
        ],
    log:
        "logs/figures/maps_{plane}.log",
    conda:
        GEARSIM_ENV
    threads: 1
    params:
        outdir=lambda wildcards, output: Path(output[0]).parent.parent,
        code_version=CODE_VERSION["presentation"],
    shell:
        "gearsim figures --maps --plane {wildcards.plane}={input.cells} "
        "--configfile {input.config} --outdir {params.outdir} > {log} 2>&1"


MAP_FILES = expand(rules.plane_maps.output, plane=PLANES)


# Every sweep of every study: its bifurcation diagram in the sweep's own units.
rule sweep_diagram:
    input:
        sweep=lambda wildcards: expand(rules.sweep.output.table, sweep=wildcards.sweep),
        config=CONFIG,
    output:
        gfr.sweep_diagram_outputs("{sweep}"),
    log:
        "logs/figures/sweep_{sweep}.log",
    wildcard_constraints:
        sweep="[^/]+",
    conda:
        GEARSIM_ENV
    threads: 1
    params:
        outdir=lambda wildcards, output: Path(output[0]).parent.parent,
        code_version=CODE_VERSION["presentation"],
    shell:
        "gearsim figures --sweep-diagrams --sweep {wildcards.sweep}={input.sweep} "
        "--configfile {input.config} --outdir {params.outdir} > {log} 2>&1"


DIAGRAM_FILES = expand(rules.sweep_diagram.output, sweep=SWEEPS)


rule figures_index:
    input:
        [f for f in FIGURE_FILES + MAP_FILES + DIAGRAM_FILES if f.endswith(".json")],
    output:
        index=f"{gfr.FIGURE_DIR}/README.md",
    log:
        "logs/figures/index.log",
    conda:
        GEARSIM_ENV
    params:
        outdir=lambda wildcards, output: Path(output.index).parent,
    shell:
        "gearsim figures --index --outdir {params.outdir} > {log} 2>&1"




# The explorer: one static page with every plane's maps and every sweep's diagram.
rule explorer:
    input:
        cells=lambda wildcards: CELL_FILES,
        sweeps=lambda wildcards: SWEEP_FILES,
        catalogue=lambda wildcards: rules.catalogue.output.build,
        config=CONFIG,
    output:
        page="results/explorer/index.html",
    log:
        "logs/figures/explorer.log",
    conda:
        GEARSIM_ENV
    params:
        results=lambda wildcards, output: Path(output.page).parent.parent,
        code_version=CODE_VERSION["presentation"],
    shell:
        "gearsim explorer --results {params.results} --catalogue {input.catalogue} "
        "--configfile {input.config} --out {output.page} > {log} 2>&1"


TARGETS_FIGURES = (
    [f for f in FIGURE_FILES if not f.endswith(".json")]
    + MAP_FILES
    + DIAGRAM_FILES
    + [rules.figures_index.output.index, rules.explorer.output.page]
)
