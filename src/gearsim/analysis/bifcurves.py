"""Two-parameter bifurcation curves: located fold, period-doubling and grazing points followed
in a second parameter (e.g. the (w, b) and (w, xi) planes).

Method (re-location with a predictor, not an augmented system): a point located by
:func:`gearsim.analysis.continuation.continue_orbit` at ``name2 = mu_0`` is moved along the
curve: the curve's secant direction in the plane (each axis scaled by its range) predicts the
next point ``(w, y)`` a step ``h`` away, and the point is re-located there (:func:`follow_curve`;
where the curve runs more along ``name`` than along ``name2`` the two swap roles).

Re-location (:mod:`gearsim.analysis.relocation`), ``method="secant"`` (the default): the test
function of the point's kind (``mu + 1`` of the real multiplier nearest -1 for a period
doubling, the signed
distance of the turning point to the boundary for a grazing) is a scalar function of ``w`` once the
orbit is corrected by Newton at each trial; its zero is found by the secant method, safeguarded by
bisection once bracketed and by a trust window, to 1e-9 in ``w`` (a fold by
:func:`relocate_fold`). ``method="window"`` (also the fallback for the first failures of the
secant, and the method for Neimark-Sacker points): a short continuation in ``name`` across ``w_pred
+/- window`` (started from a Newton orbit at one end, seeded with the predicted state) locates
every event of the same kind (and, for grazing, the same boundary) to 1e-8 in ``w``; the one
nearest the prediction is the new point. If none is found the window is doubled once, then the step
``h`` is halved (down to ``h_min``); the curve ends when the second parameter leaves its range or
the point is lost (a codimension-2 point, e.g. the period doubling meeting a grazing, or the branch
ceasing to exist). Every point carries its multipliers, so the curve's kind is checked at every
step (a PD point has a multiplier -1 to 1e-7).

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

from gearsim.analysis.continuation_options import BUDGET, Continuation
from gearsim.analysis.relocation import (
    relocate_fold,
    relocate_secant,
    relocate_window,
    section_state,
)
from gearsim.dynamics.parameters import ModelParameters, ParameterError

#: curve points are tracked with the monodromy's state-only error control (half the cost; the
#: multipliers then are good to ~6e-8 in the 6-DOF model, the curve point's w to ~1e-7); the
#: seed points (one-parameter continuation) use the full control
# (gearsim.analysis.orbits.TANGENT_ERROR)
TRACKING_TANGENT_ERROR = False

CURVE_COLUMNS = (
    "curve", "kind", "period", "boundary", "name", "value", "name2", "value2", "x", "v",
    "mu_max", "mu_re", "mu_im", "stable",
)


def _tracking_config(config: Continuation | None, kind: str, window: float) -> Continuation:
    """The settings of the short continuations that re-locate a curve's points."""
    base = dict(config.__dict__) if config else {}
    base.update(switch_depth=0, grazing=(kind == "grazing"), max_points=60,
                ds=window / 3, ds_max=window / 2, progress=None)
    return Continuation(**base)


def _curve_point(kind: str, n: int, boundary: str, name: str, name2: str, w_v: float,
                 mu_v: float, r) -> dict[str, Any]:
    """A curve row (:data:`CURVE_COLUMNS` without ``curve``) at ``(name, name2) = (w_v, mu_v)``."""
    return {
        "kind": kind, "period": n, "boundary": boundary, "name": name,
        "value": float(w_v), "name2": name2, "value2": float(mu_v),
        "x": float(r["x"]), "v": float(r["v"]), "mu_max": float(r["mu_max"]),
        "mu_re": list(r["mu_re"]), "mu_im": list(r["mu_im"]), "stable": bool(r["stable"]),
    }


