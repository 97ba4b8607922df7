"""Batched fixed-step RK4: many cells advanced at once, the cell index innermost (SIMD lanes).

Why
---
One cell integrated by :func:`gearsim.integrate.integrate_periods` is a single dependency chain
(each RK4 stage needs the previous one), so a scalar kernel cannot use the vector units. Here a
*lane* is one cell; lanes are packed in blocks of :data:`LANES` with every per-lane quantity
(state, tangent vector, parameters, frozen contact regions, per-period accumulators) stored as a
row of ``LANES`` consecutive doubles. The inner loop runs over the lanes of a block with
compile-time strides, so LLVM vectorises the whole RK4 step (AVX2: 4 doubles per instruction).

Every lane uses the same number ``N`` of RK4 steps per mesh period, so all lanes share one grid in
*phase* ``theta = w tau``: the mesh-phase ``cos``/``sin`` (stiffness, error forcing, friction
direction, variable-ratio forcing) are tabulated once on the half-step grid ``theta_i = pi i / N``
and no transcendental function is evaluated in the inner loop. Lanes may have different ``w``
(the step ``h = T / N`` is a per-lane value): each lane is an independent continuation chain
(e.g. one plane row marching along ``w``) and moves on to its next cell on its own schedule.

Contact switches
----------------
After each vector step a lane is *flagged* when any contact region changed, when a watched
velocity changed sign (a possible grazing excursion inside the step, and the Hermite extremum
that the per-period force/displacement extremes need), or when its state left the divergence
bound. Flagged lanes (a few per cent of the lane-steps) redo that step in a scalar fix-up path
that is a line-by-line port of the event handling of ``integrate_periods`` for ``METHOD_RK4``:
Hermite-cubic bracketing, graze verification by a real step, safeguarded Newton-bisection on real
RK4 sub-steps to ``|g| <= 1e-12 (1 + gap)``, landing on the switch, the region change, and the
rest of the grid interval in the new region. So every per-period summary (section state,
face/back entries, disengaged time, force and displacement extremes, tangent log-growth) is the
one ``integrate_periods`` computes with the same method and steps per period, to rounding, and
:mod:`gearsim.classify` is used unchanged (tests/test_batch.py checks both).

Differences from ``integrate_periods`` (all at rounding level, none for the default parameters):
the mesh phase comes from the table (or ``w * tau_rel`` within the period) instead of
``w * tau_abs``; with friction the direction ``lambda`` is taken per grid step (exactly constant
on it when ``N`` is even; an odd ``N`` is raised by one when ``friction != 0``); the tangent
vector is integrated (and renormalised every period) during the transient too, and discarded.

Driver
------
:func:`simulate_rows` is :func:`gearsim.sweep.continuation_chain` for many chains at once, with
the early-stopping logic of :func:`gearsim.simulate.simulate_cell` per lane (transient, chunks,
period test after each chunk, classification). Single-DOF cells are passed to
``continuation_chain`` (the batched kernel is the 6-DOF model).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from .classify import Classification, PeriodSummaries, classify_motion
from .model import N_STATE, static_state
from .parameters import ModelParameters, ParameterError
from .simulate import TANGENT_SEED, CellResult, IntegrationSettings

#: Lanes per block (compile-time stride of the vector loop; 8 = two AVX2 vectors).
LANES = 8

# ---- float rows of a block (each row holds LANES doubles) ------------------------------------
_Y = 0  # 20 rows: state (10) then tangent vector (10)
_H = 20  # step h = T / N (0 freezes the lane)
_W = 21
_EPS = 22
_XI2 = 23  # 2 xi
_B = 24
_FM = 25
_FEW2 = 26  # Fe w^2
_CPHI = 27  # cos(phi_e)
_SPHI = 28  # sin(phi_e)
_GAM = 29  # friction factor gamma
_CA = 30  # cos(alpha)
_SA = 31  # sin(alpha)
_RPCA = 32  # rho_p cos(alpha)
_RPSA = 33  # rho_p sin(alpha)
_RGCA = 34  # rho_g cos(alpha)
_RGSA = 35  # rho_g sin(alpha)
_KAP = 36  # 4 rows: kappa py, pz, gy, gz
_ZB = 40  # 4 rows: 2 xi_brg
_GAP = 44  # 4 rows: bearing half clearances
_VRA = 48  # variable-ratio amplitude A w^2
_VRS = 49  # A w^2 sin(2 pi nu K) for the current period K
_VRC = 50  # A w^2 cos(2 pi nu K)
_R0 = 51  # mesh region (-1, 0, 1) as a double
_S0 = 52  # |mesh region|
_RB = 53  # 4 rows: bearing regions
_SB = 57  # 4 rows: |bearing region|
_ACT = 61  # 4 rows: bearing channel active (1.0) or linear (0.0)
_TD = 65  # per-period accumulators: disengaged time, force and x extremes
_FMX = 66
_FMN = 67
_XMX = 68
_XMN = 69
_FLAG = 70  # 1.0 when the lane needs the scalar fix-up for the current step
NROW = 71
BLOCK = NROW * LANES

# ---- integer rows (2-D array [NI, n_lanes]; touched by scalar code only) ---------------------
_ST = 0  # status: 0 running, 1 diverged, -1 not taking part in this call
_DONE = 1  # periods completed in this call
_POS = 2  # record position of the first period of this call (-1: do not record)
_K = 3  # absolute period index at the start of the call
_STEPS = 4  # RK4 steps taken in this call (including the fix-up trial steps)
_NF = 5  # face entries in the current period
_NB = 6  # back entries in the current period
NI = 7

# ---- columns of the float per-period output ----
O_TDIS, O_FMAX, O_FMIN, O_XMAX, O_XMIN, O_LYAP = range(6)

_FASTMATH = {"contract"}  # FMA contraction only: no reassociation, NaN/inf semantics kept


# ============================================================================ the vector field
@njit(cache=True, nogil=True, inline="always")
def _dstate(c, s, lam, vr, y, P, M):
    """Right-hand side of the state for one lane with frozen regions (a 10-tuple).

    ``c, s`` = cos, sin of the mesh phase ``w tau``; ``lam`` the friction direction; ``vr`` the
    variable-ratio forcing. ``P`` lane parameters, ``M`` frozen regions (see ``_lane_params``).
    Same equations as :func:`gearsim.model.rhs` (checked by tests/test_batch.py).
    """
    (eps, xi2, b, fm, few2, cphi, sphi, gam, ca, sa, rpca, rpsa, rgca, rgsa,
     k0, k1, k2, k3, z0, z1, z2, z3, g0, g1, g2, g3) = P  # fmt: skip
    (r0, s0, rb0, rb1, rb2, rb3, sb0, sb1, sb2, sb3) = M
    F = (1.0 + eps * c) * (s0 * y[0] - r0 * b) + xi2 * y[1]
    drive = fm + few2 * (c * cphi - s * sphi) + vr
    a_py = -z0 * y[3] - k0 * (sb0 * y[2] - rb0 * g0) - rpca * F
    a_pz = -z1 * y[5] - k1 * (sb1 * y[4] - rb1 * g1) - rpsa * F
    a_gy = -z2 * y[7] - k2 * (sb2 * y[6] - rb2 * g2) + rgca * F
    a_gz = -z3 * y[9] - k3 * (sb3 * y[8] - rb3 * g3) + rgsa * F
    acc = drive - F * (1.0 + gam * lam) + (a_py - a_gy) * ca + (a_pz - a_gz) * sa
    return (y[1], acc, y[3], a_py, y[5], a_pz, y[7], a_gy, y[9], a_gz)


@njit(cache=True, nogil=True, inline="always")
def _dtangent(c, lam, z, P, M):
    """Jacobian-vector product of the same frozen (piecewise-linear) field: a 10-tuple."""
    (eps, xi2, b, fm, few2, cphi, sphi, gam, ca, sa, rpca, rpsa, rgca, rgsa,
     k0, k1, k2, k3, z0, z1, z2, z3, g0, g1, g2, g3) = P  # fmt: skip
    (r0, s0, rb0, rb1, rb2, rb3, sb0, sb1, sb2, sb3) = M
    dF = (1.0 + eps * c) * s0 * z[0] + xi2 * z[1]
    d_py = -z0 * z[3] - k0 * sb0 * z[2] - rpca * dF
    d_pz = -z1 * z[5] - k1 * sb1 * z[4] - rpsa * dF
    d_gy = -z2 * z[7] - k2 * sb2 * z[6] + rgca * dF
    d_gz = -z3 * z[9] - k3 * sb3 * z[8] + rgsa * dF
    dacc = -dF * (1.0 + gam * lam) + (d_py - d_gy) * ca + (d_pz - d_gz) * sa
    return (z[1], dacc, z[3], d_py, z[5], d_pz, z[7], d_gy, z[9], d_gz)


@njit(cache=True, nogil=True, inline="always")
def _field(c, s, lam, vr, y, z, P, M):
    """State and tangent right-hand sides ``(dy, dz)`` (for tests and the scalar path)."""
    return _dstate(c, s, lam, vr, y, P, M), _dtangent(c, lam, z, P, M)


@njit(cache=True, nogil=True, inline="always")
def _axpy(y, a, k):
    """``y + a k`` for 10-tuples."""
    return (
        y[0] + a * k[0], y[1] + a * k[1], y[2] + a * k[2], y[3] + a * k[3], y[4] + a * k[4],
        y[5] + a * k[5], y[6] + a * k[6], y[7] + a * k[7], y[8] + a * k[8], y[9] + a * k[9],
    )  # fmt: skip


@njit(cache=True, nogil=True, inline="always")
def _add2(s, k):
    """``s + 2 k`` for 10-tuples (the RK4 weight sum, accumulated in the order of integrate)."""
    return (
        s[0] + 2.0 * k[0], s[1] + 2.0 * k[1], s[2] + 2.0 * k[2], s[3] + 2.0 * k[3],
        s[4] + 2.0 * k[4], s[5] + 2.0 * k[5], s[6] + 2.0 * k[6], s[7] + 2.0 * k[7],
        s[8] + 2.0 * k[8], s[9] + 2.0 * k[9],
    )  # fmt: skip


@njit(cache=True, nogil=True, inline="always")
def _add(s, k):
    return (
        s[0] + k[0], s[1] + k[1], s[2] + k[2], s[3] + k[3], s[4] + k[4],
        s[5] + k[5], s[6] + k[6], s[7] + k[7], s[8] + k[8], s[9] + k[9],
    )  # fmt: skip


@njit(cache=True, nogil=True, inline="always")
def _rk4_state(y, h, cA, sA, vA, cM, sM, vM, cB, sB, vB, lam, P, M):
    """One classical RK4 step of the state, ``y + h/6 (k1 + 2 k2 + 2 k3 + k4)``.

    The weight sum is accumulated stage by stage (few live values: no register spills), in the
    same order of additions as ``integrate._rk4_step``.
    """
    a = 0.5 * h
    k = _dstate(cA, sA, lam, vA, y, P, M)
    acc = k
    k = _dstate(cM, sM, lam, vM, _axpy(y, a, k), P, M)
    acc = _add2(acc, k)
    k = _dstate(cM, sM, lam, vM, _axpy(y, a, k), P, M)
    acc = _add2(acc, k)
    k = _dstate(cB, sB, lam, vB, _axpy(y, h, k), P, M)
    acc = _add(acc, k)
    return _axpy(y, h / 6.0, acc)


@njit(cache=True, nogil=True, inline="always")
def _rk4_tangent(z, h, cA, cM, cB, lam, P, M):
    """The same RK4 step for the tangent vector (linear; independent of the state)."""
    a = 0.5 * h
    k = _dtangent(cA, lam, z, P, M)
    acc = k
    k = _dtangent(cM, lam, _axpy(z, a, k), P, M)
    acc = _add2(acc, k)
    k = _dtangent(cM, lam, _axpy(z, a, k), P, M)
    acc = _add2(acc, k)
    k = _dtangent(cB, lam, _axpy(z, h, k), P, M)
    acc = _add(acc, k)
    return _axpy(z, h / 6.0, acc)


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
def _lane_params(blk, o, q):
    r = o + q
    L = LANES
    return (
        blk[r + _EPS * L], blk[r + _XI2 * L], blk[r + _B * L], blk[r + _FM * L],
        blk[r + _FEW2 * L], blk[r + _CPHI * L], blk[r + _SPHI * L], blk[r + _GAM * L],
        blk[r + _CA * L], blk[r + _SA * L], blk[r + _RPCA * L], blk[r + _RPSA * L],
        blk[r + _RGCA * L], blk[r + _RGSA * L],
        blk[r + _KAP * L], blk[r + (_KAP + 1) * L], blk[r + (_KAP + 2) * L],
        blk[r + (_KAP + 3) * L],
        blk[r + _ZB * L], blk[r + (_ZB + 1) * L], blk[r + (_ZB + 2) * L], blk[r + (_ZB + 3) * L],
        blk[r + _GAP * L], blk[r + (_GAP + 1) * L], blk[r + (_GAP + 2) * L],
        blk[r + (_GAP + 3) * L],
    )  # fmt: skip


@njit(cache=True, nogil=True, inline="always")
def _lane_modes(blk, o, q):
    r = o + q
    L = LANES
    return (
        blk[r + _R0 * L], blk[r + _S0 * L],
        blk[r + _RB * L], blk[r + (_RB + 1) * L], blk[r + (_RB + 2) * L], blk[r + (_RB + 3) * L],
        blk[r + _SB * L], blk[r + (_SB + 1) * L], blk[r + (_SB + 2) * L], blk[r + (_SB + 3) * L],
    )  # fmt: skip


@njit(cache=True, nogil=True, inline="always")
def _region(x, gap):
    if x > gap:
        return 1.0
    if x < -gap:
        return -1.0
    return 0.0


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


@njit(cache=True, nogil=True, inline="always")
def _watch(v0, u1, v1, gap, r, act):
    """Bearing channel needs the fix-up: active and (region changed or velocity sign change)."""
    return (act != 0.0) & ((_region(u1, gap) != r) | (v0 * v1 < 0.0))


# ============================================================================ the vector step
@njit(cache=True, nogil=True, inline="always")
def _lane_step(blk, o, q, cA, sA, cvA, svA, cM, sM, cvM, svM, cB, sB, cvB, svB, lam, bound,
               tangent, bearings):
    """RK4 step of lane ``q`` of a block (straight-line code: selects, no branches)."""
    L = LANES
    r = o + q
    y = _load10(blk, o, _Y, q)
    P = _lane_params(blk, o, q)
    M = _lane_modes(blk, o, q)
    h = blk[r + _H * L]
    vrs = blk[r + _VRS * L]
    vrc = blk[r + _VRC * L]
    vA = vrs * cvA + vrc * svA
    vM = vrs * cvM + vrc * svM
    vB = vrs * cvB + vrc * svB
    yn = _rk4_state(y, h, cA, sA, vA, cM, sM, vM, cB, sB, vB, lam, P, M)
    b = P[2]
    r0 = M[0]
    s0 = M[1]
    flag = (_region(yn[0], b) != r0) | (y[1] * yn[1] < 0.0)
    if bearings:  # loop-invariant: LLVM unswitches the lane loop (no cost without clearances)
        flag = flag | _watch(y[3], yn[2], yn[3], P[22], M[2], blk[r + _ACT * L])
        flag = flag | _watch(y[5], yn[4], yn[5], P[23], M[3], blk[r + (_ACT + 1) * L])
        flag = flag | _watch(y[7], yn[6], yn[7], P[24], M[4], blk[r + (_ACT + 2) * L])
        flag = flag | _watch(y[9], yn[8], yn[9], P[25], M[5], blk[r + (_ACT + 3) * L])
    ok = (abs(yn[0]) < bound) & (abs(yn[1]) < bound) & (abs(yn[2]) < bound)
    ok = ok & (abs(yn[3]) < bound) & (abs(yn[4]) < bound) & (abs(yn[5]) < bound)
    ok = ok & (abs(yn[6]) < bound) & (abs(yn[7]) < bound) & (abs(yn[8]) < bound)
    ok = ok & (abs(yn[9]) < bound)
    flag = flag | (not ok)
    _store10(blk, r + _Y * L, flag, y, yn)
    if tangent:
        z = _load10(blk, o, _Y + 10, q)
        zn = _rk4_tangent(z, h, cA, cM, cB, lam, P, M)
        _store10(blk, r + (_Y + 10) * L, flag, z, zn)
    td = blk[r + _TD * L]
    blk[r + _TD * L] = _sel(flag | (r0 != 0.0), td, td + h)
    fl = (1.0 + P[0] * cB) * (s0 * yn[0] - r0 * b) + P[1] * yn[1]
    fmx = blk[r + _FMX * L]
    fmn = blk[r + _FMN * L]
    xmx = blk[r + _XMX * L]
    xmn = blk[r + _XMN * L]
    blk[r + _FMX * L] = _sel(flag, fmx, _fmax(fmx, fl))
    blk[r + _FMN * L] = _sel(flag, fmn, _fmin(fmn, fl))
    blk[r + _XMX * L] = _sel(flag, xmx, _fmax(xmx, yn[0]))
    blk[r + _XMN * L] = _sel(flag, xmn, _fmin(xmn, yn[0]))
    blk[r + _FLAG * L] = _sel(flag, 1.0, 0.0)


@njit(cache=True, nogil=True, fastmath=_FASTMATH)
def _block_step(blk, bi, cA, sA, cvA, svA, cM, sM, cvM, svM, cB, sB, cvB, svB, lam, bound,
                bearings):
    """One RK4 step (state and tangent) of the LANES lanes of ``blk`` (a view of BLOCK doubles).

    The loop over the lanes is straight-line code and vectorises (check: ``inspect_asm()``).
    Unflagged lanes are updated in place (state, tangent, accumulators); flagged lanes are left
    untouched for :func:`_fixup`. Returns True if any lane is flagged.
    """
    o = (bi & 0xFFFFFF) * BLOCK  # provably >= 0: no wrap-around selects on the indices
    for q in range(LANES):
        _lane_step(blk, o, q, cA, sA, cvA, svA, cM, sM, cvM, svM, cB, sB, cvB, svB, lam, bound,
                   True, bearings)
    anyf = False
    for q in range(LANES):
        anyf = anyf | (blk[o + _FLAG * LANES + q] != 0.0)
    return anyf


@njit(cache=True, nogil=True, fastmath=_FASTMATH)
def _block_step_state(blk, bi, cA, sA, cvA, svA, cM, sM, cvM, svM, cB, sB, cvB, svB, lam,
                      bound, bearings):
    """:func:`_block_step` without the tangent vector (transients)."""
    o = (bi & 0xFFFFFF) * BLOCK
    for q in range(LANES):
        _lane_step(blk, o, q, cA, sA, cvA, svA, cM, sM, cvM, svM, cB, sB, cvB, svB, lam, bound,
                   False, bearings)
    anyf = False
    for q in range(LANES):
        anyf = anyf | (blk[o + _FLAG * LANES + q] != 0.0)
    return anyf


# ============================================================================ scalar fix-up path
@njit(cache=True, nogil=True, inline="always")
def _hermite(x0, v0, x1, v1, h, s):
    """Cubic Hermite interpolant of x on [0, h] at fraction s (as in gearsim.integrate)."""
    s2 = s * s
    s3 = s2 * s
    return (
        (2 * s3 - 3 * s2 + 1) * x0
        + (s3 - 2 * s2 + s) * h * v0
        + (-2 * s3 + 3 * s2) * x1
        + (s3 - s2) * h * v1
    )


@njit(cache=True, nogil=True)
def _hermite_extremum(x0, v0, x1, v1, h):
    """Fraction s in (0, 1) where the Hermite cubic has zero slope (as in gearsim.integrate)."""
    a = 6 * x0 / h + 3 * v0 - 6 * x1 / h + 3 * v1
    b = -6 * x0 / h - 4 * v0 + 6 * x1 / h - 2 * v1
    c = v0
    if abs(a) < 1e-300:
        if b == 0.0:
            return -1.0
        s = -c / b
        return s if 0.0 < s < 1.0 else -1.0
    disc = b * b - 4 * a * c
    if disc < 0.0:
        return -1.0
    sq = math.sqrt(disc)
    s1 = (-b - sq) / (2 * a)
    s2 = (-b + sq) / (2 * a)
    best = -1.0
    if 0.0 < s1 < 1.0:
        best = s1
    if 0.0 < s2 < 1.0 and (best < 0.0 or s2 < best):
        best = s2
    return best


@njit(cache=True, nogil=True, inline="always")
def _iregion(x, gap):
    if x > gap:
        return 1
    if x < -gap:
        return -1
    return 0


@njit(cache=True, nogil=True, inline="always")
def _dead(x, gap, region):
    if region > 0:
        return x - gap
    if region < 0:
        return x + gap
    return 0.0


@njit(cache=True, nogil=True, inline="always")
def _modes_tuple(mode):
    return (
        float(mode[0]), float(abs(mode[0])),
        float(mode[1]), float(mode[2]), float(mode[3]), float(mode[4]),
        float(abs(mode[1])), float(abs(mode[2])), float(abs(mode[3])), float(abs(mode[4])),
    )  # fmt: skip


@njit(cache=True, nogil=True, fastmath=_FASTMATH)
def _rk4_at(tr, hh, yin, yout, P, M, lam, w, nu, vrs, vrc):
    """Scalar RK4 step from relative time ``tr`` (within the period) over ``hh``."""
    y = (yin[0], yin[1], yin[2], yin[3], yin[4], yin[5], yin[6], yin[7], yin[8], yin[9])
    z = (yin[10], yin[11], yin[12], yin[13], yin[14], yin[15], yin[16], yin[17], yin[18], yin[19])
    ph = w * tr
    pm = w * (tr + 0.5 * hh)
    pe = w * (tr + hh)
    vA = vrs * math.cos(nu * ph) + vrc * math.sin(nu * ph)
    vM = vrs * math.cos(nu * pm) + vrc * math.sin(nu * pm)
    vB = vrs * math.cos(nu * pe) + vrc * math.sin(nu * pe)
    cA, cM, cB = math.cos(ph), math.cos(pm), math.cos(pe)
    yn = _rk4_state(
        y, hh, cA, math.sin(ph), vA, cM, math.sin(pm), vM, cB, math.sin(pe), vB, lam, P, M
    )
    zn = _rk4_tangent(z, hh, cA, cM, cB, lam, P, M)
    for i in range(10):
        yout[i] = yn[i]
        yout[10 + i] = zn[i]


@njit(cache=True, nogil=True)
def _fixup(blk, o, q, l, ist, j, N, lam, nu, bound, wy, wn, wt, mode, gaps, active):
    """Redo grid step ``j`` of lane ``q`` of the block at ``o`` with located contact switches.

    A port of the event handling of ``gearsim.integrate.integrate_periods`` (METHOD_RK4) for one
    grid interval ``[j h, (j + 1) h]`` of the current period.
    """
    L = LANES
    r = o + q
    for i in range(20):
        wy[i] = blk[r + (_Y + i) * L]
    P = _lane_params(blk, o, q)
    eps = P[0]
    xi2 = P[1]
    h = blk[r + _H * L]
    w = blk[r + _W * L]
    vrs = blk[r + _VRS * L]
    vrc = blk[r + _VRC * L]
    T = 2.0 * math.pi / w
    mode[0] = int(blk[r + _R0 * L])
    gaps[0] = P[2]
    active[0] = True
    for c in range(1, 5):
        mode[c] = int(blk[r + (_RB + c - 1) * L])
        gaps[c] = P[21 + c]
        active[c] = blk[r + (_ACT + c - 1) * L] != 0.0
    td = blk[r + _TD * L]
    fmx = blk[r + _FMX * L]
    fmn = blk[r + _FMN * L]
    xmx = blk[r + _XMX * L]
    xmn = blk[r + _XMN * L]
    nf = ist[_NF, l]
    nb = ist[_NB, l]
    t = j * h
    t_end = T if j == N - 1 else (j + 1) * h
    steps = 0
    status = 0
    while t < t_end:
        hh = t_end - t
        if hh <= 1e-14 * T:
            t = t_end
            break
        M = _modes_tuple(mode)
        _rk4_at(t, hh, wy, wn, P, M, lam, w, nu, vrs, vrc)
        steps += 1
        # ---- look for switches inside the step (integrate_periods, same order and tests)
        first_c = -1
        first_s = 2.0
        graze = False
        for c in range(5):
            if not active[c]:
                continue
            ci = 2 * c
            gap = gaps[c]
            r_new = _iregion(wn[ci], gap)
            x0 = wy[ci]
            v0 = wy[ci + 1]
            x1 = wn[ci]
            v1 = wn[ci + 1]
            s_est = -1.0
            if r_new != mode[c]:
                if r_new > mode[c]:
                    bnd = -gap if mode[c] == -1 else gap
                else:
                    bnd = gap if mode[c] == 1 else -gap
                lo = 0.0
                hi = 1.0
                pre_pos = r_new < mode[c]
                for _ in range(30):
                    mid = 0.5 * (lo + hi)
                    gm = _hermite(x0, v0, x1, v1, hh, mid) - bnd
                    if (gm > 0.0) == pre_pos:
                        lo = mid
                    else:
                        hi = mid
                s_est = 0.5 * (lo + hi)
            elif v0 * v1 < 0.0:
                se = _hermite_extremum(x0, v0, x1, v1, hh)
                if se > 0.0:
                    xe = _hermite(x0, v0, x1, v1, hh, se)
                    if _iregion(xe, gap) != mode[c]:
                        s_est = se
            if s_est >= 0.0 and s_est < first_s:
                first_s = s_est
                first_c = c
                graze = r_new == mode[c]
        c = first_c
        ci = 2 * c
        lo_t = 0.0
        hi_t = hh
        if first_c >= 0:
            gap = gaps[c]
            if graze:
                te = first_s * hh
                _rk4_at(t, te, wy, wt, P, M, lam, w, nu, vrs, vrc)
                steps += 1
                if _iregion(wt[ci], gap) == mode[c]:
                    first_c = -1
                else:
                    hi_t = te
                    first_s = 0.5 * te / hh
        if first_c >= 0:
            gap = gaps[c]
            r_far = _iregion(wt[ci], gap) if graze else _iregion(wn[ci], gap)
            if r_far > mode[c]:
                bnd = -gap if mode[c] == -1 else gap
                new_region = 0 if mode[c] == -1 else 1
            else:
                bnd = gap if mode[c] == 1 else -gap
                new_region = 0 if mode[c] == 1 else -1
            if gap == 0.0:
                new_region = r_far
            pre_pos = r_far < mode[c]
            th = first_s * hh
            for _ in range(60):
                _rk4_at(t, th, wy, wt, P, M, lam, w, nu, vrs, vrc)
                steps += 1
                g = wt[ci] - bnd
                if abs(g) <= 1e-12 * (1.0 + gap):
                    break
                if (g > 0.0) == pre_pos:
                    lo_t = th
                else:
                    hi_t = th
                vel = wt[ci + 1]
                tn = th - g / vel if vel != 0.0 else -1.0
                if not (lo_t < tn < hi_t):
                    tn = 0.5 * (lo_t + hi_t)
                th = tn
                if hi_t - lo_t < 1e-15 * T:
                    break
            # land on the switch (old region up to here)
            if mode[0] == 0:
                td += th
            for i in range(20):
                wy[i] = wt[i]
            t = t + th
            if c == 0:
                if new_region == 1:
                    nf += 1
                elif new_region == -1:
                    nb += 1
            mode[c] = new_region
            fl = (1.0 + eps * math.cos(w * t)) * _dead(wy[0], gaps[0], mode[0]) + xi2 * wy[1]
            fmx = max(fmx, fl)
            fmn = min(fmn, fl)
            xmx = max(xmx, wy[0])
            xmn = min(xmn, wy[0])
            continue
        # ---- no switch: accept the whole (remaining) step
        if mode[0] == 0:
            td += hh
        v0 = wy[1]
        v1 = wn[1]
        if v0 * v1 < 0.0:
            se = _hermite_extremum(wy[0], v0, wn[0], v1, hh)
            if se > 0.0:
                xe = _hermite(wy[0], v0, wn[0], v1, hh, se)
                xmx = max(xmx, xe)
                xmn = min(xmn, xe)
                fe = (1.0 + eps * math.cos(w * (t + se * hh))) * _dead(xe, gaps[0], mode[0])
                fmx = max(fmx, fe)
                fmn = min(fmn, fe)
        for i in range(20):
            wy[i] = wn[i]
        t = t_end
        fl = (1.0 + eps * math.cos(w * t)) * _dead(wy[0], gaps[0], mode[0]) + xi2 * wy[1]
        fmx = max(fmx, fl)
        fmn = min(fmn, fl)
        xmx = max(xmx, wy[0])
        xmn = min(xmn, wy[0])
        for i in range(10):
            if not (abs(wy[i]) < bound):
                status = 1
        if status != 0:
            break
    if status == 0:
        for i in range(10):
            if not (abs(wy[i]) < bound):
                status = 1  # NaN that escaped the tests above (switch search on a bad state)
    # ---- store back
    for i in range(20):
        blk[r + (_Y + i) * L] = wy[i]
    blk[r + _R0 * L] = float(mode[0])
    blk[r + _S0 * L] = float(abs(mode[0]))
    for c in range(1, 5):
        blk[r + (_RB + c - 1) * L] = float(mode[c])
        blk[r + (_SB + c - 1) * L] = float(abs(mode[c]))
    blk[r + _TD * L] = td
    blk[r + _FMX * L] = fmx
    blk[r + _FMN * L] = fmn
    blk[r + _XMX * L] = xmx
    blk[r + _XMN * L] = xmn
    ist[_NF, l] = nf
    ist[_NB, l] = nb
    ist[_STEPS, l] += steps - 1  # the grid step itself is counted per period
    if status != 0:
        ist[_ST, l] = status
        ist[_STEPS, l] += j + 1
        blk[r + _H * L] = 0.0  # freeze the lane


# ============================================================================ the kernel
@njit(cache=True, nogil=True, fastmath=_FASTMATH)
def advance(blk, ist, N, m, C, S, LAM, CV, SV, nu, bound, sec, nface, nback, fout,
            tangent=True):
    """Advance every lane with ``ist[_ST] == 0`` by ``m`` mesh periods of ``N`` RK4 steps.

    Parameters
    ----------
    blk
        Flat float64 array of ``n_blocks * BLOCK`` lane rows (layout: the ``_*`` row constants).
    ist
        int64 ``[NI, n_lanes]``: status (lanes with status != 0 are skipped; a lane that diverges
        gets status 1 and is frozen), periods done, record position, absolute period index,
        step count, face/back entries of the current period.
    C, S
        ``cos``/``sin`` of ``theta_i = pi i / N``, ``i = 0 .. 2N`` (the half-step phase grid).
    LAM
        Friction direction on grid step ``j`` (``N`` entries).
    CV, SV, nu
        ``cos``/``sin`` of ``nu theta_i`` and the variable-ratio order shared by the lanes.
    sec, nface, nback, fout
        Per-lane records ``[n_lanes, capacity, ...]``; period ``k`` of lane ``l`` is written at
        ``ist[_POS, l] + k`` when that position is >= 0 (``fout`` columns: ``O_*``).
    """
    n_lanes = ist.shape[1]
    nblk = n_lanes // LANES
    L = LANES
    wy = np.zeros(20)
    wn = np.zeros(20)
    wt = np.zeros(20)
    mode = np.zeros(5, dtype=np.int64)
    gaps = np.zeros(5)
    active = np.zeros(5, dtype=np.bool_)
    two_pi = 2.0 * math.pi
    bearings = False  # any lane with a bearing clearance (its switching channels watched)
    for l in range(n_lanes):
        r = (l // L) * BLOCK + (l % L)
        for c in range(4):
            if blk[r + (_ACT + c) * L] != 0.0:
                bearings = True
    for k in range(m):
        # ---- period start: section, accumulators, variable-ratio phase of the lane
        for l in range(n_lanes):
            if ist[_ST, l] != 0:
                continue
            r = (l // L) * BLOCK + (l % L)
            pos = ist[_POS, l]
            x = blk[r + _Y * L]
            v = blk[r + (_Y + 1) * L]
            if pos >= 0:
                for i in range(N_STATE):
                    sec[l, pos + k, i] = blk[r + (_Y + i) * L]
            f0 = (1.0 + blk[r + _EPS * L] * C[0]) * (
                blk[r + _S0 * L] * x - blk[r + _R0 * L] * blk[r + _B * L]
            ) + blk[r + _XI2 * L] * v
            blk[r + _FMX * L] = f0
            blk[r + _FMN * L] = f0
            blk[r + _XMX * L] = x
            blk[r + _XMN * L] = x
            blk[r + _TD * L] = 0.0
            ist[_NF, l] = 0
            ist[_NB, l] = 0
            vra = blk[r + _VRA * L]
            if vra != 0.0:
                kk = ist[_K, l] + k
                a = two_pi * ((nu * kk) % 1.0)
                blk[r + _VRS * L] = vra * math.sin(a)
                blk[r + _VRC * L] = vra * math.cos(a)
            else:
                blk[r + _VRS * L] = 0.0
                blk[r + _VRC * L] = 0.0
        # ---- the N grid steps of the period
        for j in range(N):
            i2 = 2 * j
            cA = C[i2]
            sA = S[i2]
            cM = C[i2 + 1]
            sM = S[i2 + 1]
            cB = C[i2 + 2]
            sB = S[i2 + 2]
            cvA = CV[i2]
            svA = SV[i2]
            cvM = CV[i2 + 1]
            svM = SV[i2 + 1]
            cvB = CV[i2 + 2]
            svB = SV[i2 + 2]
            lam = LAM[j]
            for bi in range(nblk):
                o = bi * BLOCK
                if tangent:
                    anyf = _block_step(blk, bi, cA, sA, cvA, svA, cM, sM, cvM, svM, cB, sB,
                                       cvB, svB, lam, bound, bearings)
                else:
                    anyf = _block_step_state(blk, bi, cA, sA, cvA, svA, cM, sM, cvM, svM, cB,
                                             sB, cvB, svB, lam, bound, bearings)
                if anyf:
                    for q in range(L):
                        if blk[o + _FLAG * L + q] != 0.0:
                            ll = bi * L + q
                            if ist[_ST, ll] == 0:
                                _fixup(blk, o, q, ll, ist, j, N, lam, nu, bound, wy, wn, wt,
                                       mode, gaps, active)
        # ---- period end: tangent growth, records
        for l in range(n_lanes):
            if ist[_ST, l] != 0:
                continue
            r = (l // L) * BLOCK + (l % L)
            nrm = 0.0
            for i in range(10, 20):
                zi = blk[r + (_Y + i) * L]
                nrm += zi * zi
            nrm = math.sqrt(nrm)
            if nrm > 0.0 and nrm == nrm:
                ly = math.log(nrm)
                for i in range(10, 20):
                    blk[r + (_Y + i) * L] /= nrm
            else:
                ly = 0.0
            pos = ist[_POS, l]
            if pos >= 0:
                kk = pos + k
                nface[l, kk] = ist[_NF, l]
                nback[l, kk] = ist[_NB, l]
                fout[l, kk, O_TDIS] = blk[r + _TD * L]
                fout[l, kk, O_FMAX] = blk[r + _FMX * L]
                fout[l, kk, O_FMIN] = blk[r + _FMN * L]
                fout[l, kk, O_XMAX] = blk[r + _XMX * L]
                fout[l, kk, O_XMIN] = blk[r + _XMN * L]
                fout[l, kk, O_LYAP] = ly
            ist[_DONE, l] += 1
            ist[_STEPS, l] += N


# ============================================================================ tables, lanes
def steps_per_period(params: ModelParameters, settings: IntegrationSettings) -> int:
    """RK4 steps per mesh period: as ``integrate_periods`` (even when friction is on)."""
    n = max(int(settings.steps_per_period), int(math.ceil(params.mesh_period / settings.hmax)))
    if params.friction != 0.0 and n % 2:
        n += 1
    return n


_TABLES: dict[tuple[int, float], tuple[np.ndarray, ...]] = {}


def phase_tables(N: int, nu: float = 0.0) -> tuple[np.ndarray, ...]:
    """``(C, S, LAM, CV, SV)`` for ``N`` steps per period and variable-ratio order ``nu``."""
    key = (int(N), float(nu))
    if key not in _TABLES:
        i = np.arange(2 * N + 1)
        th = np.pi * i / N
        C = np.cos(th)
        S = np.sin(th)
        # exact values at the quarter points keep the tables symmetric
        S[0] = S[N] = S[2 * N] = 0.0
        C[0] = C[2 * N] = 1.0
        C[N] = -1.0
        LAM = np.where(np.sin(np.pi * (2 * np.arange(N) + 1) / N) >= 0.0, 1.0, -1.0)
        CV = np.cos(nu * th)
        SV = np.sin(nu * th)
        if len(_TABLES) > 64:
            _TABLES.clear()
        _TABLES[key] = (C, S, LAM, CV, SV)
    return _TABLES[key]


def initial_tangent() -> np.ndarray:
    """The fixed initial tangent vector of :func:`gearsim.simulate.simulate_cell`."""
    v = np.random.default_rng(TANGENT_SEED).standard_normal(N_STATE)
    return v / np.linalg.norm(v)


class Lanes:
    """Storage of ``n`` lanes in blocks of :data:`LANES` (padding lanes are frozen)."""

    def __init__(self, n: int, capacity: int):
        self.n = n
        self.n_blocks = max(1, -(-n // LANES))
        self.size = self.n_blocks * LANES
        self.blk = np.zeros(self.n_blocks * BLOCK)
        self.view = self.blk.reshape(self.n_blocks, NROW, LANES)
        self.ist = np.zeros((NI, self.size), dtype=np.int64)
        self.ist[_ST] = -1
        self.ist[_POS] = -1
        cap = max(1, int(capacity))
        self.sec = np.zeros((self.size, cap, N_STATE))
        self.nface = np.zeros((self.size, cap), dtype=np.int64)
        self.nback = np.zeros((self.size, cap), dtype=np.int64)
        self.fout = np.zeros((self.size, cap, 6))

    def set(self, lane: int, row: int, value) -> None:
        self.view[lane // LANES, row, lane % LANES] = value

    def get(self, lane: int, row: int) -> float:
        return float(self.view[lane // LANES, row, lane % LANES])

    def set_rows(self, lane: int, row: int, values) -> None:
        vals = np.asarray(values, dtype=float)
        self.view[lane // LANES, row : row + len(vals), lane % LANES] = vals

    def get_rows(self, lane: int, row: int, n: int) -> np.ndarray:
        return self.view[lane // LANES, row : row + n, lane % LANES].copy()

    def column(self, row: int) -> np.ndarray:
        """Row ``row`` of every lane, in lane order (a copy)."""
        return self.view[:, row, :].reshape(-1).copy()

    def set_column(self, row: int, values: np.ndarray) -> None:
        self.view[:, row, :] = np.asarray(values, dtype=float).reshape(self.n_blocks, LANES)

    def load_params(self, lane: int, params: ModelParameters, N: int) -> None:
        """Write the lane parameters of ``params`` (6-DOF model) for ``N`` steps per period."""
        w = params.w
        T = 2.0 * math.pi / w
        v = self.view[lane // LANES, :, lane % LANES]
        v[_H] = T / N
        v[_W] = w
        v[_EPS] = params.eps
        v[_XI2] = 2.0 * params.xi
        v[_B] = params.b
        v[_FM] = params.Fm
        v[_FEW2] = params.Fe * w * w
        v[_CPHI] = math.cos(params.phi_e)
        v[_SPHI] = math.sin(params.phi_e)
        v[_GAM] = params.friction
        v[_CA] = math.cos(params.alpha)
        v[_SA] = math.sin(params.alpha)
        v[_RPCA] = params.rho_p * v[_CA]
        v[_RPSA] = params.rho_p * v[_SA]
        v[_RGCA] = params.rho_g * v[_CA]
        v[_RGSA] = params.rho_g * v[_SA]
        for k, name in enumerate(("py", "pz", "gy", "gz")):
            v[_KAP + k] = getattr(params, f"kappa_{name}")
            v[_ZB + k] = 2.0 * getattr(params, f"xi_{name}")
            gap = getattr(params, f"b_{name}")
            v[_GAP + k] = gap
            v[_ACT + k] = 1.0 if gap > 0.0 else 0.0
        v[_VRA] = params.var_ratio * w * w
        v[_VRS] = 0.0
        v[_VRC] = 0.0

    def load_state(self, lane: int, y: np.ndarray) -> None:
        """Set the state (10 or 20 entries) and the frozen regions as ``integrate_periods`` does."""
        v = self.view[lane // LANES, :, lane % LANES]
        v[_Y : _Y + len(y)] = y
        self.reset_modes(lane)

    def reset_modes(self, lane: int) -> None:
        """Regions from the state (what ``integrate_periods`` does at the start of every call)."""
        v = self.view[lane // LANES, :, lane % LANES]
        x = v[_Y]
        b = v[_B]
        r0 = 1.0 if x > b else (-1.0 if x < -b else 0.0)
        v[_R0] = r0
        v[_S0] = abs(r0)
        for k in range(4):
            if v[_ACT + k] != 0.0:
                u = v[_Y + 2 + 2 * k]
                g = v[_GAP + k]
                r = 1.0 if u > g else (-1.0 if u < -g else 0.0)
            else:
                r = 1.0  # a channel without gap is linear: f(u, 0) = u
            v[_RB + k] = r
            v[_SB + k] = abs(r)

    def state(self, lane: int, n: int = 20) -> np.ndarray:
        return self.get_rows(lane, _Y, n)

    def run(self, N: int, m: int, nu: float, bound: float, tangent: bool = True) -> None:
        """Advance the lanes with status 0 by ``m`` periods (the kernel :func:`advance`)."""
        C, S, LAM, CV, SV = phase_tables(N, nu)
        advance(self.blk, self.ist, int(N), int(m), C, S, LAM, CV, SV, float(nu), float(bound),
                self.sec, self.nface, self.nback, self.fout, bool(tangent))

    def summaries(self, lane: int, n: int, copy: bool = True) -> PeriodSummaries:
        """The first ``n`` recorded periods of ``lane`` (copies, or views into the buffers)."""
        f = self.fout[lane, :n]
        parts = (
            self.sec[lane, :n], self.nface[lane, :n], self.nback[lane, :n], f[:, O_TDIS],
            f[:, O_FMAX], f[:, O_FMIN], f[:, O_XMAX], f[:, O_XMIN], f[:, O_LYAP],
        )  # fmt: skip
        if copy:
            parts = tuple(a.copy() for a in parts)
        return PeriodSummaries(*parts)


def run_periods_batched(
    params_list: Sequence[ModelParameters],
    states: np.ndarray,
    n_periods: int,
    settings: IntegrationSettings | None = None,
    *,
    start_periods: Sequence[int] | None = None,
) -> tuple[list[PeriodSummaries], np.ndarray, np.ndarray, np.ndarray]:
    """Integrate every cell ``n_periods`` periods from ``states`` (rows of 20: state, tangent).

    The batched counterpart of ``simulate.run_periods(..., tangent=True)`` with RK4 (all cells
    must have the same steps per period). Returns ``(summaries, final_states, status, steps)``.
    """
    st = settings or IntegrationSettings(method="rk4")
    n = len(params_list)
    Ns = {steps_per_period(p, st) for p in params_list}
    if len(Ns) != 1:
        raise ParameterError("run_periods_batched: all cells need the same steps per period")
    N = Ns.pop()
    nus = {p.var_ratio_order for p in params_list if p.var_ratio != 0.0}
    if len(nus) > 1:
        raise ParameterError("run_periods_batched: cells with different var_ratio_order")
    nu = nus.pop() if nus else 0.0
    lanes = Lanes(n, n_periods)
    ks = [0] * n if start_periods is None else list(start_periods)
    for l, p in enumerate(params_list):
        if p.model != "6dof":
            raise ParameterError("the batched kernel is the 6-DOF model")
        lanes.load_params(l, p, N)
        lanes.load_state(l, np.asarray(states[l], dtype=float))
        lanes.ist[_ST, l] = 0
        lanes.ist[_POS, l] = 0
        lanes.ist[_K, l] = ks[l]
    lanes.run(N, n_periods, nu, getattr(st, "divergence_bound", 1.0e6))
    out = []
    for l in range(n):
        out.append(lanes.summaries(l, int(lanes.ist[_DONE, l])))
    finals = np.array([lanes.state(l) for l in range(n)])
    return out, finals, lanes.ist[_ST, :n].copy(), lanes.ist[_STEPS, :n].copy()


# ============================================================================ the driver
@njit(cache=True, nogil=True)
def estimate_period_fast(section_x, section_v, scale, w, n_max=64, period_rtol=1e-5,
                         min_confirm=16):
    """:func:`gearsim.classify.estimate_period` compiled (same tests, same answer; ~20x faster).

    tests/test_batch.py checks the two agree on recorded section sequences.
    """
    m = len(section_x)
    scale = max(scale, 1e-9)
    tol_x = period_rtol * scale
    tol_v = period_rtol * scale * max(w, 1e-3)
    for n in range(1, n_max + 1):
        window = max(2 * n, min_confirm)
        if window + n > m:
            return 0
        ok = True
        for i in range(m - window, m):
            dx = abs(section_x[i] - section_x[i - n])
            dv = abs(section_v[i] - section_v[i - n])
            if not (dx <= tol_x and dv <= tol_v):  # NaN fails, as max() <= tol does
                ok = False
                break
        if ok:
            if n > 1:
                # classify._spread_decays: a decaying transient mimics period n
                early = 0.0
                late = 0.0
                for i in range(m - window, m - window + n):
                    early += abs(section_x[i] - section_x[i - 1])
                for i in range(m - n, m):
                    late += abs(section_x[i] - section_x[i - 1])
                early /= n
                late /= n
                if early - late > max(2.0 * tol_x, 1e-3 * early):
                    return 0
            return n
    return 0


_TRANSIENT = 0
_MEASURE = 1


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
    results: list[CellResult] = field(default_factory=list)

    @property
    def finished(self) -> bool:
        return self.i >= len(self.cells)


def _diverged_result(params: ModelParameters, k: int, steps: int) -> CellResult:
    """The record of a diverged cell (as simulate_cell builds it)."""
    nan = float("nan")
    cls = Classification(
        motion="diverged", status="diverged", I=0, n=0, p=None, q=None, label="diverged",
        label_npq="", dc=nan, kmax_peak_mean=nan, kmax_peak_static=nan, kmax_section_mean=nan,
        kmax_section_static=nan, kmin_peak_mean=nan, lyapunov=nan, x_min=nan, x_max=nan,
        converged=False, window_periods=0,
    )  # fmt: skip
    final = static_state(params.to_array())
    return CellResult(cls, final, 0, np.zeros((0, N_STATE)), k, steps, params)


def _classified_result(
    params: ModelParameters,
    summaries: PeriodSummaries,
    n: int,
    st: IntegrationSettings,
    final_state: np.ndarray,
    k: int,
    start_period: int,
    steps: int,
) -> CellResult:
    """Classification of the measured periods (the tail of simulate_cell, unchanged)."""
    if n > 0:
        keep = n * max(1, min(len(summaries), 4 * max(n, 8)) // n)
        window = summaries.tail(keep)
    else:
        window = summaries
    cls = classify_motion(
        window, w=params.w, b=params.b, eps=params.eps, xi=params.xi, Fm=params.Fm,
        Fe=params.Fe, n=n, lyap_threshold=st.lyap_threshold,
    )  # fmt: skip
    n_keep = n if n > 0 else min(len(window), 2 * st.n_max)
    poincare = window.section[-n_keep:].copy()
    return CellResult(cls, final_state.copy(), k, poincare, k - start_period, steps, params)


def simulate_rows(
    rows: Sequence[Sequence[ModelParameters]],
    *,
    settings: IntegrationSettings | None = None,
    continuation: bool = True,
    u0: np.ndarray | Sequence[np.ndarray | None] | None = None,
    on_cell: Callable[[int, int, CellResult], None] | None = None,
    start_periods: Sequence[int] | None = None,
) -> list[list[CellResult]]:
    """Simulate many continuation chains at once with the batched RK4 kernel.

    ``simulate_rows(rows)[r]`` equals ``continuation_chain(rows[r], settings=rk4_settings)``
    (same early stopping, same classification, summaries equal to rounding), where
    ``rk4_settings`` is ``settings`` with ``method="rk4"``: the batched path always integrates
    with fixed-step RK4 at ``settings.steps_per_period`` (raised to ``ceil(T / hmax)``); the DP5
    tolerances are not used. Its classifications agree with the reference DP5 settings on the
    test set of tests/test_batch.py.

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

    Returns
    -------
    One list of :class:`~gearsim.simulate.CellResult` per chain, in cell order.
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
    # single-DOF chains: the scalar path (the batched kernel is the 6-DOF model)
    chains: list[_Chain] = []
    for r, cells in enumerate(rows):
        if any(p.model != "6dof" for p in cells):
            from .simulate import simulate_cell
            from .sweep import continuation_chain

            rk4 = st.with_(method="rk4")
            if periods0[r] and not continuation:
                out[r] = [simulate_cell(p, u0s[r], settings=rk4, start_period=periods0[r])
                          for p in cells[:1]]
                out[r] += continuation_chain(cells[1:], settings=rk4, continuation=False,
                                             u0=u0s[r])
            else:
                cb = None if on_cell is None else (lambda i, res, r=r: on_cell(r, i, res))
                out[r] = continuation_chain(
                    cells, settings=rk4, continuation=continuation, u0=u0s[r], on_cell=cb
                )
        elif cells:
            start = None if u0s[r] is None else np.asarray(u0s[r], dtype=float)
            chains.append(_Chain(index=r, cells=cells, u0=start, period0=periods0[r]))
        else:
            out[r] = []
    if chains:
        _run_chains(chains, st, bound, continuation, on_cell)
        for ch in chains:
            out[ch.index] = ch.results
    return out  # type: ignore[return-value]


