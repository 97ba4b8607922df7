"""The lane-pool mapper (the gear model): one pool of SIMD lanes across cells and starts.

Same answer as the recurrence mapper :func:`~gearsim.analysis.attractors.recurrence.map_attractors`
with the gear model (the same starts, the same recurrence rule
:meth:`~gearsim.analysis.attractors.matching.KnownAttractors.recur`, the same merging and the
same last step :func:`~gearsim.analysis.attractors.matching.assemble`), scheduled so that no
lane waits for another start:

* Every start is a job of :func:`gearsim.cell.pool.run_pool` whose trajectory *is* its
  full-length run (transient, tangent lead, measurement, period test, classification and
  refinement exactly as :func:`gearsim.cell.chains.simulate_cells` from that start).
* During its transient a start records its section points; every ``chunk`` periods the starts
  of a cell are tested for recurrence onto the cell's known attractors. A labelled start frees
  its lane at once; the lane is refilled from the queue (parked starts of other cells first,
  then the starts of the next cell).
* At most one start per cell (its *runner*) goes on past ``patience`` probed periods without a
  label; the others that reach it are *parked* (lane state and history kept, lane freed). When
  the runner finishes (its motion joins the cell's list) or is labelled, the parked starts are
  tested again at once and resume (each with a fresh ``patience``); one of them becomes the
  next runner. Parking changes when a start is labelled, never what it is labelled onto.
* Certified early labels (``certified``, :mod:`gearsim.analysis.attractors.certify`): a
  start one of whose recorded section states lies inside a periodic motion's certified
  ellipsoid, with the state one orbit period later inside and closer, is labelled onto it
  (every period of its window is tested at each chunk check), before the recurrence rule of
  ``map_attractors`` (which labels the rest). Every periodic motion of the cell's own runs is
  tried once; the forward motions of the plane rows are certified before the pool in shared
  kernel calls and seed their cells' starts from the first chunk.
* The forward-continuation motion of the cell, when the plane tile already simulated it
  (``forward_results``), is a known attractor at no cost (``found_by = forward``); otherwise
  the forward state is a job of its own (the cell's first runner). Either is a recurrence
  target as soon as it is known when it is a stable orbit Newton-converged in this cell at its
  least period (``newton_seeds``, :func:`~gearsim.analysis.attractors.gear.newton_verified`):
  the starts that reach it need no full-length run to confirm it.
* Cells of one step grid share the kernel calls (one pool per grid); probes run without the
  tangent vector (the measuring lanes are a second pool with it).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping, Sequence

import numpy as np

from gearsim.analysis.attractors.certify import (
    certify,
    certify_many,
    continue_orbits,
    eligible,
    worth,
)
from gearsim.analysis.attractors.gear import (
    GearCells,
    bounded_clouds,
    fill_orbit_margins,
    gear_steady,
    newton_orbits,
    newton_verified,
)
from gearsim.analysis.attractors.mapper import check_inputs
from gearsim.analysis.attractors.matching import (
    KnownAttractors,
    assemble,
    least_periods,
    near_all,
)
from gearsim.analysis.attractors.options import FinderOptions
from gearsim.analysis.attractors.results import FOUND_BY, CellAttractors, Steady
from gearsim.cell.pool import GO, MEASURE, PARK, STOP, PoolJob, PoolStats, run_pool
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.numerics.batch import steps_per_period

_CONT = {-1: "forward", -2: "backward"}
#: job keys of a cell's seeds continued from its neighbours: -3, -4, ...
_SEED = -3


def _same_points(p: np.ndarray, q: np.ndarray, s: Steady, rtol: float) -> bool:
    """Every point of ``p`` within ``rtol`` of the range of ``s`` of a point of ``q`` and back."""
    tx, tv = rtol * max(s.scale_x, 1e-9), rtol * max(s.scale_v, 1e-9)
    return near_all(p, q, tx, tv) and near_all(q, p, tx, tv)


def _verified(s: Steady) -> bool:
    """A continuation state's motion is a recurrence target only as a Newton-refined orbit
    that is stable (``ok``, |mu|max < 1). At w = 1.99, b = 0.375 the forward reading is a 1/5T
    orbit (Floquet margin 0.63, critical multiplier complex) while every start's full-length
    run ends on 1/1T; starts spiralling into the 1/1T motion at close to 1/5 of a turn per
    period matched the 1/5T points in phase order within the recurrence tolerance. Other
    motions become targets once a start's full-length run reaches them."""
    i = s.info or {}
    mu = i.get("mu_max")
    return bool(i.get("refined")) and i.get("status") == "ok" and mu is not None and mu < 1.0


