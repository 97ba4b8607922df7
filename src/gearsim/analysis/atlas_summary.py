"""A plane's atlas: its boundary edges accounted for (:mod:`gearsim.analysis.boundaries`),
its chaotic band along one line (:mod:`gearsim.analysis.cascade`) and the paper's mechanisms
measured over the whole plane, as one JSON-ready summary.

The mechanisms (the paper's claims, :mod:`gearsim.analysis.paper`), each measured on every
edge or cell of the plane, not on one sweep:

* ``grazing``: of the edges between a non-impact (``I = 0``) and an impact periodic motion,
  the share on a grazing curve (and on a fold: the jump);
* ``doubling``: of the edges between two periodic impact motions (``I != 0`` on both sides),
  the share on a period-doubling curve (and on a grazing curve);
* ``b_independence`` (a (w, b) plane): above the paper's backlash threshold, the largest
  ``|dw/db|`` of any curve segment and the edges along b (a pattern that depends on b);
* ``damping`` (a (w, xi) plane): the impact and the chaotic areas (share of the cells) in
  each quarter of the xi range, and their rank correlation with xi.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from gearsim.analysis import boundaries as bd
from gearsim.analysis.paper import PAPER_B_THRESHOLD, PAPER_SEQUENCES, PAPER_SWEEPS


def _share(part: int, whole: int) -> float | None:
    return None if whole == 0 else part / whole


def mechanisms(edges: pd.DataFrame) -> dict[str, Any]:
    """The grazing and doubling mechanisms measured on the plane's edges."""
    per = edges["group"].isin(("I changes", "I the same"))
    i0, i1 = edges["I0"], edges["I1"]
    contact = per & ((i0 == 0) != (i1 == 0)) & (i0 != -2) & (i1 != -2)
    impact = per & (i0 != 0) & (i1 != 0) & (i0 != -2) & (i1 != -2)
    m = edges["mechanism"]
    out = {}
    for key, sel in (("grazing", contact), ("doubling", impact)):
        sub = m[sel]
        out[key] = {"edges": int(sel.sum()),
                    **{k: int((sub == k).sum()) for k in bd.MECHANISMS if (sub == k).any()}}
    return out


def b_independence(curves: pd.DataFrame | None, edges: pd.DataFrame, y_name: str,
                   x_name: str = "w", above: float = PAPER_B_THRESHOLD) -> dict[str, Any]:
    """Above ``y = above``: the largest ``|dx/dy|`` of any curve segment reaching above it
    (a straight segment's slope is that of its part above; and its curve), and the edges
    between cells along y (a label that changes with y)."""
    worst, which = 0.0, None
    for line in bd.curve_polylines(curves, x_name):
        xy = line["xy"]
        ok = (xy[:-1, 1] > above) | (xy[1:, 1] > above)
        dx, dy = np.diff(xy[:, 0])[ok], np.diff(xy[:, 1])[ok]
        keep = np.abs(dy) > 0
        if keep.any():
            s = float(np.max(np.abs(dx[keep] / dy[keep])))
            if s > worst:
                worst, which = s, f"{line['kind']} {line['boundary']} {line['period']}T".replace(
                    "  ", " ")
    up = edges[(edges["axis"] == "y") & (edges["y"] > above)]
    return {"parameter": y_name, "above": above, "max_slope": worst, "curve": which,
            "edges_along_y": int(len(up)),
            "edges_along_y_periodic": int(up["group"].isin(("I changes", "I the same")).sum())}


def damping(cells: pd.DataFrame, quarters: int = 4) -> dict[str, Any]:
    """The impact area (cells with ``I != 0``: periodic, chaotic or other) and the chaotic
    area (``motion == chaos``) per band of the plane's y axis (``quarters`` equal bands),
    with Spearman's rank correlation of each row's areas with y."""
    from scipy.stats import spearmanr

    y = cells["y"].to_numpy(float)
    impact = (cells["I"].fillna(0).to_numpy() != 0) & (cells["I"].fillna(0).to_numpy() != -2)
    chaos = (cells["motion"] == "chaos").to_numpy()
    rows = pd.DataFrame({"y": y, "impact": impact, "chaos": chaos}).groupby("y").mean()
    edges = np.linspace(y.min(), y.max(), quarters + 1)
    bands = []
    for k in range(quarters):
        sel = (y >= edges[k]) & ((y < edges[k + 1]) if k < quarters - 1 else (y <= edges[k + 1]))
        bands.append({"lo": float(edges[k]), "hi": float(edges[k + 1]),
                      "impact": float(impact[sel].mean()), "chaos": float(chaos[sel].mean())})
    out = {"bands": bands}
    for key in ("impact", "chaos"):
        v = rows[key].to_numpy(float)
        rho = spearmanr(rows.index.to_numpy(float), v).statistic if np.ptp(v) > 0 else math.nan
        out[f"rho_{key}"] = float(rho)
    return out


