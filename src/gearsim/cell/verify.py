"""Labels backed by the orbit: Newton refinement of cells that settle too slowly for the budget.

Next to a period doubling, a fold or a grazing the leading Floquet multiplier of the attracting
orbit approaches the unit circle and a transient decays over hundreds of periods: the measured
window is then a reading of the transient, not of the motion. :func:`refine` settles such a
cell: Newton shooting on the stroboscopic map (:func:`gearsim.numerics.shooting.newton_orbit`,
the one orbit solver) from the last section state, for the cell's period (or, without one, for
the periods the section points nearly repeat after:
:func:`gearsim.cell.classify.candidate_periods`).
The orbit is accepted when Newton converges, the orbit is stable (``|mu|max < 1``) and the
simulated window approaches it (its mean distance to the orbit's section points falls from the
first to the last quarter of the window, or is already below 1e-6 of the orbit's range). The
cell is then labelled by that orbit (its pattern, DC and Kmax over one motion period from the
orbit's section state; its exponent the leading Floquet exponent ``log|mu|max / (n T)``), with
its Floquet margin ``mu_max`` and the kind of its critical multiplier.

A cell whose Newton orbit has just lost stability (``1 <= |mu|max < 1 +`` the margin, e.g. a
period-2 window next to the period-1 orbit it doubled from) keeps its window's reading with
status ``bifurcation`` and that orbit's ``mu_max`` and ``critical`` (``refined`` false).

Status of a refined cell: ``ok``, or ``bifurcation`` when ``1 - |mu|max <``
:data:`BIFURCATION_MARGIN` (the transient's e-folding time exceeds 1000 motion periods: no
simulation of the budget tells the two sides of the bifurcation apart, and the cell sits within
a small fraction of a grid step of it; the label is the orbit's, ``critical`` says which
bifurcation).

Without an orbit, ``quasi-periodic`` stays only when the section points lie on a curve
(:func:`on_closed_curve`, the cut of an invariant torus); else the cell is ``unsettled``.

Which cells: a periodic cell whose settle distance
(:func:`gearsim.cell.classify.settle_estimate`) exceeds :data:`REFINE_RTOL` of its range, and a
cell without a period whose exponent does not say chaos (``quasi-periodic`` or ``unsettled``).
With ``floquet="all"`` every periodic cell gets its Floquet margin (the sweeps' and points'
option; a plane's fast-settling cells keep ``mu_max`` NaN: their refinement would cost more than
the whole simulation, docs/decisions.md "Verified motions").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gearsim.cell.classify import (
    Classification,
    candidate_periods,
    classify_motion,
    estimate_period,
    settle_estimate,
)
from gearsim.dynamics.model import N_STATE, P_ACT, project_tangent
from gearsim.dynamics.parameters import ModelParameters
from gearsim.numerics.integrate import (
    STATUS_OK,
    IntegrationSettings,
    PeriodSummaries,
    run_periods,
)
from gearsim.numerics.settings import FLOQUET_MODES, Method
from gearsim.numerics.shooting import (
    SHOOTING,
    OrbitError,
    multiplier_kind,
    newton_orbit,
    newton_step,
    section_map,
    sorted_eigs,
)
from gearsim.numerics.variational import monodromies

#: a periodic cell farther than this from settled (relative to its x range) is refined: ten
#: times below the attractor finder's merge tolerance (1e-3), so two starts on one orbit merge
REFINE_RTOL = 1e-4
#: ``1 - |mu|max`` below which a refined cell's status is ``bifurcation``
BIFURCATION_MARGIN = 1e-3
#: Newton shooting of a DP5 cell: rtol 1e-10 (multipliers within 1e-10 of those at 1e-12)
REFINE_SHOOTING = SHOOTING.with_(rtol=1e-10, atol=1e-12)
#: an RK4 cell is refined with RK4 at this many times its steps per period: the orbit of the
#: cell's own integrator, multipliers within 1.2e-7 of DP5 at 1e-12 (192 steps: 1.8e-6), at a
#: fifth of the DP5 cost (docs/decisions.md, "Verified motions")
RK4_REFINE_FACTOR = 2


def refine_settings(st: IntegrationSettings) -> IntegrationSettings:
    """The Newton-shooting settings for a cell simulated with ``st``."""
    if st.method is Method.RK4:
        return st.with_(steps_per_period=RK4_REFINE_FACTOR * st.steps_per_period)
    return REFINE_SHOOTING
#: Newton converged when max |P^n(y) - y| is below this (dimensionless state units)
REFINE_TOL = 1e-9
REFINE_MAX_ITER = 12
#: FLOQUET modes: "slow" refines the cells that need it; "margin" also gives every other periodic
#: cell its Floquet margin (the monodromy of its settled orbit, its label kept); "all" refines
#: every periodic cell (Newton, relabelled by the orbit)
FLOQUET = FLOQUET_MODES
#: the margin of a settled cell: its last section state is polished by Newton on the cell's own
#: map until ``max |P^n(y) - y|`` is below this (mostly no step: the state is settled to it)
MARGIN_TOL = 1e-9
MARGIN_MAX_ITER = 4


def wants_margin(n: int, status: str, refined: bool, mu_max, var_ratio: float) -> bool:
    """Whether a periodic reading still needs its Floquet margin: a period, status ``ok``, not
    refined (a refined orbit has its own), no margin yet, a T-periodic map (no variable
    ratio)."""
    known = mu_max is not None and math.isfinite(mu_max)
    return n > 0 and status == "ok" and not refined and not known and var_ratio == 0.0


def _wants_margin(res) -> bool:
    c = res.classification
    return wants_margin(c.n, c.status, c.refined, c.mu_max, res.params.var_ratio)


def _switch_free(res) -> bool:
    """Whether the cell's motion never changes contact region (no mesh contact entered or left,
    no bearing clearance): the field is then one linear system along the orbit and its
    neighbourhood, so the monodromy does not depend on the state it is taken at."""
    c = res.classification
    if not (c.p == 0 and c.q == 0 and (c.dc == 0.0 or c.I == -2)):
        return False
    return not np.any(res.params.to_array()[P_ACT : P_ACT + 4])


def fill_margins(results: list, st: IntegrationSettings, backend=None) -> None:
    """Give every periodic result (``CellResult``) its Floquet margin ``mu_max`` and the kind of
    its critical multiplier (:data:`FLOQUET` ``"margin"``; in place), many cells in shared
    kernel calls on ``backend`` (:func:`orbit_margins`).
    Only with ``st.floquet == "margin"`` and RK4 (a DP5 cell's margin: ``"all"``).
    """
    if st.floquet != "margin" or st.method is not Method.RK4:
        return
    todo = [r for r in results if _wants_margin(r)]
    got = orbit_margins([r.params for r in todo], [r.classification.n for r in todo],
                        [r.final_state for r in todo], st,
                        [_switch_free(r) for r in todo], backend)  # fmt: skip
    for r, m in zip(todo, got, strict=True):
        if m is not None:
            r.classification = replace(r.classification, mu_max=m[0], critical=m[1])


def orbit_margins(params_list: list[ModelParameters], ns: list[int], states: list,
                  st: IntegrationSettings, switch_free: list[bool] | None = None,
                  backend=None) -> list[tuple[float, str] | None]:
    """``(|mu|max, kind of the critical multiplier)`` of the period-``ns[i]`` orbit through
    each settled section state ``states[i]`` (None where no orbit is found), many cells in
    shared kernel calls.

    The margin is that of the cell's own map (``st``) at ``y`` = ``states[i]``
    (:func:`gearsim.numerics.variational.monodromies`, one lane per tangent column) when
    ``y`` is a fixed point of ``P^n`` to :data:`MARGIN_TOL` or the motion is switch-free
    (``switch_free[i]``, :func:`_switch_free`: the monodromy is the same at every state near the
    orbit); else at ``y`` after one Newton step
    (:func:`gearsim.numerics.shooting.newton_step`) when that is a fixed point to the
    tolerance; else the one orbit solver's (:func:`floquet_margin`). ``backend``: where the
    monodromies' lanes run (default the CPU).
    """
    out: list[tuple[float, str] | None] = [None] * len(params_list)
    free = switch_free if switch_free is not None else [False] * len(params_list)
    by_n: dict[int, list[int]] = {}
    for i, n in enumerate(ns):
        by_n.setdefault(int(n), []).append(i)
    for n, group in by_n.items():
        ys = [states[i] for i in group]
        for step in (0, 1):
            if not group:
                break
            maps = monodromies([params_list[i] for i in group], ys, n, st, backend)
            again, y_again = [], []
            done: dict[int, list] = {}  # accepted, by dimension: one eigenvalue call each
            for i, y, (yn, M, status) in zip(group, ys, maps, strict=True):
                if status == STATUS_OK and np.all(np.isfinite(M)):
                    d = len(M)
                    G = yn[:d] - y[:d]
                    if float(np.max(np.abs(G))) < MARGIN_TOL or free[i]:
                        done.setdefault(d, []).append((i, M))
                        continue
                    if step == 0:
                        y1 = np.array(y, dtype=float)[:N_STATE].copy()
                        y1[:d] += newton_step(M, G)
                        again.append(i)
                        y_again.append(y1)
                        continue
                out[i] = floquet_margin(params_list[i], n, states[i], st)
            for pairs in done.values():
                mus = sorted_eigs(np.stack([M for _, M in pairs]))
                for (i, _), mu in zip(pairs, mus, strict=True):
                    out[i] = (float(abs(mu[0])), multiplier_kind(complex(mu[0])))
            group, ys = again, y_again
    return out


def floquet_margin(params: ModelParameters, n: int, guess: np.ndarray,
                   st: IntegrationSettings) -> tuple[float, str] | None:
    """``(|mu|max, kind of the critical multiplier)`` of the period-``n`` orbit through the
    settled section state ``guess``: the monodromy of the cell's own map there (RK4: the
    tangent columns as SIMD lanes, :func:`gearsim.numerics.batch.tangent_lanes_many`), after Newton
    steps of the one orbit solver while the state is farther than :data:`MARGIN_TOL` from a
    fixed point; None without a T-periodic map or when Newton fails."""
    if params.var_ratio != 0.0:
        return None
    try:
        _, _, M, _, _ = newton_orbit(params, n, guess, st, tol=MARGIN_TOL,
                                     max_iter=MARGIN_MAX_ITER)  # fmt: skip
    except OrbitError:
        return None
    mu = sorted_eigs(M)
    if not np.isfinite(mu[0]):
        return None
    return float(abs(mu[0])), multiplier_kind(complex(mu[0]))


@dataclass
class Refinement:
    """A stable periodic orbit a cell's trajectory approaches."""

    n: int  # minimal period (mesh periods)
    state: np.ndarray  # (10,) section state of the orbit
    multipliers: np.ndarray  # of P^n, sorted by decreasing modulus
    residual: float
    iterations: int
    approach: float  # mean distance of the last quarter of the window to the orbit (rel.)

    @property
    def mu_max(self) -> float:
        return float(abs(self.multipliers[0]))

    @property
    def critical(self) -> str:
        return multiplier_kind(complex(self.multipliers[0]))


