"""Two-parameter bifurcation curves: located fold, period-doubling and grazing points followed
in a second parameter (e.g. the (w, b) and (w, xi) planes).

Method (re-location with a predictor, not an augmented system): a point located by
:func:`gearsim.continuation.continue_orbit` at ``name2 = mu_0`` is moved to ``mu_1 = mu_0 + h``;
the predictor extrapolates the curve's ``(w, y)`` linearly in ``mu`` from the last two points
(constant for the first step); at ``mu_1`` a short continuation in ``name`` across the window
``w_pred +/- window`` (started from a Newton orbit at one end, seeded with the predicted state)
locates every event of the same kind (and, for grazing, the same boundary) to 1e-8 in ``w``; the
one nearest the prediction is the new curve point. If none is found the window is doubled once,
then the step ``h`` is halved (down to ``h_min``); the curve ends when the second parameter
leaves its range or the point is lost (a codimension-2 point, e.g. the period doubling meeting a
grazing, or the branch ceasing to exist). Every point carries its multipliers, so the curve's
kind is checked at every step (a PD point has a multiplier -1 to 1e-7).

Why not a minimally augmented system: the test functions are not smooth across grazing (the
3/2-power singularity), and the re-location reuses the one event locator, so a curve point is
exactly what a one-parameter continuation at that ``mu`` would report.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from .continuation import Continuation, continue_orbit
from .orbits import OrbitError, find_periodic_orbit
from .parameters import ModelParameters, ParameterError

CURVE_COLUMNS = (
    "curve", "kind", "period", "boundary", "name", "value", "name2", "value2", "x", "v",
    "mu_max", "mu_re", "mu_im", "stable",
)
POINT_COLUMNS = (
    "point", "kind", "period", "boundary", "name", "value", "x", "v", "mu_max", "mu_re",
    "mu_im", "stable", "branch",
)


def bifurcation_points(branches: pd.DataFrame) -> pd.DataFrame:
    """The located events of a continuation table (one row each, in branch order)."""
    ev = branches[branches["event"] != ""].reset_index(drop=True)
    out = pd.DataFrame({
        "point": np.arange(len(ev)),
        "kind": ev["event"],
        "period": ev["period"],
        "boundary": ev["boundary"],
        "name": ev["name"],
        "value": ev["value"],
        "x": ev["x"],
        "v": ev["v"],
        "mu_max": ev["mu_max"],
        "mu_re": ev["mu_re"],
        "mu_im": ev["mu_im"],
        "stable": ev["stable"],
        "branch": ev["branch"],
    }, columns=list(POINT_COLUMNS))
    out.attrs.update(branches.attrs)
    return out


def _state(row, like: np.ndarray | None = None) -> np.ndarray:
    y = np.zeros(10) if like is None else like.copy()
    y[0], y[1] = row["x"], row["v"]
    return y


def _relocate(
    params: ModelParameters, kind: str, boundary: str, n: int, name: str, w_pred: float,
    y_pred: np.ndarray, window: float, cfg: Continuation,
) -> tuple[pd.Series, np.ndarray] | None:
    """Locate the event of ``kind`` nearest ``w_pred`` at ``params`` (or None)."""
    lo_lim, hi_lim = 1e-6, 100.0
    for a, b in ((w_pred - window, w_pred + window), (w_pred + window, w_pred - window)):
        a = min(max(a, lo_lim), hi_lim)
        b = min(max(b, lo_lim), hi_lim)
        try:
            orbit = find_periodic_orbit(params.with_(**{name: a}), n, y_pred, cfg.settings,
                                        max_iter=12, grazing=False)
        except (OrbitError, ParameterError):
            continue
        if orbit.minimal_period != n:
            continue
        try:
            df = continue_orbit(params.with_(**{name: a}), name, a, b, orbit, config=cfg)
        except (OrbitError, ParameterError):
            continue
        ev = df[(df["event"] == kind) & (df["branch"] == 0)]
        if boundary:
            ev = ev[ev["boundary"] == boundary]
        if len(ev):
            k = int(np.argmin(np.abs(ev["value"].to_numpy() - w_pred)))
            r = ev.iloc[k]
            return r, _state(r, y_pred)
    return None


def follow_curve(
    params: ModelParameters,
    point: pd.Series | dict[str, Any],
    name2: str,
    stop2: float,
    *,
    step2: float,
    step_min: float | None = None,
    window: float = 0.01,
    config: Continuation | None = None,
    max_points: int = 200,
) -> pd.DataFrame:
    """Follow one located bifurcation point in ``name2`` from its value in ``params`` to ``stop2``.

    ``point`` is a row of :func:`bifurcation_points` (``kind``, ``period``, ``boundary``,
    ``name``, ``value``, ``x``, ``v``). Returns the curve (columns :data:`CURVE_COLUMNS` without
    ``curve``), starting with the given point.
    """
    if name2 not in ModelParameters.names():
        raise ParameterError(f"second parameter 'name2' = {name2!r} is not a model parameter")
    kind = str(point["kind"])
    if kind not in ("fold", "period_doubling", "grazing", "neimark_sacker"):
        raise ParameterError(f"point kind {kind!r} cannot be followed")
    n = int(point["period"])
    boundary = str(point.get("boundary", "") or "")
    name = str(point["name"])
    base = dict(config.__dict__) if config else {}
    base.update(switch_depth=0, grazing=(kind == "grazing"), max_points=60,
                ds=window / 3, ds_max=window / 2, progress=None)
    cfg = Continuation(**base)
    mu = float(getattr(params, name2))
    direction = 1.0 if stop2 > mu else -1.0
    h = abs(step2)
    h_min = step_min if step_min is not None else h / 16
    pts: list[dict[str, Any]] = []

    def add(mu_v, r):
        pts.append({
            "kind": kind, "period": n, "boundary": boundary, "name": name,
            "value": float(r["value"]), "name2": name2, "value2": float(mu_v),
            "x": float(r["x"]), "v": float(r["v"]), "mu_max": float(r["mu_max"]),
            "mu_re": list(r["mu_re"]), "mu_im": list(r["mu_im"]), "stable": bool(r["stable"]),
        })

    add(mu, point)
    y_last = _state(point)
    hist = [(mu, float(point["value"]), y_last.copy())]
    reason = "max points"
    while len(pts) < max_points:
        if (stop2 - mu) * direction <= 1e-12:
            reason = f"reached {name2} = {stop2}"
            break
        hh = min(h, abs(stop2 - mu))
        mu_new = mu + direction * hh
        if len(hist) >= 2:
            (m0, w0, y0), (m1, w1, y1) = hist[-2], hist[-1]
            f = (mu_new - m1) / (m1 - m0)
            w_pred = w1 + f * (w1 - w0)
            y_pred = y1 + f * (y1 - y0)
        else:
            _, w_pred, y_pred = hist[-1]
        try:
            pnew = params.with_(**{name2: mu_new})
        except ParameterError:
            reason = f"{name2} = {mu_new} outside its range"
            break
        found = None
        for win in (window, 2 * window):
            found = _relocate(pnew, kind, boundary, n, name, w_pred, y_pred, win, cfg)
            if found is not None:
                break
        if found is None:
            h *= 0.5
            if h < h_min:
                reason = f"point lost beyond {name2} = {mu:.6g}"
                break
            continue
        r, y = found
        add(mu_new, r)
        hist.append((mu_new, float(r["value"]), y))
        mu = mu_new
        h = min(abs(step2), h * 1.5)
    df = pd.DataFrame(pts, columns=[c for c in CURVE_COLUMNS if c != "curve"])
    df.attrs["reason"] = reason
    return df


def follow_curves(
    params: ModelParameters,
    points: pd.DataFrame,
    name2: str,
    range2: Sequence[float],
    *,
    step2: float,
    kinds: Sequence[str] = ("fold", "period_doubling", "grazing"),
    window: float = 0.01,
    config: Continuation | None = None,
) -> pd.DataFrame:
    """Follow every point of ``kinds`` both ways in ``name2`` across ``range2 = (lo, hi)``."""
    t0 = time.perf_counter()
    curves = []
    reasons = []
    cid = 0
    for _, r in points.iterrows():
        if r["kind"] not in kinds:
            continue
        parts = []
        for stop in (range2[0], range2[1]):
            if math.isclose(stop, getattr(params, name2)):
                continue
            c = follow_curve(params, r, name2, stop, step2=step2, window=window, config=config)
            reasons.append(f"curve {cid} ({r['kind']} {r['boundary']} period {r['period']} at "
                           f"{r['name']} = {r['value']:.6f}) towards {name2} = {stop}: "
                           f"{c.attrs['reason']}, {len(c)} points")
            if config is not None and config.progress is not None:
                config.progress(reasons[-1])
            parts.append(c if not parts else c.iloc[1:])
        if parts:
            c = pd.concat(parts, ignore_index=True).sort_values("value2", kind="stable")
            c.insert(0, "curve", cid)
            curves.append(c)
            cid += 1
    out = (pd.concat(curves, ignore_index=True) if curves
           else pd.DataFrame(columns=list(CURVE_COLUMNS)))
    out.attrs.update(params=params.to_dict(), name2=name2, range2=list(range2), reasons=reasons,
                     wall_s=time.perf_counter() - t0)
    return out
