"""Pseudo-arclength continuation of periodic orbits in one parameter, with located bifurcations.

Unknowns ``u = (y, lam)``: the section state over the model's free states and the parameter
``lam`` (any :class:`~gearsim.dynamics.parameters.ModelParameters` name). The branch is the
solution curve
of ``G(y, lam) = P^n(y; lam) - y = 0`` (:mod:`gearsim.analysis.orbits`); ``dG/dy = M - I`` comes
from the
variational equations, ``dG/dlam`` from a forward difference of the map (step ``1e-7 (1 +
|lam|)``; its error only slows the corrector, never moves the solution).

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

Branch switching at a period doubling: the period-``2n`` branch leaves the located point along
the critical eigenvector ``v`` (multiplier -1) with ``lam`` fixed to first order, so its first
point solves ``P^{2n}(y) = y`` on the hyperplane ``v . (y - y*) = ds`` (the pitchfork of the
doubled map); it is then continued like any branch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from scipy.optimize import brentq

from gearsim.analysis.orbits import (
    KIND_FOLD,
    KIND_NS,
    KIND_PD,
    SHOOTING,
    OrbitError,
    PeriodicOrbit,
    _check_params,
    free_states,
    grazing_margin,
    section_map,
)
from gearsim.cell.simulate import IntegrationSettings
from gearsim.dynamics.parameters import ModelParameters, ParameterError

KIND_GRAZING = "grazing"
EVENT_KINDS = (KIND_FOLD, KIND_PD, KIND_NS, KIND_GRAZING)

COLUMNS = (
    "branch", "period", "name", "value", "x", "v", "norm", "amplitude", "mu_max", "mu_re",
    "mu_im", "stable", "critical_kind", "event", "grazing_margin", "boundary",
)


@dataclass
class _Point:
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


@dataclass
class Continuation:
    """Settings of :func:`continue_orbit` (``ds`` in the Euclidean norm of ``(y, lam)``)."""

    ds: float = 0.01
    ds_min: float = 1e-5
    ds_max: float = 0.05
    max_points: int = 400
    corrector_tol: float = 1e-10
    corrector_iter: int = 8
    switch_depth: int = 2
    locate_xtol: float = 1e-12
    grazing: bool = True
    substeps: int = 512
    settings: IntegrationSettings = field(default_factory=lambda: SHOOTING)
    progress: Any = None  # optional callable(str): a line every 10 branch points
    #: ``time.monotonic()`` value at which the job's wall-clock budget ends (None: no budget;
    #: a system-wide clock, so worker processes share it). Checked between points: the
    #: computation stops with status ``budget``, keeping what it has.
    deadline: float | None = None

    def out_of_budget(self) -> bool:
        """The job's wall-clock budget is spent."""
        import time

        return self.deadline is not None and time.monotonic() >= self.deadline


#: Stop reasons of a continuation or a curve that ran out of its budget start with this.
BUDGET = "budget"


class _Problem:
    def __init__(self, params: ModelParameters, name: str, n: int, cfg: Continuation):
        if name not in ModelParameters.names():
            raise ParameterError(
                f"continuation parameter 'name' = {name!r}; allowed: "
                f"{', '.join(ModelParameters.names())}"
            )
        _check_params(params)
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

    def point(self, y, lam, M, dGdl, prev_t, n=None, with_grazing=True) -> _Point:
        n = self.n if n is None else n
        t = self.tangent(M, dGdl, prev_t)
        mu = np.linalg.eigvals(M).astype(complex)
        mu = mu[np.argsort(-np.abs(mu), kind="stable")]
        tests = _tests(M, mu)
        graze: dict[str, float] = {}
        amp = math.nan
        margin = math.nan
        pt = _Point(y, lam, M, dGdl, t, mu, tests, graze, amp, margin)
        if self.cfg.grazing and with_grazing:
            self.add_grazing(pt, n)
        return pt

    def add_grazing(self, pt: _Point, n: int | None = None) -> None:
        n = self.n if n is None else n
        gm = grazing_margin(self.params(pt.lam), pt.y, n, self.cfg.settings,
                            substeps=self.cfg.substeps)
        pt.graze = gm.signed
        pt.margin = gm.smallest
        pt.amplitude = gm.x_max - gm.x_min