class OrbitCache:
    """Refined orbits of one batch of runs (e.g. the starts of one attractor search), so that
    a run that settles slowly onto an orbit already refined for the same parameters takes it
    without a Newton solve: its last section state must lie within ``max(10 settle, 1e-6)`` of
    the orbit's range from one of the orbit's section points (``settle`` = its own distance
    from settled, :func:`gearsim.cell.classify.settle_estimate`)."""

    def __init__(self) -> None:
        self._orbits: dict[tuple, list[tuple[np.ndarray, Classification]]] = {}

    def find(self, params: ModelParameters, cls: Classification, guess: np.ndarray
             ) -> tuple[Classification, np.ndarray] | None:
        if cls.n <= 0 or not math.isfinite(cls.settle):
            return None
        for section, ocls in self._orbits.get((params, cls.n), []):
            scale = max(ocls.x_max - ocls.x_min, 1e-9)
            tol = max(10.0 * cls.settle, 1e-6)
            d = _distances(np.asarray(guess, dtype=float)[None, :2], section[:, :2], scale,
                           params.w)  # fmt: skip
            if d[0] <= tol:
                return replace(ocls, settle=cls.settle), section
        return None

    def add(self, params: ModelParameters, n: int, cls: Classification,
            section: np.ndarray) -> None:
        self._orbits.setdefault((params, n), []).append((section, cls))