class _Cell:
    def __init__(self, c: int, params: ModelParameters, starts: np.ndarray, opts: FinderOptions):
        self.c = c
        self.params = params
        self.starts = starts
        self.known = KnownAttractors(opts)
        k = len(starts)
        self.labels = np.full(k, -2, dtype=np.int64)
        self.early = np.zeros(k, dtype=bool)
        self.periods = np.zeros(k, dtype=np.int64)
        self.cont: list[tuple[str, Steady]] = []
        self.runner: PoolJob | None = None
        self.parked: list[PoolJob] = []
        self.certs: dict = {}  # attractor index -> Certificate or None
        self.pre = False  # the forward motion's certificate taken before the pool (None: none)
        self.opened = False
        self.tried: set = set()  # (period, label, n-p-q) of the neighbours' motions tried
        self.seeds: list[tuple[np.ndarray, int]] = []  # continued orbits: (points, period)


class _Judge:
    """The finder's side of :func:`gearsim.cell.pool.run_pool` for the cells of one grid."""

    def __init__(self, cells: list[_Cell], forward, backward, forward_results, st,
                 opts: FinderOptions, history: int, early: bool, stats: PoolStats,
                 seeds: Sequence[bool] | None = None,
                 neighbours: Sequence[Sequence[int]] | None = None, backend=None):
        self.backend = backend  # where the certificates' and seeds' lanes run (None: the CPU)
        self.stats = stats
        self.seeds = seeds
        self.cells = deque(cells)
        self.by_c = {cell.c: cell for cell in cells}
        self.neighbours = neighbours if early and opts.neighbour_seeds else None
        self.forward = forward
        self.backward = backward
        self.early = early
        self.forward_results = forward_results
        self.st = st
        self.opts = opts
        self.history = history
        self.ready: deque[PoolJob] = deque()
        self.waiting: deque[PoolJob] = deque()

    # ---- the queue
    def _open(self, cell: _Cell) -> None:
        c = cell.c
        cell.opened = True
        fr = None if self.forward_results is None else self.forward_results[c]
        if fr is not None:
            cell.cont.append(("forward", fr))
            seed = self.seeds is not None and self.seeds[c]
            a = cell.known.add(fr, target=seed or _verified(fr))
            if cell.pre is not False and a >= 0 and a not in cell.certs:
                cell.certs[a] = cell.pre
        elif self.forward is not None and self.forward[c] is not None:
            self._continuation(cell, -1, self.forward[c])
        if self.backward is not None and self.backward[c] is not None:
            self._continuation(cell, -2, self.backward[c])
        if self.neighbours is not None:
            self._seed(cell, self._neighbour_motions(c))
        for i, y in enumerate(cell.starts):
            job = PoolJob(key=(cell, i), params=cell.params, u0=y, transient=int(self.st.transient),
                          probe=self.early, history=self.history)  # fmt: skip
            self.ready.append(job)

    def _continuation(self, cell: _Cell, i: int, y) -> None:
        """A continuation state's full-length run (continuation transient): the cell's runner."""
        job = PoolJob(key=(cell, i), params=cell.params, u0=np.asarray(y, dtype=float)[:10],
                      transient=int(self.st.transient_continuation), probe=False)  # fmt: skip
        if self.early and cell.runner is None:
            cell.runner = job
        self.ready.append(job)

    def take(self, n: int) -> list[PoolJob]:
        out = list(self.waiting)
        self.waiting.clear()
        k = 0
        while k < n:
            if self.ready:
                out.append(self.ready.popleft())
                k += 1
            elif self.cells:
                self._open(self.cells.popleft())
            else:
                break
        return out

    # ---- decisions
    def probed(self, jobs: list[PoolJob]) -> list[str]:
        by_cell: dict[int, list[int]] = {}
        for r, j in enumerate(jobs):
            by_cell.setdefault(id(j.key[0]), []).append(r)
        out = [GO] * len(jobs)
        for rows in by_cell.values():
            cell = jobs[rows[0]].key[0]
            sub = [jobs[r] for r in rows]
            hit = self._hits(cell, sub)
            for r, a in zip(rows, hit, strict=True):
                j = jobs[r]
                if a >= 0:
                    self._label(cell, j, a)
                    out[r] = STOP
                elif j is cell.runner:
                    continue
                elif j.probed - j.mark >= self.opts.rescout:
                    if cell.runner is None:
                        cell.runner = j
                    else:
                        cell.parked.append(j)
                        out[r] = PARK
            if cell.runner is None or cell.runner.where == "done":
                self._release(cell)
        return out

    def transient_over(self, job: PoolJob) -> str:
        cell = job.key[0]
        if not self.early or job.key[1] < 0:
            return MEASURE
        if cell.runner is None or cell.runner is job:
            cell.runner = job
            return MEASURE
        cell.parked.append(job)
        return PARK

    def finished(self, job: PoolJob) -> None:
        cell, i = job.key
        s = gear_steady(job.result)
        if i <= _SEED:
            self.stats.seed_periods += int(job.result.periods)
            self._seeded(cell, i, s)
        elif i < 0:
            cell.cont.append((_CONT[i], s))
            seed = (self.early and self.opts.newton_seeds
                    and newton_verified([(cell.params, s)], self.st)[0])  # fmt: skip
            cell.known.add(s, target=seed or _verified(s))
        else:
            new = len(cell.known.steadies)
            cell.labels[i] = cell.known.add(s)
            cell.known.own[i] = s
            cell.periods[i] = int(job.result.periods)
            if cell.labels[i] == new and self.neighbours is not None and s.period > 0:
                for nb in self.neighbours[cell.c]:  # a new orbit: a seed of the open neighbours
                    other = self.by_c.get(nb)
                    if other is not None and other.opened and np.any(other.labels == -2):
                        self._seed(other, [s], first=True)
        if cell.runner is job:
            cell.runner = None
            self._release(cell)

    # ---- seeds from the neighbours
    def _neighbour_motions(self, c: int) -> list[Steady]:
        """The periodic motions known in the neighbouring cells of cell ``c``: their forward
        motions and, where they are open, the motions their starts' runs reached."""
        out = []
        for nb in self.neighbours[c]:
            fr = None if self.forward_results is None else self.forward_results[nb]
            if fr is not None:
                out.append(fr)
            other = self.by_c.get(nb)
            if other is not None and other.opened:
                out += [s for a, s in enumerate(other.known.steadies) if other.known.target[a]]
        return out

    def _seed(self, cell: _Cell, motions: Sequence[Steady], first: bool = False) -> None:
        """Neighbouring cells' periodic motions of a label this cell does not know yet,
        continued by Newton into it (:func:`continue_orbits`: converged here, |mu|max < 1, at
        their least period) and not an orbit the cell knows: each a job of the cell (its
        classification, tangent lead and measurement from the orbit's state) whose motion
        becomes a recurrence target when it confirms the orbit (:meth:`_seeded`)."""
        kn = cell.known
        have = {(t.period, t.label, (t.info or {}).get("label_npq")) for t in kn.steadies}
        todo = []
        for s in motions:
            key = (s.period, s.label, (s.info or {}).get("label_npq"))
            if (s.status != "ok" or s.period <= 0 or s.final_state is None
                    or (s.info or {}).get("status", "ok") != "ok"
                    or key in have or key in cell.tried):  # fmt: skip
                continue
            cell.tried.add(key)
            todo.append(s)
        if not todo:
            return
        got = continue_orbits([(cell.params, s) for s in todo], self.st, self.backend)
        self.stats.seeds_tried += len(todo)
        for s, g in zip(todo, got, strict=True):
            if g is None:
                continue
            y, pts = g
            n = s.period
            if any(_same_points(pts, t.points[-t.period:, :2], t, self.opts.merge_rtol)
                   for t in kn.steadies
                   if t.period > 0 and (t.period % n == 0 or n % t.period == 0)):  # fmt: skip
                continue  # an orbit the cell knows
            if any(_same_points(pts, q, s, self.opts.merge_rtol) for q, m in cell.seeds if m == n):
                continue
            cell.seeds.append((pts, n))
            job = PoolJob(key=(cell, _SEED - len(cell.seeds) + 1), params=cell.params,
                          u0=np.asarray(y, dtype=float)[:10],
                          transient=int(self.st.tangent_lead), probe=False)  # fmt: skip
            self.stats.seeds_run += 1
            if first:
                self.ready.appendleft(job)
            else:
                self.ready.append(job)

    def _seeded(self, cell: _Cell, i: int, s: Steady) -> None:
        """A seed's run: its motion joins the cell's known attractors as a recurrence target
        when it is that orbit (period, status ``ok``, points within the merge tolerance);
        never a continuation reading (no attractor of the cell unless a start reaches it)."""
        pts, n = cell.seeds[_SEED - i]
        if (s.status == "ok" and s.period == n and (s.info or {}).get("status") == "ok"
                and _same_points(pts, s.points[-n:, :2], s, self.opts.merge_rtol)):  # fmt: skip
            cell.known.add(s, target=True)
            self.stats.seeds_confirmed += 1
            self._retest(cell)

    def _retest(self, cell: _Cell) -> None:
        """The parked starts of ``cell`` tested again at once (a new target): the ones that hit
        are labelled, the rest stay parked."""
        if not cell.parked:
            return
        hit = self._hits(cell, cell.parked)
        rest = []
        for j, a in zip(cell.parked, hit, strict=True):
            if a >= 0:
                self._label(cell, j, a)
                j.where, j.saved = "done", None
            else:
                rest.append(j)
        cell.parked = rest

    # ---- helpers
    def _certify(self, cell: _Cell) -> None:
        """A certificate (or None) for every periodic motion of the cell not tried yet: the
        motions of its own runs and the forward continuation's (certified before the pool in
        shared kernel calls, :func:`_precertify`)."""
        o = self.opts
        kn = cell.known
        for a, s in enumerate(kn.steadies):
            if a in cell.certs or kn.ambiguous[a] or s.period <= 0:
                continue
            cert, spent = None, 0
            if (eligible(s, self.history - 1)
                    and worth(cell.params, s, self.st, int(np.sum(cell.labels == -2)),
                              o.certify_radius, o.recur_period_rtol)):  # fmt: skip
                cert, spent = certify(cell.params, s, self.st, o.certify_radius,
                                      o.certify_tries, self.backend)  # fmt: skip
            cell.certs[a] = cert
            self.stats.certify_periods += spent
            if spent:
                self.stats.radii.append(None if cert is None else cert.r)

    def _certified(self, cell: _Cell, jobs: list[PoolJob]) -> np.ndarray:
        """Attractor each start is labelled onto by a certified ellipsoid (-1: none): one of
        its recorded section points inside it and the point one orbit period later inside
        and closer (module certify)."""
        out = np.full(len(jobs), -1, dtype=np.int64)
        if not self.opts.certified:
            return out
        self._certify(cell)
        kn = cell.known
        live = [(a, c) for a, c in cell.certs.items() if c is not None and not kn.ambiguous[a]]
        if not live:
            return out
        # the pairs ending in the last chunk (older ones were tested at earlier checks, or
        # predate the certificate: the start is tested again at its next check)
        tail = self.opts.chunk + max(c.n for _, c in live)
        hist = np.stack([j.hist[-tail:] for j in jobs])
        filled = np.minimum([j.filled for j in jobs], hist.shape[1])
        for a, c in live:
            ok = (out < 0) & c.confirmed(hist[:, -(self.opts.chunk + c.n):], filled)
            out[ok] = a
        return out

    def _hits(self, cell: _Cell, jobs: list[PoolJob]) -> np.ndarray:
        """Attractor each start is labelled onto (-1: none yet): certified first, then the
        recurrence rule."""
        hit = self._certified(cell, jobs)
        rec = self._recur(cell, jobs)
        self.stats.early_certified += int(np.sum(hit >= 0))
        self.stats.early_recurrence += int(np.sum((hit < 0) & (rec >= 0)))
        return np.where(hit >= 0, hit, rec)

    def _recur(self, cell: _Cell, jobs: list[PoolJob]) -> np.ndarray:
        out = np.full(len(jobs), -1, dtype=np.int64)
        if not cell.known.steadies:
            return out
        # only starts whose last point is near a known orbit can recur (a cheap first test)
        near = np.nonzero(cell.known.near(np.array([j.hist[-1] for j in jobs])))[0]
        if len(near):
            hist = np.stack([jobs[r].hist for r in near])
            filled = np.array([jobs[r].filled for r in near], dtype=np.int64)
            out[near] = cell.known.recur(hist, filled)
        return out

    def _label(self, cell: _Cell, j: PoolJob, a: int) -> None:
        i = j.key[1]
        cell.labels[i] = a
        cell.early[i] = True
        cell.periods[i] = j.probed
        if cell.runner is j:
            cell.runner = None

    def _release(self, cell: _Cell) -> None:
        """No runner: the parked starts are tested again at once, the rest resume."""
        if cell.runner is not None or not cell.parked:
            return
        parked, cell.parked = cell.parked, []
        hit = self._hits(cell, parked)
        rest = []
        for j, a in zip(parked, hit, strict=True):
            if a >= 0:
                self._label(cell, j, a)
                j.where, j.saved = "done", None
            else:
                rest.append(j)
        for j in rest:
            j.mark = j.probed  # a fresh patience
            if j.where == "wait":
                if cell.runner is None:
                    cell.runner = j
                    self.waiting.append(j)
                else:
                    cell.parked.append(j)
            else:
                self.ready.appendleft(j)


