"""The predictor-corrector of a one-parameter branch
(:func:`gearsim.analysis.continuation.continue_orbit`) and the location of its events.

Predictor ``u + ds t`` along the unit tangent ``t`` (null vector of ``[M - I, dG/dlam]``, oriented
with the previous one); corrector: Newton on ``G = 0`` and ``t . (u - u_pred) = 0``. The step
``ds`` (Euclidean in ``(y, lam)``) grows after easy corrections and halves after hard ones.

Test functions between consecutive points (a sign change marks an event):

=================== ============================================== =================================
event               test function                                  at the zero
=================== ============================================== =================================
``fold``            ``det(M - I)``                                 a real multiplier crosses +1
``period_doubling`` ``det(M + I)``                                 a real multiplier crosses -1
``neimark_sacker``  ``prod_{i<j} (mu_i mu_j - 1)`` (bialternate)   a complex pair crosses |mu| = 1
``grazing``         ``extremum - boundary`` of the turning point    a contact is born or lost
                    nearest each contact boundary
=================== ============================================== =================================

Each event is located by Brent's method on the secant between the two points (each trial a
corrected orbit on the hyperplane normal to the secant) to ``1e-12`` in the secant fraction,
which puts the parameter within ``1e-8`` (folds: quadratically better). A product zero without a
complex pair on the unit circle (a neutral saddle) is dropped; a grazing zero must be a true
zero (``|g| < 1e-7``), not the jump between two turning points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from gearsim.analysis.continuation_options import BUDGET, Continuation
from gearsim.analysis.orbits import (
    KIND_FOLD,
    KIND_NS,
    KIND_PD,
    OrbitError,
    check_periodic_forcing,
    free_states,
    grazing_margin,
    multiplier_kind,
    section_map,
)
from gearsim.dynamics.parameters import ModelParameters, ParameterError

KIND_GRAZING = "grazing"
EVENT_KINDS = (KIND_FOLD, KIND_PD, KIND_NS, KIND_GRAZING)


@dataclass
class BranchPoint:
    y: np.ndarray  # full 10-state
    lam: float
    M: np.ndarray
    dGdl: np.ndarray
    tangent: np.ndarray  # (d + 1,)
    mu: np.ndarray
    tests: dict[str, float]
    graze: dict[str, float]
    amplitude: float
    margin: float



class BranchProblem:
    def __init__(self, params: ModelParameters, name: str, n: int, cfg: Continuation):
        if name not in ModelParameters.names():
            raise ParameterError(
                f"continuation parameter 'name' = {name!r}; allowed: "
                f"{', '.join(ModelParameters.names())}"
            )
        check_periodic_forcing(params)
        self.base = params
        self.name = name
        self.n = n
        self.cfg = cfg
        self.dims = free_states(params)
        self.d = len(self.dims)

    def params(self, lam: float) -> ModelParameters:
        return self.base.with_(**{self.name: lam})

    def full(self, yd: np.ndarray, like: np.ndarray) -> np.ndarray:
        y = like.copy()
        y[self.dims] = yd
        return y

    def evaluate(self, y: np.ndarray, lam: float, n: int | None = None):
        """``G``, ``M``, ``dG/dlam`` at ``(y, lam)``."""
        n = self.n if n is None else n
        st = self.cfg.settings
        pr = self.params(lam)
        yn, M = section_map(pr, y, n, st)
        G = yn[self.dims] - y[self.dims]
        dl = 1e-7 * (1.0 + abs(lam))
        yn2, _ = section_map(self.params(lam + dl), y, n, st, jacobian=False)
        dGdl = ((yn2[self.dims] - y[self.dims]) - G) / dl
        return G, M, dGdl

    def correct(self, y: np.ndarray, lam: float, normal: np.ndarray, anchor: np.ndarray,
                n: int | None = None, max_step: float = 0.2):
        """Newton on ``G = 0``, ``normal . (u - anchor) = 0`` from ``(y, lam)``.

        A Newton update longer than ``max_step`` (or a parameter leaving its range) fails the
        correction, so the caller shortens the step instead of jumping to another branch.
        """
        try:
            return self._correct(y, lam, normal, anchor, n, max_step)
        except ParameterError as exc:
            raise OrbitError(str(exc)) from None

    def _correct(self, y, lam, normal, anchor, n, max_step):
        d = self.d
        u = np.concatenate([y[self.dims], [lam]])
        for _ in range(self.cfg.corrector_iter):
            if self.cfg.out_of_budget():  # a point does not outlast the job's budget
                raise OrbitError(f"{BUDGET}: wall-clock budget spent")
            yy = self.full(u[:d], y)
            G, M, dGdl = self.evaluate(yy, u[d], n)
            h = float(normal @ (u - anchor))
            r = float(np.max(np.abs(G)))
            A = np.zeros((d + 1, d + 1))
            A[:d, :d] = M - np.eye(d)
            A[:d, d] = dGdl
            A[d] = normal
            du = np.linalg.solve(A, -np.concatenate([G, [h]]))
            if r < self.cfg.corrector_tol and abs(h) < 1e-12:
                return yy, u[d], M, dGdl
            if float(np.linalg.norm(du)) > max_step:
                raise OrbitError(f"corrector step {np.linalg.norm(du):.3g} too long")
            u = u + du
            if not np.all(np.isfinite(u)):
                break
        yy = self.full(u[:d], y)
        G, M, dGdl = self.evaluate(yy, u[d], n)
        if float(np.max(np.abs(G))) < self.cfg.corrector_tol:
            return yy, u[d], M, dGdl
        raise OrbitError(f"corrector failed near {self.name} = {lam:.8g}")

    def tangent(self, M: np.ndarray, dGdl: np.ndarray, prev: np.ndarray | None) -> np.ndarray:
        J = np.hstack([M - np.eye(self.d), dGdl[:, None]])
        t = np.linalg.svd(J)[2][-1]
        if prev is not None and float(t @ prev) < 0:
            t = -t
        return t / np.linalg.norm(t)

    def point(self, y, lam, M, dGdl, prev_t, n=None, with_grazing=True) -> BranchPoint:
        n = self.n if n is None else n
        t = self.tangent(M, dGdl, prev_t)
        mu = np.linalg.eigvals(M).astype(complex)
        mu = mu[np.argsort(-np.abs(mu), kind="stable")]
        tests = test_functions(M, mu)
        graze: dict[str, float] = {}
        amp = math.nan
        margin = math.nan
        pt = BranchPoint(y, lam, M, dGdl, t, mu, tests, graze, amp, margin)
        if self.cfg.grazing and with_grazing:
            self.add_grazing(pt, n)
        return pt

    def add_grazing(self, pt: BranchPoint, n: int | None = None) -> None:
        n = self.n if n is None else n
        gm = grazing_margin(self.params(pt.lam), pt.y, n, self.cfg.settings,
                            substeps=self.cfg.substeps)
        pt.graze = gm.signed
        pt.margin = gm.smallest
        pt.amplitude = gm.x_max - gm.x_min


def test_functions(M: np.ndarray, mu: np.ndarray) -> dict[str, float]:
    d = len(mu)
    eye = np.eye(d)
    bial = 1.0 + 0j
    for i in range(d):
        for j in range(i + 1, d):
            bial *= mu[i] * mu[j] - 1.0
    return {
        KIND_FOLD: float(np.linalg.det(M - eye)),
        KIND_PD: float(np.linalg.det(M + eye)),
        KIND_NS: float(bial.real),
    }


def critical_kind(m: complex) -> str:
    return multiplier_kind(complex(m))


def locate(prob: BranchProblem, a: BranchPoint, b: BranchPoint, func, n: int,
            graze: bool = False) -> BranchPoint | None:
    """Zero of ``func(point)`` between ``a`` and ``b`` (Brent on the secant fraction)."""
    d = prob.d
    ua = np.concatenate([a.y[prob.dims], [a.lam]])
    ub = np.concatenate([b.y[prob.dims], [b.lam]])
    sec = ub - ua
    normal = sec / np.linalg.norm(sec)
    cache: dict[float, BranchPoint] = {}

    def at(s: float) -> BranchPoint:
        if s in cache:
            return cache[s]
        if s <= 0.0:
            return a
        if s >= 1.0:
            return b
        anchor = ua + s * sec
        y0 = prob.full(anchor[:d], a.y)
        yy, lam, M, dGdl = prob.correct(y0, float(anchor[d]), normal, anchor, n)
        pt = prob.point(yy, lam, M, dGdl, a.tangent, n, with_grazing=graze)
        cache[s] = pt
        return pt

    try:
        s = brentq(lambda s: func(at(s)), 0.0, 1.0, xtol=prob.cfg.locate_xtol, maxiter=80)
    except (ValueError, RuntimeError, OrbitError):
        return None
    pt = at(s)
    if prob.cfg.grazing and not pt.graze:
        prob.add_grazing(pt, n)
    return pt


def _signed(pt: BranchPoint, key: str) -> float:
    return pt.graze.get(key, math.nan)


def branch_events(prob: BranchProblem, a: BranchPoint, b: BranchPoint,
                  n: int) -> list[tuple[BranchPoint, str, str]]:
    """The located events (point, kind, boundary) between consecutive branch points a and b."""
    out: list[tuple[BranchPoint, str, str]] = []
    for kind in (KIND_FOLD, KIND_PD, KIND_NS):
        fa, fb = a.tests[kind], b.tests[kind]
        if not (np.isfinite(fa) and np.isfinite(fb)) or fa * fb >= 0:
            continue
        loc = locate(prob, a, b, lambda p, k=kind: p.tests[k], n)
        if loc is None:
            continue
        if kind == KIND_NS and not _ns_confirmed(loc.mu):
            continue
        if kind == KIND_FOLD and np.min(np.abs(loc.mu - 1.0)) > 1e-4:
            continue
        if kind == KIND_PD and np.min(np.abs(loc.mu + 1.0)) > 1e-4:
            continue
        out.append((loc, kind, ""))
    for key in sorted(set(a.graze) & set(b.graze)):
        fa, fb = _signed(a, key), _signed(b, key)
        if not (np.isfinite(fa) and np.isfinite(fb)) or fa * fb >= 0:
            continue
        loc = locate(prob, a, b, lambda p, k=key: _signed(p, k), n, graze=True)
        if loc is None or not abs(_signed(loc, key)) < 1e-7:
            continue
        out.append((loc, KIND_GRAZING, key))
    return out


def _ns_confirmed(mu: np.ndarray) -> bool:
    for m in mu:
        if abs(m.imag) > 1e-6 and abs(abs(m) - 1.0) < 1e-5:
            return True
    return False