#: a quasi-periodic reading needs its section points on a curve: the neighbourhood of every
#: point (its ``CURVE_K`` nearest points) is thin, second singular value below
#: ``CURVE_THIN`` of the first, for at least ``CURVE_SHARE`` of the points
CURVE_K = 6
CURVE_THIN = 0.25
CURVE_SHARE = 0.9


def on_closed_curve(points: np.ndarray, scale_x: float, scale_v: float) -> bool:
    """Whether the section points ``(x, x')`` lie on a curve (an invariant torus cuts the section
    in a closed curve; a chaotic or transient cloud fills an area): every point's ``CURVE_K``
    nearest neighbours (axes scaled by the motion's ranges) spread along one direction."""
    p = np.asarray(points, dtype=float)[:, :2]
    p = p / np.array([max(scale_x, 1e-12), max(scale_v, 1e-12)])
    m = len(p)
    if m < 4 * CURVE_K:
        return False
    d = np.sum((p[:, None, :] - p[None, :, :]) ** 2, axis=2)
    nn = np.argsort(d, axis=1)[:, : CURVE_K + 1]
    thin = 0
    for i in range(m):
        q = p[nn[i]] - p[nn[i]].mean(axis=0)
        sv = np.linalg.svd(q, compute_uv=False)
        thin += sv[0] > 0.0 and sv[1] <= CURVE_THIN * sv[0]
    return thin >= CURVE_SHARE * m