def simulate_cells(
    params_list: Sequence[ModelParameters],
    *,
    settings: IntegrationSettings | None = None,
    u0: np.ndarray | Sequence[np.ndarray | None] | None = None,
    start_periods: Sequence[int] | None = None,
) -> list[CellResult]:
    """Independent cells through the batched path: ``[simulate_cell(p, u0_i, start_period=k_i)]``.

    ``u0``: one start state for all cells, one per cell (None = static state), or None.
    E.g. an audit that restarts sampled plane cells from their left neighbours' final states.
    """
    res = simulate_rows([[p] for p in params_list], settings=settings, continuation=False, u0=u0,
                        start_periods=start_periods)
    return [r[0] for r in res]


def _run_chains(chains: list[_Chain], st: IntegrationSettings, bound: float, continuation: bool,
                on_cell) -> None:
    lanes = Lanes(len(chains), st.max_periods)
    tangent0 = initial_tangent()
    for l, ch in enumerate(chains):
        ch.lane = l
        ch.start = ch.u0
        ch.period = ch.period0
        _begin_cell(ch, lanes, st, tangent0)
    active = [ch for ch in chains if not ch.finished]
    while active:
        # lanes whose cell has the step grid (N, nu) of the least advanced chain take part
        lead = min(active, key=lambda c: (c.i, c.k))
        N, nu = lead.N, lead.nu
        part = [c for c in active if c.N == N and (c.nu is None or nu is None or c.nu == nu)]
        if nu is None:
            nus = {c.nu for c in part if c.nu is not None}
            nu = nus.pop() if nus else None
            part = [c for c in part if c.nu is None or c.nu == nu]
        m = min(c.left for c in part)
        ist = lanes.ist
        ist[_ST] = -1
        ist[_DONE] = 0
        ist[_STEPS] = 0
        hcol = np.zeros(lanes.size)  # h = 0 freezes the lanes that do not take part
        for c in part:
            l = c.lane
            hcol[l] = c.h
            ist[_ST, l] = 0
            ist[_POS, l] = c.measured if c.phase == _MEASURE else -1
            ist[_K, l] = c.k
        lanes.set_column(_H, hcol)
        # the tangent vector is only needed while some lane measures (else: the transient)
        tangent = any(c.phase == _MEASURE for c in part)
        lanes.run(N, m, 0.0 if nu is None else nu, bound, tangent)
        for c in part:
            l = c.lane
            done = int(ist[_DONE, l])
            c.k += done
            c.left -= done
            c.steps += int(ist[_STEPS, l])
            if c.phase == _MEASURE:
                c.measured += done
            if ist[_ST, l] != 0:
                # diverged (during the transient or a chunk): simulate_cell's diverged record
                _finish(c, _diverged_result(c.cells[c.i], c.k, c.steps), None, lanes, st,
                        tangent0, continuation, on_cell)
            elif c.left == 0:
                if c.phase == _TRANSIENT:
                    _begin_measure(c, lanes, st, tangent0)
                else:
                    _decide(c, lanes, st, tangent0, continuation, on_cell)
        active = [ch for ch in chains if not ch.finished]