def _direction(hist: list, s1: float, s2: float, direction: float) -> np.ndarray:
    """The curve's unit direction in the plane scaled by ``(s1, s2)``: its last secant (the
    first step: along ``name2`` towards the stop)."""
    if len(hist) < 2:
        return np.array([0.0, direction])
    (m0, w0, _), (m1, w1, _) = hist[-2], hist[-1]
    t = np.array([(w1 - w0) / s1, (m1 - m0) / s2])
    return t / np.linalg.norm(t)


def _predicted_state(hist: list, w_p: float, m_p: float, s1: float, s2: float) -> np.ndarray:
    """The section state at the predicted point, extrapolated from the last two points."""
    m1, w1, y1 = hist[-1]
    if len(hist) < 2:
        return y1
    m0, w0, y0 = hist[-2]
    dist = math.hypot((w1 - w0) / s1, (m1 - m0) / s2)
    f = math.hypot((w_p - w1) / s1, (m_p - m1) / s2) / max(dist, 1e-300)
    return y1 + f * (y1 - y0)


def _predict(hist: list, h: float, scale: tuple[float, float], direction: float,
             range2: tuple[float, float]):
    """The next point's prediction ``(w, mu, swap, edge, state)`` a step ``h`` (``name2``
    units) along the curve; ``swap`` where it runs more along ``name`` than along ``name2``,
    ``edge`` when the step is cut at the edge of ``range2``; the edge value (a float) when the
    last point is on it already."""
    (s1, s2), (lo2, hi2) = scale, range2
    m1, w1, _ = hist[-1]
    t = _direction(hist, s1, s2, direction)
    hn = h / s2  # step in scaled units
    w_p, m_p = w1 + hn * t[0] * s1, m1 + hn * t[1] * s2
    swap = abs(t[0]) > abs(t[1])
    edge = False
    if not swap and not (lo2 - 1e-12 <= m_p <= hi2 + 1e-12):
        m_edge = hi2 if m_p > hi2 else lo2
        if abs(m_edge - m1) <= 1e-12:
            return m_edge
        frac = (m_edge - m1) / (m_p - m1)
        w_p, m_p, edge = w1 + frac * (w_p - w1), m_edge, True
    return w_p, m_p, swap, edge, _predicted_state(hist, w_p, m_p, s1, s2)


