# Figures of the study (figures owner). Every rule only calls `gearsim figures`; which tables a
# figure reads is fixed by the paper (sweeps b015..xi015, planes wb and wxi, point sets fig5,
# fig6, fig9_11). A figure whose tables are not configured is left out of ALL_TARGETS.
# Outputs: results/figures/figNN.{png,pdf,json}; results/figures/README.md (the index).

FIGDIR = "results/figures"


def _figure_params():
    """What the simulated figures (2, 5, 6, 9-11) depend on besides their input tables."""
    return gt.canonical_json(
        {
            "parameters": gt.resolved_parameters(config),
            "integration": gt.integration_settings(config).to_dict(),
            "points": config["points"],
            "sweeps": {k: v.get("fixed", {}) for k, v in config["sweeps"].items()},
        }
    )


FIGURE_PARAMS = _figure_params()

# figure -> (sweeps, planes, point sets) it reads
FIGURE_INPUTS = {
    1: ([], [], []),
    2: (["b015"], [], []),
    3: ([], ["wb"], []),
    4: (["standard"], [], []),
    5: ([], [], ["fig5"]),
    6: ([], [], ["fig6"]),
    7: ([], ["wb"], []),
    8: (["b015", "b025", "b035"], [], []),
    12: ([], ["wb"], []),
    13: ([], ["wb"], []),
    14: ([], ["wxi"], []),
    15: (["xi005", "xi009", "xi015"], [], []),
    16: ([], ["wxi"], []),
    17: ([], ["wxi"], []),
}


def _configured(sweeps, planes, points):
    return (
        all(s in SWEEPS for s in sweeps)
        and all(p in PLANES for p in planes)
        and all(p in POINT_SETS for p in points)
    )


def figure_inputs(wildcards):
    sweeps, planes, points = FIGURE_INPUTS[int(wildcards.n)]
    return {
        "sweeps": [f"results/sweeps/{s}.parquet" for s in sweeps],
        "planes": [f"results/{p}/cells.parquet" for p in planes],
        "points": [f"results/points/{p}.parquet" for p in points],
    }


def figure_args(wildcards, input):
    """--sweep/--plane/--points NAME=PATH for the CLI (names from the file paths)."""
    args = []
    for path in input.sweeps:
        args.append(f"--sweep {Path(path).stem}={path}")
    for path in input.planes:
        args.append(f"--plane {Path(path).parent.name}={path}")
    for path in input.points:
        args.append(f"--points {Path(path).stem}={path}")
    return " ".join(args)


rule figure:
    input:
        unpack(figure_inputs),
        config=CONFIG,
    output:
        png=report(
            FIGDIR + "/fig{n}.png",
            caption="../report/fig{n}.rst",
            category="Figures",
        ),
        pdf=FIGDIR + "/fig{n}.pdf",
        json=FIGDIR + "/fig{n}.json",
    wildcard_constraints:
        n="|".join(f"{n:02d}" for n in FIGURE_INPUTS),
    log:
        "logs/figures/fig{n}.log",
    conda:
        GEARSIM_ENV
    threads: 1
    params:
        args=figure_args,
        figure=FIGURE_PARAMS,
        code_version=CODE_VERSION,
    shell:
        "gearsim figures --fig {wildcards.n} {params.args} --configfile {input.config} "
        "--outdir " + FIGDIR + " > {log} 2>&1"


# Figs 9-11: one search for coexisting motions at the captioned point, three figures.
rule figures_double_sided:
    input:
        sweep="results/sweeps/b015.parquet",
        config=CONFIG,
    output:
        png9=report(FIGDIR + "/fig09.png", caption="../report/fig09.rst", category="Figures"),
        png10=report(FIGDIR + "/fig10.png", caption="../report/fig10.rst", category="Figures"),
        png11=report(FIGDIR + "/fig11.png", caption="../report/fig11.rst", category="Figures"),
        other=multiext(FIGDIR + "/fig09", ".pdf", ".json")
        + multiext(FIGDIR + "/fig10", ".pdf", ".json")
        + multiext(FIGDIR + "/fig11", ".pdf", ".json"),
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
        "--outdir " + FIGDIR + " > {log} 2>&1"


FIGURES_BUILT = [n for n, spec in FIGURE_INPUTS.items() if _configured(*spec)]
if "b015" in SWEEPS and "fig9_11" in POINT_SETS:
    FIGURES_BUILT += [9, 10, 11]
FIGURES_BUILT = sorted(FIGURES_BUILT)


rule figures_index:
    input:
        expand(FIGDIR + "/fig{n:02d}.json", n=FIGURES_BUILT),
    output:
        FIGDIR + "/README.md",
    log:
        "logs/figures/index.log",
    conda:
        GEARSIM_ENV
    shell:
        "gearsim figures --index --outdir " + FIGDIR + " > {log} 2>&1"


ALL_TARGETS += expand(FIGDIR + "/fig{n:02d}.{ext}", n=FIGURES_BUILT, ext=["png", "pdf"])
ALL_TARGETS += [FIGDIR + "/README.md"]
