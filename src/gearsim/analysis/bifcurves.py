"""Two-parameter bifurcation curves: located fold, period-doubling and grazing points followed
in a second parameter (e.g. the (w, b) and (w, xi) planes).

Method (re-location with a predictor, not an augmented system): a point located by
:func:`gearsim.analysis.continuation.continue_orbit` at ``name2 = mu_0`` is moved along the
curve: the curve's secant direction in the plane (each axis scaled by its range) predicts the
next point ``(w, y)`` a step ``h`` away, and the point is re-located there (:func:`follow_curve`;
where the curve runs more along ``name`` than along ``name2`` the two swap roles).

Re-location, ``method="secant"`` (the default, :func:`_relocate_secant`): the test function of the
point's kind (``mu + 1`` of the real multiplier nearest -1 for a period doubling, the signed
distance of the turning point to the boundary for a grazing) is a scalar function of ``w`` once the
orbit is corrected by Newton at each trial; its zero is found by the secant method, safeguarded by
bisection once bracketed and by a trust window, to 1e-9 in ``w`` (a fold by
:func:`_relocate_fold`). ``method="window"`` (also the fallback for the first failures of the
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

from gearsim.analysis.continuation import BUDGET, Continuation, continue_orbit
from gearsim.analysis.orbits import OrbitError, find_periodic_orbit, free_states, section_map
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


def _pd_test(M: np.ndarray) -> float | None:
    """``mu + 1`` of the real multiplier nearest -1 (None without a real one)."""
    mu = np.linalg.eigvals(M)
    real = mu[np.abs(mu.imag) <= 1e-9 * np.maximum(np.abs(mu), 1.0)].real
    if not len(real):
        return None
    return float(real[np.argmin(np.abs(real + 1.0))] + 1.0)


def _relocate_secant(
    params: ModelParameters, kind: str, boundary: str, n: int, name: str, w_pred: float,
    y_pred: np.ndarray, window: float, cfg: Continuation, *, wtol: float = 1e-10,
    max_eval: int = 14, slope: float | None = None, tangent_error: bool | None = None,
) -> tuple[dict[str, Any], np.ndarray] | None:
    """Locate a period doubling or grazing of the period-``n`` orbit near ``w_pred`` directly.

    The test function along ``name`` at fixed other parameters — ``mu + 1`` of the real
    multiplier nearest -1 (period doubling), the signed distance of the turning point to the
    ``boundary`` (grazing) — is a scalar function of ``w`` once the orbit is corrected by Newton
    at each trial (warm-started by extrapolating the section state of the last two trials). Its
    zero is found by the secant method, safeguarded by bisection once bracketed and by the
    trust window (steps of at most ``window``, ``|w - w_pred| <= 3 window``); converged when
    the ``w`` step is below ``wtol``.
    Returns None when it fails (the caller then falls back to the windowed continuation).
    One trial costs one or two monodromy matrices (plus one dense run for grazing), against
    the ~20 corrected orbits of a windowed continuation with Brent location.
    """
    from gearsim.analysis.orbits import grazing_margin, newton_orbit

    settings = cfg.settings
    dims = free_states(params)
    d = len(dims)
    evals: list[tuple[float, float, np.ndarray, np.ndarray]] = []  # (w, f, y, M)
    jac: list[np.ndarray] = []  # the latest monodromy: the chord iteration's matrix

    def chord(pw: ModelParameters, guess: np.ndarray):
        """Chord Newton on P^n(y) = y with the latest monodromy (state-only maps, ~10x
        cheaper than a monodromy); None when it does not contract fast (then full Newton)."""
        if not jac:
            return None
        parr = pw.to_array()
        J = jac[-1] - np.eye(d)
        y = guess.copy()
        r_prev = math.inf
        for _ in range(10):
            yn, _ = section_map(pw, y, n, settings, jacobian=False, parray=parr)
            G = yn[dims] - y[dims]
            r = float(np.max(np.abs(G)))
            if r < 1e-10:
                return y
            if r > 0.3 * r_prev:
                return None
            r_prev = r
            y[dims] = y[dims] + np.linalg.solve(J, -G)
        return None

    def f_at(w: float, guess: np.ndarray):
        try:
            pw = params.with_(**{name: w})
            y = chord(pw, guess)
            M = None
            if y is None:
                y, _yn, M, _r, _it = newton_orbit(pw, n, guess, settings, max_iter=8,
                                                  tangent_error=tangent_error)
                jac.append(M)
        except (OrbitError, ParameterError, np.linalg.LinAlgError):
            return None
        if n > 1:  # the orbit must not have collapsed to a divisor of its period
            yh, _ = section_map(pw, y, n // 2, settings, jacobian=False)
            if float(np.max(np.abs(yh[:2] - y[:2]))) < 1e-7 * (1.0 + abs(y[0])):
                return None
        try:
            if kind == "period_doubling":
                if M is None:
                    _, M = section_map(pw, y, n, settings, tangent_error=tangent_error)
                    jac.append(M)
                f = _pd_test(M)
            else:
                g = grazing_margin(pw, y, n, settings, substeps=cfg.substeps).signed
                f = g.get(boundary)
        except OrbitError:
            return None
        if f is None or not math.isfinite(f):
            return None
        return y, M, float(f)

    w_a = w_pred
    r = f_at(w_a, y_pred)
    if r is None:
        return None
    evals.append((w_a, r[2], r[0], r[1]))
    w_b = w_pred + min(0.1 * window, 1e-3)
    if slope is not None and slope != 0.0 and math.isfinite(slope):
        # the previous curve point's secant slope: a Newton-like first step
        w_b = w_pred - r[2] / slope
        if abs(w_b - w_pred) > window or abs(w_b - w_pred) < 1e-12:
            w_b = w_pred + min(0.1 * window, 1e-3)
    lo = hi = None  # bracket
    for _ in range(max_eval):
        if cfg.out_of_budget():
            return None
        wa, fa, ya, _ = evals[-1]
        if len(evals) >= 2:
            wp, fp, yp, _ = evals[-2]
            w_b = wa - fa * (wa - wp) / (fa - fp) if fa != fp else wa + 0.5 * (wa - wp)
            if lo is not None and not (min(lo[0], hi[0]) < w_b < max(lo[0], hi[0])):
                w_b = 0.5 * (lo[0] + hi[0])
            w_b = min(max(w_b, wa - window), wa + window)
            if abs(w_b - w_pred) > 3.0 * window:
                return None
            guess = ya.copy()
            if wa != wp:
                guess[dims] = ya[dims] + (w_b - wa) / (wa - wp) * (ya[dims] - yp[dims])
        else:
            guess = ya.copy()
        r = f_at(w_b, guess)
        if r is None:
            return None
        evals.append((w_b, r[2], r[0], r[1]))
        if fa * r[2] <= 0.0:
            lo, hi = (wa, fa), (w_b, r[2])
        elif lo is not None:
            if (lo[1] < 0) == (r[2] < 0):
                lo = (w_b, r[2])
            else:
                hi = (w_b, r[2])
        if abs(w_b - wa) < wtol or r[2] == 0.0:
            break
    else:
        return None
    w, f, y, M = evals[-1]
    ok = abs(f) < (1e-6 if kind == "period_doubling" else 1e-7)
    if not ok:
        return None
    if M is None:  # grazing: the multipliers of the located orbit
        try:
            _, M = section_map(params.with_(**{name: w}), y, n, settings,
                               tangent_error=tangent_error)
        except OrbitError:
            return None
    mu = np.linalg.eigvals(M).astype(complex)
    mu = mu[np.argsort(-np.abs(mu), kind="stable")]
    row = {"value": w, "x": float(y[0]), "v": float(y[1]), "mu_max": float(abs(mu[0])),
           "mu_re": [float(m.real) for m in mu], "mu_im": [float(m.imag) for m in mu],
           "stable": bool(abs(mu[0]) < 1.0), "evals": len(evals)}
    (wp, fp, _, _), (wl, fl, _, _) = evals[-2], evals[-1]
    row["slope"] = (fl - fp) / (wl - wp) if wl != wp else math.nan
    return row, y


def _relocate_fold(
    params: ModelParameters, n: int, name: str, w_pred: float, y_pred: np.ndarray,
    window: float, cfg: Continuation, *, stol: float = 1e-10, max_eval: int = 14,
) -> tuple[dict[str, Any], np.ndarray] | None:
    """Locate the fold of the period-``n`` branch near ``(w_pred, y_pred)`` directly.

    At a fold ``w`` is not a parameter of the branch, but the coordinate ``s = v . y`` along the
    critical eigenvector ``v`` (multiplier +1) is: at fixed ``s`` the orbit and its ``w`` are
    one corrector solve (``G = 0``, ``v . y = s``; :meth:`_Problem.correct`), and the fold is
    the zero of the ``w`` component of the branch tangent (null vector of ``[M - I,
    dG/dw]``, oriented along ``v``). That scalar function of ``s`` is smooth through the fold;
    its zero is found by the secant method (bisection once bracketed), each trial started from
    the extrapolated state. Returns None on failure (the caller falls back to the windowed
    continuation). The located point has a multiplier +1 to 1e-4, as in the continuation.
    """
    from gearsim.analysis.continuation import _Problem

    prob = _Problem(params.with_(**{name: w_pred}), name, n, cfg)
    dims = prob.dims
    d = prob.d
    try:
        _G, M0, _dGdl = prob.evaluate(y_pred, w_pred)
    except (OrbitError, ParameterError):
        return None
    mu, vecs = np.linalg.eig(M0)
    k = int(np.argmin(np.abs(mu - 1.0)))
    if abs(mu[k].imag) > 1e-6 * max(abs(mu[k]), 1.0):
        return None
    v = np.real(vecs[:, k])
    v /= np.linalg.norm(v)
    normal = np.concatenate([v, [0.0]])
    s0 = float(v @ y_pred[dims])
    evals: list[tuple[float, float, np.ndarray, float, np.ndarray]] = []  # (s, f, y, w, M)

    def f_at(sv: float, y_guess: np.ndarray, w_guess: float):
        yg = y_guess.copy()
        yg[dims] = yg[dims] + (sv - float(v @ yg[dims])) * v
        anchor = np.concatenate([yg[dims], [w_guess]])
        try:
            y, w, M, dGdl = prob.correct(yg, w_guess, normal, anchor, max_step=5.0 * window)
            t = prob.tangent(M, dGdl, normal)
        except (OrbitError, ParameterError, np.linalg.LinAlgError):
            return None
        return y, w, M, float(t[d])

    r = f_at(s0, y_pred, w_pred)
    if r is None:
        return None
    evals.append((s0, r[3], r[0], r[1], r[2]))
    s_b = s0 + 1e-3
    lo = hi = None
    for _ in range(max_eval):
        if cfg.out_of_budget():
            return None
        sa, fa, ya, wa, _ = evals[-1]
        yg, wg = ya, wa
        if len(evals) >= 2:
            sp, fp, yp, wp, _ = evals[-2]
            s_b = sa - fa * (sa - sp) / (fa - fp) if fa != fp else sa + 0.5 * (sa - sp)
            if lo is not None and not (min(lo[0], hi[0]) < s_b < max(lo[0], hi[0])):
                s_b = 0.5 * (lo[0] + hi[0])
            s_b = min(max(s_b, sa - 0.05), sa + 0.05)
            if abs(s_b - s0) > 0.2:
                return None
            if sa != sp:
                f = (s_b - sa) / (sa - sp)
                yg = ya.copy()
                yg[dims] = ya[dims] + f * (ya[dims] - yp[dims])
                wg = wa + f * (wa - wp)
        r = f_at(s_b, yg, wg)
        if r is None:
            return None
        evals.append((s_b, r[3], r[0], r[1], r[2]))
        if fa * r[3] <= 0.0:
            lo, hi = (sa, fa), (s_b, r[3])
        elif lo is not None:
            if (lo[1] < 0) == (r[3] < 0):
                lo = (s_b, r[3])
            else:
                hi = (s_b, r[3])
        if abs(s_b - sa) < stol or r[3] == 0.0:
            break
    else:
        return None
    _s, _f, y, w, M = evals[-1]
    mu = np.linalg.eigvals(M).astype(complex)
    if float(np.min(np.abs(mu - 1.0))) > 1e-4 or abs(w - w_pred) > 3.0 * window:
        return None
    mu = mu[np.argsort(-np.abs(mu), kind="stable")]
    row = {"value": w, "x": float(y[0]), "v": float(y[1]), "mu_max": float(abs(mu[0])),
           "mu_re": [float(m.real) for m in mu], "mu_im": [float(m.imag) for m in mu],
           "stable": bool(abs(mu[0]) < 1.0), "evals": len(evals)}
    return row, y


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
    base = dict(config.__dict__) if config else {}
    base.update(switch_depth=0, grazing=(kind == "grazing"), max_points=60,
                ds=window / 3, ds_max=window / 2, progress=None)
    cfg = Continuation(**base)
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
    stats = {"secant": 0, "secant_failed": 0, "window": 0, "swapped": 0}

    def add(w_v, mu_v, r):
        pts.append({
            "kind": kind, "period": n, "boundary": boundary, "name": name,
            "value": float(w_v), "name2": name2, "value2": float(mu_v),
            "x": float(r["x"]), "v": float(r["v"]), "mu_max": float(r["mu_max"]),
            "mu_re": list(r["mu_re"]), "mu_im": list(r["mu_im"]), "stable": bool(r["stable"]),
        })

    slopes: dict[str, float] = {}

    def locate(p_fixed, along, pred, y_pred, win):
        found = None
        if method == "secant" and kind in ("period_doubling", "grazing", "fold"):
            if kind == "fold":
                found = _relocate_fold(p_fixed, n, along, pred, y_pred, win, cfg)
            else:
                found = _relocate_secant(p_fixed, kind, boundary, n, along, pred, y_pred,
                                         win, cfg, wtol=1e-9, slope=slopes.get(along),
                                         tangent_error=TRACKING_TANGENT_ERROR)
                if found is not None:
                    slopes[along] = found[0].get("slope", math.nan)
            stats["secant" if found is not None else "secant_failed"] += 1
            # the windowed continuation is a fallback for the first two failures only: a
            # point that neither finds is mostly the curve's end (a codimension-2 point)
            if found is None and stats["secant_failed"] > 2:
                return None
        if found is None:
            for ww in (win, 2 * win):
                found = _relocate(p_fixed, kind, boundary, n, along, pred, y_pred, ww, cfg)
                if found is not None:
                    stats["window"] += 1
                    break
        return found

    add(float(point["value"]), mu, point)
    hist = [(mu, float(point["value"]), _state(point))]
    reason = "max points"
    while len(pts) < max_points:
        m1, w1, y1 = hist[-1]
        if cfg.out_of_budget():
            reason = f"{BUDGET}: wall-clock budget spent at {name2} = {m1:.6g}"
            break
        if len(hist) >= 2:
            m0, w0, y0 = hist[-2]
            t = np.array([(w1 - w0) / s1, (m1 - m0) / s2])
            t /= np.linalg.norm(t)
        else:
            t = np.array([0.0, direction])
        hn = h / s2  # step in scaled units
        w_p, m_p = w1 + hn * t[0] * s1, m1 + hn * t[1] * s2
        swap = abs(t[0]) > abs(t[1])
        edge = False
        if not swap and not (lo2 - 1e-12 <= m_p <= hi2 + 1e-12):
            m_edge = hi2 if m_p > hi2 else lo2
            if abs(m_edge - m1) <= 1e-12:
                reason = f"reached {name2} = {m_edge}"
                break
            frac = (m_edge - m1) / (m_p - m1)
            w_p, m_p, edge = w1 + frac * (w_p - w1), m_edge, True
        if len(hist) >= 2:
            dist = math.hypot((w1 - w0) / s1, (m1 - m0) / s2)
            f = math.hypot((w_p - w1) / s1, (m_p - m1) / s2) / max(dist, 1e-300)
            y_pred = y1 + f * (y1 - y0)
        else:
            y_pred = y1
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


def pipeline_orbit_tables(config) -> list[str]:
    """The continuation tables the pipeline makes for a config (workflow/rules/orbits.smk):
    ``standard`` (config ``orbits.continuation`` and a sweep named ``standard``) and
    ``<plane>_curves`` for every plane (``orbits.curves``)."""
    opts = dict(config.get("orbits") or {})
    out = []
    if opts.get("continuation", True) and "standard" in (config.get("sweeps") or {}):
        out.append("standard")
    if opts.get("curves", True):
        out += [f"{plane}_curves" for plane in (config.get("planes") or {})]
    return out