def _begin_cell(ch: _Chain, lanes: Lanes, st: IntegrationSettings, tangent0: np.ndarray) -> None:
    params = ch.cells[ch.i]
    if params.model != "6dof":
        raise ParameterError("the batched kernel is the 6-DOF model")
    if ch.start is None:
        y = static_state(params.to_array())
    else:
        y = np.asarray(ch.start, dtype=float)[:N_STATE]
    if y.shape != (N_STATE,) or not np.all(np.isfinite(y)):
        raise ParameterError("initial state 'u0' must be 10 finite numbers")
    transient = st.transient if ch.start is None else st.transient_continuation
    ch.N = steps_per_period(params, st)
    ch.h = params.mesh_period / ch.N
    ch.nu = params.var_ratio_order if params.var_ratio != 0.0 else None
    ch.k = ch.period
    ch.steps = 0
    ch.measured = 0
    lanes.load_params(ch.lane, params, ch.N)
    lanes.load_state(ch.lane, np.concatenate([y, tangent0]))
    if transient > 0:
        ch.phase = _TRANSIENT
        ch.left = transient
    else:
        _begin_measure(ch, lanes, st, tangent0)


def _begin_measure(ch: _Chain, lanes: Lanes, st: IntegrationSettings, tangent0) -> None:
    ch.phase = _MEASURE
    ch.measured = 0
    lanes.set_rows(ch.lane, _Y + 10, tangent0)
    lanes.reset_modes(ch.lane)
    ch.left = min(st.chunk, st.max_periods)


