"""Coexisting attractors of a cell: many starts, recurrence-based early labelling, basin fractions.

The method (after the recurrence-based attractor mapping of Datseris, Rossi and Wagemakers,
Chaos 2023) is model-agnostic; a *system* supplies three operations on states of its cells:

``advance(cells, states, n_periods, start_periods)``
    Integrate each state ``n_periods`` forcing periods; return the section states of every period
    (``(k, n, d)``, NaN after a divergence), the final states and a divergence flag per state.
``steady(cells, states, transient, start_periods)``
    The *full-length run* of each state: ``transient`` periods, then measurement and
    classification. Returns one :class:`Steady` per state.
``start_states(cell, unit)``
    Map points of the unit square to full start states (the box of ``(x, x')`` the starts fill).

:func:`map_attractors` then works on section points projected to ``(x, x')`` (the first two
section components) in the system's own units. The gear model is one client
(:class:`GearCells`, the batched RK4 kernel and :mod:`gearsim.cell.classify` through
:func:`gearsim.cell.chains.simulate_cells`); tests/integration/test_attractors.py drives a
hardening Duffing
oscillator integrated with scipy through the same code.

Algorithm per cell (all cells and starts of a call advance together as SIMD lanes):

1. *Scouts* - the continuation states (``forward`` / ``backward``, where given) and the first
   ``scouts`` random starts - get the full-length run; their steady motions seed the attractor
   list (merged as below).
2. The other starts advance ``chunk`` periods at a time. After each chunk every start's last
   section points are compared with the attractors found so far (*recurrence*): a start whose
   last ``max(2 n, confirm)`` points follow a period-``n`` attractor's points in phase order,
   each within ``recur_rtol`` of the attractor's scale, and themselves repeat after ``n``
   periods within ``period_rtol`` (the classifier's own period test), or (``early_clouds``
   only) whose last ``confirm_cloud`` points all fall in the (one-cell dilated) grid occupancy
   of a non-periodic attractor, is labelled and stops. A start that diverges is recorded as
   divergent.
   Every ``rescout`` periods the first still unlabelled start of each cell is promoted to a
   scout: its full-length run continues from where it is (so it is exactly its full-length
   run) and its motion joins the list the others are tested against.
3. Starts still unlabelled after ``transient`` periods continue into measurement and
   classification exactly as their full-length run would (same state, remaining transient 0),
   and their steady motions are merged into the list.

Finally every start's motion (its own full-length one, or the attractor it was labelled onto)
is merged again in a canonical order (continuation states, then starts by index), so the list
does not depend on the order in which starts happened to finish.

Merging: starts that did not settle within the budget (status ``unsettled``) form one entry
per cell (label ``unsettled``, never labelled early). Two steady motions are the same attractor
when both have the same period ``n > 0`` and each section point of one lies within
``merge_rtol * scale`` of a point of the other (so any cyclic shift matches), or, readings of
one orbit that settled to different degrees (a refined orbit and a ``bifurcation``-status
window reading of it), the same label and n-p-q, DC within :data:`ORBIT_DC` and points within
:data:`ORBIT_RTOL` of the range; or when both are
non-periodic and at least ``cloud_overlap`` of each cloud's points fall in the dilated grid
occupancy of the other (``g x g`` cells over the joint bounding box, ``g = grid`` or fewer for
sparse clouds: ``g <= 2 sqrt(points)``, at least 4; so a cell holds ~2 points on average).

Basin fraction of an attractor: its share of the ``K`` random starts (continuation states are
not samples and are not counted; an attractor found only by continuation has fraction 0).
``early=False`` gives every start its full-length run; tests/integration/test_attractors.py
checks that the
early labelling reproduces those fractions exactly.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
import pandas as pd

from gearsim.dynamics.parameters import ModelParameters, ParameterError

#: Kinds of starts that can find an attractor (the catalogue's ``found_by``).
FOUND_BY = ("forward", "backward", "start")


@dataclass
class Steady:
    """The classified steady motion reached from one state (a system's full-length run).

    ``period`` is the motion period in forcing periods (0: none found, e.g. chaos);
    ``points`` the section states of the analysed window (``(m, d)``, at least ``(x, x')``);
    ``scale_x`` and ``scale_v`` the displacement and velocity ranges of the motion that set
    the matching tolerances (system units); ``info`` the classification record.
    """

    status: str  # "ok", "unsettled" (no steady motion within the budget) or "diverged"
    period: int
    points: np.ndarray
    scale_x: float
    scale_v: float
    label: str
    info: dict[str, Any] = field(default_factory=dict)
    final_state: np.ndarray | None = None


class System(Protocol):
    """What :func:`map_attractors` needs from a model (see the module docstring)."""

    transient: int

    def start_states(self, cell: int, unit: np.ndarray) -> np.ndarray: ...

    def advance(
        self, cells: np.ndarray, states: np.ndarray, n_periods: int, start_periods: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...

    def steady(
        self, cells: np.ndarray, states: np.ndarray, transient: int, start_periods: np.ndarray
    ) -> list[Steady]: ...


@dataclass
class Attractor:
    """One attractor of a cell: its steady motion, basin fraction and who found it."""

    index: int
    steady: Steady
    n_starts: int  # random starts that reach it
    basin_fraction: float  # n_starts / K
    found_by: tuple[str, ...]  # subset of FOUND_BY, in that order
    n_early: int = 0  # of n_starts, labelled early by recurrence

    @property
    def label(self) -> str:
        return self.steady.label

    @property
    def points(self) -> np.ndarray:
        return self.steady.points

    def record(self) -> dict[str, Any]:
        """Flat record (the catalogue's ``attractors`` columns, plus the classification)."""
        r = dict(self.steady.info)
        r.update(
            attractor=self.index,
            label=self.steady.label,
            n=int(self.steady.period),
            basin_fraction=float(self.basin_fraction),
            n_starts=int(self.n_starts),
            n_early=int(self.n_early),
            found_by=",".join(self.found_by),
            poincare_x=self.steady.points[:, 0].tolist(),
            poincare_v=self.steady.points[:, 1].tolist(),
        )
        return r


@dataclass
class CellAttractors:
    """All attractors of one cell and the fate of every start.

    ``start_labels[i]`` is the attractor index reached from random start ``i`` (-1: diverged);
    ``early[i]`` whether it was labelled by recurrence; ``start_periods_run[i]`` the forcing
    periods integrated for it; ``continuation[name]`` the attractor index reached from the
    ``forward`` / ``backward`` state (-1 diverged).
    """

    attractors: list[Attractor]
    starts: np.ndarray  # (K, d) start states
    start_labels: np.ndarray  # (K,)
    early: np.ndarray  # (K,) bool
    start_periods_run: np.ndarray  # (K,)
    continuation: dict[str, int]

    @property
    def n_starts(self) -> int:
        return len(self.start_labels)

    @property
    def diverged_fraction(self) -> float:
        k = len(self.start_labels)
        return float(np.sum(self.start_labels < 0) / k) if k else 0.0

    def records(self) -> list[dict[str, Any]]:
        return [a.record() for a in self.attractors]


# ============================================================================ matching
def _tolerances(a: Steady, b: Steady, rtol: float) -> tuple[float, float]:
    sx = max(a.scale_x, b.scale_x, 1e-9)
    sv = max(a.scale_v, b.scale_v, 1e-9)
    return rtol * sx, rtol * sv


def _near_all(p: np.ndarray, q: np.ndarray, tx: float, tv: float) -> bool:
    """Every point of ``p`` lies within ``(tx, tv)`` of some point of ``q``."""
    dx = np.abs(p[:, None, 0] - q[None, :, 0]) <= tx
    dv = np.abs(p[:, None, 1] - q[None, :, 1]) <= tv
    return bool(np.all(np.any(dx & dv, axis=1)))


def _occupancy(points: np.ndarray, lo: np.ndarray, hi: np.ndarray, grid: int) -> np.ndarray:
    """Boolean ``grid x grid`` occupancy of ``points`` in the box ``[lo, hi]``, dilated by one."""
    occ = np.zeros((grid + 2, grid + 2), dtype=bool)
    idx = _cells(points, lo, hi, grid)
    ok = np.all((idx >= 0) & (idx < grid), axis=1)
    occ[idx[ok, 0] + 1, idx[ok, 1] + 1] = True
    dil = occ.copy()
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            dil[1:-1, 1:-1] |= occ[1 + di : grid + 1 + di, 1 + dj : grid + 1 + dj]
    return dil[1:-1, 1:-1]


def _cells(points: np.ndarray, lo: np.ndarray, hi: np.ndarray, grid: int) -> np.ndarray:
    span = np.maximum(hi - lo, 1e-12)
    return np.floor((points[..., :2] - lo) / span * grid).astype(np.int64)


def _cloud_box(points: np.ndarray, pad: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    p = points[:, :2]
    lo, hi = p.min(axis=0), p.max(axis=0)
    span = np.maximum(hi - lo, 1e-9)
    return lo - pad * span, hi + pad * span


def _in_occupancy(points: np.ndarray, occ: np.ndarray, lo, hi) -> np.ndarray:
    """Per point: inside the box and in an occupied (dilated) cell."""
    grid = occ.shape[0]
    idx = _cells(points, lo, hi, grid)
    ok = np.all((idx >= 0) & (idx < grid), axis=-1)
    out = np.zeros(ok.shape, dtype=bool)
    sel = np.nonzero(ok)
    out[sel] = occ[idx[sel][:, 0], idx[sel][:, 1]]
    return out


#: two periodic readings with one n-p-q and DC within ORBIT_DC of each other, whose points lie
#: within ORBIT_RTOL of the motion's range of each other, are one orbit (docs/decisions.md)
ORBIT_DC = 1e-3
ORBIT_RTOL = 0.05


def _one_orbit(a: Steady, b: Steady, pa: np.ndarray, pb: np.ndarray) -> bool:
    """Two readings of one periodic orbit that the point test keeps apart: e.g. a stable
    orbit's refined points and the ``bifurcation``-status window reading of the same orbit,
    or two unrefined readings of a slowly settling long period. Same n-p-q, DC within
    :data:`ORBIT_DC`, points within :data:`ORBIT_RTOL` of the range (both ways)."""
    ia, ib = a.info or {}, b.info or {}
    npq = ia.get("label_npq")
    if not npq or npq != ib.get("label_npq") or a.label != b.label:
        return False
    da, db = ia.get("dc"), ib.get("dc")
    if da is None or db is None or not abs(float(da) - float(db)) <= ORBIT_DC:
        return False
    tx, tv = _tolerances(a, b, ORBIT_RTOL)
    return _near_all(pa, pb, tx, tv) and _near_all(pb, pa, tx, tv)


#: a period-kn reading of a period-n orbit has the n orbit's multipliers to the k-th power:
#: |mu|max within this relative tolerance of (|mu|max of the n reading)^k
MULTIPLE_MU_RTOL = 1e-3


def multiple_copy(short: Steady, long: Steady, merge_rtol: float = 1e-3) -> bool:
    """Whether the periodic reading ``long`` (period k n, k >= 2) is the period-n orbit
    ``short`` counted k times: same impact state, DC within :data:`ORBIT_DC`, every point of
    each within :data:`ORBIT_RTOL` of the range of a point of the other and |mu|max of ``long``
    the k-th power of that of ``short`` (:data:`MULTIPLE_MU_RTOL`); without both margins, the
    points within ``merge_rtol`` of each other (the merge test's own tolerance)."""
    n, m = short.period, long.period
    if n <= 0 or m <= n or m % n or short.status != "ok" or long.status != "ok":
        return False
    ia, ib = short.info or {}, long.info or {}
    if ia.get("I") != ib.get("I"):
        return False
    da, db = ia.get("dc"), ib.get("dc")
    if da is None or db is None or not abs(float(da) - float(db)) <= ORBIT_DC:
        return False
    pa, pb = short.points[-n:, :2], long.points[-m:, :2]
    mu_a, mu_b = ia.get("mu_max"), ib.get("mu_max")
    with_mu = (mu_a is not None and mu_b is not None and math.isfinite(mu_a)
               and math.isfinite(mu_b))  # fmt: skip
    if with_mu:
        want = float(mu_a) ** (m // n)
        if not abs(float(mu_b) - want) <= MULTIPLE_MU_RTOL * max(want, 1e-12):
            return False
    tx, tv = _tolerances(short, long, ORBIT_RTOL if with_mu else merge_rtol)
    return _near_all(pa, pb, tx, tv) and _near_all(pb, pa, tx, tv)


def least_periods(ca: CellAttractors, merge_rtol: float = 1e-3) -> CellAttractors:
    """``ca`` with every periodic attractor that is a shorter-period attractor of the cell
    counted several times (:func:`multiple_copy`) merged into that one (its starts, early
    labels and finders added): an orbit is reported once, at its least period. Attractors
    renumbered most starts first."""
    atts = list(ca.attractors)
    into: dict[int, int] = {}  # attractor index -> index it merges into
    by_period = sorted(atts, key=lambda t: t.steady.period)
    for b in by_period:  # shortest first: every target is itself kept
        for a in by_period:
            if a is not b and a.index not in into and multiple_copy(a.steady, b.steady,
                                                                     merge_rtol):
                into[b.index] = a.index
                break
    if not into:
        return ca
    by_index = {a.index: a for a in atts}
    for b_i, a_i in into.items():
        a, b = by_index[a_i], by_index[b_i]
        found = set(a.found_by) | set(b.found_by)
        a.n_starts += b.n_starts
        a.n_early += b.n_early
        a.found_by = tuple(f for f in FOUND_BY if f in found)
    kept = sorted((a for a in atts if a.index not in into), key=lambda a: (-a.n_starts, a.index))
    new = {a.index: r for r, a in enumerate(kept)}
    for b_i, a_i in into.items():
        new[b_i] = new[a_i]
    k = ca.n_starts
    for r, a in enumerate(kept):
        a.index = r
        a.basin_fraction = float(a.n_starts / k) if k else 0.0
    remap = np.array([new.get(i, -1) for i in range(max(new) + 1)] + [-1], dtype=np.int64)
    labels = np.asarray(ca.start_labels, dtype=np.int64)
    return CellAttractors(
        attractors=kept,
        starts=ca.starts,
        start_labels=remap[labels] if len(labels) else labels,
        early=ca.early,
        start_periods_run=ca.start_periods_run,
        continuation={name: int(remap[v]) for name, v in ca.continuation.items()},
    )


def same_attractor(
    a: Steady, b: Steady, *, merge_rtol: float = 1e-3, grid: int = 32, cloud_overlap: float = 0.5
) -> bool:
    """Whether two steady motions are one attractor (see the module docstring)."""
    if a.status == "diverged" or b.status == "diverged":
        return False
    if a.status == "unsettled" or b.status == "unsettled":
        # not settled within the budget: one bucket per cell, never a real attractor
        return a.status == b.status
    if a.period > 0 or b.period > 0:
        if a.period != b.period:
            return False
        tx, tv = _tolerances(a, b, merge_rtol)
        pa, pb = a.points[-a.period :, :2], b.points[-b.period :, :2]
        if _near_all(pa, pb, tx, tv) and _near_all(pb, pa, tx, tv):
            return True
        return _one_orbit(a, b, pa, pb)
    both = np.vstack([a.points[:, :2], b.points[:, :2]])
    lo, hi = _cloud_box(both, pad=0.0)
    # a sparse cloud fills few cells of a fine grid: ~2 points per cell on average at least
    grid = int(max(4, min(grid, 2 * math.isqrt(max(min(len(a.points), len(b.points)), 1)))))
    occ_a = _occupancy(a.points, lo, hi, grid)
    occ_b = _occupancy(b.points, lo, hi, grid)
    fa = float(np.mean(_in_occupancy(a.points, occ_b, lo, hi)))
    fb = float(np.mean(_in_occupancy(b.points, occ_a, lo, hi)))
    return min(fa, fb) >= cloud_overlap


class _Known:
    """The attractors of one cell found so far, with their recurrence tests precomputed."""

    def __init__(self, opts: _Options):
        self.opts = opts
        self.steadies: list[Steady] = []
        self.own: dict[int, Steady] = {}  # start index -> its full-length steady motion
        self.ambiguous: list[bool] = []
        self.target: list[bool] = []  # recurrence targets (see add)
        self._clouds: list[tuple[np.ndarray, np.ndarray, np.ndarray] | None] = []
        self._near: tuple | None = None  # (attractors seen, orbit points, tolerances)

    def add(self, s: Steady, target: bool = True) -> int:
        """Index of ``s`` in the list (merged with a known attractor, or appended); -1 diverged.

        ``target``: starts may be labelled onto it by recurrence (a motion that a start's
        full-length run reached, or an orbit verified stable); a motion added with False (e.g.
        a continuation state's reading) becomes a target when a start's run merges into it.
        """
        if s.status == "diverged":
            return -1
        o = self.opts
        for k, t in enumerate(self.steadies):
            if same_attractor(
                s, t, merge_rtol=o.merge_rtol, grid=o.grid, cloud_overlap=o.cloud_overlap
            ):
                if target and not self.target[k]:
                    self.target[k] = True
                    self._near = None
                return k
        self.steadies.append(s)
        self.ambiguous.append(False)
        self.target.append(bool(target))
        if s.period > 0:
            # a period-n and a period-2n motion close together: the cell sits at a period
            # doubling, where the full-length label depends on how far a slowly decaying
            # alternation has decayed; no early labelling onto either (their starts run full)
            for k, t in enumerate(self.steadies[:-1]):
                if t.period > 0 and max(s.period, t.period) == 2 * min(s.period, t.period):
                    tx, tv = _tolerances(s, t, self.opts.doubling_rtol)
                    ps, pt = s.points[-s.period :, :2], t.points[-t.period :, :2]
                    if _near_all(ps, pt, tx, tv) and _near_all(pt, ps, tx, tv):
                        self.ambiguous[k] = self.ambiguous[-1] = True
        if s.period > 0 or s.status == "unsettled":
            self._clouds.append(None)  # no cloud: unsettled starts are never labelled early
        else:
            lo, hi = _cloud_box(s.points)
            self._clouds.append((_occupancy(s.points, lo, hi, o.grid), lo, hi))
        return len(self.steadies) - 1

    def near(self, last: np.ndarray) -> np.ndarray:
        """Per start, whether its last section point ``last[i]`` (``(k, 2)``) lies within the
        recurrence tolerance of a point of a periodic attractor it may be labelled onto: a
        necessary condition of :meth:`recur` (all of them with ``early_clouds``)."""
        o = self.opts
        if o.early_clouds:
            return np.ones(len(last), dtype=bool)
        if self._near is None or self._near[0] != len(self.steadies):
            self._near = (len(self.steadies), *self._orbit_points())
        _, P, Tl = self._near
        if P is None:
            return np.zeros(len(last), dtype=bool)
        d = np.abs(last[:, None, :2] - P[None, :, :]) <= Tl[None, :, :]
        return np.any(d[:, :, 0] & d[:, :, 1], axis=1)

    def _orbit_points(self):
        o = self.opts
        pts, tol = [], []
        for a, s in enumerate(self.steadies):
            if s.period > 0 and not self.ambiguous[a] and self.target[a]:
                pts.append(s.points[-s.period :, :2])
                t = [o.recur_rtol * max(s.scale_x, 1e-9), o.recur_rtol * max(s.scale_v, 1e-9)]
                tol.append(np.repeat(np.array([t]), s.period, axis=0))
        if not pts:
            return None, None
        return np.vstack(pts), np.vstack(tol)

    def recur(self, hist: np.ndarray, filled: np.ndarray) -> np.ndarray:
        """Attractor index each history recurs onto (-1: none yet).

        ``hist``: ``(k, L, d)`` last section points of ``k`` starts (oldest first), of which the
        last ``filled[i]`` are valid.
        """
        o = self.opts
        k, L = hist.shape[:2]
        out = np.full(k, -1, dtype=np.int64)
        # periodic attractors first (a periodic start must never be taken for a cloud)
        for a, s in enumerate(self.steadies):
            if s.period <= 0 or self.ambiguous[a] or not self.target[a]:
                continue
            n = s.period
            need = min(max(2 * n, o.confirm), L - n)
            rows = np.nonzero((out < 0) & (filled >= need + n))[0]
            if len(rows) == 0 or need < 1:
                continue
            w = hist[rows, L - need :, :2]  # (r, need, 2)
            pts = s.points[-n:, :2]
            tx = o.recur_rtol * max(s.scale_x, 1e-9)
            tv = o.recur_rtol * max(s.scale_v, 1e-9)
            dx = np.abs(w[:, :, None, 0] - pts[None, None, :, 0]) / tx
            dv = np.abs(w[:, :, None, 1] - pts[None, None, :, 1]) / tv
            d = np.maximum(dx, dv)  # (r, need, n)
            j = np.argmin(d, axis=2)
            dmin = np.take_along_axis(d, j[:, :, None], axis=2)[:, :, 0]
            close = np.all(dmin <= 1.0, axis=1)
            phase = np.all((j - j[:, :1] - np.arange(need)[None, :]) % n == 0, axis=1)
            # the start itself passes the period-n test the classifier would apply (so a
            # nearby period-2n motion, e.g. just past a period doubling, is not taken for it)
            prev = hist[rows, L - need - n : L - n, :2]
            rtol = o.period_rtol if o.recur_period_rtol is None else o.recur_period_rtol
            px = rtol * max(s.scale_x, 1e-9)
            pv = rtol * max(s.scale_v, 1e-9)
            res = np.maximum(np.abs(w[:, :, 0] - prev[:, :, 0]) / px,
                             np.abs(w[:, :, 1] - prev[:, :, 1]) / pv)  # (r, need)
            periodic = np.all(res <= 1.0, axis=1)
            if rtol > o.period_rtol:
                # looser than the classifier's test: the start's own n-period residual must
                # not grow over the window (a persisting 2n alternation does not decay)
                periodic &= res[:, -n:].max(axis=1) <= res[:, :n].max(axis=1)
            out[rows[close & phase & periodic]] = a
        for a in range(len(self.steadies) if o.early_clouds else 0):
            cloud = self._clouds[a]
            if cloud is None or not self.target[a]:
                continue
            need = min(o.confirm_cloud, L)
            rows = np.nonzero((out < 0) & (filled >= need))[0]
            if len(rows) == 0:
                continue
            occ, lo, hi = cloud
            inside = _in_occupancy(hist[rows, L - need :], occ, lo, hi)
            out[rows[np.all(inside, axis=1)]] = a
        return out


@dataclass(frozen=True)
class _Options:
    chunk: int = 8
    confirm: int = 8
    confirm_cloud: int = 32
    recur_rtol: float = 1e-3
    merge_rtol: float = 1e-3
    grid: int = 32
    cloud_overlap: float = 0.5
    scouts: int = 1
    rescout: int = 24
    period_rtol: float = 1e-5
    doubling_rtol: float = 0.05
    early_clouds: bool = False
    recur_period_rtol: float | None = None  # the recurrence's period test (None: period_rtol)


# ============================================================================ the engine
def map_attractors(
    system: System,
    n_cells: int,
    starts: Sequence[np.ndarray],
    *,
    continuation: Sequence[Mapping[str, np.ndarray | None]] | None = None,
    continuation_periods: Sequence[Mapping[str, int]] | None = None,
    continuation_transient: int | None = None,
    early: bool = True,
    chunk: int = 8,
    confirm: int = 8,
    confirm_cloud: int = 32,
    recur_rtol: float = 1e-3,
    merge_rtol: float = 1e-3,
    grid: int = 32,
    cloud_overlap: float = 0.5,
    scouts: int = 1,
    rescout: int = 24,
    period_rtol: float = 1e-5,
    early_clouds: bool = False,
) -> list[CellAttractors]:
    """Attractors of ``n_cells`` cells of ``system`` from the start states ``starts[c]``.

    Parameters
    ----------
    starts
        Per cell a ``(K_c, d)`` array of start states (the basin samples).
    continuation
        Per cell a mapping ``{"forward": state, "backward": state}`` (either may be missing or
        None): states on a continuation branch, run with ``continuation_transient`` periods
        (default ``system.transient``); their attractors get ``found_by`` forward / backward.
    continuation_periods
        Absolute period index of each continuation state (forcing not T-periodic only).
    early
        Recurrence-based early labelling (False: full-length run of every start).
    chunk, confirm, confirm_cloud, recur_rtol, merge_rtol, grid, cloud_overlap, scouts, rescout
        See the module docstring; ``scouts`` random starts per cell get full-length runs first,
        and every ``rescout`` probed periods (a multiple of ``chunk``; 0: never) the first
        still unlabelled start of each cell gets its full-length run too.
    period_rtol
        A start is labelled onto a period-``n`` attractor only when its own last points also
        repeat after ``n`` periods within ``period_rtol`` of the attractor's scale (the
        classifier's period test; :class:`GearCells` passes ``settings.period_rtol``).
    early_clouds
        Also label starts early onto non-periodic (chaotic, quasi-periodic) attractors by
        cloud occupancy. Off by default: a torus sampled over a finite window, or a periodic
        window inside a chaotic band, can take a start that its full-length run classifies
        otherwise (benchmarks/CHANGELOG.md (h)); with it off, the early labels are exactly the
        full-length ones on every cell checked.
    """
    if len(starts) != n_cells:
        raise ParameterError("map_attractors: one array of start states per cell expected")
    for name, v in (("chunk", chunk), ("confirm", confirm), ("confirm_cloud", confirm_cloud)):
        if isinstance(v, bool) or not isinstance(v, int) or v < 1:
            raise ParameterError(f"setting '{name}' = {v!r} must be an integer >= 1")
    if isinstance(scouts, bool) or not isinstance(scouts, int) or scouts < 0:
        raise ParameterError(f"setting 'scouts' = {scouts!r} must be an integer >= 0")
    if isinstance(rescout, bool) or not isinstance(rescout, int) or rescout < 0:
        raise ParameterError(f"setting 'rescout' = {rescout!r} must be an integer >= 0")
    opts = _Options(chunk, confirm, confirm_cloud, recur_rtol, merge_rtol, grid, cloud_overlap,
                    scouts, rescout, period_rtol, 0.05, bool(early_clouds))  # fmt: skip
    known = [_Known(opts) for _ in range(n_cells)]
    starts = [np.atleast_2d(np.asarray(s, dtype=float)) for s in starts]
    K = [len(s) for s in starts]
    labels = [np.full(k, -2, dtype=np.int64) for k in K]  # -2 not yet known
    is_early = [np.zeros(k, dtype=bool) for k in K]
    periods_run = [np.zeros(k, dtype=np.int64) for k in K]
    cont_labels: list[dict[str, int]] = [{} for _ in range(n_cells)]
    cont_steady: list[list[tuple[str, Steady]]] = [[] for _ in range(n_cells)]
    cont_found: list[dict[int, set[str]]] = [{} for _ in range(n_cells)]

    # 1. continuation states (full-length runs with the continuation transient)
    if continuation is not None:
        if len(continuation) != n_cells:
            raise ParameterError("map_attractors: one continuation mapping per cell expected")
        ct = system.transient if continuation_transient is None else int(continuation_transient)
        cells, states, names, k0 = [], [], [], []
        for c, m in enumerate(continuation):
            for name, y in (m or {}).items():
                if name not in ("forward", "backward"):
                    raise ParameterError(
                        f"continuation state {name!r}; allowed: forward, backward"
                    )
                if y is None:
                    continue
                cells.append(c)
                states.append(np.asarray(y, dtype=float))
                names.append(name)
                k0.append(0 if continuation_periods is None
                          else int(continuation_periods[c].get(name, 0)))  # fmt: skip
        if cells:
            res = system.steady(np.array(cells), np.array(states), ct, np.array(k0))
            for c, name, s in zip(cells, names, res, strict=True):
                cont_steady[c].append((name, s))
                a = known[c].add(s)
                cont_labels[c][name] = a
                if a >= 0:
                    cont_found[c].setdefault(a, set()).add(name)

    # 2. full-length runs of all starts, or scouts + recurrence
    T = int(system.transient)
    if not early:
        todo = [(c, i) for c in range(n_cells) for i in range(K[c])]
        _run_full(system, known, starts, labels, periods_run, todo, T)
    else:
        scout = [(c, i) for c in range(n_cells) for i in range(min(scouts, K[c]))]
        _run_full(system, known, starts, labels, periods_run, scout, T)
        _probe(system, known, starts, labels, is_early, periods_run, opts, T)

    # 3. merge again in a canonical order, basin fractions
    return assemble(opts, starts, labels, is_early, periods_run, known, cont_steady)


def assemble(opts: _Options, starts, labels, is_early, periods_run, known, cont_steady
             ) -> list[CellAttractors]:
    """The cells' attractor lists from the fate of every start (any finder's last step).

    Every start's motion (its own full-length one in ``known[c].own``, or the attractor it was
    labelled onto) is merged again in a canonical order (continuation states, then starts by
    index), so the list does not depend on which start finished first; then basin fractions,
    most starts first. ``labels[c][i]``: index into ``known[c].steadies`` (-1 diverged).
    """
    n_cells = len(starts)
    K = [len(s) for s in starts]
    cont_labels: list[dict[str, int]] = [{} for _ in range(n_cells)]
    cont_found: list[dict[int, set[str]]] = [{} for _ in range(n_cells)]
    labels = list(labels)
    known = list(known)
    for c in range(n_cells):
        kn = _Known(opts)
        cont_labels[c], cont_found[c] = {}, {}
        for name, s in cont_steady[c]:
            a = kn.add(s)
            cont_labels[c][name] = a
            if a >= 0:
                cont_found[c].setdefault(a, set()).add(name)
        new = np.full(K[c], -1, dtype=np.int64)
        for i in range(K[c]):
            if labels[c][i] >= 0:
                s = known[c].own.get(i, known[c].steadies[labels[c][i]])
                new[i] = kn.add(s)
        labels[c] = new
        known[c] = kn
    out = []
    for c in range(n_cells):
        steadies = known[c].steadies
        counts = np.array([np.sum(labels[c] == a) for a in range(len(steadies))], dtype=int)
        order = sorted(range(len(steadies)), key=lambda a: (-counts[a], a))
        new_index = {a: r for r, a in enumerate(order)}
        attractors = []
        for a in order:
            found = set(cont_found[c].get(a, set()))
            if counts[a] > 0:
                found.add("start")
            attractors.append(
                Attractor(
                    index=new_index[a],
                    steady=steadies[a],
                    n_starts=int(counts[a]),
                    basin_fraction=float(counts[a] / K[c]) if K[c] else 0.0,
                    found_by=tuple(f for f in FOUND_BY if f in found),
                    n_early=int(np.sum((labels[c] == a) & is_early[c])),
                )
            )
        remap = np.array([new_index[a] for a in range(len(steadies))] + [-1], dtype=np.int64)
        out.append(
            CellAttractors(
                attractors=attractors,
                starts=starts[c],
                start_labels=remap[labels[c]] if K[c] else labels[c],
                early=is_early[c],
                start_periods_run=periods_run[c],
                continuation={k: int(remap[v]) for k, v in cont_labels[c].items()},
            )
        )
    return out


def _run_full(system, known, starts, labels, periods_run, todo, transient, states=None,
              done=None) -> None:
    """Full-length runs (from ``states`` after ``done`` periods, default: from the starts)."""
    if not todo:
        return
    cells = np.array([c for c, _ in todo])
    if states is None:
        states = np.array([starts[c][i] for c, i in todo])
        done = np.zeros(len(todo), dtype=np.int64)
    left = transient - int(done[0]) if len(done) else transient
    res = system.steady(cells, states, max(left, 0), done)
    for (c, i), s, d in zip(todo, res, done, strict=True):
        labels[c][i] = known[c].add(s)
        known[c].own[i] = s
        extra = int(s.info.get("periods", 0)) if s.info else 0
        periods_run[c][i] = int(d) + (extra if extra else max(left, 0))


def _probe(system, known, starts, labels, is_early, periods_run, opts: _Options, T: int) -> None:
    """Advance the unlabelled starts chunk by chunk; label on recurrence; finish the rest."""
    todo = [(c, i) for c in range(len(starts)) for i in range(len(starts[c])) if labels[c][i] == -2]
    if not todo:
        return
    d = starts[todo[0][0]].shape[1]
    n_top = max((s.period for k in known for s in k.steadies), default=1)
    L = max(opts.confirm_cloud, opts.confirm + n_top, 3 * n_top)
    cells = np.array([c for c, _ in todo])
    states = np.array([starts[c][i] for c, i in todo])
    hist = np.full((len(todo), L, d), np.nan)
    filled = np.zeros(len(todo), dtype=np.int64)
    done = 0
    active = np.arange(len(todo))
    while len(active) and done < T:
        m = min(opts.chunk, T - done)
        secs, finals, div = system.advance(
            cells[active], states[active], m, np.full(len(active), done, dtype=np.int64)
        )
        done += m
        states[active] = finals
        hist[active] = np.concatenate([hist[active], secs[:, :, :d]], axis=1)[:, -L:]
        filled[active] = np.minimum(filled[active] + m, L)
        keep = np.ones(len(active), dtype=bool)
        for r, t in enumerate(active):
            if div[r]:
                c, i = todo[t]
                labels[c][i] = -1
                periods_run[c][i] = done
                keep[r] = False
        # recurrence onto the attractors known so far, per cell
        alive = active[keep]
        for c in np.unique(cells[alive]):
            if not known[c].steadies:
                continue
            rows = alive[cells[alive] == c]
            hit = known[c].recur(hist[rows], filled[rows])
            for t, a in zip(rows, hit, strict=True):
                if a >= 0:
                    cc, i = todo[t]
                    labels[cc][i] = a
                    is_early[cc][i] = True
                    periods_run[cc][i] = done
        active = np.array([t for t in active if labels[todo[t][0]][todo[t][1]] == -2],
                          dtype=np.int64)
        if len(active) and opts.rescout and done % opts.rescout == 0 and done < T:
            # a new scout per cell that still has unlabelled starts: its full-length run
            # (continued from where it is) may reveal the attractor the others approach
            first: dict[int, int] = {}
            for t in active:
                first.setdefault(int(cells[t]), int(t))
            picks = np.array(sorted(first.values()), dtype=np.int64)
            _run_full(system, known, starts, labels, periods_run, [todo[t] for t in picks], T,
                      states=states[picks], done=np.full(len(picks), done, dtype=np.int64))
            active = np.setdiff1d(active, picks)
    if len(active):
        rest = [todo[t] for t in active]
        _run_full(system, known, starts, labels, periods_run, rest, T, states=states[active],
                  done=np.full(len(active), done, dtype=np.int64))


# ============================================================================ the gear model
def start_box(params: ModelParameters) -> tuple[float, float, float, float]:
    """Centre and half-widths ``(x0, hx, v0, hv)`` of the start box in ``(x, x')``.

    Around the static state ``x0 = b + Fm`` (displacements in units of the nominal length
    ``b_c``): ``hx = b + 2 (Fm + Fe w^2)`` (the backlash plus twice the static excitation
    amplitude, forces in units of ``Km b_c``), velocities ``x' = dx/dtau`` in ``+/- w hx``
    (``tau = w_n t``).
    """
    x0 = params.b + params.Fm
    hx = params.b + 2.0 * (params.Fm + params.Fe * params.w**2)
    return x0, hx, 0.0, params.w * hx


def sobol_unit(k: int, seed: int) -> np.ndarray:
    """``k`` scrambled Sobol points of the unit square (seeded; any ``k``, balance warning off)."""
    from scipy.stats import qmc

    if isinstance(k, bool) or not isinstance(k, int) or k < 1:
        raise ParameterError(f"setting 'starts' = {k!r} must be an integer >= 1")
    eng = qmc.Sobol(d=2, scramble=True, seed=int(seed))
    m = max(0, math.ceil(math.log2(k)))
    return eng.random_base2(m)[:k]


class GearCells:
    """The gear model as a :class:`System`: one cell per :class:`ModelParameters`.

    Runs through the batched RK4 kernel (:func:`gearsim.numerics.batch.run_periods_batched` to
    advance,
    :func:`gearsim.cell.chains.simulate_cells` for full-length runs, i.e.
    :mod:`gearsim.cell.classify`).
    Section states have 10 components ``(x, x', u_py, u_py', ...)``; ``transient`` is
    ``settings.transient`` (a start far from the motion is a start "from rest").
    """

    def __init__(self, params_list: Sequence[ModelParameters], settings=None):
        from gearsim.cell.simulate import IntegrationSettings

        self.params = list(params_list)
        st = settings or IntegrationSettings(method="rk4")
        self.settings = st.with_(method="rk4")
        self.transient = int(self.settings.transient)
        from gearsim.cell.verify import OrbitCache

        self.orbits = OrbitCache()  # the starts of a cell share their refined orbits

    def start_states(self, cell: int, unit: np.ndarray) -> np.ndarray:
        from gearsim.dynamics.model import static_state

        p = self.params[cell]
        x0, hx, v0, hv = start_box(p)
        base = static_state(p.to_array())
        y = np.repeat(base[None, :], len(unit), axis=0)
        y[:, 0] = x0 + (2.0 * unit[:, 0] - 1.0) * hx
        y[:, 1] = v0 + (2.0 * unit[:, 1] - 1.0) * hv
        return y

    def advance(self, cells, states, n_periods, start_periods):
        from gearsim.cell.simulate import initial_tangent
        from gearsim.dynamics.model import N_STATE
        from gearsim.numerics.batch import run_periods_batched, steps_per_period

        k = len(cells)
        secs = np.full((k, n_periods, N_STATE), np.nan)
        finals = np.array(states, dtype=float)[:, :N_STATE].copy()
        div = np.zeros(k, dtype=bool)
        groups: dict[tuple, list[int]] = {}
        for r, c in enumerate(cells):
            p = self.params[c]
            key = (steps_per_period(p, self.settings), p.model,
                   p.var_ratio_order if p.var_ratio != 0.0 else None)  # fmt: skip
            groups.setdefault(key, []).append(r)
        for (_, model, _), rows in groups.items():
            plist = [self.params[cells[r]] for r in rows]
            t0 = initial_tangent(plist[0])  # on the states this group's model evolves
            if model != "6dof":
                for r, p in zip(rows, plist, strict=True):
                    self._advance_scalar(r, p, states, n_periods, start_periods, secs, finals,
                                         div)  # fmt: skip
                continue
            y = np.hstack([np.asarray(states, dtype=float)[rows, :N_STATE],
                           np.repeat(t0[None, :], len(rows), axis=0)])  # fmt: skip
            # probing needs the section points only (the tangent is restarted by every
            # full-length run): no tangent vector (same states, bit for bit)
            summ, fin, status, _ = run_periods_batched(
                plist, y, n_periods, self.settings, start_periods=[int(start_periods[r])
                                                                   for r in rows],
                tangent=False,
            )  # fmt: skip
            for q, r in enumerate(rows):
                s = summ[q].section
                secs[r, : len(s)] = s
                finals[r] = fin[q, :N_STATE]
                div[r] = status[q] != 0 or len(s) < n_periods
        return secs, finals, div

    def _advance_scalar(self, r, p, states, n, start_periods, secs, finals, div) -> None:
        from gearsim.cell.simulate import run_periods

        run = run_periods(p, np.asarray(states[r], dtype=float)[:10], n, self.settings,
                          start_period=int(start_periods[r]))  # fmt: skip
        s = run.summaries.section
        secs[r, : len(s)] = s
        finals[r] = run.state[:10]
        div[r] = run.status != 0 or len(s) < n

    def steady(self, cells, states, transient, start_periods):
        from gearsim.cell.chains import simulate_cells

        st = self.settings.with_(transient_continuation=int(transient))
        plist = [self.params[c] for c in cells]
        res = simulate_cells(plist, settings=st, u0=[np.asarray(s, dtype=float)[:10]
                                                     for s in states],
                             start_periods=[int(k) for k in start_periods],
                             orbits=self.orbits)  # fmt: skip
        return [gear_steady(r) for r in res]

    def fill_margins(self, found: Sequence[CellAttractors]) -> None:
        """Every periodic attractor its Floquet margin where its run did not give one (in
        place; ``found[c]`` belongs to cell ``c``): the margin of a plane cell's motion
        (:func:`gearsim.cell.verify.orbit_margins`, the cells' attractors in shared kernel
        calls; only with ``floquet`` ``"margin"``)."""
        from gearsim.cell.verify import orbit_margins, wants_margin

        st = self.settings
        if st.floquet != "margin":
            return
        todo = []
        for p, ca in zip(self.params, found, strict=True):
            for a in ca.attractors:
                s, i = a.steady, a.steady.info
                if (s.status == "ok" and s.final_state is not None
                        and wants_margin(s.period, i.get("status", "ok"), bool(i.get("refined")),
                                         i.get("mu_max"), p.var_ratio)):
                    todo.append((p, s))
        got = orbit_margins([p for p, _ in todo], [s.period for _, s in todo],
                            [s.final_state for _, s in todo], st)  # fmt: skip
        for (_, s), m in zip(todo, got, strict=True):
            if m is not None:
                s.info["mu_max"], s.info["critical"] = m


def gear_steady(res) -> Steady:
    """:class:`Steady` of a :class:`gearsim.cell.simulate.CellResult`."""
    c = res.classification
    w = res.params.w
    info = res.row()
    info.pop("n", None)
    info.pop("label", None)
    scale = float(c.x_max - c.x_min) if math.isfinite(c.x_max - c.x_min) else 0.0
    return Steady(
        status="diverged" if c.status == "diverged" else (
            "unsettled" if c.motion == "unsettled" else "ok"
        ),
        period=int(c.n),
        points=np.asarray(res.poincare, dtype=float),
        scale_x=scale,
        scale_v=scale * w,
        label=c.label,
        info=info,
        final_state=np.asarray(res.final_state, dtype=float),
    )


def find_attractors_many(
    params_list: Sequence[ModelParameters],
    *,
    starts: int = 16,
    seed: int = 0,
    settings=None,
    forward: Sequence[np.ndarray | None] | None = None,
    backward: Sequence[np.ndarray | None] | None = None,
    early: bool = True,
    **options: Any,
) -> list[CellAttractors]:
    """:func:`find_attractors` for many gear cells at once (all starts are SIMD lanes).

    ``forward`` / ``backward``: per cell a continuation state (10 entries) or None. Every cell
    uses the same ``starts`` Sobol points of the unit square (seed ``seed``) mapped to its own
    :func:`start_box`.
    """
    system = GearCells(params_list, settings)
    unit = sobol_unit(starts, seed)
    st = [system.start_states(c, unit) for c in range(len(params_list))]
    cont = None
    if forward is not None or backward is not None:
        cont = []
        for c in range(len(params_list)):
            m = {}
            if forward is not None and forward[c] is not None:
                m["forward"] = np.asarray(forward[c], dtype=float)[:10]
            if backward is not None and backward[c] is not None:
                m["backward"] = np.asarray(backward[c], dtype=float)[:10]
            cont.append(m)
    options.setdefault("period_rtol", system.settings.period_rtol)
    found = map_attractors(
        system, len(params_list), st, continuation=cont,
        continuation_transient=system.settings.transient_continuation, early=early, **options,
    )  # fmt: skip
    system.fill_margins(found)
    return [least_periods(ca, options.get("merge_rtol", 1e-3)) for ca in found]


def find_attractors(
    params: ModelParameters,
    *,
    starts: int = 16,
    seed: int = 0,
    settings=None,
    forward: np.ndarray | None = None,
    backward: np.ndarray | None = None,
    early: bool = True,
    **options: Any,
) -> CellAttractors:
    """Coexisting attractors of one gear cell from ``starts`` seeded space-filling starts.

    Starts: scrambled Sobol points (seed ``seed``) over the :func:`start_box` in ``(x, x')``,
    bearings at their static deflection and at rest; plus the ``forward`` / ``backward``
    continuation states when given. Integration: the batched RK4 kernel with ``settings``
    (``transient`` periods from a start, ``transient_continuation`` from a continuation state).
    Returns the attractors (classification, basin fraction, section points), most likely first.
    """
    return one_cell(find_attractors_many, params, starts=starts, seed=seed, settings=settings,
                    forward=forward, backward=backward, early=early, **options)


def one_cell(find_many, params: ModelParameters, *, forward=None, backward=None,
             **options: Any) -> CellAttractors:
    """``find_many`` (a many-cell finder) for the one cell ``params``: its result for that cell."""
    return find_many([params], forward=None if forward is None else [forward],
                     backward=None if backward is None else [backward], **options)[0]


def n_real(ca: CellAttractors) -> int:
    """Number of attractors of a cell (the ``unsettled`` bucket does not count)."""
    return sum(1 for a in ca.attractors if a.steady.status != "unsettled")


def summary_lines(ca: CellAttractors) -> list[str]:
    """Human-readable lines: one per attractor, then the divergent share."""
    lines = []
    nan = float("nan")
    for a in ca.attractors:
        i = a.steady.info
        npq = i.get("label_npq") or ""
        pat = f"{a.label} ({npq})" if npq else a.label
        mu = i.get("mu_max", nan)
        verified = (f" |mu|max={mu:.5f} ({i.get('critical')})" if mu == mu else "") + (
            f" status={i.get('status')}" if i.get("status", "ok") != "ok" else "")
        lines.append(
            f"#{a.index} {pat:<18} basin={a.basin_fraction:6.3f} ({a.n_starts}/{ca.n_starts} "
            f"starts, {a.n_early} early) I={i.get('I')} DC={i.get('dc', nan):.4f} "
            f"Kmax={i.get('kmax', nan):.4f} lyapunov={i.get('lyapunov', nan):+.4f} "
            f"found_by={','.join(a.found_by)}{verified}"
        )
    nd = int(np.sum(ca.start_labels < 0))
    lines.append(f"diverged: {nd}/{ca.n_starts} starts ({ca.diverged_fraction:.3f})")
    return lines


# ============================================================================ plane tiles
#: Columns of a plane's attractor tile (results/<plane>/attractors/<tile>.parquet).
TILE_COLUMNS = ("plane", "tile", "i", "j", "x", "y", "attractor", "n_attractors", "motion",
                "status", "label", "label_npq", "I", "n", "p", "q", "dc", "kmax", "lyapunov",
                "basin_fraction", "n_starts", "n_early", "found_by", "starts",
                "diverged_fraction", "periods_run", "poincare_x", "poincare_v", "mu_max",
                "critical", "refined")  # fmt: skip


def cell_group_records(spec: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Attractor records of a group of plane cells (one dask task of ``gearsim attractor-tile``).

    ``spec`` (plain data): ``plane``, ``tile``, ``params`` (dict), ``settings`` (dict),
    ``x_name``, ``y_name``, ``cells`` (list of ``(i, j, x, y, forward_state or None)``),
    ``starts``, ``seed``. One record per attractor of each cell; a cell whose starts all
    diverged gets one record with ``attractor = -1`` and label ``diverged``.
    """
    from gearsim.cell.simulate import IntegrationSettings

    base = ModelParameters.from_mapping(dict(spec["params"]))
    settings = IntegrationSettings(**spec["settings"])
    xn, yn = spec["x_name"], spec["y_name"]
    cells = spec["cells"]
    plist = [base.with_(**{xn: float(c[2]), yn: float(c[3])}) for c in cells]
    fwd = [None if c[4] is None else np.asarray(c[4], dtype=float) for c in cells]
    found = find_attractors_many(plist, starts=int(spec["starts"]), seed=int(spec["seed"]),
                                 settings=settings, forward=fwd)  # fmt: skip
    return tile_records(spec, cells, found)


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


# ============================================================================ hysteresis
@dataclass
class Hysteresis:
    """The fold of a pair of sweeps: where each direction jumps (parameter values).

    ``jump_forward`` is the value (midpoint of the two neighbouring grid values) where the
    sweep in increasing order jumps, ``jump_backward`` where the sweep in decreasing order jumps
    back; ``band`` is the interval between them (the hysteresis band: both motions coexist
    there). ``dc_*`` are the disengagement duty cycles on both sides of each jump; ``differ``
    lists the grid values where the two sweeps reach different motions (pattern or DC).
    """

    parameter: str
    jump_forward: float | None
    jump_backward: float | None
    dc_forward: tuple[float, float] | None
    dc_backward: tuple[float, float] | None
    differ: list[float]

    @property
    def band(self) -> tuple[float, float] | None:
        if self.jump_forward is None or self.jump_backward is None:
            return None
        return (min(self.jump_forward, self.jump_backward),
                max(self.jump_forward, self.jump_backward))  # fmt: skip

    def lines(self) -> list[str]:
        """Report lines (Markdown bullets)."""
        p = self.parameter
        if self.band is None:
            return [f"- no jump pair found in the {p} sweeps (forward jump {self.jump_forward}, "
                    f"backward jump {self.jump_backward})"]  # fmt: skip
        (a, b), (c, d) = self.dc_forward, self.dc_backward
        lo, hi = self.band
        return [
            f"- jump in the increasing-{p} sweep at {p} = {self.jump_forward:.4f} "
            f"(DC {a:.3f} -> {b:.3f})",
            f"- jump back in the decreasing-{p} sweep at {p} = {self.jump_backward:.4f} "
            f"(DC {c:.3f} -> {d:.3f})",
            f"- hysteresis band {lo:.4f} <= {p} <= {hi:.4f} (width {hi - lo:.4f}); the two "
            f"sweeps reach different motions at {len(self.differ)} grid values, "
            f"{sum(lo <= v <= hi for v in self.differ)} of them inside the band",
        ]


def _largest_jump(df: pd.DataFrame, jump_dc: float):
    from gearsim.analysis.landmarks import find_landmarks

    lms = find_landmarks(df.reset_index(drop=True), jump_dc=jump_dc)
    j = lms[lms["kind"] == "jump"]
    if not len(j):
        return None, None
    k = (j["dc_hi"] - j["dc_lo"]).abs().idxmax()
    r = j.loc[k]
    return float(r["value"]), (float(r["dc_lo"]), float(r["dc_hi"]))


def hysteresis(
    sweeps: pd.DataFrame, *, jump_dc: float = 0.15, dc_tol: float = 0.02
) -> Hysteresis:
    """Jump-up and jump-down values of the fold from a sweep run in both directions.

    ``sweeps``: rows of a ``direction: both`` sweep (or a forward and a backward sweep
    concatenated) with ``direction``, ``value``, ``label``, ``label_npq``, ``dc`` (the output
    of ``gearsim sweep``). Jumps are the largest DC discontinuity of each direction
    (:func:`gearsim.analysis.landmarks.find_landmarks`, ``jump_dc``). Two sweeps *differ* at a grid
    value when pattern (label, n-p-q) or DC (by more than ``dc_tol``) differ.
    """
    need = {"direction", "value", "label", "label_npq", "dc", "parameter"}
    if not need <= set(sweeps.columns):
        raise ParameterError(f"hysteresis: sweep table lacks {sorted(need - set(sweeps.columns))}")
    fwd = sweeps[sweeps["direction"] == "forward"].sort_values("value")
    bwd = sweeps[sweeps["direction"] == "backward"].sort_values("value", ascending=False)
    if not len(fwd) or not len(bwd):
        raise ParameterError("hysteresis: needs a forward and a backward sweep (direction: both)")
    jf, dcf = _largest_jump(fwd, jump_dc)
    jb, dcb = _largest_jump(bwd, jump_dc)
    a = fwd.set_index("value")[["label", "label_npq", "dc"]]
    b = bwd.set_index("value")[["label", "label_npq", "dc"]]
    common = a.index.intersection(b.index)
    differ = [float(v) for v in common
              if (a.loc[v, "label"], a.loc[v, "label_npq"])
              != (b.loc[v, "label"], b.loc[v, "label_npq"])
              or abs(float(a.loc[v, "dc"]) - float(b.loc[v, "dc"])) > dc_tol]  # fmt: skip
    return Hysteresis(str(fwd["parameter"].iloc[0]), jf, jb, dcf, dcb, sorted(differ))
