"""The CUDA lane kernel: one GPU thread per lane, on the one field, step and event layer.

The SIMD kernel (:mod:`gearsim.numerics.kernel`) advances blocks of lanes in vector registers and
hands a flagged lane to the scalar event layer; a GPU runs one lane per thread, so here a thread
walks its own lane through the same calls: :func:`~gearsim.numerics.kernel.period_start`, the
grid step :func:`~gearsim.numerics.kernel.lane_step` (which inlines
:func:`gearsim.numerics.steps.rk4_state`, :func:`~gearsim.numerics.steps.rk4_tangent` and
:func:`~gearsim.numerics.steps.grid_step_flag` on :func:`gearsim.dynamics.model.field_state`), a
flagged step redone inside the thread by :func:`~gearsim.numerics.kernel.redo_lane` (the event
layer :func:`gearsim.numerics.events.advance_interval`: locate the switch, restart the step in the
new region), and :func:`~gearsim.numerics.kernel.period_end`. numba-cuda compiles those ``@njit``
functions as device code; nothing of the physics is written here.

The lane state and the records are the SIMD kernel's (the block layout of
:class:`gearsim.numerics.batch.Lanes`), so a lanes object moves between the two devices as plain
arrays. The results equal the CPU kernel's to the rounding of the step (the two compilers
contract multiply-adds differently), with the same impact counts and status
(tests/unit/test_cuda_lanes.py, under Numba's CUDA simulator).

This module imports ``numba.cuda``: import it only after :mod:`gearsim.numerics.device` found
numba-cuda (``NUMBA_ENABLE_CUDASIM=1`` selects the simulator before Numba is imported).
"""

from __future__ import annotations

import numpy as np
from numba import cuda, float64, int64

from gearsim.dynamics.model import N_MODE, N_PARAMS, N_STATE, N_SWITCH, P_W
from gearsim.numerics.device import Device, DeviceError
from gearsim.numerics.events import N_ACC, N_CNT
from gearsim.numerics.kernel import (
    lane_general,
    lane_reset_modes,
    lane_step,
    period_end,
    period_start,
    redo_lane,
    step_entries,
)
from gearsim.numerics.lanes_layout import (
    BLOCK,
    IST_DONE,
    IST_POS,
    IST_ST,
    IST_STEPS,
    LANES,
    NI,
    ROW_FLAG,
    ROW_PAR,
)

# ---- rows of a launch's per-lane plan (int64 ``[PLAN_ROWS, n_lanes]``, :func:`make_plan`) ----
PLAN_LEFT = 0  # periods the lane runs at most in this launch
PLAN_TEST = 1  # 1: a measuring lane, its verdict taken on the device at the end of each chunk
PLAN_STEPS = 2  # the lane's cell's RK4 steps before this launch (the budget's count)
PLAN_N = 3  # out: the period the verdict stopped the lane with (-1: not stopped by a verdict)
PLAN_NEXT = 4  # in and out: periods to the end of the lane's current measuring chunk
PLAN_MEASURED = 5  # periods the lane measured before this launch (its record position)
PLAN_ROWS = 6

SIMULATED = bool(cuda.core.config.ENABLE_CUDASIM)  # Numba's CUDA simulator (NUMBA_ENABLE_CUDASIM=1)

if SIMULATED:
    def _raw(a):
        """The simulator hands a kernel wrapped arrays; the ``@njit`` layers take the array."""
        return a._item._ary
else:
    @cuda.jit(device=True, inline=True)
    def _raw(a):
        """The array itself (compiled kernels pass arrays as they are)."""
        return a

#: Threads per CUDA block (a multiple of the warp; the lane's locals are ~1 kB of local memory).
#: The simulator runs a block's threads as Python threads at once, and their first calls would
#: compile the ``@njit`` layers concurrently: there, one thread per block (blocks run in turn).
THREADS = 1 if SIMULATED else 128


