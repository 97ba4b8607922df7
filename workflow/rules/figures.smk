# Figures of the study (figures owner). One rule per figure group, generated from the one figure
# table gearsim.presentation.figures.registry.FIGURES (inputs, CLI arguments, outputs, captions); a figure
# whose tables are not configured is left out. Every plane, whatever its axes, also gets its
# maps (pattern, DC, Kmax, and any registered later) from rule plane_maps.
# Outputs: results/figures/figNN.{png,pdf,json}, results/figures/planes/<plane>-<kind>.*, and
# the index results/figures/README.md.
from gearsim.analysis.bifcurves import pipeline_orbit_tables
from gearsim.presentation.figures import rules as gfr

FIGURE_PARAMS = gfr.figure_params(config)
# continuation tables made by workflow/rules/orbits.smk (config `orbits:`)
ORBIT_TABLES = pipeline_orbit_tables(config)
FIGURE_GROUPS = gfr.groups(SWEEPS, PLANES, POINT_SETS, ORBIT_TABLES)
FIGURES_BUILT = gfr.built_figures(SWEEPS, PLANES, POINT_SETS, ORBIT_TABLES)


for _spec in FIGURE_GROUPS:

    rule:
        name:
            gfr.rule_name(_spec)
        input:
            **gfr.input_paths(_spec, ORBIT_TABLES),
            config=CONFIG,
            # a figure that simulates its own points waits for the compiled kernels (it would
            # otherwise compile them again beside the compile job)
            kernels=[] if _spec.tables_required else [COMPILED],
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
            args=gfr.cli_args(_spec, ORBIT_TABLES),
            caption=gfr.caption_params(_spec),
            figure=FIGURE_PARAMS,
            code_version=CODE_VERSION["presentation"],
        shell:
            "gearsim figures {params.args} --configfile {input.config} "
            "--outdir results/figures > {log} 2>&1"


rule plane_maps:
    input:
        cells="results/{plane}/cells.parquet",
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
        code_version=CODE_VERSION["presentation"],
    shell:
        "gearsim figures --maps --plane {wildcards.plane}={input.cells} "
        "--configfile {input.config} --outdir results/figures > {log} 2>&1"


# Every sweep of every study: its bifurcation diagram in the sweep's own units.
rule sweep_diagram:
    input:
        sweep="results/sweeps/{sweep}.parquet",
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
        code_version=CODE_VERSION["presentation"],
    shell:
        "gearsim figures --sweep-diagrams --sweep {wildcards.sweep}={input.sweep} "
        "--configfile {input.config} --outdir results/figures > {log} 2>&1"


rule figures_index:
    input:
        expand("results/figures/fig{n:02d}.json", n=FIGURES_BUILT),
        [f for plane in PLANES for f in gfr.map_outputs(plane) if f.endswith(".json")],
        [f for s in SWEEPS for f in gfr.sweep_diagram_outputs(s) if f.endswith(".json")],
    output:
        "results/figures/README.md",
    log:
        "logs/figures/index.log",
    conda:
        GEARSIM_ENV
    shell:
        "gearsim figures --index --outdir results/figures > {log} 2>&1"


ALL_TARGETS += expand(
    "results/figures/fig{n:02d}.{ext}", n=FIGURES_BUILT, ext=["png", "pdf"]
)
ALL_TARGETS += [f for plane in PLANES for f in gfr.map_outputs(plane)]
ALL_TARGETS += [f for s in SWEEPS for f in gfr.sweep_diagram_outputs(s)]
ALL_TARGETS += ["results/figures/README.md"]


# The explorer: one static page with every plane's maps and every sweep's diagram.
rule explorer:
    input:
        cells=expand("results/{plane}/cells.parquet", plane=PLANES),
        sweeps=expand("results/sweeps/{sweep}.parquet", sweep=SWEEPS),
        catalogue=CATALOGUE,
        config=CONFIG,
    output:
        "results/explorer/index.html",
    log:
        "logs/figures/explorer.log",
    conda:
        GEARSIM_ENV
    params:
        code_version=CODE_VERSION["presentation"],
    shell:
        "gearsim explorer --results results --catalogue {input.catalogue} "
        "--configfile {input.config} --out {output} > {log} 2>&1"


ALL_TARGETS += ["results/explorer/index.html"]
