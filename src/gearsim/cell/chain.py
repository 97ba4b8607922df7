"""The chain machine: one continuation chain of cells in one lane, the phases each cell moves
through, and the two drivers' one way to run a part of their chains and act on it.

A cell of a chain runs :func:`gearsim.cell.simulate.simulate_cell`'s plan in phases: the
transient without the tangent vector (:data:`TRANSIENT`), a recurrence probe of a continued cell
(:data:`PROBE`), the adaptive transient's checked windows (:data:`SETTLE`), the tangent vector's
lead (:data:`LEAD`), then measuring chunks (:data:`MEASURE`), each followed by the period test
and the verdict (:func:`decide`); a cell whose step budget cannot be met is not integrated
(:data:`BUDGET`). :func:`begin_cell` starts a chain's current cell, :func:`run_part` runs the
lanes of some chains on the lanes' backend until the next decision (where the backend can, the
measuring lanes take their verdict inside the call) and :func:`act` moves each chain on.

Both drivers use it: the plane rows' (:func:`gearsim.cell.chains.simulate_rows`) and the
attractor finder's lane pool (:func:`gearsim.cell.pool.run_pool`, whose jobs are one-cell
chains).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from gearsim.cell import simulate
from gearsim.cell.simulate import (
    CellResult,
    IntegrationSettings,
    diverged_result,
    finish_cell,
    initial_tangent,
    next_settle_check,
    period_of,
    recurrence_probe,
    seeds_continuation,
    settled_period,
)
from gearsim.cell.verdict import DONE, OVER_BUDGET, measure_verdict
from gearsim.cell.verify import OrbitCache
from gearsim.dynamics.model import N_STATE, static_state
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.numerics.backend import Part
from gearsim.numerics.batch import Lanes, steps_per_period
from gearsim.numerics.integrate import steps_lower_bound

# ---- the phases of a cell --------------------------------------------------------------------
TRANSIENT = 0
MEASURE = 1
LEAD = 2  # end of the transient with the tangent vector on (simulate_cell's tangent_lead)
BUDGET = 3  # the cell needs more steps than IntegrationSettings.max_steps: not integrated
PROBE = 4  # transient_recurrence: a continued cell's probe for recurrence, recorded
SETTLE = 5  # settle_check: the adaptive transient, tangent on and recorded
RECORDED = (MEASURE, PROBE, SETTLE)  # the phases whose periods are recorded

#: ``on_cell(chain index, cell index, result)``, called as a cell is done
OnCell = Callable[[int, int, CellResult], None] | None


@dataclass
class Chain:
    """One continuation chain (a plane row, or one start of the finder) and the progress of its
    current cell."""

    index: int
    cells: list[ModelParameters]
    u0: np.ndarray | None
    period0: int = 0  # start period of the first cell
    lane: int = -1
    i: int = 0  # current cell
    start: np.ndarray | None = None  # start state of the current cell (None: static)
    period: int = 0  # start period of the current cell
    N: int = 0
    h: float = 0.0  # RK4 step of the current cell
    nu: float | None = None  # variable-ratio order if the cell uses it
    phase: int = TRANSIENT
    left: int = 0  # periods to run before the next decision
    k: int = 0  # absolute period index now
    steps: int = 0
    measured: int = 0
    tangent0: np.ndarray | None = None  # initial tangent vector of the current cell
    lead: int = 0  # periods of tangent lead of the current cell
    transient: int = 0  # transient of the current cell (settle_check: the longest)
    results: list[CellResult] = field(default_factory=list)

    @property
    def finished(self) -> bool:
        return self.i >= len(self.cells)


@dataclass(frozen=True)
class Rules:
    """What a driver's chains do when a cell is done: ``continuation`` (the next cell starts
    from this one's final state), ``on_cell``, the Floquet option and the shared refined
    orbits of :func:`gearsim.cell.simulate.finish_cell`, and whether the end of a transient
    checks it (``settle``: the adaptive transient, ``settle_check``)."""

    continuation: bool = True
    on_cell: OnCell = None
    floquet: str = "slow"
    orbits: OrbitCache | None = None
    settle: bool = True


def window(st: IntegrationSettings) -> int:
    """The window of the adaptive transient's checks: the first measuring chunk's length."""
    return min(st.chunk, st.max_periods)


def records(st: IntegrationSettings) -> int:
    """Periods of records a lane keeps: the measured periods, or a longer recurrence probe
    (the adaptive transient keeps its last window plus one check interval)."""
    return max(st.max_periods, st.transient_recurrence, window(st) + st.settle_check)


# ---- the phases, begun ---------------------------------------------------------------------
def begin_cell(ch: Chain, lanes: Lanes, st: IntegrationSettings) -> None:
    """Load the chain's current cell into its lane and begin its first phase."""
    params = ch.cells[ch.i]
    if ch.start is None:
        y = static_state(params.to_array())
    else:
        y = np.asarray(ch.start, dtype=float)[:N_STATE]
    if y.shape != (N_STATE,) or not np.all(np.isfinite(y)):
        raise ParameterError("initial state 'u0' must be 10 finite numbers")
    transient = st.transient if ch.start is None else st.transient_continuation
    ch.k = ch.period
    ch.steps = 0
    if steps_lower_bound(params, st, transient + min(st.chunk, st.max_periods)) > st.max_steps:
        # finished by the driver with status 'budget' (no phase tables of its huge grid)
        ch.phase, ch.left, ch.N, ch.nu = BUDGET, 0, int(st.steps_per_period), None
        lanes.set_step(ch.lane, 0.0)
        return
    ch.N = steps_per_period(params, st)
    ch.h = params.mesh_period / ch.N
    ch.nu = params.var_ratio_order if params.var_ratio != 0.0 else None
    ch.measured = 0
    lanes.load_params(ch.lane, params, ch.N)
    ch.tangent0 = initial_tangent(params)
    lanes.load_state(ch.lane, np.concatenate([y, ch.tangent0]))
    ch.lead = min(st.tangent_lead, transient)
    ch.transient = transient
    probe = recurrence_probe(st, ch.start is not None, transient)
    if probe:
        # simulate_cell's probe: the tangent runs from the start, the periods are recorded
        ch.phase, ch.left = PROBE, probe
    else:
        begin_transient(ch, lanes, st, transient)


