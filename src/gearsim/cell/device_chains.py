"""The chain driver's verdict inside a CUDA thread: a measuring lane runs chunk after chunk on the
GPU and stops when its cell is settled, without a return to the host every chunk.

The CPU driver (:mod:`gearsim.cell.chains`) runs a measuring chunk, copies nothing, and takes
the verdict on the host (:func:`gearsim.cell.simulate.period_of`, then
:func:`gearsim.cell.verdict.measure_verdict`). On a GPU the same two ``@njit`` functions --
:func:`gearsim.cell.classify.window_period` and :func:`~gearsim.cell.verdict.measure_verdict` --
are compiled into the lane kernel (:func:`gearsim.numerics.cuda_lanes.lane_kernel`) and called
by each thread after each chunk over its records on the device; the host gets the lane back
with its period and classifies the cell with the one ``cell/classify`` over the records copied
back (:func:`gearsim.cell.simulate.finish_cell`).

This module imports ``numba.cuda``: the chain driver loads it only where the lanes run on cuda.
"""

from __future__ import annotations

from numba import cuda

from gearsim.cell.classify import window_period
from gearsim.cell.verdict import GO_ON, measure_verdict
from gearsim.numerics.cuda_lanes import lane_kernel
from gearsim.numerics.kernel import O_XMAX, O_XMIN


@cuda.jit(device=True)
def chunk_verdict(sec, fout, l, k, w, steps, n_max, rtol, max_periods, max_steps):
    """The period lane ``l`` stops with after its first ``k`` measured periods (records from
    position 0, ``steps`` RK4 steps so far in its cell), or -1 to measure on."""
    n = window_period(sec[l, :k, 0], sec[l, :k, 1], fout[l, :k, O_XMAX], fout[l, :k, O_XMIN], w,
                      n_max, rtol)
    if measure_verdict(n, k, max_periods, steps, max_steps) == GO_ON:
        return -1
    return n


#: the lane kernel whose measuring lanes stop on the chain driver's verdict (compiled in each
#: process: its cache key would not be stable, :func:`~gearsim.numerics.cuda_lanes.lane_kernel`)
chain_kernel = lane_kernel(chunk_verdict, cache=False)