def _first_wave(neighbours: Sequence[Sequence[int]]) -> list[bool]:
    """The cells opened first: each cell in order joins unless a neighbour already did (on a
    grid every other cell), so that the rest find their neighbours' attractors known."""
    first = [False] * len(neighbours)
    for c, nbs in enumerate(neighbours):
        first[c] = not any(first[k] for k in nbs if k < c)
    return first


def _forward_margins(params_list, forward_results, st) -> None:
    """The Floquet margins of the plane rows' periodic motions in shared kernel calls, before
    the pool (the margins the finder's last step would take one by one at a certification;
    ``GearCells.fill_margins`` then finds them known)."""
    fill_orbit_margins(list(zip(params_list, forward_results, strict=True)), st)


def _precertify(cells: list[_Cell], forward_results, st, opts: FinderOptions, history: int,
                stats: PoolStats, orbits, backend=None) -> None:
    """The certificates of the cells' forward motions (one step grid) in shared kernel calls,
    before the pool: each seeds its cell from the first chunk (``_Cell.pre``)."""
    todo = [cell for cell in cells
            if (fr := forward_results[cell.c]) is not None and eligible(fr, history - 1)
            and worth(cell.params, fr, st, len(cell.starts), opts.certify_radius,
                      opts.recur_period_rtol)]  # fmt: skip
    if not todo:
        return
    got, spent = certify_many([(cell.params, forward_results[cell.c]) for cell in todo], st,
                              opts.certify_radius, opts.certify_tries,
                              [orbits[cell.c] for cell in todo], backend)  # fmt: skip
    stats.certify_periods += spent
    for cell, cert in zip(todo, got, strict=True):
        cell.pre = cert
        stats.radii.append(None if cert is None else cert.r)