def begin_transient(ch: Chain, lanes: Lanes, st: IntegrationSettings, transient: int) -> None:
    if transient - ch.lead > 0:
        ch.phase = TRANSIENT
        ch.left = transient - ch.lead
    elif st.settle_check:
        begin_settle(ch, lanes, st)
    else:
        begin_lead(ch, lanes, st)


def begin_settle(ch: Chain, lanes: Lanes, st: IntegrationSettings) -> None:
    """The tangent vector starts (as :func:`begin_lead`); its lead is recorded and checked
    every ``settle_check`` periods (simulate_cell's adaptive transient)."""
    if ch.lead == 0:
        begin_lead(ch, lanes, st)  # no lead: nothing to check before the fixed plan
        return
    lanes.set_tangent(ch.lane, ch.tangent0)
    lanes.reset_modes(ch.lane)
    done = ch.k - ch.period
    ch.phase, ch.measured = SETTLE, 0
    ch.left = next_settle_check(done, st, ch.transient, window(st)) - done


def begin_lead(ch: Chain, lanes: Lanes, st: IntegrationSettings) -> None:
    """The tangent vector starts; it aligns over ``ch.lead`` periods before measuring."""
    lanes.set_tangent(ch.lane, ch.tangent0)
    lanes.reset_modes(ch.lane)
    if ch.lead > 0:
        ch.phase = LEAD
        ch.left = ch.lead
    else:
        begin_measure(ch, lanes, st)


def begin_measure(ch: Chain, lanes: Lanes, st: IntegrationSettings) -> None:
    ch.phase = MEASURE
    ch.measured = 0
    if ch.lead > 0:
        lanes.reset_modes(ch.lane)  # a new run_periods call in simulate_cell
    ch.left = min(st.chunk, st.max_periods)


# ---- a part of the chains, run -------------------------------------------------------------
def _device_verdict():
    """The lane kernel that takes :func:`decide`'s verdict inside a GPU thread (made only by a
    backend that runs one)."""
    from gearsim.cell.device_chains import chain_kernel

    return chain_kernel


def run_part(chains: list[Chain], lanes: Lanes, st: IntegrationSettings, N: int,
             nu: float | None, bound: float, tangent: bool) -> tuple[int, np.ndarray]:
    """Run the enrolled lanes of ``chains`` (status 0) on the lanes' backend until the next
    decision, and count what each ran into its chain; returns the periods run and, per lane,
    the period a verdict taken inside the call stopped it with (-1: none)."""
    part = Part.empty(lanes.size, verdict=_device_verdict,
                      test=(st.chunk, st.max_periods, st.n_max, st.period_rtol, st.max_steps))
    for c in chains:
        part.left[c.lane] = c.left
        part.measuring[c.lane] = c.phase == MEASURE
        part.measured[c.lane] = c.measured
        part.steps[c.lane] = c.steps
    m = lanes.run_part(N, 0.0 if nu is None else nu, bound, tangent, part)
    for c in chains:
        done = int(lanes.done[c.lane])
        c.k += done
        c.steps += int(lanes.steps[c.lane])
        c.left = int(part.left[c.lane])
        if c.phase in RECORDED:
            c.measured += done
    return m, part.period


