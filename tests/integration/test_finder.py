"""The lane-pool attractor finder (gearsim.analysis.attractors.pool, gearsim.cell.pool.run_pool).

- A job of the pool is its full-length run: parked and resumed at every chunk, a start gives
  the result of ``chains.simulate_cells`` from it, section points bit for bit.
- The pool's early labels are the attractors of the full-length runs of every start (the
  recurrence mapper ``map_attractors`` with ``early=False``) on gear cells with 1-3 attractors,
  chaos included, with starts parked and resumed on the way.
- A plane tile's row of a cell is a known attractor equal to its own run's.
"""

import numpy as np
from attractor_checks import GEAR, REFERENCE, assert_same_attractors_per_start, reference_attractors

from gearsim.analysis import attractors as ref
from gearsim.analysis.attractors import (
    FinderOptions,
    find_attractors,
    gear_steady,
    same_attractor,
    steady_from_row,
)
from gearsim.cell import chains
from gearsim.cell.pool import MEASURE, PARK, PoolJob, PoolStats, run_pool
from gearsim.dynamics.parameters import ModelParameters
from gearsim.numerics.batch import steps_per_period

CELLS = [
    ModelParameters(w=1.1, b=0.15, **REFERENCE),  # 2-2-1 and 3-3-2
    ModelParameters(w=0.82, b=0.15, **REFERENCE),
    ModelParameters(w=1.5, b=1.0, **REFERENCE),
    ModelParameters(w=0.66, b=1.0, **REFERENCE),  # the softening fold: two attractors
    ModelParameters(w=1.45, b=1.0, **REFERENCE),  # chaos and a 2-1-1
    ModelParameters(w=1.95, b=0.3, **REFERENCE),
]


class _ParkEveryChunk:
    """Parks every job at every check and hands it back at once (worst case of the pool)."""

    def __init__(self, jobs):
        self.queue = list(jobs)
        self.parked: list[PoolJob] = []
        self.done: list[PoolJob] = []
        self.waited: set[int] = set()

    def take(self, n):
        self.queue += self.parked
        self.parked = []
        out = [j for j in self.queue if j.where != "wait"][:n]
        out += [j for j in self.queue if j.where == "wait"]
        self.queue = [j for j in self.queue if j not in out]
        return out

    def probed(self, jobs):
        self.parked += jobs
        return [PARK] * len(jobs)

    def transient_over(self, job):
        if job.key % 2 and job.key not in self.waited:  # every other job waits once more
            self.waited.add(job.key)
            self.parked.append(job)
            return PARK
        return MEASURE

    def finished(self, job):
        self.done.append(job)


def test_parked_jobs_are_their_full_length_runs_bit_for_bit():
    p = ModelParameters(w=1.1, b=0.15, **REFERENCE)
    cells = [p, p.with_(w=1.12), p.with_(w=1.45, b=1.0)]
    N = steps_per_period(p, GEAR)
    assert all(steps_per_period(c, GEAR) == N for c in cells)
    unit = ref.sobol_unit(4, 3)
    sys_ = ref.GearCells(cells, GEAR)
    jobs, want = [], []
    for c, q in enumerate(cells):
        for y in sys_.start_states(c, unit):
            jobs.append(PoolJob(key=len(jobs), params=q, u0=y, transient=GEAR.transient))
            want.append((q, y))
    judge = _ParkEveryChunk(jobs)
    stats = run_pool(judge, GEAR, N, None, lanes=8, chunk=8)
    assert stats.parked > len(jobs) * 10
    assert len(judge.done) == len(jobs)
    # a start's full-length run: simulate_cell from it with the transient of a start
    ref_res = chains.simulate_cells([q for q, _ in want],
                                    settings=GEAR.with_(transient_continuation=GEAR.transient),
                                    u0=[y for _, y in want])  # fmt: skip
    for j in jobs:
        a, b = j.result, ref_res[j.key]
        assert a.classification.label == b.classification.label
        assert a.classification.status == b.classification.status
        assert np.array_equal(a.poincare, b.poincare)
        assert np.array_equal(a.final_state, b.final_state)
        assert a.periods == b.periods and a.steps == b.steps


def test_pool_labels_equal_full_length_runs_of_every_start():
    stats = PoolStats()
    opts = FinderOptions(starts=24, seed=7)
    fast = find_attractors(CELLS, opts.with_(lanes=64), settings=GEAR, stats=stats)
    full = reference_attractors(CELLS, opts.with_(early=False), GEAR)
    n_early = assert_same_attractors_per_start(fast, full)
    assert n_early >= 0.5 * 24 * len(CELLS)
    assert stats.parked > 0  # starts were parked while a runner of their cell ran
    assert 0.0 < stats.lane_use <= 1.0
    assert any(len(a.attractors) >= 2 for a in fast)