def map_gear_cells(
    system: GearCells,
    starts: Sequence[np.ndarray],
    options: FinderOptions | None = None,
    *,
    continuation: Sequence[Mapping[str, np.ndarray | None]] | None = None,
    forward_results: Sequence[Steady | None] | None = None,
    stats: PoolStats | None = None,
    neighbours: Sequence[Sequence[int]] | None = None,
) -> list[CellAttractors]:
    """Coexisting attractors of the gear cells of ``system`` through one lane pool (module
    docstring): the :class:`~gearsim.analysis.attractors.mapper.AttractorMapper` signature,
    and per cell the already classified forward motion (``forward_results``) and the
    neighbouring cells (``neighbours``) of :func:`gearsim.analysis.attractors.find_attractors`."""
    params_list = system.params
    st = system.settings
    n = check_inputs(starts, continuation)
    if n != len(params_list):
        raise ParameterError("starts: one array of start states per cell expected")
    for name, seq in (("forward_results", forward_results), ("neighbours", neighbours)):
        if seq is not None and len(seq) != n:
            raise ParameterError(f"{name}: one entry per cell expected")  # fmt: skip
    forward = backward = None
    if continuation is not None:
        forward = [(m or {}).get("forward") for m in continuation]
        backward = [(m or {}).get("backward") for m in continuation]
    opts = (options or FinderOptions()).resolved(st.period_rtol)
    st_states = [np.atleast_2d(np.asarray(s, dtype=float)) for s in starts]
    history = max(opts.confirm_cloud, opts.confirm + st.n_max, 3 * st.n_max)
    if opts.early and opts.certified and forward_results is not None:
        _forward_margins(params_list, forward_results, st)
    seeds = orbits = None
    if opts.early and (opts.newton_seeds or opts.certified) and forward_results is not None:
        orbits = newton_orbits(list(zip(params_list, forward_results, strict=True)), st)
        if opts.newton_seeds:
            seeds = [o is not None for o in orbits]
    cells = [_Cell(c, p, st_states[c], opts) for c, p in enumerate(params_list)]
    order = cells
    if neighbours is not None and opts.early and opts.neighbour_seeds:
        first = _first_wave(neighbours)
        order = sorted(cells, key=lambda cell: (not first[cell.c], cell.c))
    groups: dict[tuple, list[_Cell]] = {}
    for cell in order:
        p = cell.params
        key = (steps_per_period(p, st), p.var_ratio_order if p.var_ratio != 0.0 else None)
        groups.setdefault(key, []).append(cell)
    stats = stats if stats is not None else PoolStats()
    for (N, nu), group in groups.items():
        if opts.early and opts.certified and forward_results is not None:
            _precertify(group, forward_results, st, opts, history, stats, orbits, system.backend)
        judge = _Judge(group, forward, backward, forward_results, st, opts, history,
                       opts.early, stats, seeds, neighbours, system.backend)  # fmt: skip
        run_pool(judge, st, N, nu, lanes=opts.lanes, chunk=opts.chunk, orbits=system.orbits,
                 stats=stats, backend=system.backend)  # fmt: skip
    for cell in cells:
        if np.any(cell.labels == -2) or cell.parked:
            raise RuntimeError("attractor pool ended with unlabelled starts")  # a bug, not input
        cell.cont.sort(key=lambda t: FOUND_BY.index(t[0]))
    found = assemble(opts, [c.starts for c in cells], [c.labels for c in cells],
                     [c.early for c in cells], [c.periods for c in cells],
                     [c.known for c in cells], [c.cont for c in cells])  # fmt: skip
    system.fill_margins(found)
    found = [least_periods(ca, opts.merge_rtol) for ca in found]
    return bounded_clouds(params_list, found, st, system.backend)
