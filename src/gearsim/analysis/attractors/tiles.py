"""The plane tiles' attractor records: one task of ``gearsim attractor-tile`` and its rows."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from gearsim.analysis.attractors.api import find_attractors
from gearsim.analysis.attractors.options import FinderOptions
from gearsim.analysis.attractors.results import CellAttractors, Steady, n_real
from gearsim.cell.simulate import IntegrationSettings, result_columns
from gearsim.dynamics.parameters import ModelParameters

#: Columns of a plane's attractor tile (results/<plane>/attractors/<tile>.parquet).
TILE_COLUMNS = ("plane", "tile", "i", "j", "x", "y", "attractor", "n_attractors", "motion",
                "status", "label", "label_npq", "I", "n", "p", "q", "dc", "kmax", "lyapunov",
                "basin_fraction", "n_starts", "n_early", "found_by", "starts",
                "diverged_fraction", "periods_run", "poincare_x", "poincare_v", "mu_max",
                "critical", "refined")  # fmt: skip




def grid_neighbours(ij: Sequence[tuple[int, int]]) -> list[list[int]]:
    """Per cell of a grid sample (its indices ``(i, j)`` along x and y): the nearest cells of
    the sample on either side along each axis (at most four), as indices into ``ij``."""
    rows: dict[int, list[tuple[int, int]]] = {}
    cols: dict[int, list[tuple[int, int]]] = {}
    for k, (i, j) in enumerate(ij):
        rows.setdefault(int(j), []).append((int(i), k))
        cols.setdefault(int(i), []).append((int(j), k))
    out: list[list[int]] = [[] for _ in ij]
    for line in list(rows.values()) + list(cols.values()):
        line.sort()
        for (_, a), (_, b) in zip(line, line[1:], strict=False):
            out[a].append(b)
            out[b].append(a)
    return out


def tile_records(spec: Mapping[str, Any], cells, found: Sequence[CellAttractors]
                 ) -> list[dict[str, Any]]:
    """The attractor-tile records (:data:`TILE_COLUMNS`) of ``cells`` and their attractors."""
    out: list[dict[str, Any]] = []
    for (i, j, x, y, _), ca in zip(cells, found, strict=True):
        common = {
            "plane": spec["plane"], "tile": int(spec["tile"]), "i": int(i), "j": int(j),
            "x": float(x), "y": float(y), "n_attractors": n_real(ca),
            "starts": int(ca.n_starts), "diverged_fraction": ca.diverged_fraction,
            "periods_run": int(ca.start_periods_run.sum()),
        }  # fmt: skip
        if not ca.attractors:
            out.append({**common, "attractor": -1, "motion": "diverged", "status": "diverged",
                        "label": "diverged", "label_npq": "", "I": 0, "n": 0, "p": None,
                        "q": None, "dc": float("nan"), "kmax": float("nan"),
                        "lyapunov": float("nan"), "basin_fraction": 0.0, "n_starts": 0,
                        "n_early": 0, "found_by": "", "poincare_x": [],
                        "poincare_v": [], "mu_max": float("nan"), "critical": "",
                        "refined": False})  # fmt: skip
            continue
        for a in ca.attractors:
            r = a.record()
            out.append({**common, **{k: r.get(k) for k in TILE_COLUMNS if k in r}})
    return out




def steady_from_row(row: Mapping[str, Any], w: float) -> Steady | None:
    """The :class:`~gearsim.analysis.attractors.Steady` of a plane tile's cell row (its
    classification, Poincare points and final state; ``w`` the cell's frequency ratio), None
    without them."""
    if row.get("poincare_x") is None or row.get("n") is None:
        return None
    info = {k: _plain(row.get(k)) for k in result_columns() if k in row}
    n = int(info.pop("n"))
    label = str(info.pop("label"))
    scale = float(info["x_max"]) - float(info["x_min"])
    scale = scale if math.isfinite(scale) else 0.0
    status, motion = info.get("status"), info.get("motion")
    return Steady(
        status="diverged" if status == "diverged" else (
            "unsettled" if motion == "unsettled" else "ok"),
        period=n,
        points=np.column_stack([np.asarray(row["poincare_x"], dtype=float),
                                np.asarray(row["poincare_v"], dtype=float)]),
        scale_x=scale,
        scale_v=scale * float(w),
        label=label,
        info=info,
        final_state=None if row.get("final_state") is None
        else np.asarray(row["final_state"], dtype=float),
    )  # fmt: skip


def _plain(v):
    """A Parquet value as a plain Python one (pandas' NA as None)."""
    if v is None:
        return None
    try:
        import pandas as pd

        if v is pd.NA:
            return None
    except ImportError:  # pragma: no cover
        pass
    return v.item() if isinstance(v, np.generic) else v


def cell_group_records(spec: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Attractor records of a group of plane cells (one task of ``gearsim attractor-tile``).

    ``spec`` (plain data): ``plane``, ``tile``, ``params`` (dict), ``settings`` (dict),
    ``x_name``, ``y_name``, ``cells`` (list of ``(i, j, x, y, forward_state or None)``),
    ``starts``, ``seed`` and optionally ``forward_rows`` (per cell the plane tile's row of
    that cell, or None: its motion is known without a run). One record per attractor of each
    cell; a cell whose starts all diverged gets one record with ``attractor = -1`` and label
    ``diverged``.
    """
    base = ModelParameters.from_mapping(dict(spec["params"]))
    settings = IntegrationSettings(**spec["settings"])
    xn, yn = spec["x_name"], spec["y_name"]
    cells = spec["cells"]
    plist = [base.with_(**{xn: float(c[2]), yn: float(c[3])}) for c in cells]
    fwd = [None if c[4] is None else np.asarray(c[4], dtype=float) for c in cells]
    rows = spec.get("forward_rows")
    known = None if rows is None else [None if r is None else steady_from_row(r, p.w)
                                       for r, p in zip(rows, plist, strict=True)]
    options = FinderOptions(starts=int(spec["starts"]), seed=int(spec["seed"]))
    found = find_attractors(plist, options, settings=settings, forward=fwd,
                            forward_results=known, stats=spec.get("stats"),
                            neighbours=grid_neighbours([(c[0], c[1]) for c in cells]))  # fmt: skip
    return tile_records(spec, cells, found)