def _tests(M: np.ndarray, mu: np.ndarray) -> dict[str, float]:
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


def _row(prob: _Problem, branch: int, n: int, pt: _Point, event: str = "",
         boundary: str = "") -> dict[str, Any]:
    mu = pt.mu
    return {
        "branch": branch,
        "period": n,
        "name": prob.name,
        "value": pt.lam,
        "x": float(pt.y[0]),
        "v": float(pt.y[1]),
        "norm": float(np.linalg.norm(pt.y[prob.dims])),
        "amplitude": pt.amplitude,
        "mu_max": float(abs(mu[0])),
        "mu_re": [float(m.real) for m in mu],
        "mu_im": [float(m.imag) for m in mu],
        "stable": bool(abs(mu[0]) < 1.0),
        "critical_kind": _kind(mu[0]),
        "event": event,
        "grazing_margin": pt.margin,
        "boundary": boundary,
    }


def _kind(m: complex) -> str:
    from gearsim.analysis.orbits import multiplier_kind

    return multiplier_kind(complex(m))


def _locate(prob: _Problem, a: _Point, b: _Point, func, n: int,
            graze: bool = False) -> _Point | None:
    """Zero of ``func(point)`` between ``a`` and ``b`` (Brent on the secant fraction)."""
    d = prob.d
    ua = np.concatenate([a.y[prob.dims], [a.lam]])
    ub = np.concatenate([b.y[prob.dims], [b.lam]])
    sec = ub - ua
    normal = sec / np.linalg.norm(sec)
    cache: dict[float, _Point] = {}

    def at(s: float) -> _Point:
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


def _signed(pt: _Point, key: str) -> float:
    return pt.graze.get(key, math.nan)


