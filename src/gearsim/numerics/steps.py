"""Single steps of the two methods on the one field (:mod:`gearsim.dynamics.model`).

* :func:`dp5_step`: one Dormand-Prince 5(4) step (FSAL), RMS error norm over the evolved states
  with ``atol + rtol * max(|y_old|, |y_new|)``.
* :func:`rk4_state` / :func:`rk4_tangent`: one classical RK4 step on tuples, given the mesh phase
  at the step's start, middle and end. The batched SIMD kernel inlines these into its lane loop;
  :func:`rk4_step` is the same step on arrays from a time within the period (phases from
  ``cos(w t)``), used by the scalar integrator's event handling and the batched kernel's flagged
  lanes alike.

Every step evaluates the field in the frozen regions ``mode`` (no switch inside a step; the event
layer :mod:`gearsim.numerics.events` cuts steps at switches). Time ``t`` is measured within the
current
mesh period.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gearsim.dynamics.model import (
    MODE_FRICTION,
    N_STATE,
    P_B,
    P_GAP,
    P_VR_ORDER,
    P_VRA,
    P_W,
    arm_phase,
    field_params,
    field_state,
    field_tangent,
    mode_tuple,
    region_of,
    rhs,
    variable_ratio,
)
from gearsim.numerics.settings import (  # noqa: F401  (the integration methods' codes)
    METHOD_DP5,
    METHOD_DP5_TANGENT,
    METHOD_RK4,
    METHODS,
)

# FMA contraction only (no reassociation; NaN/inf semantics kept): the same flag on every RK4
# path, so the scalar and the batched kernels round identically.
FASTMATH = {"contract"}

# ``_nrt=False`` on the array functions of the step and event layers (rk4_step, dp5_step,
# trial_step, events.*, kernel.redo_lane): they never allocate, they only read and write the
# caller's arrays, so they need no reference counting. With Numba's runtime on, every array
# argument and view is increfed/decrefed with a locked (atomic) instruction at each call
# boundary; in the flagged-lane redo that was ~60 % of its time (perf: `lock incq`/`lock decq`
# in NRT_incref/NRT_decref).

# Dormand-Prince 5(4) tableau
_A21 = 1.0 / 5.0
_A31, _A32 = 3.0 / 40.0, 9.0 / 40.0
_A41, _A42, _A43 = 44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0
_A51, _A52, _A53, _A54 = 19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0
_A61, _A62, _A63, _A64, _A65 = (
    9017.0 / 3168.0,
    -355.0 / 33.0,
    46732.0 / 5247.0,
    49.0 / 176.0,
    -5103.0 / 18656.0,
)
_B1, _B3, _B4, _B5, _B6 = 35.0 / 384.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0
_E1, _E3, _E4, _E5, _E6, _E7 = (
    71.0 / 57600.0,
    -71.0 / 16695.0,
    71.0 / 1920.0,
    -17253.0 / 339200.0,
    22.0 / 525.0,
    -1.0 / 40.0,
)
_C2, _C3, _C4, _C5 = 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0


# ---------------------------------------------------------------------------- RK4 on tuples
# Compile cost: Numba's ``inline="always"`` copies the callee's IR at every call site and types
# it again (deep copies: most of a cold compile), so the large pieces of the RK4 step (the field,
# its Jacobian product, the state and tangent steps) are compiled once each and inlined by LLVM
# instead (``forceinline``: the ``alwaysinline`` attribute). Each carries ``fastmath=FASTMATH``
# itself, the flag its RK4 callers compile with, so the arithmetic and its FMA contraction are
# those of the IR-inlined code; the DP5 field (``model.rhs``) keeps its own, uncontracted copy.
@njit(cache=True, nogil=True, fastmath=FASTMATH, forceinline=True)
def _state_rate(c, s, lam, q, vr, y, P, M):
    """:func:`gearsim.dynamics.model.field_state` as one LLVM-inlined function (RK4 stages)."""
    return field_state(c, s, lam, q, vr, y, P, M)


@njit(cache=True, nogil=True, fastmath=FASTMATH, forceinline=True)
def _tangent_rate(c, lam, q, z, P, M):
    """:func:`gearsim.dynamics.model.field_tangent` as one LLVM-inlined function."""
    return field_tangent(c, lam, q, z, P, M)


@njit(cache=True, nogil=True, inline="always")
def axpy10(y, a, k):
    """``y + a k`` for 10-tuples."""
    return (
        y[0] + a * k[0], y[1] + a * k[1], y[2] + a * k[2], y[3] + a * k[3], y[4] + a * k[4],
        y[5] + a * k[5], y[6] + a * k[6], y[7] + a * k[7], y[8] + a * k[8], y[9] + a * k[9],
    )  # fmt: skip


@njit(cache=True, nogil=True, inline="always")
def _add2(s, k):
    """``s + 2 k`` for 10-tuples (the RK4 weight sum)."""
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


@njit(cache=True, nogil=True, fastmath=FASTMATH, forceinline=True)
def rk4_state(y, h, cA, sA, vA, cM, sM, vM, cB, sB, vB, lam, qA, qM, qB, P, M):
    """One RK4 step of the state, ``y + h/6 (k1 + 2 k2 + 2 k3 + k4)``.

    ``(c, s, v)`` at A (start), M (middle), B (end): cos, sin of the mesh phase and the
    variable-ratio forcing there; ``q`` the friction arm's phase there
    (:func:`gearsim.dynamics.model.arm_phase`). The weight sum is accumulated stage by stage (few
    live
    values: no register spills in the vector loop).
    """
    a = 0.5 * h
    k = _state_rate(cA, sA, lam, qA, vA, y, P, M)
    acc = k
    k = _state_rate(cM, sM, lam, qM, vM, axpy10(y, a, k), P, M)
    acc = _add2(acc, k)
    k = _state_rate(cM, sM, lam, qM, vM, axpy10(y, a, k), P, M)
    acc = _add2(acc, k)
    k = _state_rate(cB, sB, lam, qB, vB, axpy10(y, h, k), P, M)
    acc = _add(acc, k)
    return axpy10(y, h / 6.0, acc)


@njit(cache=True, nogil=True, fastmath=FASTMATH, forceinline=True)
def rk4_tangent(z, h, cA, cM, cB, lam, qA, qM, qB, P, M):
    """The same RK4 step for the tangent vector (linear; independent of the state)."""
    a = 0.5 * h
    k = _tangent_rate(cA, lam, qA, z, P, M)
    acc = k
    k = _tangent_rate(cM, lam, qM, axpy10(z, a, k), P, M)
    acc = _add2(acc, k)
    k = _tangent_rate(cM, lam, qM, axpy10(z, a, k), P, M)
    acc = _add2(acc, k)
    k = _tangent_rate(cB, lam, qB, axpy10(z, h, k), P, M)
    acc = _add(acc, k)
    return axpy10(z, h / 6.0, acc)


@njit(cache=True, nogil=True, inline="always")
def _rk4_phases(t, h, p):
    """cos of the mesh phase and the friction arm's phase at a step's start, middle and end
    (time ``t`` within the period, step ``h``), with the phases themselves."""
    w = p[P_W]
    ph = w * t
    pm = w * (t + 0.5 * h)
    pe = w * (t + h)
    return (ph, pm, pe, math.cos(ph), math.cos(pm), math.cos(pe), arm_phase(w, t),
            arm_phase(w, t + 0.5 * h), arm_phase(w, t + h))


@njit(cache=True, nogil=True, fastmath=FASTMATH, _nrt=False)
def rk4_step(t, y, h, p, mode, tangent, yout):
    """RK4 step on arrays from time ``t`` (within the period) over ``h``; writes ``yout``."""
    ph, pm, pe, cA, cM, cB, qA, qM, qB = _rk4_phases(t, h, p)
    vA = 0.0
    vM = 0.0
    vB = 0.0
    if p[P_VRA] != 0.0:
        nu = p[P_VR_ORDER]
        vA = variable_ratio(p, math.cos(nu * ph), math.sin(nu * ph))
        vM = variable_ratio(p, math.cos(nu * pm), math.sin(nu * pm))
        vB = variable_ratio(p, math.cos(nu * pe), math.sin(nu * pe))
    P = field_params(p, 0, 1)
    M = mode_tuple(mode)
    lam = float(mode[MODE_FRICTION])
    ys = (y[0], y[1], y[2], y[3], y[4], y[5], y[6], y[7], y[8], y[9])
    yn = rk4_state(ys, h, cA, math.sin(ph), vA, cM, math.sin(pm), vM, cB, math.sin(pe), vB, lam,
                   qA, qM, qB, P, M)
    for i in range(N_STATE):
        yout[i] = yn[i]
    if tangent:
        z = (y[10], y[11], y[12], y[13], y[14], y[15], y[16], y[17], y[18], y[19])
        zn = rk4_tangent(z, h, cA, cM, cB, lam, qA, qM, qB, P, M)
        for i in range(N_STATE):
            yout[10 + i] = zn[i]
    return 0.0


@njit(cache=True, nogil=True, fastmath=FASTMATH, _nrt=False)
def rk4_tangent_step(t, y, h, p, mode, yout):
    """The tangent vector's part of :func:`rk4_step` alone (``y[10:20]`` to ``yout[10:20]``).

    The tangent's RK4 step does not enter the state's, so the event layer's switch search takes
    its trial steps without it and steps the tangent once over the step that stands: the same
    numbers as ``rk4_step(..., tangent=True)``.
    """
    ph, pm, pe, cA, cM, cB, qA, qM, qB = _rk4_phases(t, h, p)
    P = field_params(p, 0, 1)
    M = mode_tuple(mode)
    lam = float(mode[MODE_FRICTION])
    z = (y[10], y[11], y[12], y[13], y[14], y[15], y[16], y[17], y[18], y[19])
    zn = rk4_tangent(z, h, cA, cM, cB, lam, qA, qM, qB, P, M)
    for i in range(N_STATE):
        yout[10 + i] = zn[i]


# ---------------------------------------------------------------------------- DP5 on arrays
@njit(cache=True, nogil=True, fastmath=FASTMATH, _nrt=False)
def dp5_step(t, y, h, p, mode, n, nerr, tangent, ks, ytmp, yout, rtol, atol, k1_valid):
    """One DP5 step; returns the RMS error norm. ``ks[0]`` must hold g(t, y) if ``k1_valid``."""
    k1 = ks[0]
    k2 = ks[1]
    k3 = ks[2]
    k4 = ks[3]
    k5 = ks[4]
    k6 = ks[5]
    k7 = ks[6]
    if not k1_valid:
        rhs(t, y, p, mode, k1, tangent)
    for i in range(n):
        ytmp[i] = y[i] + h * _A21 * k1[i]
    rhs(t + _C2 * h, ytmp, p, mode, k2, tangent)
    for i in range(n):
        ytmp[i] = y[i] + h * (_A31 * k1[i] + _A32 * k2[i])
    rhs(t + _C3 * h, ytmp, p, mode, k3, tangent)
    for i in range(n):
        ytmp[i] = y[i] + h * (_A41 * k1[i] + _A42 * k2[i] + _A43 * k3[i])
    rhs(t + _C4 * h, ytmp, p, mode, k4, tangent)
    for i in range(n):
        ytmp[i] = y[i] + h * (_A51 * k1[i] + _A52 * k2[i] + _A53 * k3[i] + _A54 * k4[i])
    rhs(t + _C5 * h, ytmp, p, mode, k5, tangent)
    for i in range(n):
        ytmp[i] = y[i] + h * (
            _A61 * k1[i] + _A62 * k2[i] + _A63 * k3[i] + _A64 * k4[i] + _A65 * k5[i]
        )
    rhs(t + h, ytmp, p, mode, k6, tangent)
    for i in range(n):
        yout[i] = y[i] + h * (
            _B1 * k1[i] + _B3 * k3[i] + _B4 * k4[i] + _B5 * k5[i] + _B6 * k6[i]
        )
    rhs(t + h, yout, p, mode, k7, tangent)
    acc = 0.0
    for i in range(nerr):
        e = h * (
            _E1 * k1[i] + _E3 * k3[i] + _E4 * k4[i] + _E5 * k5[i] + _E6 * k6[i] + _E7 * k7[i]
        )
        sc = atol + rtol * max(abs(y[i]), abs(yout[i]))
        acc += (e / sc) ** 2
    return math.sqrt(acc / nerr)


@njit(cache=True, nogil=True, _nrt=False)
def trial_step(method, t, y, h, p, mode, n, nerr, tangent, ks, ytmp, yout, rtol, atol, k1_valid):
    """One step of ``method`` (returns the DP5 error norm; 0 for RK4)."""
    if method == METHOD_RK4:
        return rk4_step(t, y, h, p, mode, tangent, yout)
    return dp5_step(t, y, h, p, mode, n, nerr, tangent, ks, ytmp, yout, rtol, atol, k1_valid)


# ---------------------------------------------------------------------------- RK4 grid steps
@njit(cache=True, nogil=True, inline="always")
def _watch(v0, u1, v1, gap, r, act):
    """Bearing channel needs the event layer: active, and region change or velocity sign change."""
    return (act != 0.0) & ((region_of(u1, gap) != r) | (v0 * v1 < 0.0))


@njit(cache=True, nogil=True, inline="always")
def grid_step_flag(y, yn, P, M, A, bound, bearings):
    """``(event, turn)`` of an RK4 grid step from ``y`` to ``yn``.

    ``event``: the step must be redone by the event layer: a contact region changed, a watched
    bearing velocity changed sign, or the state left the divergence bound. ``turn`` (and no
    event): x' changed sign, a turning point of x inside the step; it stands when
    :func:`turn_stands` (else the event layer redoes it: a possible grazing contact), and its
    extremum goes into the per-period extremes (:func:`gearsim.numerics.events.turn_extremum`).
    ``A`` are the four bearing channels' active flags; ``bearings`` is false when no channel has
    a clearance (a loop invariant in the vector kernel).
    """
    event = (P[P_B] > 0.0) & (region_of(yn[0], P[P_B]) != M[0])
    if bearings:
        event = event | _watch(y[3], yn[2], yn[3], P[P_GAP + 0], M[2], A[0])
        event = event | _watch(y[5], yn[4], yn[5], P[P_GAP + 1], M[3], A[1])
        event = event | _watch(y[7], yn[6], yn[7], P[P_GAP + 2], M[4], A[2])
        event = event | _watch(y[9], yn[8], yn[9], P[P_GAP + 3], M[5], A[3])
    ok = (abs(yn[0]) < bound) & (abs(yn[1]) < bound) & (abs(yn[2]) < bound)
    ok = ok & (abs(yn[3]) < bound) & (abs(yn[4]) < bound) & (abs(yn[5]) < bound)
    ok = ok & (abs(yn[6]) < bound) & (abs(yn[7]) < bound) & (abs(yn[8]) < bound)
    ok = ok & (abs(yn[9]) < bound)
    event = event | (not ok)
    return event, (y[1] * yn[1] < 0.0) & (not event)


@njit(cache=True, nogil=True, inline="always")
def _inside(x, gap, r, m):
    """``x`` lies in the region ``r`` (-1, 0, 1 as a double) of ``[-gap, gap]`` by more than
    ``m``."""
    return (((r > 0.0) & (x > gap + m)) | ((r < 0.0) & (x < -gap - m))
            | ((r == 0.0) & (abs(x) < gap - m)))


@njit(cache=True, nogil=True, inline="always")
def turn_stands(y, yn, h, P, r0):
    """A grid step (``h``) with a turning point of x stands: the Hermite cubic of x over it
    cannot reach the mesh boundary from its region ``r0`` (or the mesh has no backlash).

    The cubic lies in the convex hull of its Bernstein points ``x0``, ``x0 + h x0'/3``,
    ``x1 - h x1'/3``, ``x1``: all four inside the region (with a margin far above the cubic's
    rounding) exclude a crossing and a grazing excursion, so the event layer would find no
    switch in the step.
    """
    b = P[P_B]
    m = 1e-9 * (1.0 + b + abs(y[0]) + abs(yn[0]))
    c1 = y[0] + (h / 3.0) * y[1]
    c2 = yn[0] - (h / 3.0) * yn[1]
    return (b <= 0.0) | (_inside(y[0], b, r0, m) & _inside(c1, b, r0, m)
                         & _inside(c2, b, r0, m) & _inside(yn[0], b, r0, m))


def rk4_steps_per_period(params, settings, substeps: int = 1) -> int:
    """RK4 steps per mesh period: ``max(steps_per_period, ceil(T / hmax))``.

    Even when friction is on (the friction direction flips at T/2, a grid point then) and a
    multiple of ``substeps`` (output points land on the grid). The one definition for the scalar
    and the batched paths.
    """
    n = max(int(settings.steps_per_period), int(math.ceil(params.mesh_period / settings.hmax)))
    unit = int(substeps) * (2 if (params.friction != 0.0 and substeps % 2) else 1)
    if params.friction != 0.0 and n % 2:
        n += 1
    return unit * int(math.ceil(n / unit))


_TABLES: dict = {}


def phase_tables(N: int, nu: float = 0.0):
    """``(C, S, LAM, CV, SV, Q)`` for ``N`` RK4 steps per period and variable-ratio order ``nu``.

    ``C``/``S``: cos/sin of the mesh phase ``theta_i = pi i / N`` on the half-step grid
    (``i = 0 .. 2N``); ``LAM``: the friction direction on grid step ``j``; ``CV``/``SV``:
    cos/sin of ``nu theta_i``; ``Q``: the friction arm's phase ``theta_i / pi - 1 = i / N - 1``
    (:func:`gearsim.dynamics.model.arm_phase`, exact on the grid). No transcendental function is
    evaluated
    inside an RK4 grid step.
    """
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
        Q = i / N - 1.0
        if len(_TABLES) > 64:
            _TABLES.clear()
        _TABLES[key] = (C, S, LAM, CV, SV, Q)
    return _TABLES[key]