class _Relocator:
    """Re-locates a curve's point at fixed other parameters along one parameter: the direct
    secant solve (``method="secant"``), with the windowed continuation as the fallback for its
    first two failures (and the method for Neimark-Sacker points); counts what it used."""

    def __init__(self, kind: str, boundary: str, n: int, method: str, cfg: Continuation):
        self.kind, self.boundary, self.n, self.method, self.cfg = kind, boundary, n, method, cfg
        self.stats = {"secant": 0, "secant_failed": 0, "window": 0, "swapped": 0}
        self.slopes: dict[str, float] = {}

    def __call__(self, p_fixed, along, pred, y_pred, win):
        kind, boundary, n, cfg, stats = self.kind, self.boundary, self.n, self.cfg, self.stats
        found = None
        if self.method == "secant" and kind in ("period_doubling", "grazing", "fold"):
            if kind == "fold":
                found = relocate_fold(p_fixed, n, along, pred, y_pred, win, cfg)
            else:
                found = relocate_secant(p_fixed, kind, boundary, n, along, pred, y_pred,
                                        win, cfg, wtol=1e-9, slope=self.slopes.get(along),
                                        tangent_error=TRACKING_TANGENT_ERROR)
                if found is not None:
                    self.slopes[along] = found[0].get("slope", math.nan)
            stats["secant" if found is not None else "secant_failed"] += 1
            # the windowed continuation is a fallback for the first two failures only: a
            # point that neither finds is mostly the curve's end (a codimension-2 point)
            if found is None and stats["secant_failed"] > 2:
                return None
        if found is None:
            for ww in (win, 2 * win):
                found = relocate_window(p_fixed, kind, boundary, n, along, pred, y_pred, ww,
                                        cfg)
                if found is not None:
                    stats["window"] += 1
                    break
        return found


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
    method: str = "secant",
    range2: Sequence[float] | None = None,
    range1: Sequence[float] | None = None,
) -> pd.DataFrame:
    """Follow one located bifurcation point in ``name2`` from its value in ``params`` towards
    ``stop2``.

    ``point`` is a row of :func:`bifurcation_points` (``kind``, ``period``, ``boundary``,
    ``name``, ``value``, ``x``, ``v``). Returns the curve (columns :data:`CURVE_COLUMNS` without
    ``curve``), starting with the given point.

    Stepping: the first step moves ``name2`` towards ``stop2``; then the curve's secant
    direction in the plane (each axis scaled by its range: ``range1`` for ``name``, default
    2.4 wide; ``range2``, default the start-to-``stop2`` distance) predicts the next point,
    ``step2`` (in ``name2`` units) long. Where the curve runs more along ``name`` than along
    ``name2`` the roles swap: ``name`` is fixed at the prediction and the point is located
    along ``name2`` (a curve turning back in ``name2`` is followed round its turn instead of
    being lost). The curve ends when it leaves ``range2`` (the last point lands on its edge)
    or ``range1``, or is lost.
    """
    if name2 not in ModelParameters.names():
        raise ParameterError(f"second parameter 'name2' = {name2!r} is not a model parameter")
    kind = str(point["kind"])
    if kind not in ("fold", "period_doubling", "grazing", "neimark_sacker"):
        raise ParameterError(f"point kind {kind!r} cannot be followed")
    n = int(point["period"])
    boundary = str(point.get("boundary", "") or "")
    name = str(point["name"])
    cfg = _tracking_config(config, kind, window)
    mu = float(getattr(params, name2))
    direction = 1.0 if stop2 > mu else -1.0
    lo2, hi2 = ((min(range2), max(range2)) if range2 is not None
                else (min(mu, stop2), max(mu, stop2)))
    lo1, hi1 = (min(range1), max(range1)) if range1 is not None else (1e-6, 100.0)
    s1 = (hi1 - lo1) if range1 is not None else 2.4
    s2 = max(hi2 - lo2, abs(step2))
    h = abs(step2)
    h_min = step_min if step_min is not None else h / 4
    pts: list[dict[str, Any]] = []
    locate = _Relocator(kind, boundary, n, method, cfg)
    stats = locate.stats

    def add(w_v, mu_v, r):
        pts.append(_curve_point(kind, n, boundary, name, name2, w_v, mu_v, r))

    add(float(point["value"]), mu, point)
    hist = [(mu, float(point["value"]), section_state(point))]
    reason = "max points"
    while len(pts) < max_points:
        m1, w1, y1 = hist[-1]
        if cfg.out_of_budget():
            reason = f"{BUDGET}: wall-clock budget spent at {name2} = {m1:.6g}"
            break
        pred = _predict(hist, h, (s1, s2), direction, (lo2, hi2))
        if not isinstance(pred, tuple):
            reason = f"reached {name2} = {pred}"
            break
        w_p, m_p, swap, edge, y_pred = pred
        try:
            if swap:
                found = locate(params.with_(**{name2: m1, name: w_p}), name2, m_p, y_pred,
                               window * s2 / s1)
                stats["swapped"] += 1
            else:
                found = locate(params.with_(**{name2: m_p}), name, w_p, y_pred, window)
        except ParameterError:
            found = None
        if found is None:
            h *= 0.5
            if h < h_min:
                reason = f"point lost beyond {name2} = {m1:.6g}, {name} = {w1:.6g}"
                break
            continue
        r, y = found
        w_new, m_new = (w_p, float(r["value"])) if swap else (float(r["value"]), m_p)
        if not (lo2 - 1e-12 <= m_new <= hi2 + 1e-12):
            reason = f"left {name2} in [{lo2}, {hi2}] near {name} = {w_new:.6g}"
            break
        add(w_new, m_new, r)
        hist.append((m_new, w_new, y))
        if edge:
            reason = f"reached {name2} = {m_new}"
            break
        if not (lo1 <= w_new <= hi1):
            reason = f"left {name} in [{lo1}, {hi1}] at {name2} = {m_new:.6g}"
            break
        h = min(abs(step2), h * 1.5)
    df = pd.DataFrame(pts, columns=[c for c in CURVE_COLUMNS if c != "curve"])
    df.attrs["reason"] = reason
    df.attrs["status"] = BUDGET if reason.startswith(BUDGET) else "ok"
    df.attrs["relocations"] = stats
    return df


