# Figures of the study (figures owner). Every rule only calls `gearsim figures`; which tables a
# figure reads is fixed by the paper (gearsim.figures.rules.FIGURE_INPUTS). A figure whose
# tables are not configured is left out of ALL_TARGETS.
# Outputs: results/figures/figNN.{png,pdf,json} and the index results/figures/README.md.
from gearsim.figures import rules as gfr

FIGURE_PARAMS = gfr.figure_params(config)
FIGURES_BUILT = gfr.built_figures(SWEEPS, PLANES, POINT_SETS)


rule figure:
    input:
        unpack(gfr.figure_inputs),
        config=CONFIG,
    output:
        png=report(
            "results/figures/fig{n}.png",
            caption="../report/figure.rst",
            category="Figures",
        ),
        pdf="results/figures/fig{n}.pdf",
        json="results/figures/fig{n}.json",
    log:
        "logs/figures/fig{n}.log",
    wildcard_constraints:
        n=gfr.FIGURE_WILDCARDS,
    conda:
        GEARSIM_ENV
    threads: 1
    params:
        args=gfr.figure_args,
        figure=FIGURE_PARAMS,
        code_version=CODE_VERSION,
    shell:
        "gearsim figures --fig {wildcards.n} {params.args} --configfile {input.config} "
        "--outdir results/figures > {log} 2>&1"


# Figs 9-11: one search for coexisting motions at the captioned point, three figures.
rule figures_double_sided:
    input:
        sweep="results/sweeps/b015.parquet",
        config=CONFIG,
    output:
        png9=report(
            "results/figures/fig09.png",
            caption="../report/fig09.rst",
            category="Figures",
        ),
        png10=report(
            "results/figures/fig10.png",
            caption="../report/fig10.rst",
            category="Figures",
        ),
        png11=report(
            "results/figures/fig11.png",
            caption="../report/fig11.rst",
            category="Figures",
        ),
        other=multiext("results/figures/fig09", ".pdf", ".json")
        + multiext("results/figures/fig10", ".pdf", ".json")
        + multiext("results/figures/fig11", ".pdf", ".json"),
    log:
        "logs/figures/fig09_11.log",
    conda:
        GEARSIM_ENV
    threads: 1
    params:
        figure=FIGURE_PARAMS,
        code_version=CODE_VERSION,
    shell:
        "gearsim figures --fig 9 10 11 --sweep b015={input.sweep} --configfile {input.config} "
        "--outdir results/figures > {log} 2>&1"


rule figures_index:
    input:
        expand("results/figures/fig{n:02d}.json", n=FIGURES_BUILT),
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
ALL_TARGETS += ["results/figures/README.md"]