def _pairs(edges: pd.DataFrame, cells: pd.DataFrame, top: int = 10) -> list[dict[str, Any]]:
    """The most frequent label pairs of the unexplained edges (group, pair, verdict, edges)."""
    u = bd.unexplained(edges, cells)
    if not len(u):
        return []
    t = u.groupby(["group", "pair", "verdict"]).size().rename("edges").reset_index()
    t = t.sort_values("edges", ascending=False).head(top)
    return t.to_dict("records")


def crises(edges: pd.DataFrame, top: int = 8) -> list[dict[str, Any]]:
    """Where the chaotic band ends abruptly (edges classified ``crisis``), as the grid reads
    it: per pair of labels, the edges and the extent of their midpoints."""
    c = edges[edges["mechanism"] == "crisis"]
    if not len(c):
        return []
    pair = [" | ".join(sorted((a, b))) for a, b in zip(c["label0"], c["label1"], strict=True)]
    t = c.assign(pair=pair).groupby("pair").agg(edges=("x", "size"), x_lo=("x", "min"),
                                                 x_hi=("x", "max"), y_lo=("y", "min"),
                                                 y_hi=("y", "max")).reset_index()
    return t.sort_values("edges", ascending=False).head(top).to_dict("records")


def plane_atlas(cells: pd.DataFrame, curves: pd.DataFrame | None, *, plane: str,
                x_name: str, y_name: str, newton=None) -> tuple[pd.DataFrame, dict[str, Any]]:
    """The classified edges (:func:`gearsim.analysis.boundaries.classify_edges`; with
    ``newton``, the unexplained periodic ones read by Newton,
    :func:`gearsim.analysis.boundaries.apply_newton`) and the plane's summary: the near-curve
    table, boundary length by mechanism, the periodic groups' explained shares, the
    mechanisms and the axis-specific claims."""
    edges = bd.classify_edges(cells, curves, plane, x_name)
    if newton is not None:
        edges = bd.apply_newton(edges, newton)
    near = bd.near_table(edges)
    mech = bd.mechanism_table(edges)
    g = bd.plane_grid(cells)
    summary: dict[str, Any] = {
        "plane": plane, "x": x_name, "y": y_name, "cells": int(len(cells)),
        "cell": [g.dx, g.dy], "near_cells": bd.NEAR_CELLS,
        "curves": 0 if curves is None or not len(curves) else int(curves["curve"].nunique()),
        "edges": int(len(edges)),
        "near": near.to_dict("records"),
        "by_mechanism": mech.to_dict("records"),
        "explained": {k: list(v) for k, v in bd.explained_share(edges).items()},
        "mechanisms": mechanisms(edges),
        "unexplained_pairs": _pairs(edges, cells),
        "unexplained_verdicts": {k: int(v) for k, v in bd.unexplained(edges, cells).get(
            "verdict", pd.Series(dtype=str)).value_counts().items()},
        "newton": newton_summary(edges),
        "crises": crises(edges),
    }
    if y_name == "b":
        summary["b_independence"] = b_independence(curves, edges, y_name, x_name)
    if y_name == "xi":
        summary["damping"] = damping(cells)
    return edges, summary


def newton_summary(edges: pd.DataFrame) -> dict[str, Any] | None:
    """Per periodic group: the edges Newton read (those no curve or band explains, periods up
    to :data:`gearsim.analysis.coexistence.MAX_PERIOD`), those across coexisting motions and
    those with a label Newton refutes; None when Newton did not run."""
    if "coexist" not in edges:
        return None
    from gearsim.analysis.coexistence import MAX_PERIOD

    out: dict[str, Any] = {"max_period": MAX_PERIOD}
    refuted = bd.newton_refuted(edges)
    for g in ("I changes", "I the same"):
        sel = (edges["group"] == g).to_numpy()
        read = sel & ((edges["newton_n0"] > 0) | (edges["newton_n1"] > 0)).to_numpy()
        out[g] = {"read": int(read.sum()), "coexist": int((sel & edges["coexist"].to_numpy(
            bool)).sum()), "wrong_label": int((sel & refuted).sum())}
    return out


