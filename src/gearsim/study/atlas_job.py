"""The atlas job of one plane (``gearsim bifurcation-curves``): the plane's grid and base
parameters from the study, its map's cells, the curves seeded from the map's boundaries
(:func:`gearsim.analysis.atlas.plane_atlas`), their codimension-2 points, and the provenance
of the tables."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pandas as pd

from gearsim.analysis.atlas import (
    ATLAS_COLUMNS,
    SEED_COLUMNS,
    AtlasOptions,
    apply_codim2,
    plane_atlas,
)
from gearsim.analysis.atlas_seeds import Grid
from gearsim.analysis.bifcurves import CURVE_COLUMNS
from gearsim.analysis.codim2 import CODIM2_COLUMNS, codim2_points
from gearsim.analysis.continuation import COLUMNS as BRANCH_COLUMNS
from gearsim.analysis.continuation_options import Continuation
from gearsim.errors import UsageError
from gearsim.study import provenance as gprov
from gearsim.study.config import Study

#: A plane whose cells are more than this fraction diverged or out of their step budget (stiff)
#: has no periodic orbits to follow: its curves are skipped (status 'skipped').
MAX_UNUSABLE = 0.5
KINDS = ("fold", "period_doubling", "grazing", "neimark_sacker")
#: the cells table's columns the atlas reads
CELL_COLUMNS = ("i", "j", "motion", "status", "label", "n", "I", "p", "q", "final_state")
#: read where the table has them: the readings that tell a jump (a fold seeds there first)
JUMP_COLUMNS = ("dc", "x_min", "x_max")


def _cpu() -> float:
    """CPU seconds of this process and its finished worker processes."""
    import resource

    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def plane_grid(study: Study, plane: str) -> Grid:
    pl = study.config["planes"][plane]
    return Grid(pl["x"]["name"], pl["y"]["name"], float(pl["x"]["min"]), float(pl["x"]["max"]),
                int(pl["x"]["n"]), float(pl["y"]["min"]), float(pl["y"]["max"]),
                int(pl["y"]["n"]))


def read_cells(path: str | Path) -> pd.DataFrame:
    """The map's cells (the columns the atlas reads); one line naming the file when it is
    missing or not a cells table."""
    p = Path(path)
    if not p.is_file():
        raise UsageError(f"--cells: file not found: {path}")
    try:
        import pyarrow.parquet as pq

        have = set(pq.read_schema(p).names)
        return pd.read_parquet(p, columns=[*CELL_COLUMNS,
                                           *(c for c in JUMP_COLUMNS if c in have)])
    except Exception as exc:  # pyarrow: a foreign or damaged file
        cause = " ".join(str(exc).split()) or type(exc).__name__
        raise UsageError(f"--cells: {path} is not a readable cells table ({cause})") from None


def unusable(cells: pd.DataFrame, path: str | Path) -> str | None:
    """Why a plane's curves are not worth following (most cells diverged or stiff), or None."""
    if not len(cells):
        return f"plane has no cells in {path}"
    bad = cells["status"].isin(["diverged", "budget"])
    if float(bad.mean()) > MAX_UNUSABLE:
        return (f"{int(bad.sum())} of {len(cells)} cells diverged or out of their step budget "
                f"(more than {MAX_UNUSABLE:.0%}): no periodic orbits to follow")
    return None


def run_atlas(study: Study, plane: str, cells_path: str | Path, *, kinds: tuple[str, ...],
              max_period: int, workers: int, method: str, budget_s: float, started: str,
              progress=None) -> dict[str, Any]:
    """The plane's atlas: ``{"curves", "seeds", "codim2", "branches", "provenance",
    "stats", "reasons", "status", "cells"}`` (``status`` ``ok``, ``budget`` or ``skipped``)."""
    for k in kinds:
        if k not in KINDS:
            raise UsageError(f"--kinds: {k!r} is not one of {', '.join(KINDS)}")
    if max_period < 1:
        raise UsageError(f"--max-period = {max_period} must be >= 1")
    grid = plane_grid(study, plane)
    cells = read_cells(cells_path)
    base = study.parameters(plane=plane).model
    t0 = time.perf_counter()
    c0 = _cpu()
    skip = unusable(cells, cells_path)
    reasons: list[str]
    if skip is not None:
        reasons = [f"curves skipped: {skip}"]
        atlas = {"curves": pd.DataFrame(columns=[*CURVE_COLUMNS, *ATLAS_COLUMNS]),
                 "seeds": pd.DataFrame(columns=list(SEED_COLUMNS)), "stats": {},
                 "reasons": reasons, "branches": pd.DataFrame(columns=list(BRANCH_COLUMNS))}
        codim2 = pd.DataFrame(columns=list(CODIM2_COLUMNS))
        status = "skipped"
    else:
        cfg = Continuation(progress=progress, deadline=time.monotonic() + budget_s)
        opts = AtlasOptions(kinds=kinds, max_period=max_period, workers=workers, method=method,
                            config=cfg)
        atlas = plane_atlas(base, cells, grid, opts)
        codim2 = codim2_points(base, atlas["curves"], grid, opts, atlas["ends"])
        atlas["curves"] = apply_codim2(atlas["curves"], atlas["ends"], grid)
        reasons = atlas["reasons"]
        status = "budget" if atlas["stats"].get("budget") else "ok"
    wall = time.perf_counter() - t0
    return {**atlas, "codim2": codim2, "status": status, "cells": cells_path,
            "wall_s": wall, "cpu_s": _cpu() - c0, "grid": grid,
            "started": started}


def atlas_provenance(study: Study, plane: str, res: dict[str, Any], finished: str,
                     budget_s: float) -> dict[str, Any]:
    """The provenance record of the plane's atlas tables."""
    return gprov.provenance(
        gprov.plane_subtree(study, plane), kind="curves", name=plane, study=study,
        scope="analysis", started=res["started"], finished=finished, wall_s=res["wall_s"],
        cpu_s=res["cpu_s"], reasons=res["reasons"], stats=res.get("stats", {}),
        workers="in-process", status=res["status"], budget_s=budget_s,
    )