def _decide(ch: _Chain, lanes: Lanes, st: IntegrationSettings, tangent0, continuation,
            on_cell) -> None:
    """After a measuring chunk: the period test of simulate_cell, then finish or go on."""
    params = ch.cells[ch.i]
    s = lanes.summaries(ch.lane, ch.measured, copy=False)  # read before the lane moves on
    scale = float(s.xmax.max() - s.xmin.min())
    n = estimate_period_fast(s.section[:, 0], s.section[:, 1], scale, params.w, st.n_max,
                             st.period_rtol)
    if n > 0 or ch.measured >= st.max_periods:
        y = lanes.state(ch.lane, N_STATE)
        res = _classified_result(params, s, n, st, y, ch.k, ch.period, ch.steps)
        _finish(ch, res, y, lanes, st, tangent0, continuation, on_cell)
    else:
        lanes.reset_modes(ch.lane)
        ch.left = min(st.chunk, st.max_periods - ch.measured)


def _finish(ch: _Chain, res: CellResult, y, lanes: Lanes, st, tangent0, continuation,
            on_cell) -> None:
    ch.results.append(res)
    if on_cell is not None:
        on_cell(ch.index, ch.i, res)
    if continuation and res.classification.status != "diverged":
        ch.start, ch.period = res.final_state, res.final_period
    else:
        ch.start, ch.period = ch.u0, 0
    ch.i += 1
    if ch.finished:
        lanes.ist[_ST, ch.lane] = -1
        lanes.set(ch.lane, _H, 0.0)
        return
    _begin_cell(ch, lanes, st, tangent0)


def warm_up() -> float:
    """Compile the batched kernels (or load them from ``NUMBA_CACHE_DIR``); returns seconds.

    Call once before many workers start (``gearsim compile``), so that they do not race to
    compile and write the cache (a cold compile of :func:`advance` takes ~20 s).
    """
    import time

    t0 = time.perf_counter()
    st = IntegrationSettings(
        method="rk4", transient=2, transient_continuation=1, chunk=4, max_periods=8, n_max=2
    )
    simulate_cells([ModelParameters(w=1.0), ModelParameters(w=1.3, b=0.2)], settings=st)
    return time.perf_counter() - t0