def read_window(params: ModelParameters, summaries: PeriodSummaries, n: int,
                st: IntegrationSettings) -> tuple[PeriodSummaries, Classification]:
    """The analysed window of measured periods ``summaries`` (period ``n``, 0 if none: whole
    motion periods only, the early part of a long measurement dropped) and its classification,
    with the settle distance read from all measured periods."""
    if n > 0:
        keep = n * max(1, min(len(summaries), 4 * max(n, 8)) // n)
        window = summaries.tail(keep)
    else:
        window = summaries
    cls = classify_motion(
        window, params, n=n, lyap_threshold=st.lyap_threshold,
    )  # fmt: skip
    if n > 0:
        cls.settle = window_settle(params, summaries, n)
    return window, cls


def window_settle(params: ModelParameters, summaries: PeriodSummaries, n: int) -> float:
    """The settle distance of the recorded periods ``summaries`` for period ``n``
    (:func:`gearsim.cell.classify.settle_estimate`, relative to their x range)."""
    scale = float(summaries.xmax.max() - summaries.xmin.min())
    # contiguous copies: a strided view of the lanes' records misses Numba's fast dispatch
    xs = np.ascontiguousarray(summaries.section[:, 0])
    vs = np.ascontiguousarray(summaries.section[:, 1])
    return float(settle_estimate(xs, vs, int(n), scale, float(params.w), 96)[0])


def needs_refinement(cls: Classification, floquet: str = "slow") -> bool:
    """Whether :func:`refine` should settle this classification (see the module docstring)."""
    if cls.status in ("diverged", "budget"):
        return False
    if cls.n > 0:
        return floquet == "all" or not cls.settle <= REFINE_RTOL
    return cls.motion in ("quasi-periodic", "unsettled")


def _distances(points: np.ndarray, orbit: np.ndarray, scale: float, w: float) -> np.ndarray:
    """Relative distance of each point to the nearest orbit section point (x, x')."""
    dx = np.abs(points[:, None, 0] - orbit[None, :, 0]) / scale
    dv = np.abs(points[:, None, 1] - orbit[None, :, 1]) / (scale * max(w, 1e-3))
    return np.min(np.maximum(dx, dv), axis=1)


def _minimal_period(section: np.ndarray, n: int) -> int:
    scale = 1.0 + float(np.max(np.abs(section[:, :2])))
    for m in range(1, n + 1):
        if n % m == 0 and np.all(np.abs(section[m % n] - section[0]) <= 1e-7 * scale):
            return m
    return n


def refine(params: ModelParameters, window: PeriodSummaries, n: int, guess: np.ndarray,
           st: IntegrationSettings, saddles: list | None = None) -> Refinement | None:
    """The stable period-``n`` orbit the window approaches, from the section state ``guess``,
    or an orbit that has just lost stability (``|mu|max < 1 +`` :data:`BIFURCATION_MARGIN`, no
    approach test); None when Newton fails, the orbit is farther from stable or the window
    does not approach it. An orbit farther from stable is appended to ``saddles`` if given."""
    if params.var_ratio != 0.0:
        return None  # the map is not T-periodic: no orbit to refine
    p = params.to_array()
    rst = refine_settings(st)
    try:
        y, _, M, r, it = newton_orbit(params, n, guess, rst, tol=REFINE_TOL,
                                      max_iter=REFINE_MAX_ITER, parray=p)  # fmt: skip
    except OrbitError:
        return None
    run = run_periods(params, y, n, rst, parray=p)
    if run.status != STATUS_OK:
        return None
    section = run.summaries.section  # states at the start of each period: P^k(y), k < n
    m = _minimal_period(section, n)
    if m < n:
        try:
            _, M = section_map(params, y, m, rst, parray=p)
        except OrbitError:
            return None
        section = section[:m]
    mu = sorted_eigs(M)
    if not abs(mu[0]) < 1.0:
        if abs(mu[0]) < 1.0 + BIFURCATION_MARGIN:
            # just past a bifurcation: the window leaves this orbit slowly (no approach test)
            return Refinement(m, y[:N_STATE].copy(), mu, r, it, math.nan)
        if saddles is not None:
            saddles.append(Refinement(m, y[:N_STATE].copy(), mu, r, it, math.nan))
        return None
    scale = max(float(window.xmax.max() - window.xmin.min()), 1e-9)
    q = max(len(window) // 4, 1)
    d = _distances(window.section[:, :2], section[:, :2], scale, params.w)
    early, late = float(np.mean(d[:q])), float(np.mean(d[-q:]))
    if not (late < early or late <= 1e-6):
        return None
    return Refinement(m, y[:N_STATE].copy(), mu, r, it, late)


def orbit_classification(params: ModelParameters, ref: Refinement, st: IntegrationSettings,
                         settle: float) -> tuple[Classification, np.ndarray] | None:
    """The classification of the refined orbit (one motion period from its section state, the
    cell's integrator) and its section points; None if that run diverges."""
    run = run_periods(params, ref.state, ref.n, st)
    if run.status != STATUS_OK or len(run.summaries) < ref.n:
        return None
    cls = classify_motion(
        run.summaries, params, n=ref.n, lyap_threshold=st.lyap_threshold,
    )  # fmt: skip
    T = 2.0 * math.pi / params.w
    status = "bifurcation" if 1.0 - ref.mu_max < BIFURCATION_MARGIN else "ok"
    cls = replace(cls, status=status, lyapunov=math.log(ref.mu_max) / (ref.n * T),
                  mu_max=ref.mu_max, critical=ref.critical, refined=True, settle=settle,
                  converged=True)  # fmt: skip
    return cls, run.summaries.section.copy()


#: a window next to a saddle, or without a period, chaos or an orbit, is followed for at most
#: this many periods (the long simulations that decide such cells in
#: tests/integration/test_verify.py: 4 000)
SADDLE_MAX_PERIODS = 4000


def _is_saddle(ref: Refinement) -> bool:
    """One real multiplier outside the unit circle, the others inside: a saddle with one
    unstable direction (past a fold: mu > 1; past a period doubling: mu < -1, the trajectory
    leaving on alternate sides)."""
    mu = ref.multipliers
    return (abs(mu[0].imag) <= 1e-9 * abs(mu[0]) and abs(mu[0]) > 1.0
            and (len(mu) < 2 or abs(mu[1]) < 1.0))


def saddle_periods(params: ModelParameters, window: PeriodSummaries, saddle: Refinement,
                   st: IntegrationSettings, guess: np.ndarray) -> int:
    """Periods a trajectory at ``guess`` takes to leave the saddle (relative distance ``d``:
    ``log(1/d) / log|mu_u|``) plus one measuring budget, at most :data:`SADDLE_MAX_PERIODS`."""
    scale = max(float(window.xmax.max() - window.xmin.min()), 1e-9)
    d = float(_distances(np.asarray(guess, dtype=float)[None, :2],
                         saddle.state[None, :2], scale, params.w)[0])  # fmt: skip
    rate = math.log(abs(saddle.multipliers[0]))
    k = int(math.ceil(math.log(1.0 / max(d, 1e-12)) / rate)) + st.max_periods
    return min(max(k, st.max_periods), SADDLE_MAX_PERIODS)


def follow_motion(params: ModelParameters, periods: int, st: IntegrationSettings,
                  guess: np.ndarray, floquet: str, orbits: OrbitCache | None
                  ) -> tuple[Classification, np.ndarray | None] | None:
    """Go on from the last state ``guess`` for ``periods`` periods and read the last
    ``max_periods`` of them as the cell's window (the period test, the classification, the
    refinement). Returns that reading when it is periodic and settled (status ``ok``), else
    None. For a window that is a reading of a passage, not of the motion: next to a saddle
    (:func:`saddle_periods`), or without a period, without chaos and without an orbit Newton
    finds (:data:`SADDLE_MAX_PERIODS`)."""
    y = np.asarray(guess, dtype=float)[:N_STATE]
    # a fixed tangent start (not the caller's: the scalar and batched drivers pass different
    # ones), aligned over the periods before the read window
    z = project_tangent(np.ones(N_STATE) / math.sqrt(N_STATE), params.to_array())
    run = run_periods(params, np.concatenate([y, z]), periods, st, tangent=True)
    if run.status != STATUS_OK or len(run.summaries) < st.max_periods:
        return None
    s = run.summaries.tail(st.max_periods)
    scale = float(s.xmax.max() - s.xmin.min())
    n = int(estimate_period(np.ascontiguousarray(s.section[:, 0]),
                            np.ascontiguousarray(s.section[:, 1]), scale, params.w, st.n_max,
                            st.period_rtol, 16))  # fmt: skip
    _, cls = read_window(params, s, n, st)
    c, orbit = verify_motion(params, s, cls, st, run.state, floquet, orbits, follow=False)
    if c.motion != "periodic" or c.status != "ok":
        return None
    if orbit is None:
        # the reading is the followed window's: so are its points and its margin (the
        # caller's final state is the passage's, not a state on this orbit)
        orbit = s.section[-c.n:].copy()
        if not math.isfinite(c.mu_max) and st.floquet != "slow":
            m = floquet_margin(params, c.n, run.state, st)
            if m is not None:
                c = replace(c, mu_max=m[0], critical=m[1])
    return c, orbit


def verify_motion(params: ModelParameters, window: PeriodSummaries, cls: Classification,
                  st: IntegrationSettings, guess: np.ndarray, floquet: str = "slow",
                  orbits: OrbitCache | None = None, follow: bool = True
                  ) -> tuple[Classification, np.ndarray | None]:
    """Settle ``cls`` by its orbit where it needs it: ``(classification, orbit section points or
    None)``. A periodic cell whose refinement fails keeps its label with status
    ``not_converged`` when it is farther than :data:`REFINE_RTOL` from settled."""
    if not needs_refinement(cls, floquet):
        return cls, None
    if cls.n > 0:
        periods = [cls.n]
        known = orbits.find(params, cls, guess) if orbits is not None else None
        if known is not None:
            return known
    else:
        scale = float(window.xmax.max() - window.xmin.min())
        periods = candidate_periods(window.section[:, 0], window.section[:, 1], scale,
                                    params.w, min(st.n_max, 16))  # fmt: skip
    saddles: list[Refinement] = []
    for n in periods:
        ref = refine(params, window, n, guess, st, saddles)
        if ref is None:
            continue
        if ref.mu_max >= 1.0:
            # the orbit Newton finds has just lost stability: the window's own reading stays,
            # the status says the cell sits at that orbit's bifurcation
            return replace(cls, status="bifurcation", mu_max=ref.mu_max, critical=ref.critical,
                           converged=cls.n > 0 or cls.converged), None  # fmt: skip
        out = orbit_classification(params, ref, st, cls.settle)
        if out is not None:
            if orbits is not None and cls.n > 0:
                orbits.add(params, cls.n, *out)
            return out
    near = [r for r in saddles if _is_saddle(r)]
    if follow and (cls.n == 0 or not cls.settle <= REFINE_RTOL):
        if near:
            k = saddle_periods(params, window, near[0], st, guess)
        else:
            k = SADDLE_MAX_PERIODS if cls.n == 0 else 0
        out = follow_motion(params, k, st, guess, floquet, orbits) if k else None
        if out is not None:
            return out
    if cls.n > 0 and not cls.settle <= REFINE_RTOL:
        return replace(cls, status="not_converged", converged=False), None
    if cls.motion == "quasi-periodic":
        # no orbit found: quasi-periodic only with the section points on a closed curve
        pts = window.section[-min(len(window), 256):]
        scale = float(window.xmax.max() - window.xmin.min())
        if not on_closed_curve(pts, scale, scale * params.w):
            return replace(cls, motion="unsettled", status="not_converged", label="unsettled",
                           converged=False), None  # fmt: skip
    return cls, None


__all__ = ["REFINE_RTOL", "BIFURCATION_MARGIN", "FLOQUET", "OrbitCache", "Refinement",
           "fill_margins", "floquet_margin",
           "needs_refinement", "window_settle",
           "refine", "orbit_classification", "verify_motion"]
