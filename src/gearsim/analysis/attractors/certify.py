"""Certified neighbourhoods of stable periodic orbits: where an early label needs no recurrence.

For a periodic attractor of period ``n`` whose orbit is a stable orbit of its cell (its section
state Newton-converged on the cell's own RK4 map, |mu|max < 1:
:func:`gearsim.analysis.attractors.gear.newton_orbits`, the one orbit solver where one small
step does not converge; the orbit's points those of the attractor to the merge tolerance, at
its least period: :func:`_the_motions`), a neighbourhood of that fixed point ``c`` of the
``n``-period map (phase 0) is *certified* in a norm adapted to the orbit:

* the monodromy ``M`` of the orbit's own ``n`` periods at ``c`` (the one Newton used), in the
  scaled coordinates ``z = (y - c) / s`` (``s`` the orbit's displacement range for
  displacements, ``w`` times it for velocities; the single-DOF model's frozen bearing states
  left out), gives the matrix
  ``P`` of the discrete Lyapunov (Stein) equation ``M^T P M - rho^2 P = -rho^2 I`` with
  ``rho = (1 + |mu|max) / 2`` (:func:`scipy.linalg.solve_discrete_lyapunov` on ``M / rho``):
  the linearised ``n``-period map contracts the norm ``|z|_P = sqrt(z^T P z)`` by ``rho``.
  ``P`` is scaled so that its smallest eigenvalue is 1, so the ellipsoid ``|z|_P <= r`` lies
  inside the scaled sup-norm ball of radius ``r`` (``r`` is a fraction of the range in every
  component). In the sup norm itself the same non-normal monodromy first *grows* the ball's
  corners (transient growth: 1-3.4 radii over 8 periods at |mu|max 0.74-0.83), which is why a
  sup-norm ball needed the 24-period map (docs/decisions.md).
* A radius ``r`` is certified when the true nonlinear ``n``-period map takes the centre to
  within ``CENTRE_FRACTION r`` of itself and every sampled boundary point of the ellipsoid
  (its principal axes, both signs, plus ``RANDOM`` points of a seeded generator,
  :data:`SAMPLE_SEED`) to inside ``rho' r``, ``rho' = (1 + rho) / 2``, each sample keeping the
  orbit's contact sequence (the entries into face and back contact of every period equal to
  the orbit's: no contact gained or lost, no grazing on the sampled paths). Radii from
  ``FinderOptions.certify_radius`` down by factors of 3 (``certify_tries`` of them: 0.3 to
  0.0037 of the range by default); none passing leaves the orbit uncertified (its starts keep
  the recurrence rule).

A probing start is labelled onto a certified orbit when one of its section points ``y_k`` lies
inside the ellipsoid and the point ``n`` periods later, ``y_{k+n}``, lies inside it too and
closer to the centre in the ``P`` norm (the contraction confirmed on the start's own
trajectory); every period of the start's recorded window is tested, not only the chunk ends.
Sampled boundary points are evidence, not a proof of contraction over the whole ellipsoid;
the finder's tests check every early label against the start's full-length run.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gearsim.analysis.attractors.results import Steady
from gearsim.dynamics.parameters import ModelParameters

#: the orbit's own state must return to within this fraction of the radius after n periods
CENTRE_FRACTION = 0.05
#: random boundary points sampled besides the 2 d principal-axis points
RANDOM = 12
#: seed of the random boundary points (recorded: the samples of an orbit are reproducible)
SAMPLE_SEED = 0
#: the certified orbit's points lie within this fraction of the range of the motion's (the
#: finder's merge tolerance: the orbit is that attractor)
MERGE_RTOL = 1e-3


@dataclass(frozen=True)
class Certificate:
    """A certified ellipsoid ``|(y - centre)[ev] / scales|_P <= r`` around phase 0 of a
    period-``n`` orbit: ``P`` ``(d, d)`` (smallest eigenvalue 1), the linear contraction
    ``rho`` per ``n`` periods in that norm, the worst sampled image ``ratio`` (image norm / r)."""

    centre: np.ndarray
    ev: np.ndarray
    scales: np.ndarray
    P: np.ndarray
    r: float
    rho: float
    ratio: float
    n: int

    def distance(self, y: np.ndarray) -> np.ndarray:
        """``P``-norm distance of states ``y`` ``(..., 10)`` to the centre, over ``r``."""
        z = (y[..., self.ev] - self.centre[self.ev]) / self.scales
        q = np.sum((z @ self.P) * z, axis=-1)
        return np.sqrt(np.maximum(q, 0.0)) / self.r

    def confirmed(self, hist: np.ndarray, filled: np.ndarray) -> np.ndarray:
        """Per history ``hist[i]`` ``(L, 10)`` (last ``filled[i]`` valid, oldest first): some
        point ``y_k`` of it inside the ellipsoid with ``y_{k+n}`` inside and closer."""
        L, n = hist.shape[1], self.n
        d = self.distance(hist)  # (k, L); NaN where not filled
        later = d[:, n:]
        earlier = d[:, :-n]
        ok = (earlier < 1.0) & (later < earlier)
        idx = np.arange(n, L)[None, :]
        ok &= idx >= L - np.asarray(filled)[:, None] + n  # both points filled
        return ok.any(axis=1)


def _evolved(params: ModelParameters) -> np.ndarray:
    """Indices of the state the model evolves (the single-DOF model freezes the bearings)."""
    return np.arange(10) if params.model == "6dof" else np.arange(2)


def eligible(s: Steady, max_period: int) -> bool:
    """A periodic attractor whose neighbourhood may be certified (period at most
    ``max_period``, the probing window's reach; its Floquet margin, where known, below 1)."""
    i = s.info or {}
    mu = i.get("mu_max")
    known = mu is not None and math.isfinite(mu)
    return (s.status == "ok" and 0 < s.period <= max_period
            and s.final_state is not None and (not known or mu < 1.0)
            and i.get("status", "ok") == "ok")  # fmt: skip


def stable_margin(params: ModelParameters, s: Steady, settings) -> bool:
    """Whether the orbit's Floquet margin |mu|max is below 1: its own (refined orbit, or
    computed before), else that of the orbit through its settled section state
    (:func:`gearsim.cell.verify.orbit_margins`, written into ``s.info`` as the finder's last
    step would)."""
    from gearsim.cell.verify import orbit_margins

    mu = (s.info or {}).get("mu_max")
    if mu is None or not math.isfinite(mu):
        got = orbit_margins([params], [s.period], [s.final_state], settings)[0]
        if got is None:
            return False
        s.info["mu_max"], s.info["critical"] = got
        mu = got[0]
    return bool(mu < 1.0)


def samples(params: ModelParameters) -> int:
    """Lanes of one try: the centre, 2 per evolved coordinate, the random points."""
    return 1 + 2 * len(_evolved(params)) + RANDOM


def worth(params: ModelParameters, s: Steady, settings, open_starts: int, radius: float,
          recur_rtol: float) -> bool:
    """Whether certifying the orbit of ``s`` is expected to cost fewer lane-periods than it
    saves its cell's ``open_starts`` unlabelled starts: a start converging at the rate
    |mu|max per period reaches the ellipsoid of ``radius`` some ``ln(radius / recur_rtol) /
    ln(1 / |mu|max)`` periods before the recurrence rule's ``recur_rtol`` (the period test);
    certifying costs the monodromy (``d`` lanes) and a try (:func:`samples` lanes), each
    ``n`` periods. Reads (and fills) the orbit's Floquet margin; False where it is not below
    1."""
    if open_starts <= 0 or not stable_margin(params, s, settings):
        return False
    mu = float(s.info["mu_max"])
    if mu <= 0.0:
        return True
    saved = open_starts * math.log(radius / recur_rtol) / math.log(1.0 / mu) / s.period
    return saved > samples(params) + len(_evolved(params))


def _ellipsoid(M: np.ndarray, scales: np.ndarray) -> tuple[np.ndarray, float] | None:
    """``(P, rho)`` of the scaled monodromy (module docstring), None where |mu|max >= 1."""
    from scipy.linalg import solve_discrete_lyapunov

    Ms = M / scales[:, None] * scales[None, :]
    mu = float(np.max(np.abs(np.linalg.eigvals(Ms))))
    if not mu < 1.0:
        return None
    rho = 0.5 * (1.0 + mu)
    A = Ms / rho
    P = solve_discrete_lyapunov(A.T, np.eye(len(M)))
    P = 0.5 * (P + P.T)
    lam = np.linalg.eigvalsh(P)
    if not (np.all(np.isfinite(P)) and lam[0] > 0.0):
        return None
    return P / lam[0], rho


def _the_motions(s: Steady, pts: np.ndarray) -> bool:
    """Whether the orbit's points ``pts`` ``(n, 2)`` (phase 0 on) are the motion ``s``'s, to the
    merge tolerance of the finder (:data:`MERGE_RTOL` of the range, any cyclic shift), at its
    least period (no two phases ``m | n`` apart within
    :data:`gearsim.analysis.attractors.gear.LEAST_PERIOD_RTOL`): Newton on ``P^n`` also
    converges to other orbits, the fixed points of ``P^m`` among them."""
    from gearsim.analysis.attractors.gear import shorter_period
    from gearsim.analysis.attractors.matching import near_all

    n = s.period
    sx, sv = max(s.scale_x, 1e-9), max(s.scale_v, 1e-9)
    if shorter_period(pts, np.array([sx, sv])):
        return False
    own = np.asarray(s.points, dtype=float)[-n:, :2]
    tx, tv = MERGE_RTOL * sx, MERGE_RTOL * sv
    return near_all(pts, own, tx, tv) and near_all(own, pts, tx, tv)


def images(plist: list[ModelParameters], rows: list[np.ndarray], n: int, settings,
            packed: dict[int, np.ndarray], backend=None):
    """The ``n``-period images of the states ``rows`` (one SIMD lane each, without the tangent
    vector: the cells' one RK4 kernel, as a probing lane runs them, on ``backend``), their
    status and the entries into face and back contact of every period."""
    from gearsim.numerics.batch import Lanes, steps_per_period

    k = len(rows)
    N = steps_per_period(plist[0], settings)
    lanes = Lanes(k, n, backend)
    for l, (p, y) in enumerate(zip(plist, rows, strict=True)):
        lanes.load_params(l, p, N, packed[id(p)])
        lanes.load_state(l, y)
    lanes.status[:k] = 0
    lanes.position[:k] = 0
    lanes.period[:k] = 0
    lanes.run(N, n, 0.0, float(getattr(settings, "divergence_bound", 1.0e6)), False)
    return (lanes.states(k, 10), lanes.status[:k].copy(), lanes.nface[:k, :n].copy(),
            lanes.nback[:k, :n].copy(), lanes.sec[:k, :n, :2].copy())  # fmt: skip


def continue_orbits(pairs: Sequence[tuple[ModelParameters, Steady]], st, backend=None
                    ) -> list[tuple[np.ndarray, np.ndarray] | None]:
    """Per ``(cell parameters, a periodic motion of a neighbouring cell)``: ``(y, points)``, the
    section state of that motion's orbit continued by Newton into *this* cell (the one orbit
    solver from the motion's section state on this cell's RK4 map,
    :func:`gearsim.analysis.attractors.gear.newton_orbits` with ``solve``: converged to its
    ``NEWTON_TOL``, |mu|max < 1) and its ``n`` section points ``(n, 2)`` there (one lane each,
    :func:`images`), where they have no shorter period
    (:func:`gearsim.analysis.attractors.gear.shorter_period`; Newton on ``P^n`` also converges to
    the fixed points of ``P^m``, e.g. across a period doubling); else None. Attractors.jl's
    ``AttractorSeedContinueMatch``: seeds continued from the neighbours."""
    from gearsim.analysis.attractors.gear import newton_orbits, shorter_period
    from gearsim.dynamics.model import pack_parameters

    got = newton_orbits(pairs, st, solve=True)
    out: list[tuple[np.ndarray, np.ndarray] | None] = [None] * len(pairs)
    by_n: dict[int, list[int]] = {}
    for i, o in enumerate(got):
        if o is not None:
            by_n.setdefault(pairs[i][1].period, []).append(i)
    for n, group in by_n.items():
        plist = [pairs[i][0] for i in group]
        packed = {id(p): pack_parameters(p) for p in plist}
        _fin, status, _face, _back, sec = images(plist, [got[i][0] for i in group], n, st,
                                                 packed, backend)  # fmt: skip
        for q, i in enumerate(group):
            s = pairs[i][1]
            pts = sec[q]
            sc = np.array([max(s.scale_x, 1e-9), max(s.scale_v, 1e-9)])
            if status[q] == 0 and np.all(np.isfinite(pts)) and not shorter_period(pts, sc):
                out[i] = (got[i][0], pts)
    return out


def certify_many(pairs: Sequence[tuple[ModelParameters, Steady]], settings, radius: float,
                 tries: int, orbits: Sequence | None = None, backend=None
                 ) -> tuple[list[Certificate | None], int]:
    """The largest certified radius of each orbit (module docstring), or None, all orbits of
    one period in shared kernel calls (cells of one step grid); and the lane-periods
    integrated to find them. Only an orbit Newton-converged in its cell at its least period
    with |mu|max < 1 is certified (:func:`gearsim.analysis.attractors.gear.newton_orbits`;
    ``orbits``: its result for ``pairs`` if the caller has it): the ellipsoid is centred on
    that fixed point of the orbit map, so a contraction of the ellipsoid into itself leads to
    this orbit and no other (the fixed point in it is unique)."""
    from gearsim.dynamics.model import pack_parameters

    out: list[Certificate | None] = [None] * len(pairs)
    spent = 0
    packed: dict[int, np.ndarray] = {}  # id(params) -> packed parameters
    from gearsim.analysis.attractors.gear import newton_orbits

    if orbits is None:
        orbits = [None] * len(pairs)
    redo = [i for i, o in enumerate(orbits) if o is None]
    if redo:  # the one orbit solver where one small Newton step does not converge
        got = newton_orbits([(pairs[i][0], pairs[i][1] if eligible(pairs[i][1], pairs[i][1].period)
                              else None) for i in redo], settings, solve=True)  # fmt: skip
        orbits = list(orbits)
        for i, o in zip(redo, got, strict=True):
            orbits[i] = o
    by_n: dict[int, list[int]] = {}
    for i, (p, s) in enumerate(pairs):
        if orbits[i] is not None and eligible(s, s.period):
            by_n.setdefault(s.period, []).append(i)
            spent += len(orbits[i][1]) * s.period
            if id(p) not in packed:
                packed[id(p)] = pack_parameters(p)
    for n, group in by_n.items():
        todo = []  # (pair index, centre, ev, scales, P, rho, unit directions)
        for i in group:
            p, s = pairs[i]
            y, M = orbits[i]
            ev = _evolved(p)
            scales = np.array([max(s.scale_x, 1e-9) if k % 2 == 0 else max(s.scale_v, 1e-9)
                               for k in ev])  # fmt: skip
            got = _ellipsoid(M[: len(ev), : len(ev)], scales)
            if got is None:
                continue
            P, rho = got
            lam, V = np.linalg.eigh(P)
            axes = (V / np.sqrt(lam)[None, :]).T  # P-norm 1 along each principal axis
            rng = np.random.default_rng(SAMPLE_SEED)
            g = rng.standard_normal((RANDOM, len(ev)))
            g /= np.sqrt(np.einsum("ki,ij,kj->k", g, P, g))[:, None]
            dirs = np.vstack([axes, -axes, g])
            todo.append((i, y, ev, scales, P, rho, dirs))
        r = float(radius)
        for _ in range(int(tries)):
            if not todo:
                break
            rows, plist, owner = [], [], []
            for k, (i, y, ev, scales, _P, _rho, dirs) in enumerate(todo):
                rows.append(y)
                for e in dirs:
                    yy = y.copy()
                    yy[ev] += r * e * scales
                    rows.append(yy)
                plist += [pairs[i][0]] * (len(dirs) + 1)
                owner += [k] * (len(dirs) + 1)
            fin, status, face_all, back_all, sec = images(plist, rows, n, settings, packed,
                                                          backend)
            spent += len(rows) * n
            owner = np.array(owner)
            left = []
            for k, (i, y, ev, scales, P, rho, _dirs) in enumerate(todo):
                q = np.nonzero(owner == k)[0]
                ok = bool(np.all(status[q] == 0)) and _the_motions(pairs[i][1], sec[q[0]])
                if ok:  # every sample with the centre's (the orbit's) contact sequence
                    ok = bool(np.all(face_all[q] == face_all[q[0]])
                              and np.all(back_all[q] == back_all[q[0]]))  # fmt: skip
                if ok:
                    z = (fin[q][:, ev] - y[ev]) / scales
                    d = np.sqrt(np.maximum(np.einsum("ki,ij,kj->k", z, P, z), 0.0)) / r
                    rho2 = 0.5 * (1.0 + rho)
                    ok = bool(d[0] <= CENTRE_FRACTION and np.all(d[1:] < rho2))
                if ok:
                    out[i] = Certificate(y.copy(), ev, scales, P, r, rho, float(d[1:].max()), n)
                else:
                    left.append(todo[k])
            todo = left
            r /= 3.0
    return out, spent


def certify(params: ModelParameters, s: Steady, settings, radius: float, tries: int,
            backend=None) -> tuple[Certificate | None, int]:
    """:func:`certify_many` of one orbit (its lanes on ``backend``)."""
    got, spent = certify_many([(params, s)], settings, radius, tries, backend=backend)
    return got[0], spent