def test_pool_without_early_labels_equals_the_reference_full_runs():
    opts = FinderOptions(starts=8, seed=2, early=False)
    fast = find_attractors(CELLS[:3], opts, settings=GEAR)
    full = reference_attractors(CELLS[:3], opts, GEAR)
    for a, b in zip(fast, full, strict=True):
        assert not a.early.any()
        assert np.array_equal(a.start_labels, b.start_labels)
        assert [x.label for x in a.attractors] == [x.label for x in b.attractors]
        for x, y in zip(a.attractors, b.attractors, strict=True):
            assert np.array_equal(x.points, y.points)


def test_tile_row_is_a_known_attractor():
    """The forward motion read from a plane tile's row equals the motion of its own run, and
    the finder counts it as found by the forward continuation without running it."""
    row = [CELLS[0].with_(w=w) for w in (1.08, 1.09, 1.1)]
    res = chains.simulate_rows([row], settings=GEAR)[0]
    r = res[-1]
    rec = r.row()
    rec.update(poincare_x=r.poincare[:, 0].tolist(), poincare_v=r.poincare[:, 1].tolist(),
               final_state=r.final_state.tolist())  # fmt: skip
    s = steady_from_row(rec, row[-1].w)
    g = gear_steady(r)
    assert s.period == g.period and s.label == g.label
    assert np.array_equal(s.points, g.points[:, :2])
    assert same_attractor(s, g)
    (ca,) = find_attractors([row[-1]], FinderOptions(starts=8, seed=1), settings=GEAR,
                            forward=[r.final_state], forward_results=[s])  # fmt: skip
    k = ca.continuation["forward"]
    assert "forward" in ca.attractors[k].found_by
    assert ca.attractors[k].steady is s  # taken as it is: no run of the forward state


def test_continuation_reading_is_no_recurrence_target():
    """At w = 1.99, b = 0.375 (the study's standard set) the forward chain reads 1/5T after
    its continuation transient, while every start's full-length run ends on 1/1T: starts
    turning about the 1/1T motion match the 1/5T points and must not be labelled onto it."""
    from gearsim.study.config import Study

    base, st = Study.load().parameters().model, Study.load().settings
    ws = 0.1 + (np.arange(100) + 0.5) * 2.4 / 100
    chain = [base.with_(w=float(w), b=0.375) for w in ws]
    res = chains.simulate_rows([chain], settings=st)[0]
    pick = [78, 97]
    cells = [chain[i] for i in pick]
    known = [gear_steady(res[i]) for i in pick]
    opts = FinderOptions(starts=16, seed=0)
    fast = find_attractors(cells, opts, settings=st, forward_results=known)
    full = reference_attractors(cells, opts.with_(early=False), st)
    for a, b in zip(fast, full, strict=True):
        got = sorted((x.label, x.n_starts) for x in a.attractors if x.n_starts)
        assert got == sorted((x.label, x.n_starts) for x in b.attractors if x.n_starts)


def test_every_periodic_attractor_carries_the_floquet_margin_of_its_orbit():
    """A periodic attractor's ``mu_max`` is its orbit's largest multiplier modulus: the one
    orbit solver (``gearsim orbit``'s), run from the attractor's state on the same RK4 map,
    gives the same value; the accurate DP5 shooting differs by the RK4 map's own error at the
    study's steps (here up to 2.1e-5, at w = 0.66; 1.9e-6 for the 3T orbit at w = 1.1;
    docs/decisions.md), far below the distance between distinct orbits' margins."""
    from gearsim.analysis.orbits import find_periodic_orbit

    found = find_attractors(CELLS, FinderOptions(starts=8, seed=5), settings=GEAR)
    checked = 0
    for p, ca in zip(CELLS, found, strict=True):
        for a in ca.attractors:
            s = a.steady
            if s.period == 0 or s.status != "ok" or s.info.get("status") != "ok":
                continue
            mu = s.info["mu_max"]
            assert mu is not None and 0.0 < mu < 1.0, (p.w, a.label, mu)
            n = int(s.period)
            same_map = find_periodic_orbit(p, n, s.final_state, GEAR, grazing=False)
            assert abs(same_map.mu_max - mu) < 1e-7, (p.w, a.label, mu, same_map.mu_max)
            flow = find_periodic_orbit(p, n, s.final_state, grazing=False)
            assert abs(flow.mu_max - mu) < 1e-4, (p.w, mu, flow.mu_max)
            checked += 1
    assert checked >= len(CELLS)


def test_no_copy_of_an_orbit_at_its_doubling():
    """w = 1.423, xi = 0.07015 (the study's wxi plane, xi index 100 of 400): 14 starts end on
    the refined 1/4T orbit at its period doubling (|mu|max 0.99984), 2 on a 1/8T reading of
    its undecayed alternation (no margin of its own): one attractor, period 4, all 16 starts."""
    from gearsim.study.config import Study

    study = Study.load()
    p = study.parameters().model.with_(w=1.423, xi=0.07015)
    ca = find_attractors(p, FinderOptions(starts=16, seed=0), settings=study.settings)
    assert [(a.steady.period, a.n_starts) for a in ca.attractors] == [(4, 16)]
    assert ca.attractors[0].steady.info["critical"] == "period_doubling"