@cuda.jit(device=True)
def lane_periods(blk, ist, l, k0, k1, N, C, S, LAM, CV, SV, Q, nu, bound, sec, nface, nback,
                 fout, tangent, events, general, wk, wz):
    """Periods ``k0 .. k1-1`` of lane ``l`` (the arrays raw); True when the lane diverged (it
    stops there, as the CPU kernel freezes it)."""
    q = l % LANES
    o = (l // LANES) * BLOCK
    r = o + q
    tabs = (C, S, LAM, CV, SV, Q)
    for k in range(k0, k1):
        period_start(blk, ist, l, k, nu, sec)
        for j in range(N):
            i2 = 2 * j
            cA, sA, cM, sM, cB, sB = step_entries(C, S, i2)
            cvA, svA, cvM, svM, cvB, svB = step_entries(CV, SV, i2)
            lane_step(blk, o, q, cA, sA, cvA, svA, cM, sM, cvM, svM, cB, sB, cvB, svB, LAM[j],
                       Q[i2], Q[i2 + 1], Q[i2 + 2], bound, tangent, general, general)
            fq = blk[r + ROW_FLAG * LANES]
            if fq != 0.0 and events:
                redo_lane(blk, o, q, l, ist, j, N, LAM[j], bound, tangent, wk, fq == 2.0,
                           general, tabs)
                if ist[IST_ST, l] != 0:
                    return True
        period_end(blk, ist, l, k, N, wz, nface, nback, fout)
    return False


@cuda.jit(device=True)
def _never(sec, fout, l, k, w, steps, n_max, rtol, max_periods, max_steps):
    """No verdict on the device: a lane runs its periods (no launch of this kernel tests)."""
    return -1


def lane_kernel(verdict, cache: bool = True):
    """The lane kernel whose measuring lanes take ``verdict`` on the device after every chunk.

    ``verdict(sec, fout, l, k, w, steps, n_max, rtol, max_periods, max_steps)`` is a device
    function of the layer that owns the decision (the chain driver's,
    :mod:`gearsim.cell.device_chains`): the period ``n >= 0`` the lane stops with after its
    first ``k`` measured periods (records from position 0), or -1 to measure on. A lane marked
    ``PLAN_TEST`` runs to the end of its chunk (``PLAN_NEXT`` periods), takes the verdict, and
    goes on with the next chunk (``min(chunk, max_periods - measured)``) until the verdict stops
    it or the launch's periods (``PLAN_LEFT``) are used; between two chunks its regions are set
    from its state, as the CPU driver does between two calls
    (:func:`~gearsim.numerics.kernel.lane_reset_modes`). Another lane runs its ``PLAN_LEFT``
    periods. ``cache``: keep the compiled kernel in ``NUMBA_CACHE_DIR``. numba-cuda keys a
    closure's cache entry by its pickled cell (the verdict): stable for :func:`_never`, not for
    a verdict that calls CPU ``@njit`` functions (their pickles carry a per-process id), whose
    kernel then compiles in every process (``cache=False``: no entry that no process reads).
    """

    @cuda.jit(cache=cache)
    def kernel(blk, ist, N, m, C, S, LAM, CV, SV, Q, nu, bound, sec, nface, nback, fout, tangent,
               events, plan, chunk, max_periods, n_max, rtol, max_steps):
        l = cuda.grid(1)
        if l >= ist.shape[1] or ist[IST_ST, l] != 0:
            return
        blk = _raw(blk)
        ist = _raw(ist)
        sec = _raw(sec)
        nface = _raw(nface)
        nback = _raw(nback)
        fout = _raw(fout)
        plan = _raw(plan)
        r = (l // LANES) * BLOCK + l % LANES
        general = lane_general(blk, r)
        wk = (
            cuda.local.array(20, float64), cuda.local.array(N_PARAMS, float64),
            cuda.local.array(N_MODE, int64), cuda.local.array(N_SWITCH, float64),
            cuda.local.array(N_SWITCH, np.bool_), cuda.local.array(N_ACC, float64),
            cuda.local.array(N_CNT, int64), cuda.local.array((7, 20), float64),
            cuda.local.array(20, float64), cuda.local.array(20, float64),
            cuda.local.array(20, float64), cuda.local.array(1, float64),
            cuda.local.array(1, int64),
        )  # fmt: skip  (a local array has a length >= 1: a one-entry event log nobody reads)
        wz = cuda.local.array(N_STATE, float64)
        # local memory starts undefined; the CPU kernel's scratch starts at zero, and the event
        # counter (CNT_EV, the index of the log's next entry) carries from one redo to the next
        for i in range(N_ACC):
            wk[5][i] = 0.0
        for i in range(N_CNT):
            wk[6][i] = 0
        C, S, LAM, CV, SV, Q = _raw(C), _raw(S), _raw(LAM), _raw(CV), _raw(SV), _raw(Q)
        left = min(plan[PLAN_LEFT, l], m)
        if plan[PLAN_TEST, l] == 0:
            lane_periods(blk, ist, l, 0, left, N, C, S, LAM, CV, SV, Q, nu, bound, sec, nface,
                         nback, fout, tangent, events, general, wk, wz)
            return
        w = blk[r + (ROW_PAR + P_W) * LANES]
        nxt = plan[PLAN_NEXT, l]
        k = 0
        while k < left:
            k1 = min(k + nxt, left)
            if lane_periods(blk, ist, l, k, k1, N, C, S, LAM, CV, SV, Q, nu, bound, sec, nface,
                            nback, fout, tangent, events, general, wk, wz):
                return
            nxt -= k1 - k
            k = k1
            if nxt > 0:
                break  # the launch ends inside the chunk
            measured = plan[PLAN_MEASURED, l] + k
            n = verdict(sec, fout, l, measured, w, plan[PLAN_STEPS, l] + ist[IST_STEPS, l], n_max,
                        rtol, max_periods, max_steps)
            if n >= 0:
                plan[PLAN_N, l] = n
                return
            lane_reset_modes(blk, l, wk[1], wk[2], wk[0], wk[3], wk[4])
            nxt = min(chunk, max_periods - measured)
            if nxt <= 0:
                break  # a verdict that never stops a lane ends at the most periods measured
        plan[PLAN_NEXT, l] = nxt

    return kernel


#: the kernel of :func:`gearsim.numerics.kernel.advance` (every lane runs its periods)
advance_kernel = lane_kernel(_never)


def _errors() -> tuple[type[BaseException], ...]:
    """The exceptions of a failed allocation, copy or launch (the driver's and the compiler's)."""
    from numba.cuda.cudadrv import driver, error

    return tuple(e for e in (getattr(driver, "CudaAPIError", None),
                             getattr(error, "CudaDriverError", None),
                             getattr(error, "CudaSupportError", None),
                             getattr(error, "NvvmError", None), MemoryError) if e is not None)


def make_plan(size: int, lanes, measuring, m: int, left, measured, steps) -> np.ndarray:
    """The per-lane plan of a launch of ``m`` periods: every lane of ``lanes`` runs at most
    ``m`` periods from its cell's ``steps``; each of ``measuring`` (a subset) goes on from chunk
    to chunk with its verdict (``left``: periods to the end of its current chunk, ``measured``:
    its periods measured before)."""
    plan = np.zeros((PLAN_ROWS, size), dtype=np.int64)
    plan[PLAN_LEFT, lanes] = m
    plan[PLAN_STEPS, lanes] = steps[lanes]
    plan[PLAN_TEST, measuring] = 1
    plan[PLAN_NEXT, measuring] = left[measuring]
    plan[PLAN_MEASURED, measuring] = measured[measuring]
    return plan


def advance_device(blk, ist, N, m, tables, nu, bound, sec, nface, nback, fout, tangent,
                   events=True, kernel=None, plan=None, test=(1, 1, 1, 0.0, 0),
                   device: Device | None = None):
    """Run a lane kernel over every lane and copy the results into the host arrays.

    The arguments and their effect are those of :func:`gearsim.numerics.kernel.advance` (the
    phase tables ``tables`` as one tuple). The device holds the lane rows and ``m`` periods of
    records per lane (written from position 0, then placed at each lane's record position), not
    the whole record buffers. Returns the kernel's wall time in seconds (launch to finish).
    ``plan``: the per-lane plan (``PLAN_*`` rows; copied back, its ``PLAN_N`` row filled) of a
    kernel made by :func:`lane_kernel`, with ``test`` = ``(chunk, max_periods, n_max,
    period_rtol, max_steps)`` for its verdict; by default every lane runs ``m`` periods.
    A failed allocation, copy or launch, or lanes whose arrays exceed the GPU's free memory
    (checked before anything is allocated), is one
    :class:`~gearsim.numerics.device.DeviceError` line naming the GPU, the lanes asked and the
    setting; the host arrays are then unchanged. ``device``: the GPU's record (its name in
    that line).
    ``kernel``: by default :data:`advance_kernel` (benchmarks/bench_gpu.py compiles it with
    register limits).
    """
    n = ist.shape[1]
    need = launch_bytes(n, m if plan is None else sec.shape[1], N, fout.shape[2])
    free = free_bytes()
    dev = device or Device(kind="cuda")
    where = (f"execution.device: cuda ({dev.name or 'GPU'}): {n} lanes x {m} periods of {N} "
             "steps")
    if free is not None and need > free:
        raise DeviceError(f"{where} need {need / 2**30:.2f} GiB of GPU memory, "
                          f"{free / 2**30:.2f} GiB free; use fewer lanes per job "
                          "(execution.lanes, tile_rows) or execution.device: cpu")
    try:
        return _advance_device(blk, ist, N, m, tables, nu, bound, sec, nface, nback, fout,
                               tangent, events, kernel or advance_kernel, plan, test)
    except _errors() as exc:
        first = (str(exc).splitlines() or [type(exc).__name__])[0][:160]
        raise DeviceError(
            f"{where}: {first}; use fewer lanes per job (execution.lanes, tile_rows) or "
            "execution.device: cpu"
        ) from exc


def launch_bytes(n: int, m: int, N: int, n_out: int = 6) -> int:
    """GPU memory a launch of ``n`` lanes over ``m`` periods of ``N`` steps allocates: the lane
    rows, counters, plan, phase tables and ``m`` periods of records per lane."""
    blocks = -(-n // LANES)
    rows = blocks * BLOCK * 8 + n * 8 * (NI + PLAN_ROWS)
    tables = 8 * (5 * (2 * N + 1) + N)
    records = n * max(1, m) * 8 * (N_STATE + 2 + n_out)
    return rows + tables + records


def free_bytes() -> int | None:
    """Free memory of the current GPU in bytes, or None where it cannot be read (the
    simulator)."""
    try:
        free, _total = cuda.current_context().get_memory_info()
    except Exception:  # no context to ask (the launch then reports its own failure)
        return None
    return int(free) if np.isfinite(free) else None  # the simulator: unbounded


def _advance_device(blk, ist, N, m, tables, nu, bound, sec, nface, nback, fout, tangent,
                    events, kernel, plan, test):
    import time

    n = ist.shape[1]
    before = ist.copy()
    taking = before[IST_ST] == 0
    recorded = taking & (before[IST_POS] >= 0)
    whole = plan is not None  # the records travel whole: a verdict reads a lane's earlier ones
    if plan is None:
        plan = np.zeros((PLAN_ROWS, n), dtype=np.int64)
        plan[PLAN_LEFT] = m
    plan_h = np.ascontiguousarray(plan, dtype=np.int64).copy()
    plan_h[PLAN_N] = -1
    ist_d = before.copy()
    if not whole:
        ist_d[IST_POS, recorded] = 0
    d_blk = cuda.to_device(blk)
    d_ist = cuda.to_device(ist_d)
    d_plan = cuda.to_device(plan_h)
    d_tab = tuple(cuda.to_device(np.ascontiguousarray(t, dtype=np.float64)) for t in tables)
    cap = max(1, int(m))
    if whole:
        d_sec, d_nf, d_nb, d_out = (cuda.to_device(a) for a in (sec, nface, nback, fout))
    else:  # uninitialised: only the entries the kernel wrote are copied back
        d_sec = cuda.device_array((n, cap, N_STATE))
        d_nf = cuda.device_array((n, cap), dtype=np.int64)
        d_nb = cuda.device_array((n, cap), dtype=np.int64)
        d_out = cuda.device_array((n, cap, fout.shape[2]))
    grid = max(1, -(-n // THREADS))
    chunk, max_periods, n_max, rtol, max_steps = test
    t0 = time.perf_counter()
    kernel[grid, THREADS](d_blk, d_ist, int(N), int(m), *d_tab, float(nu), float(bound), d_sec,
                          d_nf, d_nb, d_out, bool(tangent), bool(events), d_plan,
                          max(1, int(chunk)), int(max_periods), int(n_max), float(rtol),
                          int(max_steps))
    cuda.synchronize()
    wall = time.perf_counter() - t0
    plan_out = d_plan.copy_to_host()
    d_blk.copy_to_host(blk)
    after = d_ist.copy_to_host()
    after[IST_POS] = before[IST_POS]
    ist[:] = after
    plan[PLAN_N] = plan_out[PLAN_N]
    plan[PLAN_NEXT] = plan_out[PLAN_NEXT]
    if whole:
        for d, a in ((d_sec, sec), (d_nf, nface), (d_nb, nback), (d_out, fout)):
            d.copy_to_host(a)
    elif recorded.any():
        lanes = np.flatnonzero(recorded)
        done = after[IST_DONE, lanes] - before[IST_DONE, lanes]  # periods completed in this call
        # a lane that diverged wrote the section point of the period it stopped in
        span = np.minimum(np.where(after[IST_ST, lanes] != 0, done + 1, done), cap)
        li = np.repeat(lanes, span)
        ki = np.arange(int(span.sum())) - np.repeat(np.cumsum(span) - span, span)
        dest = before[IST_POS, li] + ki
        sec[li, dest] = d_sec.copy_to_host()[li, ki]
        full = ki < np.repeat(done, span)
        li, ki, dest = li[full], ki[full], dest[full]
        nface[li, dest] = d_nf.copy_to_host()[li, ki]
        nback[li, dest] = d_nb.copy_to_host()[li, ki]
        fout[li, dest] = d_out.copy_to_host()[li, ki]
    return wall
