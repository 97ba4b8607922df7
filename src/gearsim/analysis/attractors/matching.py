"""When two steady motions are one attractor, when a start recurs onto a known one, and the
cells' attractor lists from the fate of every start (every mapper's last step).

Merging: starts that did not settle within the budget (status ``unsettled``) form one entry
per cell (label ``unsettled``, never labelled early). Two steady motions are the same attractor
when both have the same period ``n > 0`` and each section point of one lies within
``merge_rtol * scale`` of a point of the other (so any cyclic shift matches), or, readings of
one orbit that settled to different degrees (a refined orbit and a ``bifurcation``-status
window reading of it), the same label and n-p-q, DC within :data:`ORBIT_DC` and points within
:data:`ORBIT_RTOL` of the range; or when both are non-periodic and at least ``cloud_overlap``
of each cloud's points fall in the dilated grid occupancy of the other (``g x g`` cells over
the joint bounding box, ``g = grid`` or fewer for sparse clouds: ``g <= 2 sqrt(points)``, at
least 4; so a cell holds ~2 points on average). A period-kn reading of a period-n orbit is
merged into the period-n one after the margins are known (:func:`least_periods`).
"""

from __future__ import annotations

import math

import numpy as np

from gearsim.analysis.attractors.options import FinderOptions
from gearsim.analysis.attractors.results import FOUND_BY, Attractor, CellAttractors, Steady


def _tolerances(a: Steady, b: Steady, rtol: float) -> tuple[float, float]:
    sx = max(a.scale_x, b.scale_x, 1e-9)
    sv = max(a.scale_v, b.scale_v, 1e-9)
    return rtol * sx, rtol * sv


def near_all(p: np.ndarray, q: np.ndarray, tx: float, tv: float) -> bool:
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
    return near_all(pa, pb, tx, tv) and near_all(pb, pa, tx, tv)


#: a period-kn reading of a period-n orbit has the n orbit's multipliers to the k-th power:
#: |mu|max within this relative tolerance of (|mu|max of the n reading)^k
MULTIPLE_MU_RTOL = 1e-3


def multiple_copy(short: Steady, long: Steady, merge_rtol: float = 1e-3) -> bool:
    """Whether the periodic reading ``long`` (period k n, k >= 2) is the period-n orbit
    ``short`` counted k times: same impact state, DC within :data:`ORBIT_DC`, every point of
    each within :data:`ORBIT_RTOL` of the range of a point of the other and |mu|max of ``long``
    the k-th power of that of ``short`` (:data:`MULTIPLE_MU_RTOL`); without both margins, the
    points within ``merge_rtol`` of each other (the merge test's own tolerance), or within
    :data:`ORBIT_RTOL` when ``long`` (period 2 n, no margin of its own) sits beside an orbit
    at its period doubling (refined, status ``bifurcation``, critical multiplier
    ``period_doubling``): a stable orbit at a doubling has no stable period-2n orbit next to
    it (supercritical: the 2n branch is born when the orbit loses stability; subcritical: the
    2n branch beside it is unstable), so that reading is the orbit's alternation, decaying by
    |mu|max ~ 1 per n periods, and no Newton orbit of period 2n is found for it (w = 1.423,
    xi = 0.07015: 1/4T with |mu|max 0.99984, a 1/8T reading 1.8e-3 of the range from it)."""
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
    doubling = (not with_mu and m == 2 * n and mu_a is not None and math.isfinite(mu_a)
                and mu_a < 1.0 and bool(ia.get("refined")) and ia.get("status") == "bifurcation"
                and ia.get("critical") == "period_doubling"
                and (mu_b is None or not math.isfinite(mu_b)))  # fmt: skip
    tx, tv = _tolerances(short, long, ORBIT_RTOL if with_mu or doubling else merge_rtol)
    return near_all(pa, pb, tx, tv) and near_all(pb, pa, tx, tv)


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
    return _renumbered(ca, set(into), into)


def drop(ca: CellAttractors, gone: set[int]) -> CellAttractors:
    """``ca`` without the attractors ``gone`` (indices): their starts count as diverged, the
    rest renumbered most starts first."""
    if not gone:
        return ca
    return _renumbered(ca, gone, {})


def _renumbered(ca: CellAttractors, out: set[int], into: dict[int, int]) -> CellAttractors:
    """``ca`` without the attractors ``out`` (indices), the starts of each one in ``into`` moved
    to the attractor it maps to, the others' starts diverged (-1); the rest renumbered most
    starts first, basin fractions over the cell's starts."""
    top = max([a.index for a in ca.attractors] + [0])
    kept = sorted((a for a in ca.attractors if a.index not in out),
                  key=lambda a: (-a.n_starts, a.index))  # fmt: skip
    new = {a.index: r for r, a in enumerate(kept)}
    for b_i, a_i in into.items():
        new[b_i] = new[a_i]
    k = ca.n_starts
    for r, a in enumerate(kept):
        a.index = r
        a.basin_fraction = float(a.n_starts / k) if k else 0.0
    remap = np.array([new.get(i, -1) for i in range(top + 1)] + [-1], dtype=np.int64)
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
        if near_all(pa, pb, tx, tv) and near_all(pb, pa, tx, tv):
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


class KnownAttractors:
    """The attractors of one cell found so far, with their recurrence tests precomputed."""

    def __init__(self, opts: FinderOptions):
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
                    if near_all(ps, pt, tx, tv) and near_all(pt, ps, tx, tv):
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




def assemble(opts: FinderOptions, starts, labels, is_early, periods_run, known, cont_steady
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
        kn = KnownAttractors(opts)
        cont_labels[c], cont_found[c] = {}, {}
        for name, s in cont_steady[c]:
            a = kn.add(s)
            cont_labels[c][name] = a
            if a >= 0:
                cont_found[c].setdefault(a, set()).add(name)
        new = np.full(K[c], -1, dtype=np.int64)
        done: dict[int, int] = {}  # id(motion) -> its index (one motion merges once)
        for i in range(K[c]):
            if labels[c][i] >= 0:
                s = known[c].own.get(i, known[c].steadies[labels[c][i]])
                if id(s) not in done:
                    done[id(s)] = kn.add(s)
                new[i] = done[id(s)]
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


