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
from gearsim.analysis.orbits import shooting_settings
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


def _end(reason: str) -> str:
    """The end code of a curve half's stop reason (docs/orbits.md, ``end_first``)."""
    for code in ("edge", "lost", "closed", "joins", BUDGET, "max_points"):
        if reason.startswith(code):
            return code
    return "lost"


class _Stepper:
    """The curve's geometry in cell units: ``U = ((w - lo1) / c1, (mu - lo2) / c2)`` (one unit
    is one cell of the map the curve is drawn on), the box of the plane, the predictor."""

    def __init__(self, box: tuple[float, float, float, float], cell: tuple[float, float]):
        self.lo1, self.hi1, self.lo2, self.hi2 = box
        self.c1, self.c2 = cell
        self.n1 = (self.hi1 - self.lo1) / self.c1
        self.n2 = (self.hi2 - self.lo2) / self.c2

    def u(self, w: float, m: float) -> np.ndarray:
        return np.array([(w - self.lo1) / self.c1, (m - self.lo2) / self.c2])

    def wm(self, u: np.ndarray) -> tuple[float, float]:
        return self.lo1 + u[0] * self.c1, self.lo2 + u[1] * self.c2

    def clip(self, u0: np.ndarray, t: np.ndarray, h: float):
        """The step ``alpha <= h`` along ``t`` that stays inside the box, and the box side it
        reaches (``"x"``: a w edge, ``"y"``: a mu edge, ``""``: none)."""
        alpha, side = h, ""
        for k, (n, s) in enumerate(((self.n1, "x"), (self.n2, "y"))):
            if t[k] > 1e-15:
                a = (n - u0[k]) / t[k]
            elif t[k] < -1e-15:
                a = -u0[k] / t[k]
            else:
                continue
            if a < alpha:
                alpha, side = max(a, 0.0), s
        return alpha, side

    def inside(self, u: np.ndarray, tol: float = 1e-9) -> bool:
        return bool(-tol <= u[0] <= self.n1 + tol and -tol <= u[1] <= self.n2 + tol)


def _near_any(u: np.ndarray, polys: Sequence[np.ndarray], r: float) -> bool:
    """``u`` lies within ``r`` of one of the polylines (cell units)."""
    for poly in polys:
        if len(poly) < 2:
            continue
        a, b = poly[:-1], poly[1:]
        ab = b - a
        s = np.clip(((u - a) * ab).sum(axis=1) / np.maximum((ab * ab).sum(axis=1), 1e-300),
                    0.0, 1.0)
        if float(np.min(np.linalg.norm(a + s[:, None] * ab - u, axis=1))) <= r:
            return True
    return False


def _predicted_state(hist: list, u_p: np.ndarray) -> np.ndarray:
    """The section state at the predicted point, extrapolated from the last two points."""
    u1, y1 = hist[-1]
    if len(hist) < 2:
        return y1
    u0, y0 = hist[-2]
    f = float(np.linalg.norm(u_p - u1)) / max(float(np.linalg.norm(u1 - u0)), 1e-300)
    return y1 + min(f, 4.0) * (y1 - y0)


