"""Re-location of a bifurcation point of a period-``n`` orbit near a predicted parameter value: the
three methods :func:`gearsim.analysis.bifcurves.follow_curve` steps a curve with (a secant on the
test function, a secant on the fold's tangent component, a short windowed continuation).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from gearsim.analysis.continuation import continue_orbit
from gearsim.analysis.continuation_options import Continuation
from gearsim.analysis.corrector import BranchProblem
from gearsim.analysis.orbits import (
    OrbitError,
    find_periodic_orbit,
    free_states,
    grazing_margin,
    newton_orbit,
    section_map,
)
from gearsim.dynamics.parameters import ModelParameters, ParameterError


def section_state(row, like: np.ndarray | None = None) -> np.ndarray:
    y = np.zeros(10) if like is None else like.copy()
    y[0], y[1] = row["x"], row["v"]
    return y


def relocate_window(
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
            return r, section_state(r, y_pred)
    return None


def pd_test(M: np.ndarray) -> float | None:
    """``mu + 1`` of the real multiplier nearest -1 (None without a real one)."""
    mu = np.linalg.eigvals(M)
    real = mu[np.abs(mu.imag) <= 1e-9 * np.maximum(np.abs(mu), 1.0)].real
    if not len(real):
        return None
    return float(real[np.argmin(np.abs(real + 1.0))] + 1.0)


def fold_test(M: np.ndarray) -> float | None:
    """``mu - 1`` of the real multiplier nearest +1 (None without a real one)."""
    mu = np.linalg.eigvals(M)
    real = mu[np.abs(mu.imag) <= 1e-9 * np.maximum(np.abs(mu), 1.0)].real
    if not len(real):
        return None
    return float(real[np.argmin(np.abs(real - 1.0))] - 1.0)


def _bracket(lo, hi, a: tuple[float, float], b: tuple[float, float]):
    """The sign-change bracket ``(lo, hi)`` of a secant search after trial ``b = (x, f)``
    followed trial ``a`` (None, None until the first sign change)."""
    if a[1] * b[1] <= 0.0:
        return a, b
    if lo is not None:
        if (lo[1] < 0) == (b[1] < 0):
            return b, hi
        return lo, b
    return lo, hi


def _located(w: float, y: np.ndarray, mu: np.ndarray, evals: int) -> dict[str, Any]:
    """The row of a located point at ``w`` with section state ``y`` and multipliers ``mu``
    (sorted here by decreasing modulus)."""
    mu = mu[np.argsort(-np.abs(mu), kind="stable")]
    return {"value": w, "x": float(y[0]), "v": float(y[1]), "mu_max": float(abs(mu[0])),
            "mu_re": [float(m.real) for m in mu], "mu_im": [float(m.imag) for m in mu],
            "stable": bool(abs(mu[0]) < 1.0), "evals": evals}


class _TrialFunction:
    """The test function of a period doubling or grazing of the period-``n`` orbit along
    ``name`` at fixed other parameters: ``(y, M, f)`` at a trial ``w`` (None when the orbit is
    not found, has collapsed to a divisor of its period, or has no finite test value)."""

    def __init__(self, params: ModelParameters, kind: str, boundary: str, n: int, name: str,
                 cfg: Continuation, tangent_error: bool | None):
        self.params, self.kind, self.boundary, self.n, self.name = params, kind, boundary, n, name
        self.cfg, self.settings, self.tangent_error = cfg, cfg.settings, tangent_error
        self.dims = free_states(params)
        self.jac: list[np.ndarray] = []  # the latest monodromy: the chord iteration's matrix

    def chord(self, pw: ModelParameters, guess: np.ndarray):
        """Chord Newton on P^n(y) = y with the latest monodromy (state-only maps, ~10x
        cheaper than a monodromy); None when it does not contract fast (then full Newton)."""
        if not self.jac:
            return None
        dims, n, settings = self.dims, self.n, self.settings
        parr = pw.to_array()
        J = self.jac[-1] - np.eye(len(dims))
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

    def __call__(self, w: float, guess: np.ndarray):
        n, settings, tangent_error = self.n, self.settings, self.tangent_error
        try:
            pw = self.params.with_(**{self.name: w})
            y = self.chord(pw, guess)
            M = None
            if y is None:
                y, _yn, M, _r, _it = newton_orbit(pw, n, guess, settings, max_iter=8,
                                                  tangent_error=tangent_error)
                self.jac.append(M)
        except (OrbitError, ParameterError, np.linalg.LinAlgError):
            return None
        if n > 1:  # the orbit must not have collapsed to a divisor of its period
            yh, _ = section_map(pw, y, n // 2, settings, jacobian=False)
            if float(np.max(np.abs(yh[:2] - y[:2]))) < 1e-7 * (1.0 + abs(y[0])):
                return None
        try:
            if self.kind in ("period_doubling", "fold"):
                if M is None:
                    _, M = section_map(pw, y, n, settings, tangent_error=tangent_error)
                    self.jac.append(M)
                f = pd_test(M) if self.kind == "period_doubling" else fold_test(M)
            else:
                g = grazing_margin(pw, y, n, settings, substeps=self.cfg.substeps).signed
                f = g.get(self.boundary)
        except OrbitError:
            return None
        if f is None or not math.isfinite(f):
            return None
        return y, M, float(f)


def test_value(params: ModelParameters, kind: str, boundary: str, n: int, guess: np.ndarray,
               cfg: Continuation, tangent_error: bool | None = None):
    """``(y, M, f)`` at ``params``: the period-``n`` orbit corrected by Newton from ``guess``,
    its monodromy (None for a grazing found by chord Newton) and the test function of
    ``kind`` (``period_doubling``: ``mu + 1``; ``fold``: ``mu - 1``; ``grazing``: the signed
    distance of the turning point nearest ``boundary``); None where there is no such orbit."""
    return _TrialFunction(params, kind, boundary, n, "w", cfg, tangent_error)(params.w, guess)


def relocate_secant(
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
    settings = cfg.settings
    dims = free_states(params)
    evals: list[tuple[float, float, np.ndarray, np.ndarray]] = []  # (w, f, y, M)
    f_at = _TrialFunction(params, kind, boundary, n, name, cfg, tangent_error)

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
        lo, hi = _bracket(lo, hi, (wa, fa), (w_b, r[2]))
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
    row = _located(w, y, np.linalg.eigvals(M).astype(complex), len(evals))
    (wp, fp, _, _), (wl, fl, _, _) = evals[-2], evals[-1]
    row["slope"] = (fl - fp) / (wl - wp) if wl != wp else math.nan
    return row, y


def relocate_fold(
    params: ModelParameters, n: int, name: str, w_pred: float, y_pred: np.ndarray,
    window: float, cfg: Continuation, *, stol: float = 1e-10, max_eval: int = 14,
) -> tuple[dict[str, Any], np.ndarray] | None:
    """Locate the fold of the period-``n`` branch near ``(w_pred, y_pred)`` directly.

    At a fold ``w`` is not a parameter of the branch, but the coordinate ``s = v . y`` along the
    critical eigenvector ``v`` (multiplier +1) is: at fixed ``s`` the orbit and its ``w`` are
    one corrector solve (``G = 0``, ``v . y = s``; :meth:`BranchProblem.correct`), and the fold is
    the zero of the ``w`` component of the branch tangent (null vector of ``[M - I,
    dG/dw]``, oriented along ``v``). That scalar function of ``s`` is smooth through the fold;
    its zero is found by the secant method (bisection once bracketed), each trial started from
    the extrapolated state. Returns None on failure (the caller falls back to the windowed
    continuation). The located point has a multiplier +1 to 1e-4, as in the continuation.
    """
    prob = BranchProblem(params.with_(**{name: w_pred}), name, n, cfg)
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
        lo, hi = _bracket(lo, hi, (sa, fa), (s_b, r[3]))
        if abs(s_b - sa) < stol or r[3] == 0.0:
            break
    else:
        return None
    _s, _f, y, w, M = evals[-1]
    mu = np.linalg.eigvals(M).astype(complex)
    if float(np.min(np.abs(mu - 1.0))) > 1e-4 or abs(w - w_pred) > 3.0 * window:
        return None
    return _located(w, y, mu, len(evals)), y
