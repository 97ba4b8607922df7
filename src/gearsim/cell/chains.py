"""Continuation chains on the batched kernel: many cells as SIMD lanes, each lane moving on to its
next cell on its own schedule.

:func:`simulate_rows` is :func:`gearsim.cell.sweep.continuation_chain` for many chains at once, with
the early-stopping logic of :func:`gearsim.cell.simulate.simulate_cell` per lane (transient, chunks,
period test after each chunk, classification by :func:`gearsim.cell.simulate.finish_cell`), then
the long runs of :func:`gearsim.cell.growth.check_growth` in shared kernel calls.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from gearsim.cell import simulate
from gearsim.cell.classify import repeats_throughout
from gearsim.cell.growth import check_growth
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
from gearsim.numerics import kernel as plan_rows  # the PLAN_* rows of a GPU launch
from gearsim.numerics.batch import (
    LANES,
    Lanes,
    steps_per_period,
)
from gearsim.numerics.integrate import steps_lower_bound

# ============================================================================ the driver
_TRANSIENT = 0
_LEAD = 2  # end of the transient with the tangent vector on (simulate_cell's tangent_lead)
_BUDGET = 3  # the cell needs more steps than IntegrationSettings.max_steps: not integrated
_MEASURE = 1
_PROBE = 4  # transient_recurrence: a continued cell's probe for recurrence, recorded
_SETTLE = 5  # settle_check: the adaptive transient, tangent on and recorded
_RECORDED = (_MEASURE, _PROBE, _SETTLE)


@dataclass
class _Chain:
    """One continuation chain (a plane row) and the progress of its current cell."""

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
    phase: int = _TRANSIENT
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


def simulate_rows(
    rows: Sequence[Sequence[ModelParameters]],
    *,
    settings: IntegrationSettings | None = None,
    continuation: bool = True,
    u0: np.ndarray | Sequence[np.ndarray | None] | None = None,
    on_cell: Callable[[int, int, CellResult], None] | None = None,
    start_periods: Sequence[int] | None = None,
    floquet: str = "slow",
    orbits: OrbitCache | None = None,
) -> list[list[CellResult]]:
    """Simulate many continuation chains at once with the batched RK4 kernel.

    ``simulate_rows(rows)[r]`` equals ``continuation_chain(rows[r], settings=rk4_settings)``
    (same early stopping, same classification, summaries equal to rounding), where
    ``rk4_settings`` is ``settings`` with ``method="rk4"``: the batched path always integrates
    with fixed-step RK4 at ``settings.steps_per_period`` (raised to ``ceil(T / hmax)``); the DP5
    tolerances are not used. Its classifications agree with the reference DP5 settings on the
    test set of tests/unit/test_batch.py.

    Parameters
    ----------
    rows
        Chains of parameter cells, e.g. the rows of a plane tile, each in sweep order.
    settings
        Integration settings (transient, chunks, budget, period test, RK4 steps).
    continuation
        Each cell starts from the previous cell's final state (as ``continuation_chain``).
    u0
        Start state of the first cell of every chain (one array for all, or one per chain).
    on_cell
        Called as ``on_cell(row, i, result)`` as soon as cell ``i`` of chain ``row`` is done.
    start_periods
        Absolute period index of each chain's ``u0`` (``start_period`` of simulate_cell; only
        the slow variable-ratio forcing depends on it). Default 0.
    floquet
        ``"slow"``: Newton-refine the cells that settle too slowly; ``"all"``: also give every
        periodic cell its Floquet margin (:func:`gearsim.cell.simulate.finish_cell`).
    orbits
        Refined orbits shared by the cells of this call (:class:`gearsim.cell.verify.OrbitCache`,
        e.g. the starts of one attractor search), or None.

    Returns
    -------
    One list of :class:`~gearsim.cell.simulate.CellResult` per chain, in cell order.
    """
    st = settings or IntegrationSettings()
    bound = float(getattr(st, "divergence_bound", 1.0e6))
    rows = [list(r) for r in rows]
    if u0 is None or (isinstance(u0, np.ndarray) and u0.ndim == 1):
        u0s = [u0] * len(rows)
    else:
        u0s = list(u0)
        if len(u0s) != len(rows):
            raise ParameterError("u0: one start state per row expected")
    periods0 = [0] * len(rows) if start_periods is None else [int(k) for k in start_periods]
    if len(periods0) != len(rows):
        raise ParameterError("start_periods: one start period per row expected")
    out: list[list[CellResult] | None] = [None] * len(rows)
    chains: list[_Chain] = []
    for r, cells in enumerate(rows):
        if cells:
            start = None if u0s[r] is None else np.asarray(u0s[r], dtype=float)
            chains.append(_Chain(index=r, cells=cells, u0=start, period0=periods0[r]))
        else:
            out[r] = []
    if chains:
        _run_chains(chains, st, bound, continuation, on_cell, floquet, orbits)
        for ch in chains:
            out[ch.index] = ch.results
        # motions without a period where the linear limit is unstable: the long run decides
        # (after the chains: the chains went on from the windows' end states, as simulate_cell's)
        check_growth([r for ch in chains for r in ch.results], st)
    return out  # type: ignore[return-value]


def simulate_cells(
    params_list: Sequence[ModelParameters],
    *,
    settings: IntegrationSettings | None = None,
    u0: np.ndarray | Sequence[np.ndarray | None] | None = None,
    start_periods: Sequence[int] | None = None,
    floquet: str = "slow",
    orbits: OrbitCache | None = None,
) -> list[CellResult]:
    """Independent cells through the batched path: ``[simulate_cell(p, u0_i, start_period=k_i)]``.

    ``u0``: one start state for all cells, one per cell (None = static state), or None.
    E.g. an audit that restarts sampled plane cells from their left neighbours' final states.

    Cells are run in groups of one step grid (steps per period, variable-ratio order): a kernel
    call advances the lanes of one grid and computes every block of its lanes, so a few cells of
    another grid (small ``w``: ``ceil(T / hmax)`` steps) in the same lanes would cost a call
    over all blocks for one lane. Cells are independent: the grouping changes no result.
    """
    params_list = list(params_list)
    n = len(params_list)
    if u0 is None or (isinstance(u0, np.ndarray) and u0.ndim == 1):
        u0s = [u0] * n
    else:
        u0s = list(u0)
        if len(u0s) != n:
            raise ParameterError("u0: one start state per row expected")
    ks = [0] * n if start_periods is None else [int(k) for k in start_periods]
    if len(ks) != n:
        raise ParameterError("start_periods: one start period per row expected")
    st = settings or IntegrationSettings()
    groups: dict[tuple, list[int]] = {}
    for k, p in enumerate(params_list):
        key = (steps_per_period(p, st), p.var_ratio_order if p.var_ratio != 0.0 else None)
        groups.setdefault(key, []).append(k)
    out: list[CellResult | None] = [None] * n
    for idx in groups.values():
        res = simulate_rows([[params_list[k]] for k in idx], settings=settings,
                            continuation=False, u0=[u0s[k] for k in idx],
                            start_periods=[ks[k] for k in idx], floquet=floquet,
                            orbits=orbits)  # fmt: skip
        for k, r in zip(idx, res, strict=True):
            out[k] = r[0]
    return out  # type: ignore[return-value]


def _run_chains(chains: list[_Chain], st: IntegrationSettings, bound: float, continuation: bool,
                on_cell, floquet: str = "slow", orbits: OrbitCache | None = None) -> None:
    # records of the measured periods, or of a longer recurrence probe
    # (the adaptive transient keeps its last window plus one check interval)
    lanes = Lanes(len(chains), max(st.max_periods, st.transient_recurrence,
                                   _window(st) + st.settle_check))
    for l, ch in enumerate(chains):
        ch.lane = l
        ch.start = ch.u0
        ch.period = ch.period0
        _begin_cell(ch, lanes, st)
    active = [ch for ch in chains if not ch.finished]
    while active:
        if len(active) <= (lanes.n_blocks - 1) * LANES:
            lanes = _compact(lanes, active)
        # lanes whose cell has the step grid (N, nu) of the least advanced chain take part
        lead = min(active, key=lambda c: (c.i, c.k))
        N, nu = lead.N, lead.nu
        part = [c for c in active if c.N == N and (c.nu is None or nu is None or c.nu == nu)]
        if nu is None:
            nus = {c.nu for c in part if c.nu is not None}
            nu = nus.pop() if nus else None
            part = [c for c in part if c.nu is None or c.nu == nu]
        m = min(c.left for c in part)
        lanes.begin_call()
        hcol = np.zeros(lanes.size)  # h = 0 freezes the lanes that do not take part
        for c in part:
            l = c.lane
            hcol[l] = c.h
            lanes.status[l] = 0
            lanes.position[l] = c.measured if c.phase in _RECORDED else -1
            lanes.period[l] = c.k
        lanes.set_steps(hcol)
        # the tangent vector is only needed while some lane measures (else: the transient)
        tangent = any(c.phase != _TRANSIENT for c in part)
        plan = None
        if lanes.device == "cuda":
            m, plan = _device_plan(part, lanes, st)
            from gearsim.cell.device_chains import chain_kernel

            lanes.run(N, m, 0.0 if nu is None else nu, bound, tangent, kernel=chain_kernel,
                      plan=plan, test=(st.chunk, st.max_periods, st.n_max, st.period_rtol,
                                       st.max_steps))
        else:
            lanes.run(N, m, 0.0 if nu is None else nu, bound, tangent)
        for c in part:
            l = c.lane
            done = int(lanes.done[l])
            c.k += done
            c.left -= done
            c.steps += int(lanes.steps[l])
            if c.phase in _RECORDED:
                c.measured += done
            if plan is not None and plan[plan_rows.PLAN_TEST, l] and lanes.status[l] == 0:
                if plan[plan_rows.PLAN_N, l] >= 0:  # the device's verdict stopped the lane
                    _decide(c, lanes, st, continuation, on_cell, floquet, orbits,
                            n=int(plan[plan_rows.PLAN_N, l]))
                else:  # the launch ended before the verdict: the lane's chunk goes on
                    c.left = int(plan[plan_rows.PLAN_NEXT, l])
                continue
            if lanes.status[l] != 0:
                # diverged (during the transient or a chunk): simulate_cell's diverged record
                _finish(c, diverged_result(c.cells[c.i], c.k, c.steps), lanes, st,
                        continuation, on_cell)
            elif c.left == 0:
                if c.phase == _BUDGET:
                    _finish(c, diverged_result(c.cells[c.i], c.k, 0, status="budget"), lanes,
                            st, continuation, on_cell)
                elif c.phase == _TRANSIENT:
                    (_begin_settle if st.settle_check else _begin_lead)(c, lanes, st)
                elif c.phase == _LEAD:
                    _begin_measure(c, lanes, st)
                elif c.phase == _PROBE:
                    _end_probe(c, lanes, st)
                elif c.phase == _SETTLE:
                    _settle_check(c, lanes, st, continuation, on_cell, floquet, orbits)
                else:
                    _decide(c, lanes, st, continuation, on_cell, floquet, orbits)
        active = [ch for ch in chains if not ch.finished]


def _device_plan(part: list[_Chain], lanes: Lanes, st: IntegrationSettings):
    """``(m, plan)`` of a GPU launch: a measuring lane goes on from chunk to chunk on the device
    (its verdict there, :mod:`gearsim.cell.device_chains`), so only the other lanes' next
    decisions end the launch (all measuring: the longest measurement left)."""
    others = [c.left for c in part if c.phase != _MEASURE]
    m = min(others) if others else max(st.max_periods - c.measured for c in part)
    plan = np.zeros((plan_rows.PLAN_ROWS, lanes.size), dtype=np.int64)
    for c in part:
        l = c.lane
        plan[plan_rows.PLAN_LEFT, l] = m
        plan[plan_rows.PLAN_STEPS, l] = c.steps
        if c.phase == _MEASURE:
            plan[plan_rows.PLAN_TEST, l] = 1
            plan[plan_rows.PLAN_NEXT, l] = c.left
            plan[plan_rows.PLAN_MEASURED, l] = c.measured
    return m, plan


def _compact(lanes: Lanes, chains: list[_Chain]) -> Lanes:
    """Move the lanes of the unfinished ``chains`` into as few SIMD blocks as they need.

    Finished chains leave frozen lanes behind that the vector step still computes (a block
    costs the same with 1 or 8 lanes taking part); the remaining lanes are copied, with their
    records, into a new :class:`Lanes` (lanes are independent: results are unchanged).
    """
    new = Lanes(len(chains), lanes.sec.shape[1], lanes.device)
    new.gather(lanes, np.array([c.lane for c in chains], dtype=np.int64))
    for l, c in enumerate(chains):
        c.lane = l
    return new


def _begin_cell(ch: _Chain, lanes: Lanes, st: IntegrationSettings) -> None:
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
        ch.phase, ch.left, ch.N, ch.nu = _BUDGET, 0, int(st.steps_per_period), None
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
        ch.phase, ch.left = _PROBE, probe
    else:
        _begin_transient(ch, lanes, st, transient)


def _begin_transient(ch: _Chain, lanes: Lanes, st: IntegrationSettings, transient: int) -> None:
    if transient - ch.lead > 0:
        ch.phase = _TRANSIENT
        ch.left = transient - ch.lead
    elif st.settle_check:
        _begin_settle(ch, lanes, st)
    else:
        _begin_lead(ch, lanes, st)


def _begin_settle(ch: _Chain, lanes: Lanes, st: IntegrationSettings) -> None:
    """The tangent vector starts (as :func:`_begin_lead`); its lead is recorded and checked
    every ``settle_check`` periods (simulate_cell's adaptive transient)."""
    if ch.lead == 0:
        _begin_lead(ch, lanes, st)  # no lead: nothing to check before the fixed plan
        return
    lanes.set_tangent(ch.lane, ch.tangent0)
    lanes.reset_modes(ch.lane)
    done = ch.k - ch.period
    ch.phase, ch.measured = _SETTLE, 0
    ch.left = next_settle_check(done, st, ch.transient, _window(st)) - done


def _begin_lead(ch: _Chain, lanes: Lanes, st: IntegrationSettings) -> None:
    """The tangent vector starts; it aligns over ``ch.lead`` periods before measuring."""
    lanes.set_tangent(ch.lane, ch.tangent0)
    lanes.reset_modes(ch.lane)
    if ch.lead > 0:
        ch.phase = _LEAD
        ch.left = ch.lead
    else:
        _begin_measure(ch, lanes, st)


def _end_probe(ch: _Chain, lanes: Lanes, st: IntegrationSettings) -> None:
    """After the recurrence probe: measure at once if the start recurred, else restart the cell
    from its start state with the plan without the probe (as simulate_cell does)."""
    params = ch.cells[ch.i]
    recurs = period_of(lanes.summaries(ch.lane, ch.measured, copy=False), params, st) > 0
    ch.measured = 0
    if recurs:
        ch.lead = 0
        lanes.reset_modes(ch.lane)  # a new run_periods call in simulate_cell
        _begin_measure(ch, lanes, st)
    else:
        y = np.asarray(ch.start, dtype=float)[:N_STATE]
        lanes.load_state(ch.lane, np.concatenate([y, ch.tangent0]))
        ch.k = ch.period
        _begin_transient(ch, lanes, st, st.transient_continuation)


def _window(st: IntegrationSettings) -> int:
    """The window of the adaptive transient's checks: the first measuring chunk's length."""
    return min(st.chunk, st.max_periods)


def _settle_check(ch: _Chain, lanes: Lanes, st: IntegrationSettings, continuation, on_cell,
                  floquet: str = "slow", orbits: OrbitCache | None = None) -> None:
    """A check of the adaptive transient (simulate_cell's): finish when the last window is
    settled; at the end of the transient that window is the first measuring chunk."""
    params = ch.cells[ch.i]
    w = _window(st)
    done = ch.k - ch.period
    if done >= ch.transient + w:
        _keep_last(lanes, ch.lane, ch.measured, w)
        ch.phase, ch.measured = _MEASURE, w
        _decide(ch, lanes, st, continuation, on_cell, floquet, orbits)
        return
    s = lanes.summaries(ch.lane, ch.measured, copy=False).tail(min(w, simulate.EARLY_WINDOW))
    n = settled_period(s, params, st)
    if n > 0:
        y = lanes.state(ch.lane, N_STATE)
        res = finish_cell(params, s, n, st, y, ch.k, ch.period, ch.steps, floquet, orbits)
        _finish(ch, res, lanes, st, continuation, on_cell)
        return
    lanes.reset_modes(ch.lane)  # a new run_periods call in simulate_cell
    ch.left = next_settle_check(done, st, ch.transient, w) - done
    if ch.measured + ch.left > lanes.sec.shape[1]:
        _keep_last(lanes, ch.lane, ch.measured, w)
        ch.measured = w


def _keep_last(lanes: Lanes, lane: int, measured: int, w: int) -> None:
    """Move the last ``w`` of the ``measured`` records of ``lane`` to the front."""
    if measured > w:
        for a in (lanes.sec, lanes.nface, lanes.nback, lanes.fout):
            a[lane, :w] = a[lane, measured - w : measured].copy()


def _begin_measure(ch: _Chain, lanes: Lanes, st: IntegrationSettings) -> None:
    ch.phase = _MEASURE
    ch.measured = 0
    if ch.lead > 0:
        lanes.reset_modes(ch.lane)  # a new run_periods call in simulate_cell
    ch.left = min(st.chunk, st.max_periods)


def _decide(ch: _Chain, lanes: Lanes, st: IntegrationSettings, continuation, on_cell,
            floquet: str = "slow", orbits: OrbitCache | None = None,
            n: int | None = None) -> None:
    """After a measuring chunk: the period test of simulate_cell (``n``: its result where the
    GPU took it), then finish or go on (:func:`measure_verdict`)."""
    params = ch.cells[ch.i]
    s = lanes.summaries(ch.lane, ch.measured, copy=False)  # read before the lane moves on
    if n is None:
        n = period_of(s, params, st)
    verdict = measure_verdict(n, ch.measured, st.max_periods, ch.steps, st.max_steps)
    if verdict == DONE:
        y = lanes.state(ch.lane, N_STATE)
        res = finish_cell(params, s, n, st, y, ch.k, ch.period, ch.steps, floquet, orbits)
        _finish(ch, res, lanes, st, continuation, on_cell)
    elif verdict == OVER_BUDGET:
        res = diverged_result(params, ch.k, ch.steps, status="budget")
        _finish(ch, res, lanes, st, continuation, on_cell)
    else:
        lanes.reset_modes(ch.lane)
        ch.left = min(st.chunk, st.max_periods - ch.measured)


def _finish(ch: _Chain, res: CellResult, lanes: Lanes, st, continuation, on_cell) -> None:
    ch.results.append(res)
    if on_cell is not None:
        on_cell(ch.index, ch.i, res)
    if continuation and seeds_continuation(res):
        ch.start, ch.period = res.final_state, res.final_period
    else:
        ch.start, ch.period = ch.u0, 0
    ch.i += 1
    if ch.finished:
        lanes.freeze(ch.lane)
        return
    _begin_cell(ch, lanes, st)


def warm_up() -> float:
    """Compile the batched kernels (or load them from ``NUMBA_CACHE_DIR``); returns seconds.

    Call once before many workers start (``gearsim compile``), so that they do not race to
    compile and write the cache (a cold compile of :func:`advance` takes ~20 s).
    """
    t0 = time.perf_counter()
    st = IntegrationSettings(
        method="rk4", transient=2, transient_continuation=1, chunk=4, max_periods=8, n_max=2
    )
    simulate_cells([ModelParameters(w=1.0), ModelParameters(w=1.3, b=0.2)], settings=st)
    z = np.zeros((4, N_STATE))
    repeats_throughout(z[:, 0], z[:, 1], 1.0, 1.0, 4, 1e-7)  # settle_check's
    return time.perf_counter() - t0
