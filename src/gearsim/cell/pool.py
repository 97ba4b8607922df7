"""The lane pool: full-length runs of one step grid in SIMD lanes refilled from a judge (the
attractor finder), each run exactly :func:`gearsim.cell.simulate.simulate_cell` from its start,
whose transient the judge may cut short or pause.

The phases of a run are those of the chain machine (:mod:`gearsim.cell.chain`): a job is a
one-cell chain there.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from gearsim.cell import chain
from gearsim.cell.chain import Chain, Rules
from gearsim.cell.simulate import (
    CellResult,
    IntegrationSettings,
    diverged_result,
    initial_tangent,
    recurrence_probe,
)
from gearsim.cell.verify import OrbitCache
from gearsim.dynamics.model import N_STATE, pack_parameters
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.numerics.backend import CPU, CpuLanes
from gearsim.numerics.batch import LANES, Lanes
from gearsim.numerics.integrate import steps_lower_bound

#: what a pool's judge answers for a probing job after each chunk of its transient
GO, STOP, PARK = "go", "stop", "park"
#: ... and at the end of its transient
MEASURE = "measure"


@dataclass(eq=False)
class PoolJob:
    """One full-length run in a :func:`run_pool`: ``simulate_cell(params, u0,
    transient=transient, start_period=period0)``, whose transient the judge may cut short (the
    job is labelled by the caller: :data:`STOP`) or pause (:data:`PARK`: state kept, lane
    freed; the judge hands the job back to resume it exactly where it stopped).

    ``where``: ``"new"`` (not yet loaded), ``"probe"`` (in its transient), ``"wait"``
    (transient over, not yet measuring), ``"measure"`` (lead and measurement), ``"done"``.
    ``hist[-filled:]`` are the last section states (10 entries each) of the transient (oldest
    first), ``probed`` the transient periods run; ``result`` the full-length result (a
    diverged record for a start that diverged while probing).
    """

    key: Any
    params: ModelParameters
    u0: np.ndarray
    transient: int
    probe: bool = True  # record the transient's section points and ask the judge every chunk
    period0: int = 0
    history: int = 32  # points kept in hist
    where: str = "new"
    probed: int = 0
    rest: int = 0  # transient periods left after the probing chunks (run before the lead)
    mark: int = 0  # the judge's: probed periods when it last (re)started the job
    filled: int = 0
    hist: np.ndarray | None = None
    state: np.ndarray | None = None  # the section state (10) when last shown to the judge
    result: CellResult | None = None
    ch: Chain | None = field(default=None, repr=False)
    saved: np.ndarray | None = field(default=None, repr=False)


class PoolJudge(Protocol):
    """What :func:`run_pool` asks its caller (the attractor finder)."""

    def take(self, n: int) -> list[PoolJob]:
        """Up to ``n`` jobs to (re)load into probe lanes, plus any number of ``"wait"`` jobs to
        measure (all of the pool's step grid); [] when there is nothing to load now."""
        ...

    def probed(self, jobs: list[PoolJob]) -> list[str]:
        """After a chunk of their transients: :data:`GO`, :data:`STOP` or :data:`PARK` each."""
        ...

    def transient_over(self, job: PoolJob) -> str:
        """An unlabelled job at the end of its transient: :data:`MEASURE` or :data:`PARK`."""
        ...

    def finished(self, job: PoolJob) -> None:
        """``job.result`` is set (its full-length run, or a diverged record)."""
        ...


@dataclass
class PoolStats:
    """Lane use of a pool: lane-periods integrated by running lanes / lane-periods the kernel
    computed (every lane of a block with a running lane costs the same)."""

    useful: int = 0
    computed: int = 0
    calls: int = 0
    periods: int = 0  # job periods integrated (probe + measure)
    steps: int = 0  # lane-steps the kernel computed (blocks x LANES x steps of each call)
    kernel_cpu_s: float = 0.0  # CPU time inside the kernel calls
    parked: int = 0  # times a job was parked
    certify_periods: int = 0  # lane-periods integrated to certify orbits' neighbourhoods
    radii: list = field(default_factory=list)  # certified radii (None: no radius passed)
    early_certified: int = 0  # starts labelled inside a certified ellipsoid
    early_recurrence: int = 0  # starts labelled by recurrence
    seeds_tried: int = 0  # neighbouring cells' motions continued by Newton into a cell
    seeds_run: int = 0  # ... converged there as an orbit the cell did not know (a seed run)
    seeds_confirmed: int = 0  # ... whose run confirmed the orbit (a recurrence target)
    seed_periods: int = 0  # lane-periods of the seeds' runs

    @property
    def lane_use(self) -> float:
        return self.useful / self.computed if self.computed else float("nan")


class _Pool:
    """Lanes of one step grid with a job per occupied lane, and the last ``history`` section
    states of every lane (probing pool)."""

    def __init__(self, capacity: int, records: int, history: int = 0,
                 backend: CpuLanes | None = None):
        self.records = records
        self.history = history
        self.lanes = Lanes(max(1, capacity), records, backend)
        self.jobs: list[PoolJob | None] = [None] * self.lanes.size
        self.hist = np.full((self.lanes.size, history, N_STATE), np.nan)

    def free(self) -> int:
        return sum(j is None for j in self.jobs)

    def occupied(self) -> list[PoolJob]:
        return [j for j in self.jobs if j is not None]

    def ensure(self, n: int) -> None:
        """Room for ``n`` more jobs."""
        if self.free() < n:
            self._resize(len(self.occupied()) + n)

    def put(self, job: PoolJob) -> int:
        if None not in self.jobs:
            self._resize(len(self.occupied()) + LANES)
        l = self.jobs.index(None)
        self.jobs[l] = job
        job.ch.lane = l
        return l

    def release(self, job: PoolJob) -> None:
        l = job.ch.lane
        self.jobs[l] = None
        self.lanes.freeze(l)

    def column(self, job: PoolJob) -> np.ndarray:
        return self.lanes.column(job.ch.lane)

    def restore(self, job: PoolJob, col: np.ndarray) -> None:
        self.lanes.restore(job.ch.lane, col)

    def pack(self) -> None:
        """Fewer blocks when the occupied lanes fit in them (the kernel steps every block)."""
        occ = self.occupied()
        if len(occ) <= (self.lanes.n_blocks - 1) * LANES:
            self._resize(len(occ))

    def _resize(self, n: int) -> None:
        occ = [j for j in self.jobs if j is not None]
        new = Lanes(max(n, len(occ), 1), self.records, self.lanes.backend)
        hist = np.full((new.size, self.history, N_STATE), np.nan)
        if occ:
            old = np.array([j.ch.lane for j in occ], dtype=np.int64)
            idx = np.arange(len(occ))
            new.gather(self.lanes, old)
            hist[idx] = self.hist[old]
            for j, l in zip(occ, idx, strict=True):
                j.ch.lane = int(l)
        self.lanes, self.hist = new, hist
        self.jobs = [None] * new.size
        for j in occ:
            self.jobs[j.ch.lane] = j

    def run(self, jobs: list[PoolJob], m: int, N: int, nu, bound: float, tangent: bool,
            record_transient: bool, stats: PoolStats, st: IntegrationSettings | None = None
            ) -> tuple[int, np.ndarray | None]:
        """Advance the lanes of ``jobs`` (all occupied lanes) ``m`` periods; with ``st``, as one
        part of their chains (:func:`gearsim.cell.chain.run_part`: on a backend that can, the
        measuring lanes take their verdicts inside the call, and the part's own periods run).
        Returns the periods run and, with ``st``, each lane's verdict period (-1: none)."""
        lanes = self.lanes
        lanes.begin_call()
        idx = np.array([j.ch.lane for j in jobs], dtype=np.int64)
        lanes.status[idx] = 0
        lanes.position[idx] = [j.ch.measured if j.ch.phase == chain.MEASURE
                               else 0 if record_transient else -1 for j in jobs]  # fmt: skip
        lanes.period[idx] = [j.ch.k for j in jobs]
        t0 = time.process_time()
        period = None
        if st is not None:
            m, period = chain.run_part([j.ch for j in jobs], lanes, st, N, nu, bound, tangent)
        else:
            lanes.run(N, m, 0.0 if nu is None else nu, bound, tangent)
        stats.kernel_cpu_s += time.process_time() - t0
        computed = self.lanes.n_blocks * LANES * m  # the kernel steps every block
        stats.computed += computed
        stats.steps += computed * N
        stats.calls += 1
        done = lanes.done[idx].tolist()
        stats.useful += sum(done)
        stats.periods += sum(done)
        if st is None:
            for j, d, n in zip(jobs, done, lanes.steps[idx].tolist(), strict=True):
                c = j.ch
                c.k += d
                c.left -= d
                c.steps += n
        if self.history:
            # the last section states of every lane, oldest first
            h, k = self.hist, min(m, self.history)
            h[:, : self.history - k] = h[:, k:]
            h[:, -k:] = self.lanes.sec[:, m - k : m]
        return m, period


def run_pool(
    judge: PoolJudge,
    settings: IntegrationSettings,
    N: int,
    nu: float | None,
    *,
    lanes: int = 256,
    chunk: int = 8,
    floquet: str = "slow",
    orbits: OrbitCache | None = None,
    stats: PoolStats | None = None,
    backend: CpuLanes | None = None,
) -> PoolStats:
    """Run full-length runs of one step grid (``N`` RK4 steps per period, variable-ratio order
    ``nu``) in a pool of SIMD lanes refilled from ``judge`` until it has no job left.

    Every job is exactly its full-length run (:func:`gearsim.cell.simulate.simulate_cell` from
    its start state with its transient; the phases and the tail of :func:`simulate_rows`:
    the transient without the tangent vector, then the tangent lead, measuring chunks, the
    period test and :func:`gearsim.cell.simulate.finish_cell`). Probing jobs record the
    section points of their transient and are shown to the judge every ``chunk`` periods; a
    job it labels (:data:`STOP`) frees its lane at once, a parked one is kept with its state
    (lane column) and resumes bit for bit when the judge hands it back. Lanes that measure
    (tangent on) are a second, smaller pool, so the probes never integrate a tangent vector.
    ``backend``: where the lanes run (default the CPU; a GPU's probing pool is as wide as it
    holds, :meth:`~gearsim.numerics.backend.CpuLanes.pool_lanes`).
    """
    st = settings
    backend = backend or CPU
    lanes = backend.pool_lanes(lanes)  # a GPU's width: the starts fill it (the CPU's: lanes)
    rules = Rules(continuation=False, floquet=floquet, orbits=orbits, settle=False)
    if recurrence_probe(st, True, st.transient):
        raise ParameterError("the lane pool needs integration.transient_recurrence = 0")
    bound = float(getattr(st, "divergence_bound", 1.0e6))
    stats = stats or PoolStats()
    history = 0
    probe: _Pool | None = None
    meas = _Pool(LANES, max(st.max_periods, 1), backend=backend)
    packed: dict[int, tuple[ModelParameters, np.ndarray]] = {}  # id(params) -> packed
    tangents: dict[int, tuple[ModelParameters, np.ndarray]] = {}  # id(params) -> tangent0

    def load_new(pool: _Pool, job: PoolJob, y: np.ndarray) -> None:
        p = job.params
        pk = packed.get(id(p))
        if pk is None:
            pk = packed[id(p)] = (p, pack_parameters(p))
        l = job.ch.lane
        pool.lanes.load_packed(l, pk[1], job.ch.h)
        pool.lanes.load_state(l, np.concatenate([y, job.ch.tangent0]))

    def load(job: PoolJob) -> None:
        if job.where == "new":
            p = job.params
            if steps_lower_bound(p, st, job.transient + min(st.chunk, st.max_periods)) \
                    > st.max_steps:
                job.where = "done"
                job.result = diverged_result(p, job.period0, 0, status="budget")
                judge.finished(job)
                return
            y = np.asarray(job.u0, dtype=float)[:N_STATE]
            if y.shape != (N_STATE,) or not np.all(np.isfinite(y)):
                raise ParameterError("initial state 'u0' must be 10 finite numbers")
            c = Chain(index=0, cells=[p], u0=y, period0=job.period0)
            c.start, c.period, c.k, c.N, c.h, c.nu = y, job.period0, job.period0, N, \
                p.mesh_period / N, nu
            tg = tangents.get(id(p))
            if tg is None:  # the starts of a cell share their parameters and tangent
                tg = tangents[id(p)] = (p, initial_tangent(p))
            c.tangent0 = tg[1]
            c.lead = min(st.tangent_lead, job.transient)
            # the probe pool runs whole chunks (its lanes stay in step); the rest of the
            # transient runs in the measuring pool before the lead
            c.phase, c.left = chain.TRANSIENT, (job.transient - c.lead) // chunk * chunk
            job.rest = job.transient - c.lead - c.left
            job.ch = c
            job.hist = None
            if c.left <= 0:
                job.where = "wait"
                job.saved = None
            else:
                job.where = "probe"
                probe.put(job)
                load_new(probe, job, y)
                probe.hist[c.lane] = np.nan
                return
        if job.where == "probe":
            probe.put(job)
            probe.restore(job, job.saved)
            probe.hist[job.ch.lane] = job.hist
            job.saved = None
        elif job.where == "wait":
            c = job.ch
            meas.put(job)
            if job.saved is None:  # nothing run yet
                load_new(meas, job, c.start)
            else:
                meas.restore(job, job.saved)
            job.saved = None
            job.where = "measure"
            c.measured = 0
            if job.rest > 0:
                c.phase, c.left = chain.TRANSIENT, job.rest
            else:
                chain.begin_lead(c, meas.lanes, st)

    def park(pool: _Pool, job: PoolJob) -> None:
        stats.parked += 1
        job.saved = pool.column(job)
        if pool is probe:
            job.hist = pool.hist[job.ch.lane].copy()
        pool.release(job)

    def end(pool: _Pool, job: PoolJob, res: CellResult) -> None:
        pool.release(job)
        job.where = "done"
        job.result = res
        judge.finished(job)

    while True:
        new = judge.take(max(0, lanes - (len(probe.occupied()) if probe else 0)))
        if probe is None:
            history = max([j.history for j in new if j.probe], default=0)
            probe = _Pool(lanes, chunk, history, backend)
        probe.ensure(sum(j.where in ("new", "probe") for j in new))
        meas.ensure(sum(j.where == "wait" for j in new))
        for job in new:
            load(job)
        if not probe.occupied() and not meas.occupied():
            if new:
                continue
            break
        jobs = probe.occupied()
        if jobs:
            probe.pack()
            m = min(chunk, min(j.ch.left for j in jobs))
            probe.run(jobs, m, N, nu, bound, False, True, stats)
            ready = []
            status = probe.lanes.status
            for j in jobs:
                c = j.ch
                if status[c.lane] != 0:
                    end(probe, j, diverged_result(j.params, c.k, c.steps))
                    continue
                j.probed += m
                if j.probe:
                    j.hist = probe.hist[c.lane]  # a view: valid until the next call
                    j.filled = min(j.filled + m, j.history)
                if c.left == 0 or (j.probe and j.probed % chunk == 0):
                    ready.append(j)
            checks = [j for j in ready if j.probe]
            for j in checks:
                j.state = probe.lanes.state(j.ch.lane, N_STATE)
            verdict = dict(zip(checks, judge.probed(checks), strict=True)) if checks else {}
            for j in ready:
                v = verdict.get(j, GO)
                if v == STOP:
                    probe.release(j)
                    j.where = "done"
                    continue
                if v == GO and j.ch.left == 0:
                    v = judge.transient_over(j)
                    if v == MEASURE:
                        col = probe.column(j)
                        probe.release(j)
                        j.where, j.saved = "wait", col
                        meas.ensure(1)
                        load(j)
                        continue
                if v == PARK:
                    if j.ch.left == 0:
                        j.where = "wait"  # transient over: it resumes with its lead
                    park(probe, j)
        jobs = meas.occupied()
        if jobs:
            meas.pack()
            jobs = meas.occupied()
            m = min(j.ch.left for j in jobs)
            _, period = meas.run(jobs, m, N, nu, bound, True, False, stats, st)
            for j in jobs:
                c = j.ch
                chain.act(c, meas.lanes, st, rules, int(period[c.lane]))
                if c.results:  # classified, diverged or over the step budget: the run is over
                    end(meas, j, c.results[0])
    return stats
