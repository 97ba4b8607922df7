"""The CUDA lane kernel: one GPU thread per lane, on the one field, step and event layer.

The SIMD kernel (:mod:`gearsim.numerics.kernel`) advances blocks of lanes in vector registers and
hands a flagged lane to the scalar event layer; a GPU runs one lane per thread, so here a thread
walks its own lane through the same calls: :func:`~gearsim.numerics.kernel.period_start`, the
grid step :func:`~gearsim.numerics.kernel._lane_step` (which inlines
:func:`gearsim.numerics.steps.rk4_state`, :func:`~gearsim.numerics.steps.rk4_tangent` and
:func:`~gearsim.numerics.steps.grid_step_flag` on :func:`gearsim.dynamics.model.field_state`), a
flagged step redone inside the thread by :func:`~gearsim.numerics.kernel._redo_lane` (the event
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

from gearsim.dynamics.model import N_MODE, N_PARAMS, N_STATE, N_SWITCH
from gearsim.numerics.device import DeviceError, current
from gearsim.numerics.events import N_ACC, N_CNT
from gearsim.numerics.kernel import (
    _DONE,
    _FLAG,
    _POS,
    _ST,
    BLOCK,
    LANES,
    _lane_step,
    _redo_lane,
    lane_general,
    period_end,
    period_start,
)

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


@cuda.jit(cache=True)
def advance_kernel(blk, ist, N, m, C, S, LAM, CV, SV, Q, nu, bound, sec, nface, nback, fout,
                   tangent, events):
    """:func:`gearsim.numerics.kernel.advance` for lane ``cuda.grid(1)`` (same arguments).

    The lane's general step (bearing channels, model forms) is chosen per lane: a base lane
    gets the base step's numbers either way (the kernel's docstring). A lane that diverges
    stops here, as the CPU kernel freezes it. ``events`` False measures the step alone
    (benchmarks/bench_gpu.py: a flagged step is left as it was, not redone; no result of a
    study runs so).
    """
    l = cuda.grid(1)
    if l >= ist.shape[1] or ist[_ST, l] != 0:
        return
    blk = _raw(blk)
    ist = _raw(ist)
    sec = _raw(sec)
    nface = _raw(nface)
    nback = _raw(nback)
    fout = _raw(fout)
    q = l % LANES
    o = (l // LANES) * BLOCK
    r = o + q
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
    C, S, LAM, CV, SV, Q = _raw(C), _raw(S), _raw(LAM), _raw(CV), _raw(SV), _raw(Q)
    tabs = (C, S, LAM, CV, SV, Q)
    for k in range(m):
        period_start(blk, ist, l, k, nu, sec)
        for j in range(N):
            i2 = 2 * j
            _lane_step(blk, o, q, C[i2], S[i2], CV[i2], SV[i2], C[i2 + 1], S[i2 + 1], CV[i2 + 1],
                       SV[i2 + 1], C[i2 + 2], S[i2 + 2], CV[i2 + 2], SV[i2 + 2], LAM[j], Q[i2],
                       Q[i2 + 1], Q[i2 + 2], bound, tangent, general, general)
            fq = blk[r + _FLAG * LANES]
            if fq != 0.0 and events:
                _redo_lane(blk, o, q, l, ist, j, N, LAM[j], bound, tangent, wk, fq == 2.0,
                           general, tabs)
                if ist[_ST, l] != 0:
                    return
        period_end(blk, ist, l, k, N, wz, nface, nback, fout)


def _errors() -> tuple[type[BaseException], ...]:
    """The exceptions of a failed allocation, copy or launch (the driver's and the compiler's)."""
    from numba.cuda.cudadrv import driver, error

    return tuple(e for e in (getattr(driver, "CudaAPIError", None),
                             getattr(error, "CudaDriverError", None),
                             getattr(error, "CudaSupportError", None),
                             getattr(error, "NvvmError", None), MemoryError) if e is not None)


def advance_device(blk, ist, N, m, tables, nu, bound, sec, nface, nback, fout, tangent,
                   events=True, kernel=None):
    """Run :func:`advance_kernel` over every lane and copy the results into the host arrays.

    The arguments and their effect are those of :func:`gearsim.numerics.kernel.advance` (the
    phase tables ``tables`` as one tuple). The device holds the lane rows and ``m`` periods of
    records per lane (written from position 0, then placed at each lane's record position), not
    the whole record buffers. Returns the kernel's wall time in seconds (launch to finish).
    A failed allocation, copy or launch is one :class:`~gearsim.numerics.device.DeviceError`
    line naming the GPU, the lanes asked and the setting; the host arrays are then unchanged.
    ``kernel``: another compile of :func:`advance_kernel` (benchmarks/bench_gpu.py compares
    register limits); by default the kernel itself.
    """
    try:
        return _advance_device(blk, ist, N, m, tables, nu, bound, sec, nface, nback, fout,
                               tangent, events, kernel or advance_kernel)
    except _errors() as exc:
        dev = current()
        first = (str(exc).splitlines() or [type(exc).__name__])[0][:160]
        raise DeviceError(
            f"execution.device: cuda ({dev.name or 'GPU'}): {first} running {ist.shape[1]} "
            f"lanes x {m} periods of {N} steps; use fewer lanes per job or execution.device: cpu"
        ) from exc


def _advance_device(blk, ist, N, m, tables, nu, bound, sec, nface, nback, fout, tangent,
                    events, kernel):
    import time

    n = ist.shape[1]
    before = ist.copy()
    taking = before[_ST] == 0
    recorded = taking & (before[_POS] >= 0)
    ist_d = before.copy()
    ist_d[_POS, recorded] = 0
    d_blk = cuda.to_device(blk)
    d_ist = cuda.to_device(ist_d)
    d_tab = tuple(cuda.to_device(np.ascontiguousarray(t, dtype=np.float64)) for t in tables)
    cap = max(1, int(m))
    # uninitialised: only the entries the kernel wrote are copied back
    d_sec = cuda.device_array((n, cap, N_STATE))
    d_nf = cuda.device_array((n, cap), dtype=np.int64)
    d_nb = cuda.device_array((n, cap), dtype=np.int64)
    d_out = cuda.device_array((n, cap, fout.shape[2]))
    grid = max(1, -(-n // THREADS))
    t0 = time.perf_counter()
    kernel[grid, THREADS](d_blk, d_ist, int(N), int(m), *d_tab, float(nu), float(bound), d_sec,
                          d_nf, d_nb, d_out, bool(tangent), bool(events))
    cuda.synchronize()
    wall = time.perf_counter() - t0
    d_blk.copy_to_host(blk)
    after = d_ist.copy_to_host()
    after[_POS] = before[_POS]
    ist[:] = after
    if recorded.any():
        lanes = np.flatnonzero(recorded)
        done = after[_DONE, lanes] - before[_DONE, lanes]  # periods completed in this call
        # a lane that diverged wrote the section point of the period it stopped in
        span = np.minimum(np.where(after[_ST, lanes] != 0, done + 1, done), cap)
        li = np.repeat(lanes, span)
        ki = np.arange(int(span.sum())) - np.repeat(np.cumsum(span) - span, span)
        dest = before[_POS, li] + ki
        sec[li, dest] = d_sec.copy_to_host()[li, ki]
        full = ki < np.repeat(done, span)
        li, ki, dest = li[full], ki[full], dest[full]
        nface[li, dest] = d_nf.copy_to_host()[li, ki]
        nback[li, dest] = d_nb.copy_to_host()[li, ki]
        fout[li, dest] = d_out.copy_to_host()[li, ki]
    return wall
