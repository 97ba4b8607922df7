"""The measuring rule of a continuation chain: after a measuring chunk, is the cell done, over its
step budget, or measured on. One ``@njit`` function that both drivers take their verdict from:
the host's (:mod:`gearsim.cell.chains`) and a CUDA thread's (:mod:`gearsim.cell.device_chains`,
which compiles it into the lane kernel)."""

from __future__ import annotations

from numba import njit

GO_ON, DONE, OVER_BUDGET = 0, 1, 2  # measure_verdict's answers


@njit(cache=True, nogil=True)
def measure_verdict(n, measured, max_periods, steps, max_steps):
    """After a measuring chunk of period test ``n`` (0: none) with ``measured`` periods and
    ``steps`` RK4 steps in the cell: DONE (a period, or the most periods measured), OVER_BUDGET
    (past its step budget) or GO_ON (measure on)."""
    if n > 0 or measured >= max_periods:
        return DONE
    if steps > max_steps:
        return OVER_BUDGET
    return GO_ON
