"""The lane layout both lane kernels share: the rows of a lane in its block, the integer counters
of every lane and the columns of its per-period records.

A lanes object (:class:`gearsim.numerics.batch.Lanes`) holds its lanes in blocks of
:data:`LANES`; a block is :data:`NROW` rows of ``LANES`` consecutive doubles (``ROW_*``), so the
SIMD kernel (:mod:`gearsim.numerics.kernel`) runs a row of a block as one vector, and a CUDA
thread (:mod:`gearsim.numerics.cuda_lanes`) walks its own lane through the same rows. The integer
counters are the rows ``IST_*`` of a ``[NI, n_lanes]`` array; each recorded period writes its
section state, its face and back contact entries and the float outputs ``O_*``.
"""

from __future__ import annotations

from gearsim.dynamics.model import N_PARAMS

#: Lanes per block (compile-time stride of the vector loop; 8 = two AVX2 vectors).
LANES = 8

# ---- float rows of a block (each row holds LANES doubles) ------------------------------------
ROW_Y = 0  # 20 rows: state (10) then tangent vector (10)
ROW_H = 20  # step h = T / N (0 freezes the lane)
ROW_PAR = 21  # N_PARAMS rows: the packed parameters (gearsim.dynamics.model layout)
ROW_R0 = ROW_PAR + N_PARAMS  # mesh region (-1, 0, 1) as a double
ROW_S0 = ROW_R0 + 1  # |mesh region|
ROW_RB = ROW_R0 + 2  # 4 rows: bearing regions
ROW_SB = ROW_R0 + 6  # 4 rows: |bearing region|
ROW_TD = ROW_R0 + 10  # per-period accumulators: disengaged time, force and x extremes
ROW_FMX = ROW_TD + 1
ROW_FMN = ROW_TD + 2
ROW_XMX = ROW_TD + 3
ROW_XMN = ROW_TD + 4
ROW_FLAG = ROW_TD + 5  # 1.0: the lane needs the event layer for the step; 2.0: a turning point
NROW = ROW_FLAG + 1
BLOCK = NROW * LANES

# ---- integer counters (2-D array [NI, n_lanes]; touched by scalar code only) -----------------
IST_ST = 0  # status: 0 running, 1 diverged, -1 not taking part in this call
IST_DONE = 1  # periods completed in this call
IST_POS = 2  # record position of the first period of this call (-1: do not record)
IST_K = 3  # absolute period index at the start of the call
IST_STEPS = 4  # RK4 steps taken in this call (including the event layer's trial steps)
IST_NF = 5  # face entries in the current period
IST_NB = 6  # back entries in the current period
NI = 7

# ---- columns of the float per-period output ----
O_TDIS, O_FMAX, O_FMIN, O_XMAX, O_XMIN, O_LYAP = range(6)