def act(c: Chain, lanes: Lanes, st: IntegrationSettings, rules: Rules, period: int = -1
        ) -> None:
    """After a part: the chain's cell diverged, was stopped by a verdict taken inside the call
    (``period``), or reached its next decision (its next phase, or :func:`decide`)."""
    if lanes.status[c.lane] != 0:
        # diverged (during the transient or a chunk): simulate_cell's diverged record
        finish(c, diverged_result(c.cells[c.i], c.k, c.steps), lanes, st, rules)
    elif period >= 0:
        decide(c, lanes, st, rules, n=period)
    elif c.left == 0:
        if c.phase == BUDGET:
            finish(c, diverged_result(c.cells[c.i], c.k, 0, status="budget"), lanes, st, rules)
        elif c.phase == TRANSIENT:
            (begin_settle if rules.settle and st.settle_check else begin_lead)(c, lanes, st)
        elif c.phase == LEAD:
            begin_measure(c, lanes, st)
        elif c.phase == PROBE:
            end_probe(c, lanes, st)
        elif c.phase == SETTLE:
            settle_check(c, lanes, st, rules)
        else:
            decide(c, lanes, st, rules)


# ---- the decisions -------------------------------------------------------------------------
def end_probe(ch: Chain, lanes: Lanes, st: IntegrationSettings) -> None:
    """After the recurrence probe: measure at once if the start recurred, else restart the cell
    from its start state with the plan without the probe (as simulate_cell does)."""
    params = ch.cells[ch.i]
    recurs = period_of(lanes.summaries(ch.lane, ch.measured, copy=False), params, st) > 0
    ch.measured = 0
    if recurs:
        ch.lead = 0
        lanes.reset_modes(ch.lane)  # a new run_periods call in simulate_cell
        begin_measure(ch, lanes, st)
    else:
        y = np.asarray(ch.start, dtype=float)[:N_STATE]
        lanes.load_state(ch.lane, np.concatenate([y, ch.tangent0]))
        ch.k = ch.period
        begin_transient(ch, lanes, st, st.transient_continuation)


def settle_check(ch: Chain, lanes: Lanes, st: IntegrationSettings, rules: Rules) -> None:
    """A check of the adaptive transient (simulate_cell's): finish when the last window is
    settled; at the end of the transient that window is the first measuring chunk."""
    params = ch.cells[ch.i]
    w = window(st)
    done = ch.k - ch.period
    if done >= ch.transient + w:
        keep_last(lanes, ch.lane, ch.measured, w)
        ch.phase, ch.measured = MEASURE, w
        decide(ch, lanes, st, rules)
        return
    s = lanes.summaries(ch.lane, ch.measured, copy=False).tail(min(w, simulate.EARLY_WINDOW))
    n = settled_period(s, params, st)
    if n > 0:
        y = lanes.state(ch.lane, N_STATE)
        res = finish_cell(params, s, n, st, y, ch.k, ch.period, ch.steps, rules.floquet,
                          rules.orbits)
        finish(ch, res, lanes, st, rules)
        return
    lanes.reset_modes(ch.lane)  # a new run_periods call in simulate_cell
    ch.left = next_settle_check(done, st, ch.transient, w) - done
    if ch.measured + ch.left > lanes.sec.shape[1]:
        keep_last(lanes, ch.lane, ch.measured, w)
        ch.measured = w


def keep_last(lanes: Lanes, lane: int, measured: int, w: int) -> None:
    """Move the last ``w`` of the ``measured`` records of ``lane`` to the front."""
    if measured > w:
        for a in (lanes.sec, lanes.nface, lanes.nback, lanes.fout):
            a[lane, :w] = a[lane, measured - w : measured].copy()


def decide(ch: Chain, lanes: Lanes, st: IntegrationSettings, rules: Rules,
           n: int | None = None) -> None:
    """After a measuring chunk: the period test of simulate_cell (``n``: its result where a
    verdict was taken inside the call), then finish or go on (:func:`measure_verdict`)."""
    params = ch.cells[ch.i]
    s = lanes.summaries(ch.lane, ch.measured, copy=False)  # read before the lane moves on
    if n is None:
        n = period_of(s, params, st)
    verdict = measure_verdict(n, ch.measured, st.max_periods, ch.steps, st.max_steps)
    if verdict == DONE:
        y = lanes.state(ch.lane, N_STATE)
        res = finish_cell(params, s, n, st, y, ch.k, ch.period, ch.steps, rules.floquet,
                          rules.orbits)
        finish(ch, res, lanes, st, rules)
    elif verdict == OVER_BUDGET:
        res = diverged_result(params, ch.k, ch.steps, status="budget")
        finish(ch, res, lanes, st, rules)
    else:
        lanes.reset_modes(ch.lane)
        ch.left = min(st.chunk, st.max_periods - ch.measured)


def finish(ch: Chain, res: CellResult, lanes: Lanes, st: IntegrationSettings,
           rules: Rules) -> None:
    """The chain's current cell is ``res``; the chain moves on to its next cell (from this
    one's final state under ``rules.continuation``) or, at its end, frees its lane."""
    ch.results.append(res)
    if rules.on_cell is not None:
        rules.on_cell(ch.index, ch.i, res)
    if rules.continuation and seeds_continuation(res):
        ch.start, ch.period = res.final_state, res.final_period
    else:
        ch.start, ch.period = ch.u0, 0
    ch.i += 1
    if ch.finished:
        lanes.freeze(ch.lane)
        return
    begin_cell(ch, lanes, st)
