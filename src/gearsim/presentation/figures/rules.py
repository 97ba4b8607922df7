"""Helpers of ``workflow/rules/figures.smk`` (kept here so the rules file holds only rules).

Everything comes from the one figure table :data:`gearsim.presentation.figures.registry.FIGURES`:
which
tables a figure reads (rule inputs and the CLI's ``--sweep/--plane/--points NAME=PATH``), which
figures are drawn together (one job per group, e.g. Figs 9-11), the report caption. Names are
those of the config (``sweeps``, ``planes``, ``points``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from gearsim.presentation.figures import maps, registry
from gearsim.study.config import Study

#: where the figures, plane maps and sweep diagrams go (``gearsim figures --outdir``)
FIGURE_DIR = "results/figures"


def groups(files: Mapping[str, Mapping[str, str]]) -> list[registry.FigureSpec]:
    """The lead spec of every figure group whose inputs are all configured (one job each).
    ``files``: kind (``sweeps``, ``planes``, ``points``, ``orbits``, ``figure_data``) -> table
    name -> path, the
    tables the pipeline makes."""
    names = {kind: list(files.get(kind, {})) for kind in KINDS}
    out, seen = [], set()
    for spec in registry.figures().values():
        if spec.lead in seen:
            continue
        seen.add(spec.lead)
        lead = registry.FIGURES[spec.lead]
        if lead.available(names["sweeps"], names["planes"], names["points"], names["orbits"],
                          names["figure_data"]):
            out.append(lead)
    return out


def built_figures(files: Mapping[str, Mapping[str, str]]) -> list[int]:
    """Every figure number the pipeline draws for these tables (:func:`groups`)."""
    return sorted(n for g in groups(files) for n in g.members)


#: the kinds of table a figure reads, as ``Inputs`` fields and CLI options
KINDS = {"sweeps": "sweep", "planes": "plane", "points": "points", "orbits": "orbits",
         "figure_data": "figure-data"}


def _names(spec: registry.FigureSpec, kind: str, files: Mapping[str, Mapping[str, str]]
           ) -> list[str]:
    i = spec.inputs
    if kind != "orbits":
        return list(getattr(i, kind))
    return [*i.orbits, *(o for o in i.optional_orbits if o in files.get("orbits", {}))]


def input_paths(spec: registry.FigureSpec, files: Mapping[str, Mapping[str, str]]
                ) -> dict[str, list[str]]:
    """Rule inputs of a figure: its tables' paths, by kind. ``files``: kind -> table name ->
    path, the outputs of the rules that make them (``workflow/rules/figures.smk``); an optional
    continuation table is an input only when ``files["orbits"]`` has it."""
    return {kind: [files[kind][n] for n in _names(spec, kind, files)] for kind in KINDS}


def cli_args(spec: registry.FigureSpec, files: Mapping[str, Mapping[str, str]]) -> str:
    """``--fig N [M ...] --sweep NAME=PATH --plane NAME=PATH --points NAME=PATH``
    (``--orbits NAME=PATH``, ``--figure-data NAME=PATH``), the paths those of
    :func:`input_paths`."""
    paths = input_paths(spec, files)
    args = ["--fig", *(str(n) for n in spec.members)]
    for kind, option in KINDS.items():
        args += [f"--{option} {n}={p}"
                 for n, p in zip(_names(spec, kind, files), paths[kind], strict=True)]
    return " ".join(args)


def outputs(spec: registry.FigureSpec) -> dict[str, list[str]]:
    """``png`` (report items), and the ``other`` files (PDF, JSON record) of a group."""
    stems = [f"{FIGURE_DIR}/fig{n:02d}" for n in spec.members]
    return {"png": [f"{s}.png" for s in stems],
            "other": [f"{s}.{ext}" for s in stems for ext in ("pdf", "json")]}


def rule_name(spec: registry.FigureSpec) -> str:
    return "figure_" + "_".join(f"{n:02d}" for n in spec.members)


def report_captions(spec: registry.FigureSpec) -> list[str]:
    return [registry.FIGURES[n].report_caption for n in spec.members]


def caption_params(spec: registry.FigureSpec) -> dict[str, Any]:
    """What ``workflow/report/figure.rst`` renders: number, our line, the paper's caption."""
    return {"number": spec.number, "caption": spec.caption or spec.paper_caption,
            "paper_caption": spec.paper_caption, "in_paper": spec.in_paper}


def map_outputs(plane: str) -> list[str]:
    """The maps drawn for a plane of any axes (PNG, PDF, JSON of each registered kind)."""
    registry.figures()
    return [f"{FIGURE_DIR}/planes/{plane}-{kind}.{ext}" for kind in maps.PLANE_MAPS
            for ext in ("png", "pdf", "json")]


def sweep_diagram_outputs(sweep: str) -> list[str]:
    """The bifurcation diagram of a sweep (PNG, PDF, JSON record)."""
    return [f"{FIGURE_DIR}/sweeps/{sweep}.{ext}" for ext in ("png", "pdf", "json")]


def figure_params(study: Study) -> str:
    """What the figures of simulated motions (2, 5, 6, 9-11, 19, 20) state besides their
    tables (JSON)."""
    from gearsim.study import provenance as gprov

    config = study.config
    return gprov.canonical_json(
        {
            "parameters": study.parameters().model.to_dict(),
            "integration": study.settings.to_dict(),
            "points": config.get("points", {}),
            "sweeps": {k: v.get("fixed", {}) for k, v in config.get("sweeps", {}).items()},
        }
    )