def continue_orbit(
    params: ModelParameters,
    name: str,
    start: float,
    stop: float,
    orbit: PeriodicOrbit | None = None,
    *,
    n: int | None = None,
    config: Continuation | None = None,
) -> pd.DataFrame:
    """Continue a periodic orbit in parameter ``name`` from ``start`` towards ``stop``.

    Parameters
    ----------
    params
        Model parameters; ``name`` is set to ``start`` (or taken from ``orbit``).
    orbit
        Starting orbit at ``name = start`` (:func:`gearsim.analysis.orbits.find_periodic_orbit`);
        default: simulated from rest at ``start`` and refined for period ``n``.
    n
        Period of the branch (default: ``orbit.n``).

    Returns
    -------
    DataFrame, one row per branch point (columns :data:`COLUMNS`): ``branch`` (0 the start
    branch; period-doubled branches get new numbers), ``period``, parameter ``value``, section
    ``x``, ``v``, ``norm`` (Euclidean norm of the section state over the free states),
    ``mu_max``, the multipliers (``mu_re``, ``mu_im``, decreasing modulus), ``stable``,
    ``critical_kind``, ``event`` (``""`` on regular points; ``fold``, ``period_doubling``,
    ``neimark_sacker``, ``grazing`` on located points, inserted in branch order),
    ``grazing_margin`` and the ``boundary`` that grazes. ``df.attrs`` holds the parameters,
    the stop reasons and the wall time.
    """
    import time

    from gearsim.analysis.orbits import find_periodic_orbit

    cfg = config or Continuation()
    t0 = time.perf_counter()
    if name not in ModelParameters.names():
        raise ParameterError(
            f"continuation parameter 'name' = {name!r}; allowed: "
            f"{', '.join(ModelParameters.names())}"
        )
    if orbit is None:
        if n is None:
            raise ParameterError("continue_orbit needs 'orbit' or the period 'n'")
        orbit = find_periodic_orbit(params.with_(**{name: start}), n, None, cfg.settings,
                                    grazing=False)
    n = orbit.n
    p0 = orbit.params
    lam0 = float(getattr(p0, name))
    if not math.isclose(lam0, start, rel_tol=0, abs_tol=1e-12):
        p0 = p0.with_(**{name: start})
        orbit = find_periodic_orbit(p0, n, orbit.state, cfg.settings, grazing=False)
    if start == stop:
        raise ParameterError(f"continuation range of '{name}' is empty: from = to = {start}")
    rows: list[dict[str, Any]] = []
    reasons: list[str] = []
    prob = _Problem(p0, name, n, cfg)
    G, M, dGdl = prob.evaluate(orbit.state, start)
    direction = 1.0 if stop > start else -1.0
    first = prob.point(orbit.state, start, M, dGdl, None)
    if first.tangent[-1] * direction < 0:
        first.tangent = -first.tangent
    lo, hi = min(start, stop), max(start, stop)
    # jobs: continue a branch ("run"), or switch onto the doubled branch at a period doubling
    # ("switch"). The doublings of one branch form a group; a doubled branch that ends at
    # another doubling of its group (a period-2n bubble joining two doublings) makes the switch
    # there redundant.
    jobs: list[dict[str, Any]] = [dict(kind="run", branch=0, n=n, pt=first, origins=[],
                                       own=-1, group=None, depth=0)]
    reached: dict[int, set[int]] = {}
    next_branch = 1
    while jobs:
        if cfg.out_of_budget():
            reasons.append(f"{BUDGET}: wall-clock budget spent, {len(jobs)} branch job(s) "
                           "not run")
            break
        job = jobs.pop(0)
        nb = job["n"]
        if job["kind"] == "switch":
            pd_pt = job["pt"]
            if job["own"] in reached[job["group"]]:
                reasons.append(f"no switch at {name} = {pd_pt.lam:.8f}: the doubled branch of "
                               "another doubling ends there")
                continue
            sw = _switch(_Problem(p0, name, nb // 2, cfg), pd_pt, cfg)
            if sw is None:
                reasons.append(f"branch switch at {name} = {pd_pt.lam:.8f} failed")
                continue
            jobs.insert(0, dict(job, kind="run", branch=next_branch, pt=sw))
            next_branch += 1
            continue
        branch, depth = job["branch"], job["depth"]
        bprob = _Problem(p0, name, nb, cfg)
        reason, new, hit = _run_branch(bprob, branch, job["pt"], lo, hi, rows, cfg,
                                       origins=job["origins"], own=job["own"])
        reasons.append(f"branch {branch} (period {nb}): {reason}")
        if hit is not None and job["group"] is not None:
            reached[job["group"]].add(hit)
        if depth < cfg.switch_depth and new:
            gid = len(reached)
            reached[gid] = set()
            origins = [_orbit_points(bprob, q) for q in new]
            for k, pd_pt in enumerate(new):
                jobs.append(dict(kind="switch", n=2 * nb, pt=pd_pt, origins=origins, own=k,
                                 group=gid, depth=depth + 1))
    df = pd.DataFrame(rows, columns=list(COLUMNS))
    df.attrs.update(
        params=p0.to_dict(), name=name, start=start, stop=stop, reasons=reasons,
        wall_s=time.perf_counter() - t0,
        status=BUDGET if any(f"{BUDGET}: " in r for r in reasons) else "ok",
    )
    return df


def _switch(prob: _Problem, pd_pt: _Point, cfg: Continuation) -> _Point | None:
    """First point of the period-doubled branch at a located period doubling."""
    mu, vecs = np.linalg.eig(pd_pt.M)
    k = int(np.argmin(np.abs(mu + 1.0)))
    v = np.real(vecs[:, k])
    v /= np.linalg.norm(v)
    n2 = 2 * prob.n
    dprob = _Problem(prob.base, prob.name, n2, cfg)
    d = prob.d
    for ds in (1e-3, 3e-3, 1e-2, 3e-4):
        for sgn in (1.0, -1.0):
            normal = np.concatenate([sgn * v, [0.0]])
            anchor = np.concatenate([pd_pt.y[prob.dims] + sgn * ds * v, [pd_pt.lam]])
            y0 = dprob.full(anchor[:d], pd_pt.y)
            try:
                yy, lam, M, dGdl = dprob.correct(y0, pd_pt.lam, normal, anchor)
            except (OrbitError, np.linalg.LinAlgError):
                continue
            # reject the period-n orbit itself
            yn, _ = section_map(prob.params(lam), yy, prob.n, cfg.settings, jacobian=False)
            if float(np.max(np.abs(yn[prob.dims] - yy[prob.dims]))) < 1e-3 * ds:
                continue
            pt = dprob.point(yy, lam, M, dGdl, normal)
            return pt
    return None


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Euclidean distance of point ``p`` to the segment ``[a, b]``."""
    ab = b - a
    L2 = float(ab @ ab)
    s = 0.0 if L2 == 0.0 else min(max(float((p - a) @ ab) / L2, 0.0), 1.0)
    return float(np.linalg.norm(p - (a + s * ab)))


def _orbit_points(prob: _Problem, pt: _Point) -> np.ndarray:
    """The ``n`` section points of the orbit at ``pt`` as ``(y_free, lam)`` rows."""
    from gearsim.cell.simulate import run_periods

    r = run_periods(prob.params(pt.lam), pt.y, prob.n, prob.cfg.settings)
    sec = np.asarray(r.summaries.section, dtype=float)[:, : len(pt.y)]
    return np.column_stack([sec[:, prob.dims], np.full(len(sec), pt.lam)])


def _run_branch(prob: _Problem, branch: int, first: _Point, lo: float, hi: float,
                rows: list[dict[str, Any]], cfg: Continuation,
                origins: list[np.ndarray] | None = None,
                own: int = -1) -> tuple[str, list[_Point], int | None]:
    """Continue one branch; append rows; return (stop reason, located period doublings, index
    of the origin it ended at).

    A closed branch ends where it returns through a doubling point of its parent (``origins``:
    per doubling, the parent orbit's section points as ``(y, lam)`` rows; ``own`` the one it
    was switched at) or through its own first point: a doubled branch joining two doublings
    (a bubble), or coming back through its own doubling (it then continues as the same orbit
    shifted by ``n/2`` periods), and an isola would otherwise be traced round and round until
    ``max_points``.
    """
    n = prob.n
    d = prob.d
    pt = first
    origins = list(origins or [])
    targets = [(k, o) for k, pts in enumerate(origins) for o in np.atleast_2d(pts)]
    if own < 0:
        targets.append((-1, np.concatenate([first.y[prob.dims], [first.lam]])))
    home = [o for k, o in targets if k == own or k < 0]  # where the branch starts
    far = 0.0
    rows.append(_row(prob, branch, n, pt))
    ds = cfg.ds
    pds: list[_Point] = []
    for step in range(cfg.max_points):
        if cfg.out_of_budget():
            return (f"{BUDGET}: wall-clock budget spent at {prob.name} = {pt.lam:.8g}", pds,
                    None)
        u = np.concatenate([pt.y[prob.dims], [pt.lam]])
        while True:
            upred = u + ds * pt.tangent
            y0 = prob.full(upred[:d], pt.y)
            try:
                yy, lam, M, dGdl = prob.correct(y0, float(upred[d]), pt.tangent, upred,
                                                max_step=max(0.5 * ds, 1e-4))
                ok = True
            except (OrbitError, np.linalg.LinAlgError):
                ok = False
            if ok:
                break
            if cfg.out_of_budget():
                return (f"{BUDGET}: wall-clock budget spent at {prob.name} = {pt.lam:.8g}",
                        pds, None)
            ds *= 0.5
            if ds < cfg.ds_min:
                return (f"step size below {cfg.ds_min} at {prob.name} = {pt.lam:.8g}", pds,
                        None)
        new = prob.point(yy, lam, M, dGdl, pt.tangent)
        # closed branch: it passes through a doubling point (a pitchfork of P^n, where the
        # fold test changes sign without a fold); the interval is not tested, the point not kept
        u_new = np.concatenate([new.y[prob.dims], [new.lam]])
        seg = float(np.linalg.norm(u_new - u))
        for k, o in targets:
            if k == own or k < 0:  # its own start: only after it has gone away
                if far <= 4.0 * max(seg, cfg.ds):
                    continue
            if _segment_distance(o, u, u_new) < 0.1 * seg:
                what = "its start" if k < 0 else ("its own doubling" if k == own else
                                                  "another doubling of its parent")
                return (f"closed: returned through {what} at {prob.name} = {new.lam:.8g}",
                        pds, (k if k >= 0 else None))
        if home:
            far = max(far, min(float(np.linalg.norm(u_new - o)) for o in home))
        # the first interval of a switched branch starts on a branch point: skip its tests
        events = [] if (step == 0 and branch > 0) else _events(prob, pt, new, n)
        for ev_pt, kind, bnd in sorted(events, key=lambda e: abs(e[0].lam - pt.lam)):
            rows.append(_row(prob, branch, n, ev_pt, kind, bnd))
            if kind == KIND_PD:
                pds.append(ev_pt)
        rows.append(_row(prob, branch, n, new))
        if cfg.progress is not None and step % 10 == 9:
            cfg.progress(f"branch {branch} (period {n}): {step + 1} points, {prob.name} = "
                         f"{new.lam:.6f}, |mu|max = {abs(new.mu[0]):.4f}")
        # merged back into a shorter period (a doubled branch ending at its inverse doubling)
        if n > 1 and branch > 0:
            half = n // 2
            yn, _ = section_map(prob.params(new.lam), new.y, half, cfg.settings, jacobian=False)
            if float(np.max(np.abs(yn[prob.dims] - new.y[prob.dims]))) < 1e-7:
                # turned onto its parent at a doubling: which one (the nearest)
                near = [(float(np.linalg.norm(u_new - o)), k) for k, o in targets if k >= 0]
                hit = min(near)[1] if near and min(near)[0] < 4.0 * cfg.ds_max else None
                return (f"merged into period {half} at {prob.name} = {new.lam:.8g}", pds,
                        hit)
        pt = new
        if not (lo - 1e-12 <= pt.lam <= hi + 1e-12):
            return f"left [{lo}, {hi}] at {prob.name} = {pt.lam:.8g}", pds, None
        ds = min(cfg.ds_max, ds * 1.3)
    return f"{cfg.max_points} points", pds, None


def _events(prob: _Problem, a: _Point, b: _Point, n: int) -> list[tuple[_Point, str, str]]:
    out: list[tuple[_Point, str, str]] = []
    for kind in (KIND_FOLD, KIND_PD, KIND_NS):
        fa, fb = a.tests[kind], b.tests[kind]
        if not (np.isfinite(fa) and np.isfinite(fb)) or fa * fb >= 0:
            continue
        loc = _locate(prob, a, b, lambda p, k=kind: p.tests[k], n)
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
        loc = _locate(prob, a, b, lambda p, k=key: _signed(p, k), n, graze=True)
        if loc is None or not abs(_signed(loc, key)) < 1e-7:
            continue
        out.append((loc, KIND_GRAZING, key))
    return out


def _ns_confirmed(mu: np.ndarray) -> bool:
    for m in mu:
        if abs(m.imag) > 1e-6 and abs(abs(m) - 1.0) < 1e-5:
            return True
    return False


def write_branches(df: pd.DataFrame, path) -> None:
    """Write a branch table as Parquet (``df.attrs`` as JSON schema metadata)."""
    import json
    import os
    from pathlib import Path

    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    table = pa.Table.from_pandas(df, preserve_index=False)
    meta = {b"gearsim.analysis.continuation": json.dumps(df.attrs, default=float).encode()}
    table = table.replace_schema_metadata({**(table.schema.metadata or {}), **meta})
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        pq.write_table(table, tmp)
        tmp.replace(path)
    finally:  # a full disk or a kill leaves the previous file and no temporary one
        if tmp.exists():
            tmp.unlink()