class _Relocator:
    """Re-locates a curve's point at fixed other parameters along one parameter: the direct
    secant solve (``method="secant"``), with the windowed continuation as the fallback for its
    first two failures (and the method for Neimark-Sacker points); counts what it used."""

    def __init__(self, kind: str, boundary: str, n: int, method: str, cfg: Continuation,
                 wtol: float = 1e-9, fallback: int = 2):
        self.kind, self.boundary, self.n, self.method, self.cfg = kind, boundary, n, method, cfg
        self.wtol, self.fallback = wtol, fallback
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
                                        win, cfg, wtol=self.wtol, slope=self.slopes.get(along),
                                        tangent_error=TRACKING_TANGENT_ERROR)
                if found is not None:
                    self.slopes[along] = found[0].get("slope", math.nan)
            stats["secant" if found is not None else "secant_failed"] += 1
            # the windowed continuation is a fallback for the first two failures only: a
            # point that neither finds is mostly the curve's end (a codimension-2 point)
            if found is None and stats["secant_failed"] > self.fallback:
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
    window: float | None = None,
    config: Continuation | None = None,
    max_points: int = 200,
    method: str = "secant",
    range2: Sequence[float] | None = None,
    range1: Sequence[float] | None = None,
    cell: Sequence[float] | None = None,
    deviation: float = 0.3,
    tangent: Sequence[float] | None = None,
    avoid: Sequence[np.ndarray] = (),
    fallback: int = 2,
    rtol: float | None = None,
) -> pd.DataFrame:
    """Follow one located bifurcation point across the plane ``(name, name2)``.

    ``point`` is a row of :func:`bifurcation_points` (``kind``, ``period``, ``boundary``,
    ``name``, ``value``, ``x``, ``v``; ``name2`` is at its value in ``params``). Returns the
    curve (columns :data:`CURVE_COLUMNS` without ``curve``), starting with the given point;
    ``attrs``: ``reason`` (in words), ``end`` (``edge``, ``lost``, ``closed``, ``budget``,
    ``max_points``), ``last_state`` (the last point's section state), ``relocations``.

    Geometry in cell units (``cell = (c1, c2)``, the map's cell sizes; default a 400th of each
    range): the first step goes along ``tangent`` (default: along ``name2`` towards
    ``stop2``), then along the secant of the last two points. A point is located at the
    predicted value of the coordinate the curve runs along more (secant on its test function
    along the other one), so a curve turning in either parameter is followed round its turn.
    Step control (pseudo-arclength in the plane): the distance ``d`` between the predicted and
    the located point is the curve's curvature times half the squared step; the next step is
    ``h sqrt(deviation / d)`` (at most twice, at least half the last; at most ``step2``, in
    ``name2`` units), and a step whose ``d`` exceeds one cell is refused and halved. So the
    polygon of the points stays within ~``deviation`` cells of the curve: as fine as the map,
    and long steps where the curve is straight. The curve ends at the plane's edge (its last
    point on the edge), where it returns to its start (``closed``), or where the point is lost
    (the step halved below ``step_min``: a codimension-2 point, or the branch ceasing to
    exist). ``avoid``: polylines (cell units) of curves of the same kind already followed; two
    points in a row within half a cell of one of them end the curve (``joins``).
    ``fallback``: how many failures of the secant the windowed continuation retries.
    ``rtol``: the DP5 relative tolerance of the orbits that track the curve (default the
    shooting's, 1e-12; :func:`gearsim.analysis.orbits.shooting_settings`).
    """
    if name2 not in ModelParameters.names():
        raise ParameterError(f"second parameter 'name2' = {name2!r} is not a model parameter")
    kind = str(point["kind"])
    if kind not in ("fold", "period_doubling", "grazing", "neimark_sacker"):
        raise ParameterError(f"point kind {kind!r} cannot be followed")
    n = int(point["period"])
    boundary = str(point.get("boundary", "") or "")
    name = str(point["name"])
    mu = float(getattr(params, name2))
    direction = 1.0 if stop2 > mu else -1.0
    lo2, hi2 = ((min(range2), max(range2)) if range2 is not None
                else (min(mu, stop2), max(mu, stop2)))
    lo1, hi1 = (min(range1), max(range1)) if range1 is not None else (1e-6, 100.0)
    if cell is None:
        cell = ((hi1 - lo1 if range1 is not None else 2.4) / 400.0,
                max(hi2 - lo2, abs(step2)) / 400.0)
    geo = _Stepper((lo1, hi1, lo2, hi2), (float(cell[0]), float(cell[1])))
    h_max = abs(step2) / geo.c2
    h_min = (step_min / geo.c2) if step_min is not None else min(0.2, h_max / 4)
    win_min = {name: (window if window is not None else geo.c1),
               name2: (window * geo.c2 / geo.c1 if window is not None else geo.c2)}
    cfg = _tracking_config(config, kind, win_min[name])
    if rtol is not None:
        cfg.settings = shooting_settings(rtol)
    locate = _Relocator(kind, boundary, n, method, cfg, fallback=fallback)
    stats = locate.stats
    pts: list[dict[str, Any]] = []

    def add(w_v, mu_v, r):
        pts.append(_curve_point(kind, n, boundary, name, name2, w_v, mu_v, r))

    add(float(point["value"]), mu, point)
    u0 = geo.u(float(point["value"]), mu)
    hist = [(u0, section_state(point))]
    t = np.array(tangent, dtype=float) if tangent is not None else np.array([0.0, direction])
    t /= np.linalg.norm(t)
    h = min(h_max, 1.0)  # the first step: a cell, its direction a guess
    path = 0.0
    near = 0
    reason = "max_points"
    while len(pts) < max_points:
        u1, y1 = hist[-1]
        w1, m1 = geo.wm(u1)
        if cfg.out_of_budget():
            reason = f"{BUDGET}: wall-clock budget spent at {name2} = {m1:.6g}"
            break
        alpha, side = geo.clip(u1, t, h)
        if alpha <= 1e-9:
            reason = f"edge: reached the plane's edge at {name} = {w1:.6g}, {name2} = {m1:.6g}"
            break
        u_p = u1 + alpha * t
        w_p, m_p = geo.wm(u_p)
        y_pred = _predicted_state(hist, u_p)
        swap = side == "x" or (side == "" and abs(t[0]) > abs(t[1]))
        try:
            if swap:  # fixed name at the prediction, located along name2
                win = max(0.5 * alpha, 1.0) * geo.c2
                found = locate(params.with_(**{name2: m1, name: w_p}), name2, m_p, y_pred,
                               max(win, win_min[name2]))
                stats["swapped"] += 1
            else:
                win = max(0.5 * alpha, 1.0) * geo.c1
                found = locate(params.with_(**{name2: m_p}), name, w_p, y_pred,
                               max(win, win_min[name]))
        except ParameterError:
            found = None
        if found is not None:
            r, y = found
            w_new, m_new = (w_p, float(r["value"])) if swap else (float(r["value"]), m_p)
            u_new = geo.u(w_new, m_new)
            dev = float(np.linalg.norm(u_new - u_p))
            if not geo.inside(u_new):
                found = None  # beyond the edge: a shorter step lands on it
            elif len(hist) > 1 and dev > max(1.0, 4 * deviation) and alpha > 2 * h_min:
                found = None  # the curve bends more than the step resolves
        if found is None:
            h = (0.5 if alpha > 2.0 else 0.25) * min(h, alpha)
            if h < h_min:
                reason = f"lost: point lost beyond {name} = {w1:.8g}, {name2} = {m1:.8g}"
                break
            continue
        add(w_new, m_new, r)
        seg = u_new - u1
        path += float(np.linalg.norm(seg))
        hist.append((u_new, y))
        t_new = seg / float(np.linalg.norm(seg))
        turn = math.acos(max(-1.0, min(1.0, float(t_new @ t))))
        t = t_new
        if side:
            reason = (f"edge: reached the plane's edge at {name} = {w_new:.6g}, "
                      f"{name2} = {m_new:.6g}")
            break
        near = near + 1 if len(hist) > 2 and _near_any(u_new, avoid, 0.5) else 0
        if near >= 2:
            reason = (f"joins: runs onto a curve already followed at {name} = {w_new:.6g}, "
                      f"{name2} = {m_new:.6g}")
            break
        if path > 8.0 and float(np.linalg.norm(u_new - u0)) < max(1.0, 0.75 * alpha):
            reason = f"closed: returned to its start at {name} = {w_new:.6g}, {name2} = {m_new:.6g}"
            break
        grow = 2.0 if len(hist) <= 2 else min(2.0, max(0.5, 0.9 * math.sqrt(
            deviation / max(dev, 1e-12))))
        if turn > 0.35:
            grow = min(grow, 0.5)
        h = min(h_max, max(h_min, alpha * grow))
    df = pd.DataFrame(pts, columns=[c for c in CURVE_COLUMNS if c != "curve"])
    df.attrs["reason"] = reason
    df.attrs["end"] = _end(reason)
    df.attrs["status"] = BUDGET if reason.startswith(BUDGET) else "ok"
    df.attrs["relocations"] = stats
    df.attrs["last_state"] = [float(v) for v in hist[-1][1]]
    df.attrs["last_tangent"] = [float(v) for v in t]
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
