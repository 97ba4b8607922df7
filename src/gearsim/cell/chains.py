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

import numpy as np

from gearsim.cell import chain
from gearsim.cell.chain import Chain, Rules
from gearsim.cell.classify import repeats_throughout
from gearsim.cell.growth import check_growth
from gearsim.cell.simulate import CellResult, IntegrationSettings
from gearsim.cell.verify import OrbitCache
from gearsim.dynamics.model import N_STATE
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.numerics.backend import CpuLanes
from gearsim.numerics.batch import LANES, Lanes, steps_per_period


# ============================================================================ the driver
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
    backend: CpuLanes | None = None,
) -> list[list[CellResult]]:
    """Simulate many continuation chains at once with the batched RK4 kernel (the chain
    machine of :mod:`gearsim.cell.chain`, one chain per lane).

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
    backend
        Where the lanes run (:func:`gearsim.numerics.backend.select`; default the CPU).

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
    chains: list[Chain] = []
    for r, cells in enumerate(rows):
        if cells:
            start = None if u0s[r] is None else np.asarray(u0s[r], dtype=float)
            chains.append(Chain(index=r, cells=cells, u0=start, period0=periods0[r]))
        else:
            out[r] = []
    if chains:
        rules = Rules(continuation, on_cell, floquet, orbits)
        _run_chains(chains, st, bound, rules, backend)
        for ch in chains:
            out[ch.index] = ch.results
        # motions without a period where the linear limit is unstable: the long run decides
        # (after the chains: the chains went on from the windows' end states, as simulate_cell's)
        check_growth([r for ch in chains for r in ch.results], st, backend=backend)
    return out  # type: ignore[return-value]


def simulate_cells(
    params_list: Sequence[ModelParameters],
    *,
    settings: IntegrationSettings | None = None,
    u0: np.ndarray | Sequence[np.ndarray | None] | None = None,
    start_periods: Sequence[int] | None = None,
    floquet: str = "slow",
    orbits: OrbitCache | None = None,
    backend: CpuLanes | None = None,
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
                            orbits=orbits, backend=backend)  # fmt: skip
        for k, r in zip(idx, res, strict=True):
            out[k] = r[0]
    return out  # type: ignore[return-value]


def _run_chains(chains: list[Chain], st: IntegrationSettings, bound: float, rules: Rules,
                backend: CpuLanes | None) -> None:
    lanes = Lanes(len(chains), chain.records(st), backend)
    for l, ch in enumerate(chains):
        ch.lane = l
        ch.start = ch.u0
        ch.period = ch.period0
        chain.begin_cell(ch, lanes, st)
    active = [ch for ch in chains if not ch.finished]
    while active:
        if len(active) <= (lanes.n_blocks - 1) * LANES:
            lanes = compact(lanes, active)
        # lanes whose cell has the step grid (N, nu) of the least advanced chain take part
        lead = min(active, key=lambda c: (c.i, c.k))
        N, nu = lead.N, lead.nu
        part = [c for c in active if c.N == N and (c.nu is None or nu is None or c.nu == nu)]
        if nu is None:
            nus = {c.nu for c in part if c.nu is not None}
            nu = nus.pop() if nus else None
            part = [c for c in part if c.nu is None or c.nu == nu]
        lanes.begin_call()
        hcol = np.zeros(lanes.size)  # h = 0 freezes the lanes that do not take part
        for c in part:
            l = c.lane
            hcol[l] = c.h
            lanes.status[l] = 0
            lanes.position[l] = c.measured if c.phase in chain.RECORDED else -1
            lanes.period[l] = c.k
        lanes.set_steps(hcol)
        # the tangent vector is only needed while some lane measures (else: the transient)
        tangent = any(c.phase != chain.TRANSIENT for c in part)
        _, period = chain.run_part(part, lanes, st, N, nu, bound, tangent)
        for c in part:
            chain.act(c, lanes, st, rules, int(period[c.lane]))
        active = [ch for ch in chains if not ch.finished]


def compact(lanes: Lanes, chains: list[Chain]) -> Lanes:
    """Move the lanes of the unfinished ``chains`` into as few SIMD blocks as they need.

    Finished chains leave frozen lanes behind that the vector step still computes (a block
    costs the same with 1 or 8 lanes taking part); the remaining lanes are copied, with their
    records, into a new :class:`Lanes` (lanes are independent: results are unchanged).
    """
    new = Lanes(len(chains), lanes.sec.shape[1], lanes.backend)
    new.gather(lanes, np.array([c.lane for c in chains], dtype=np.int64))
    for l, c in enumerate(chains):
        c.lane = l
    return new


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
