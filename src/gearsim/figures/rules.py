"""Helpers of ``workflow/rules/figures.smk`` (kept here so the rules file holds only rules).

Which tables each figure reads is fixed by the paper; the names are those of
``config/config.yaml`` (sweeps ``standard``, ``b015``..., planes ``wb``, ``wxi``, point sets
``fig5``, ``fig6``, ``fig9_11``).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

# figure -> (sweeps, planes, point sets) it reads; Figs 9-11 have their own rule
FIGURE_INPUTS: dict[int, tuple[list[str], list[str], list[str]]] = {
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
DOUBLE_SIDED = (9, 10, 11)
DOUBLE_SIDED_INPUTS = (["b015"], [], ["fig9_11"])
FIGURE_WILDCARDS = "|".join(f"{n:02d}" for n in FIGURE_INPUTS)


def figure_inputs(wildcards) -> dict[str, list[str]]:
    sweeps, planes, points = FIGURE_INPUTS[int(wildcards.n)]
    return {
        "sweeps": [f"results/sweeps/{s}.parquet" for s in sweeps],
        "planes": [f"results/{p}/cells.parquet" for p in planes],
        "points": [f"results/points/{p}.parquet" for p in points],
    }


def figure_args(wildcards, input) -> str:  # noqa: A002 (Snakemake's name)
    """``--sweep/--plane/--points NAME=PATH`` for the CLI, names taken from the file paths."""
    args = [f"--sweep {Path(p).stem}={p}" for p in input.sweeps]
    args += [f"--plane {Path(p).parent.name}={p}" for p in input.planes]
    args += [f"--points {Path(p).stem}={p}" for p in input.points]
    return " ".join(args)


def built_figures(sweeps, planes, point_sets) -> list[int]:
    """The figures whose input tables are all configured."""

    def ok(spec):
        s, p, q = spec
        return all(x in sweeps for x in s) and all(x in planes for x in p) and all(
            x in point_sets for x in q
        )

    out = [n for n, spec in FIGURE_INPUTS.items() if ok(spec)]
    if ok(DOUBLE_SIDED_INPUTS):
        out += list(DOUBLE_SIDED)
    return sorted(out)


def figure_params(config: Mapping[str, Any]) -> str:
    """What the simulated figures (2, 5, 6, 9-11) depend on besides their tables (JSON)."""
    from .. import config as gcfg
    from .. import provenance as gprov

    return gprov.canonical_json(
        {
            "parameters": gcfg.resolved_parameters(config),
            "integration": gcfg.integration_settings(config).to_dict(),
            "points": config.get("points", {}),
            "sweeps": {k: v.get("fixed", {}) for k, v in config.get("sweeps", {}).items()},
        }
    )