def _follow_task(args: tuple) -> pd.DataFrame:
    params, point, name2, stop, kw = args
    return follow_curve(params, point, name2, stop, **kw)


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
    workers: int = 1,
    method: str = "secant",
    range1: Sequence[float] | None = None,
    max_period: int | None = None,
) -> pd.DataFrame:
    """Follow every point of ``kinds`` both ways in ``name2`` across ``range2 = (lo, hi)``
    (and inside ``range1`` of the points' own parameter, e.g. the plane's w range); with
    ``max_period`` only the points of orbits of at most that period.

    ``workers > 1`` runs the curve halves (one point, one direction each) in that many
    processes; the result does not depend on ``workers`` (each half is computed alone).
    """
    t0 = time.perf_counter()
    tasks = []
    for _, r in points.iterrows():
        if r["kind"] not in kinds or (max_period is not None and int(r["period"]) > max_period):
            continue
        for stop in (range2[0], range2[1]):
            if math.isclose(stop, getattr(params, name2)):
                continue
            cfg = config
            if config is not None and workers > 1:
                cfg = Continuation(**{**config.__dict__, "progress": None})
            tasks.append((params, r.to_dict(), name2, stop,
                          dict(step2=step2, window=window, config=cfg, method=method,
                               range2=tuple(range2), range1=range1)))
    if workers > 1 and len(tasks) > 1:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        ctx = mp.get_context("fork")
        with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as ex:
            halves = list(ex.map(_follow_task, tasks))
    else:
        halves = [_follow_task(t) for t in tasks]
    curves = []
    reasons = []
    relocations = {"secant": 0, "secant_failed": 0, "window": 0}
    cid = -1
    key = None
    parts: list[pd.DataFrame] = []

    def flush():
        if parts:  # in curve order: the first half reversed, then the second
            first = parts[0].iloc[::-1]
            c = pd.concat([first, *parts[1:]], ignore_index=True)
            c.insert(0, "curve", cid)
            curves.append(c)

    for (_, r, _, stop, _), c in zip(tasks, halves, strict=True):
        k = (r["kind"], r["boundary"], r["period"], r["value"])
        if k != key:
            flush()
            parts = []
            key = k
            cid += 1
        reasons.append(f"curve {cid} ({r['kind']} {r['boundary']} period {r['period']} at "
                       f"{r['name']} = {r['value']:.6f}) towards {name2} = {stop}: "
                       f"{c.attrs['reason']}, {len(c)} points")
        for kk, vv in c.attrs.get("relocations", {}).items():
            relocations[kk] = relocations.get(kk, 0) + vv
        if config is not None and config.progress is not None:
            config.progress(reasons[-1])
        parts.append(c if not parts else c.iloc[1:])
    flush()
    out = (pd.concat(curves, ignore_index=True) if curves
           else pd.DataFrame(columns=list(CURVE_COLUMNS)))
    status = BUDGET if any(c.attrs.get("status") == BUDGET for c in halves) else "ok"
    out.attrs.update(params=params.to_dict(), name2=name2, range2=list(range2), reasons=reasons,
                     wall_s=time.perf_counter() - t0, workers=workers, method=method,
                     relocations=relocations, status=status)
    return out
