"""The batched RK4 kernel: many cells advanced at once, the cell index innermost (SIMD lanes).

Why
---
One cell integrated by :func:`gearsim.numerics.integrate.integrate_periods` is a single dependency
chain
(each RK4 stage needs the previous one), so a scalar kernel cannot use the vector units. Here a
*lane* is one cell; lanes are packed in blocks of :data:`LANES` with every per-lane quantity
(state, tangent vector, the packed parameters of :func:`gearsim.dynamics.model.pack_parameters`,
frozen
contact regions, per-period accumulators) stored as a row of ``LANES`` consecutive doubles. The
inner loop runs over the lanes of a block with compile-time strides, so LLVM vectorises the whole
RK4 step (AVX2: 4 doubles per instruction, FMA).

Nothing of the numerics is written here: the lane step inlines the one field
(:func:`gearsim.dynamics.model.field_state` / :func:`~gearsim.dynamics.model.field_tangent`), the
one RK4 step
(:func:`gearsim.numerics.steps.rk4_state` / :func:`~gearsim.numerics.steps.rk4_tangent`) and the
one test for a step
that needs event handling (:func:`gearsim.numerics.steps.grid_step_flag`); a flagged lane is redone
by the
one event layer (:func:`gearsim.numerics.events.advance_interval`, the same call the scalar
integrator
makes). The scalar RK4 path (:func:`gearsim.numerics.integrate.integrate_periods`) runs the same
algorithm for one cell, so the two give bit-identical section points (tests/unit/test_batch.py).

Every lane uses the same number ``N`` of RK4 steps per mesh period, so all lanes share one grid in
*phase* ``theta = w tau`` (:func:`gearsim.numerics.steps.phase_tables`). Lanes may have different
``w``
(the step ``h = T / N`` is a per-lane value): each lane is an independent continuation chain
(e.g. one plane row marching along ``w``) and moves on to its next cell on its own schedule.

The chain driver that moves lanes from cell to cell (transient, chunks, the period test,
classification) is :mod:`gearsim.cell.chains`; the lane storage and the batched runs built on
this kernel are :mod:`gearsim.numerics.batch`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from gearsim.dynamics.model import (
    MODE_FRICTION,
    N_FIELD,
    N_MODE,
    N_PARAMS,
    N_STATE,
    N_SWITCH,
    P_ACT,
    P_DOF6,
    P_GAM1,
    P_VRA,
    P_VRC,
    P_VRS,
    P_VTE,
    P_W,
    P_XIO,
    field_params,
    mesh_force,
    mesh_force_full,
    period_forcing,
    tracked_force,
)
from gearsim.numerics.events import (
    ACC_FMAX,
    ACC_FMIN,
    ACC_TD,
    ACC_XMAX,
    ACC_XMIN,
    CNT_NB,
    CNT_NF,
    CNT_STEPS,
    N_ACC,
    N_CNT,
    advance_interval,
    channels,
)
from gearsim.numerics.integrate import _rk4_grid_interval, end_period_tangent
from gearsim.numerics.lanes_layout import (
    BLOCK,
    IST_DONE,
    IST_K,
    IST_NB,
    IST_NF,
    IST_POS,
    IST_ST,
    IST_STEPS,
    LANES,
    O_FMAX,
    O_FMIN,
    O_LYAP,
    O_TDIS,
    O_XMAX,
    O_XMIN,
    ROW_FLAG,
    ROW_FMN,
    ROW_FMX,
    ROW_H,
    ROW_PAR,
    ROW_R0,
    ROW_RB,
    ROW_S0,
    ROW_SB,
    ROW_TD,
    ROW_XMN,
    ROW_XMX,
    ROW_Y,
)
from gearsim.numerics.steps import (
    FASTMATH,
    METHOD_RK4,
    grid_step_flag,
    rk4_state,
    rk4_tangent,
)


# ============================================================================ block accessors
@njit(cache=True, nogil=True, inline="always")
def _load10(blk, o, row, q):
    r = o + row * LANES + q
    return (
        blk[r], blk[r + LANES], blk[r + 2 * LANES], blk[r + 3 * LANES], blk[r + 4 * LANES],
        blk[r + 5 * LANES], blk[r + 6 * LANES], blk[r + 7 * LANES], blk[r + 8 * LANES],
        blk[r + 9 * LANES],
    )  # fmt: skip


@njit(cache=True, nogil=True, inline="always")
def _lane_modes(blk, o, q):
    r = o + q
    L = LANES
    return (
        blk[r + ROW_R0 * L], blk[r + ROW_S0 * L],
        blk[r + ROW_RB * L], blk[r + (ROW_RB + 1) * L], blk[r + (ROW_RB + 2) * L],
        blk[r + (ROW_RB + 3) * L],
        blk[r + ROW_SB * L], blk[r + (ROW_SB + 1) * L], blk[r + (ROW_SB + 2) * L],
        blk[r + (ROW_SB + 3) * L],
    )  # fmt: skip


@njit(cache=True, nogil=True, inline="always")
def step_entries(A, B, i2):
    """The entries of two phase tables at grid step ``i2 / 2``'s start, middle and end,
    interleaved: ``A[i2], B[i2], A[i2 + 1], B[i2 + 1], A[i2 + 2], B[i2 + 2]``."""
    return A[i2], B[i2], A[i2 + 1], B[i2 + 1], A[i2 + 2], B[i2 + 2]


@njit(cache=True, nogil=True, inline="always")
def _fmax(a, b):
    return a if a >= b else b


@njit(cache=True, nogil=True, inline="always")
def _fmin(a, b):
    return a if a <= b else b


@njit(cache=True, nogil=True, inline="always")
def _sel(flag, a, b):
    return a if flag else b


@njit(cache=True, nogil=True, inline="always")
def _store10(blk, r, flag, old, new):
    """Store ``old`` (flagged lane) or ``new`` into 10 consecutive rows starting at ``r``."""
    blk[r] = _sel(flag, old[0], new[0])
    blk[r + LANES] = _sel(flag, old[1], new[1])
    blk[r + 2 * LANES] = _sel(flag, old[2], new[2])
    blk[r + 3 * LANES] = _sel(flag, old[3], new[3])
    blk[r + 4 * LANES] = _sel(flag, old[4], new[4])
    blk[r + 5 * LANES] = _sel(flag, old[5], new[5])
    blk[r + 6 * LANES] = _sel(flag, old[6], new[6])
    blk[r + 7 * LANES] = _sel(flag, old[7], new[7])
    blk[r + 8 * LANES] = _sel(flag, old[8], new[8])
    blk[r + 9 * LANES] = _sel(flag, old[9], new[9])


# ============================================================================ the vector step
# the model-form slots are the field tuple's last three: the base form is its head and zeros
assert (P_VTE, P_XIO, P_GAM1, N_FIELD) == (26, 27, 28, 29)


@njit(cache=True, nogil=True, inline="always")
def _base_form(P):
    """The field tuple ``P`` with its model-form slots (``P_VTE``, ``P_XIO``, ``P_GAM1``) the
    constant 0.0 (a static slice and a literal tail: the CPU and CUDA targets both type it)."""
    return P[:26] + (0.0, 0.0, 0.0)


@njit(cache=True, nogil=True, inline="always")
def lane_step(blk, o, q, cA, sA, cvA, svA, cM, sM, cvM, svM, cB, sB, cvB, svB, lam, qA, qM, qB,
               bound, tangent, bearings, forms):
    """RK4 grid step of lane ``q`` of a block (straight-line code: selects, no branches).

    The arithmetic of ``integrate._rk4_grid_interval`` (the same inlined functions). With
    ``forms`` a literal False (no lane uses a model-form option), the form parameters are the
    constant 0.0 they hold, so LLVM drops the field's form branch (bit-identical; without this
    the branch is if-converted and computed for every lane: +21 % instructions).
    """
    L = LANES
    r = o + q
    y = _load10(blk, o, ROW_Y, q)
    P = field_params(blk, r + ROW_PAR * L, L)
    if not forms:
        P = _base_form(P)
    M = _lane_modes(blk, o, q)
    h = blk[r + ROW_H * L]
    vrs = blk[r + (ROW_PAR + P_VRS) * L]
    vrc = blk[r + (ROW_PAR + P_VRC) * L]
    vA = vrs * cvA + vrc * svA
    vM = vrs * cvM + vrc * svM
    vB = vrs * cvB + vrc * svB
    yn = rk4_state(y, h, cA, sA, vA, cM, sM, vM, cB, sB, vB, lam, qA, qM, qB, P, M)
    A = (blk[r + (ROW_PAR + P_ACT) * L], blk[r + (ROW_PAR + P_ACT + 1) * L],
         blk[r + (ROW_PAR + P_ACT + 2) * L], blk[r + (ROW_PAR + P_ACT + 3) * L])
    event, turn = grid_step_flag(y, yn, P, M, A, bound, bearings)
    flag = event | turn
    _store10(blk, r + ROW_Y * L, flag, y, yn)
    if tangent:
        z = _load10(blk, o, ROW_Y + 10, q)
        zn = rk4_tangent(z, h, cA, cM, cB, lam, qA, qM, qB, P, M)
        _store10(blk, r + (ROW_Y + 10) * L, flag, z, zn)
    r0 = M[0]
    td = blk[r + ROW_TD * L]
    blk[r + ROW_TD * L] = _sel(flag | (r0 != 0.0), td, td + h)
    if forms:  # a literal: the base lane loop keeps mesh_force
        fl = mesh_force_full(cB, sB, yn[0], yn[1], P, r0, M[1])
    else:
        fl = mesh_force(cB, yn[0], yn[1], P, r0, M[1])
    fmx = blk[r + ROW_FMX * L]
    fmn = blk[r + ROW_FMN * L]
    xmx = blk[r + ROW_XMX * L]
    xmn = blk[r + ROW_XMN * L]
    blk[r + ROW_FMX * L] = _sel(flag, fmx, _fmax(fmx, fl))
    blk[r + ROW_FMN * L] = _sel(flag, fmn, _fmin(fmn, fl))
    blk[r + ROW_XMX * L] = _sel(flag, xmx, _fmax(xmx, yn[0]))
    blk[r + ROW_XMN * L] = _sel(flag, xmn, _fmin(xmn, yn[0]))
    blk[r + ROW_FLAG * L] = _sel(event, 1.0, _sel(turn, 2.0, 0.0))


@njit(cache=True, nogil=True, fastmath=FASTMATH)
def _block_step(blk, bi, cA, sA, cvA, svA, cM, sM, cvM, svM, cB, sB, cvB, svB, lam, qA, qM, qB,
                bound, tangent, general):
    """One RK4 step (the state, and the tangent vector if ``tangent``) of block ``bi``'s lanes.

    The loop over the lanes is straight-line code and vectorises (check: ``inspect_asm()``).
    ``tangent`` and ``general`` must be literals at the call site: compiled loops without the
    tangent code for the transients, and the base loop (``general`` False: no lane has a
    bearing clearance or a model-form option, so neither the bearing channels' watch nor the
    forms' terms are computed) beside the general one (``general`` True: both, for every lane;
    a lane without them gets the base loop's numbers, bit for bit: an inactive channel is never
    flagged and the forms' terms of a base lane are exact zeros).
    Unflagged lanes are updated in place (state, tangent, accumulators); flagged lanes (1.0: an
    event, 2.0: a turning point of x) are left untouched for :func:`redo_lane`. Returns True if
    any lane is flagged.
    """
    o = (bi & 0xFFFFFF) * BLOCK  # provably >= 0: no wrap-around selects on the indices
    for q in range(LANES):
        lane_step(blk, o, q, cA, sA, cvA, svA, cM, sM, cvM, svM, cB, sB, cvB, svB, lam, qA, qM,
                   qB, bound, tangent, general, general)
    anyf = False
    for q in range(LANES):
        anyf = anyf | (blk[o + ROW_FLAG * LANES + q] != 0.0)
    return anyf


# ============================================================================ flagged lanes
@njit(cache=True, nogil=True, _nrt=False)
def redo_lane(blk, o, q, l, ist, j, N, lam, bound, tangent, wk, turn, general, tabs):
    """Redo grid step ``j`` of lane ``q`` as the scalar integrator does.

    The lane's rows are copied into the scalar work arrays of ``wk``; a turning point (``turn``)
    takes the scalar path's grid step (:func:`gearsim.numerics.integrate._rk4_grid_interval`
    with the phase tables ``tabs``: the same step as the vector one, which stands when its
    turning point cannot graze, with its extremum); an event, or a turning point that may graze,
    is advanced by :func:`gearsim.numerics.events.advance_interval` over ``[j h, (j + 1) h]``.
    The rows are copied back.
    """
    wy, pw, mode, gaps, active, acc, cnt, ks, ytmp, ynew, ytry, ev_t, ev_c = wk
    L = LANES
    r = o + q
    for i in range(20):
        wy[i] = blk[r + (ROW_Y + i) * L]
    for i in range(N_PARAMS):
        pw[i] = blk[r + (ROW_PAR + i) * L]
    mode[0] = int(blk[r + ROW_R0 * L])
    for c in range(1, N_SWITCH):
        mode[c] = int(blk[r + (ROW_RB + c - 1) * L])
    mode[MODE_FRICTION] = int(lam)
    channels(pw, mode, wy, gaps, active, False)
    acc[ACC_TD] = blk[r + ROW_TD * L]
    acc[ACC_FMAX] = blk[r + ROW_FMX * L]
    acc[ACC_FMIN] = blk[r + ROW_FMN * L]
    acc[ACC_XMAX] = blk[r + ROW_XMX * L]
    acc[ACC_XMIN] = blk[r + ROW_XMN * L]
    cnt[CNT_NF] = ist[IST_NF, l]
    cnt[CNT_NB] = ist[IST_NB, l]
    cnt[CNT_STEPS] = 0
    h = blk[r + ROW_H * L]
    C, S, LAM, CV, SV, Q = tabs
    status = 0
    if not turn or _rk4_grid_interval(j, h, wy, pw, mode, tangent, C, S, LAM, CV, SV, Q, general,
                                      bound, acc):
        T = 2.0 * np.pi / pw[P_W]
        t_end = T if j == N - 1 else (j + 1) * h
        nerr = N_STATE if pw[P_DOF6] != 0.0 else 2
        status = advance_interval(METHOD_RK4, j * h, t_end, wy, pw, mode, gaps, active,
                                  20 if tangent else 10, nerr, tangent, ks, ytmp, ynew, ytry, 0.0,
                                  0.0, 0.0, T, bound, acc, cnt, ev_t, ev_c, 0.0)
        ist[IST_STEPS, l] += cnt[CNT_STEPS] - 1  # the grid step itself is counted per period
    # ---- store back
    for i in range(20):
        blk[r + (ROW_Y + i) * L] = wy[i]
    blk[r + ROW_R0 * L] = float(mode[0])
    blk[r + ROW_S0 * L] = float(abs(mode[0]))
    for c in range(1, N_SWITCH):
        blk[r + (ROW_RB + c - 1) * L] = float(mode[c])
        blk[r + (ROW_SB + c - 1) * L] = float(abs(mode[c]))
    blk[r + ROW_TD * L] = acc[ACC_TD]
    blk[r + ROW_FMX * L] = acc[ACC_FMAX]
    blk[r + ROW_FMN * L] = acc[ACC_FMIN]
    blk[r + ROW_XMX * L] = acc[ACC_XMAX]
    blk[r + ROW_XMN * L] = acc[ACC_XMIN]
    ist[IST_NF, l] = cnt[CNT_NF]
    ist[IST_NB, l] = cnt[CNT_NB]
    if status != 0:
        ist[IST_ST, l] = 1
        ist[IST_STEPS, l] += j + 1
        blk[r + ROW_H * L] = 0.0  # freeze the lane


# ============================================================================ lane bookkeeping
# The per-lane pieces of a period that every lane kernel shares (this SIMD kernel and the
# one-thread-per-lane CUDA kernel of :mod:`gearsim.numerics.cuda_lanes`): the same functions, so
# the two keep one lane state and one record layout.
@njit(cache=True, nogil=True, inline="always")
def lane_general(blk, r):
    """The lane at row offset ``r`` needs the general step: a bearing clearance (its channels
    watched) or a model-form option (docs/model.md)."""
    L = LANES
    g = False
    for c in range(4):
        if blk[r + (ROW_PAR + P_ACT + c) * L] != 0.0:
            g = True
    if (blk[r + (ROW_PAR + P_VTE) * L] != 0.0 or blk[r + (ROW_PAR + P_XIO) * L] != 0.0
            or blk[r + (ROW_PAR + P_GAM1) * L] != 0.0):
        g = True
    return g


@njit(cache=True, nogil=True)
def lane_reset_modes(blk, l, p, mode, y, gaps, active):
    """The regions of lane ``l`` from its state (what ``integrate_periods`` does at the start of
    every call): the host's :meth:`gearsim.numerics.batch.Lanes.reset_modes` and a CUDA thread
    between two measuring chunks call this one function. ``p``, ``mode``, ``y``, ``gaps``,
    ``active``: scratch of N_PARAMS, N_MODE, N_STATE, N_SWITCH floats and N_SWITCH bools."""
    L = LANES
    r = (l // L) * BLOCK + (l % L)
    for i in range(N_PARAMS):
        p[i] = blk[r + (ROW_PAR + i) * L]
    for i in range(N_STATE):
        y[i] = blk[r + (ROW_Y + i) * L]
    for i in range(N_MODE):
        mode[i] = 0
    channels(p, mode, y, gaps, active, True)
    blk[r + ROW_R0 * L] = float(mode[0])
    blk[r + ROW_S0 * L] = float(abs(mode[0]))
    for c in range(1, 5):
        blk[r + (ROW_RB + c - 1) * L] = float(mode[c])
        blk[r + (ROW_SB + c - 1) * L] = float(abs(mode[c]))


@njit(cache=True, nogil=True, inline="always")
def period_start(blk, ist, l, k, nu, sec):
    """Start period ``k`` of lane ``l``: its section point, the per-period accumulators and
    counters, and the period's variable-ratio phase."""
    L = LANES
    r = (l // L) * BLOCK + (l % L)
    pos = ist[IST_POS, l]
    if pos >= 0:
        for i in range(N_STATE):
            sec[l, pos + k, i] = blk[r + (ROW_Y + i) * L]
    x = blk[r + ROW_Y * L]
    r0 = blk[r + ROW_R0 * L]
    f0 = tracked_force(1.0, 0.0, x, blk[r + (ROW_Y + 1) * L], field_params(blk, r + ROW_PAR * L, L),
                       r0, abs(r0))
    blk[r + ROW_FMX * L] = f0
    blk[r + ROW_FMN * L] = f0
    blk[r + ROW_XMX * L] = x
    blk[r + ROW_XMN * L] = x
    blk[r + ROW_TD * L] = 0.0
    ist[IST_NF, l] = 0
    ist[IST_NB, l] = 0
    vrs, vrc = period_forcing(blk[r + (ROW_PAR + P_VRA) * L], nu, ist[IST_K, l] + k)
    blk[r + (ROW_PAR + P_VRS) * L] = vrs
    blk[r + (ROW_PAR + P_VRC) * L] = vrc


@njit(cache=True, nogil=True, inline="always")
def period_end(blk, ist, l, k, N, wz, nface, nback, fout):
    """End period ``k`` of lane ``l``: the tangent vector's growth (renormalised; ``wz`` is
    scratch of N_STATE), the period's records, the counters."""
    L = LANES
    r = (l // L) * BLOCK + (l % L)
    for i in range(N_STATE):
        wz[i] = blk[r + (ROW_Y + 10 + i) * L]
    ly = end_period_tangent(wz)
    for i in range(N_STATE):
        blk[r + (ROW_Y + 10 + i) * L] = wz[i]
    pos = ist[IST_POS, l]
    if pos >= 0:
        kk = pos + k
        nface[l, kk] = ist[IST_NF, l]
        nback[l, kk] = ist[IST_NB, l]
        fout[l, kk, O_TDIS] = blk[r + ROW_TD * L]
        fout[l, kk, O_FMAX] = blk[r + ROW_FMX * L]
        fout[l, kk, O_FMIN] = blk[r + ROW_FMN * L]
        fout[l, kk, O_XMAX] = blk[r + ROW_XMX * L]
        fout[l, kk, O_XMIN] = blk[r + ROW_XMN * L]
        fout[l, kk, O_LYAP] = ly
    ist[IST_DONE, l] += 1
    ist[IST_STEPS, l] += N


# ============================================================================ the kernel
@njit(cache=True, nogil=True, fastmath=FASTMATH)
def advance(blk, ist, N, m, C, S, LAM, CV, SV, Q, nu, bound, sec, nface, nback, fout,
            tangent=True):
    """Advance every lane with ``ist[IST_ST] == 0`` by ``m`` mesh periods of ``N`` RK4 steps.

    Parameters
    ----------
    blk
        Flat float64 array of ``n_blocks * BLOCK`` lane rows (layout: the ``_*`` row constants).
    ist
        int64 ``[NI, n_lanes]``: status (lanes with status != 0 are skipped; a lane that diverges
        gets status 1 and is frozen), periods done, record position, absolute period index,
        step count, face/back entries of the current period.
    C, S, LAM, CV, SV, Q
        The phase tables of :func:`gearsim.numerics.steps.phase_tables` for ``N`` and ``nu``.
    sec, nface, nback, fout
        Per-lane records ``[n_lanes, capacity, ...]``; period ``k`` of lane ``l`` is written at
        ``ist[IST_POS, l] + k`` when that position is >= 0 (``fout`` columns: ``O_*``).
    """
    n_lanes = ist.shape[1]
    nblk = n_lanes // LANES
    L = LANES
    wk = (
        np.zeros(20), np.zeros(N_PARAMS), np.zeros(N_MODE, dtype=np.int64), np.zeros(N_SWITCH),
        np.zeros(N_SWITCH, dtype=np.bool_), np.zeros(N_ACC), np.zeros(N_CNT, dtype=np.int64),
        np.zeros((7, 20)), np.zeros(20), np.zeros(20), np.zeros(20), np.zeros(0),
        np.zeros(0, dtype=np.int64),
    )  # fmt: skip
    wz = np.zeros(N_STATE)
    # the lane-set property, read back from an array: a variable assigned the constant False
    # would be typed Literal[bool](False) first, and every block step compiled twice
    anyof = np.zeros(1, dtype=np.bool_)
    for l in range(n_lanes):
        if lane_general(blk, (l // L) * BLOCK + (l % L)):
            anyof[0] = True
    general = anyof[0]
    for k in range(m):
        # ---- period start: section, accumulators, variable-ratio phase of the lane
        for l in range(n_lanes):
            if ist[IST_ST, l] == 0:
                period_start(blk, ist, l, k, nu, sec)
        # ---- the N grid steps of the period
        for j in range(N):
            i2 = 2 * j
            cA, sA, cM, sM, cB, sB = step_entries(C, S, i2)
            cvA, svA, cvM, svM, cvB, svB = step_entries(CV, SV, i2)
            lam = LAM[j]
            qA = Q[i2]
            qM = Q[i2 + 1]
            qB = Q[i2 + 2]
            for bi in range(nblk):
                o = bi * BLOCK
                if tangent and general:
                    anyf = _block_step(blk, bi, cA, sA, cvA, svA, cM, sM, cvM, svM, cB, sB,
                                       cvB, svB, lam, qA, qM, qB, bound, True, True)
                elif tangent:
                    anyf = _block_step(blk, bi, cA, sA, cvA, svA, cM, sM, cvM, svM, cB, sB,
                                       cvB, svB, lam, qA, qM, qB, bound, True, False)
                elif general:
                    anyf = _block_step(blk, bi, cA, sA, cvA, svA, cM, sM, cvM, svM, cB, sB,
                                       cvB, svB, lam, qA, qM, qB, bound, False, True)
                else:
                    anyf = _block_step(blk, bi, cA, sA, cvA, svA, cM, sM, cvM, svM, cB, sB,
                                       cvB, svB, lam, qA, qM, qB, bound, False, False)
                if anyf:
                    for q in range(L):
                        fq = blk[o + ROW_FLAG * L + q]
                        if fq != 0.0:
                            ll = bi * L + q
                            if ist[IST_ST, ll] == 0:
                                redo_lane(blk, o, q, ll, ist, j, N, lam, bound, tangent, wk,
                                           fq == 2.0, general, (C, S, LAM, CV, SV, Q))
        # ---- period end: tangent growth, records
        for l in range(n_lanes):
            if ist[IST_ST, l] == 0:
                period_end(blk, ist, l, k, N, wz, nface, nback, fout)