def default_line(y_name: str, base_value: float) -> float:
    """The line of a plane's cascade: the paper's sweep of that parameter whose sequence runs
    into chaos (Fig 15a: xi = 0.05), else the base value (the standard set)."""
    for key, (name, value) in PAPER_SWEEPS.items():
        if name == y_name and "chaos" in PAPER_SEQUENCES.get(key, ()):
            return float(value)
    return float(base_value)


def cascade_line(cells: pd.DataFrame, y_value: float) -> tuple[float, dict | None]:
    """The plane row nearest ``y_value`` that has a grid-read cascade into chaos
    (:func:`gearsim.analysis.cascade.grid_cascade`), searched outwards from it: ``(y, reading)``;
    ``(nan, None)`` when no row has one."""
    from gearsim.analysis.cascade import grid_cascade

    ys = np.sort(cells["y"].unique())
    for y in sorted(ys, key=lambda v: abs(v - y_value)):
        reading = grid_cascade(cells[cells["y"] == y])
        if reading is not None and len(reading["periods"]) >= 3:
            return float(y), reading
    return math.nan, None


def _located(branches: pd.DataFrame, start: float, stop: float) -> dict[str, Any]:
    """The cascade located by a continuation from ``start`` towards ``stop``: its doublings,
    ratios and accumulation."""
    from gearsim.analysis.cascade import FEIGENBAUM, accumulation, cascade_doublings

    d = cascade_doublings(branches, start, stop)
    w_inf, delta = accumulation(d)
    rows = []
    for k, r in enumerate(d.itertuples(index=False)):
        smooth = None
        if k >= 2:  # the ratio of intervals k-1 and k: smooth when neither has a grazing
            smooth = not (bool(d["grazing_before"].iat[k - 1]) or bool(r.grazing_before))
        rows.append({"period": int(r.period), "value": float(r.value),
                     "interval": None if k == 0 else float(r.interval),
                     "ratio": None if k < 2 else float(r.ratio), "smooth": smooth,
                     "grazing_before": bool(r.grazing_before)})
    return {"from": start, "to": stop, "doublings": rows, "accumulation": w_inf,
            "delta_used": delta, "feigenbaum": FEIGENBAUM,
            "reasons": list(branches.attrs.get("reasons", [])),
            "wall_s": float(branches.attrs.get("wall_s", math.nan))}


def chaotic_band(cells: pd.DataFrame, params, *, x_name: str, y_name: str, y_value: float,
                 depth: int = 4, progress=None, deadline: float | None = None
                 ) -> dict[str, Any]:
    """The chaotic band along the plane row nearest ``y_value`` that has a cascade
    (:func:`cascade_line`): the grid reading, the cascade located from its start towards the
    onset (:func:`gearsim.analysis.cascade.locate_cascade`) and, where the band ends by an
    inverse cascade, the one located from the first period-1 cell after it back towards the
    band; a crisis exit is named as the grid reads it."""
    from gearsim.analysis.cascade import locate_cascade
    from gearsim.analysis.orbits import OrbitError

    failed = (OrbitError, ValueError, ArithmeticError, np.linalg.LinAlgError)
    y, reading = cascade_line(cells, y_value)
    out: dict[str, Any] = {"parameter": y_name, "value": y, "row": y, "grid": reading}
    if reading is None:
        out["note"] = "no row of the plane has a cascade into chaos"
        return out
    dy = float(np.median(np.diff(np.sort(cells["y"].unique())))) if cells["y"].nunique() > 1 \
        else 0.0
    if abs(y - y_value) <= dy:  # the line itself; the grid reading is its nearest row's
        out["value"] = y = float(y_value)
    p = params.with_(**{y_name: y})
    try:
        br = locate_cascade(p, x_name, reading["start"], reading["onset"], depth=depth,
                            progress=progress, deadline=deadline)
        out["onset"] = _located(br, reading["start"], reading["onset"])
    except failed as exc:  # the band's grid reading stands; the line says why
        out["onset"] = {"error": str(exc)}
    if reading.get("exit") == "cascade":
        row = cells[cells["y"] == out["row"]].sort_values("x")
        after = row[(row["x"] > reading["end"]) & (row["motion"] == "periodic")
                    & (row["n"] == 1)]
        if len(after):
            w1 = float(after["x"].iloc[0])
            try:
                br = locate_cascade(p, x_name, w1, reading["end"], depth=depth,
                                    progress=progress, deadline=deadline)
                out["exit"] = _located(br, w1, reading["end"])
            except failed as exc:
                out["exit"] = {"error": str(exc)}
    return out
