"""Helpers of ``workflow/rules/figures.smk`` (kept here so the rules file holds only rules).

Everything comes from the one figure table :data:`gearsim.presentation.figures.registry.FIGURES`:
which
tables a figure reads (rule inputs and the CLI's ``--sweep/--plane/--points NAME=PATH``), which
figures are drawn together (one job per group, e.g. Figs 9-11), the report caption. Names are
those of the config (``sweeps``, ``planes``, ``points``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from gearsim.presentation.figures import registry


def groups(sweeps: Iterable[str], planes: Iterable[str], points: Iterable[str],
           orbits: Iterable[str] | None = None) -> list[registry.FigureSpec]:
    """The lead spec of every figure group whose inputs are all configured (one job each);
    ``orbits``: the continuation tables the pipeline makes (default: by their sweep / plane)."""
    sweeps, planes, points = list(sweeps), list(planes), list(points)
    orbits = None if orbits is None else list(orbits)
    out, seen = [], set()
    for spec in registry.figures().values():
        if spec.lead in seen:
            continue
        seen.add(spec.lead)
        lead = registry.FIGURES[spec.lead]
        if lead.available(sweeps, planes, points, orbits):
            out.append(lead)
    return out


def built_figures(sweeps, planes, point_sets, orbits=None) -> list[int]:
    """Every figure number the pipeline draws for this config."""
    return sorted(n for g in groups(sweeps, planes, point_sets, orbits) for n in g.members)


def _orbit_names(spec: registry.FigureSpec, orbits) -> list[str]:
    i = spec.inputs
    return [*i.orbits, *(o for o in i.optional_orbits if orbits is not None and o in orbits)]


def input_paths(spec: registry.FigureSpec, orbits=None) -> dict[str, list[str]]:
    """Rule inputs of a figure: its tables' paths, by kind (``orbits``: the continuation
    tables the pipeline makes; optional ones are inputs only when listed there)."""
    i = spec.inputs
    return {
        "sweeps": [f"results/sweeps/{s}.parquet" for s in i.sweeps],
        "planes": [f"results/{p}/cells.parquet" for p in i.planes],
        "points": [f"results/points/{p}.parquet" for p in i.points],
        "orbits": [f"results/orbits/{o}.parquet" for o in _orbit_names(spec, orbits)],
    }


def cli_args(spec: registry.FigureSpec, orbits=None) -> str:
    """``--fig N [M ...] --sweep NAME=PATH --plane NAME=PATH --points NAME=PATH``
    (``--orbits NAME=PATH``)."""
    paths = input_paths(spec, orbits)
    i = spec.inputs
    args = ["--fig", *(str(n) for n in spec.members)]
    args += [f"--sweep {n}={p}" for n, p in zip(i.sweeps, paths["sweeps"], strict=True)]
    args += [f"--plane {n}={p}" for n, p in zip(i.planes, paths["planes"], strict=True)]
    args += [f"--points {n}={p}" for n, p in zip(i.points, paths["points"], strict=True)]
    args += [f"--orbits {n}={p}" for n, p in zip(_orbit_names(spec, orbits), paths["orbits"],
                                                  strict=True)]
    return " ".join(args)


def outputs(spec: registry.FigureSpec) -> dict[str, list[str]]:
    """``png`` (report items), and the ``other`` files (PDF, JSON record) of a group."""
    stems = [f"results/figures/fig{n:02d}" for n in spec.members]
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
    return [f"results/figures/planes/{plane}-{kind}.{ext}" for kind in registry.PLANE_MAPS
            for ext in ("png", "pdf", "json")]


def sweep_diagram_outputs(sweep: str) -> list[str]:
    """The bifurcation diagram of a sweep (PNG, PDF, JSON record)."""
    return [f"results/figures/sweeps/{sweep}.{ext}" for ext in ("png", "pdf", "json")]


def figure_params(config: Mapping[str, Any]) -> str:
    """What the simulated figures (2, 5, 6, 9-11) depend on besides their tables (JSON)."""
    from gearsim.study import config as gcfg
    from gearsim.study import provenance as gprov

    return gprov.canonical_json(
        {
            "parameters": gcfg.resolved_parameters(config),
            "integration": gcfg.integration_settings(config).to_dict(),
            "points": config.get("points", {}),
            "sweeps": {k: v.get("fixed", {}) for k, v in config.get("sweeps", {}).items()},
        }
    )
