"""Dimensionless equations of motion of the curve-face gear pair: the one vector field.

Everything that evaluates the equations (the scalar DP5/RK4 integrators, the batched SIMD kernel,
the tangent vector of the Lyapunov exponent, the monodromy matrix of periodic orbits, every
diagnostic) calls :func:`field_state` / :func:`field_tangent` here. They are
``inline="always"`` Numba functions on tuples, so the batched kernel inlines them into its vector
loop and keeps its FMA code, and a scalar caller pays no call overhead.

State vector ``y`` (length 10; the tangent vector ``z`` has the same layout):

====  =========================================================
0, 1  mesh displacement ``x = X_n / b_c`` and its rate ``x'``
2, 3  pinion bearing displacement ``u_py`` (Y) and rate
4, 5  pinion bearing displacement ``u_pz`` (Z) and rate
6, 7  gear bearing displacement ``u_gy`` (Y) and rate
8, 9  gear bearing displacement ``u_gz`` (Z) and rate
====  =========================================================

Equations (``d_y = cos alpha``, ``d_z = sin alpha``, ``' = d/dtau``, ``tau = w_n t``)::

    F     = (1 + eps cos(w tau)) f(x, b) + 2 xi x'                 mesh force / (Km b_c)
    u_pj'' = -2 xi_pj u_pj' - kappa_pj f(u_pj, b_pj) - rho_p F d_j   j = y, z
    u_gj'' = -2 xi_gj u_gj' - kappa_gj f(u_gj, b_gj) + rho_g F d_j
    x''   = Fm + Fe w^2 cos(w tau + phi_e) + A_vr w^2 sin(nu w tau)
            - F (1 + gamma lambda(tau))
            + (u_py'' - u_gy'') d_y + (u_pz'' - u_gz'') d_z

Model-form options (docs/model.md, "Model forms"; all off by default, the field then is the base one
bit for bit): ``F`` gains ``2 xi (1 - beta) e'(tau)`` (the damper follows only part of the
transmission-error rate, ``te_damping = beta``) and loses ``2 xi delta (x' + ...)`` inside the
backlash (``mesh_damping_contact = delta``); the friction factor ``gamma lambda`` becomes
``gamma lambda (1 + a q)`` (the sawtooth arm of Eq 9, ``friction_arm_var = a``).

``f(x, b)`` is the dead zone (x - b above b, 0 inside, x + b below -b);
``lambda = sign(sin(w tau))`` is the friction direction (it flips at the pitch point, mid
mesh cycle). The single-DOF model is the same field with the bearing couplings packed as zero
(``rho = kappa = xi_brg = 0``, no clearance channels): ``x'' + 2 xi x' + (1 + eps cos w tau)
f(x, b) = ...`` remains, the bearing states are frozen, and the tangent vector and the DP5 error
norm act on ``(x, x')`` only (:data:`N_EVOLVED`).

Piecewise-smooth handling: every dead zone is evaluated in a *frozen region* (``M``) chosen at
the start of a step; the event layer (:mod:`gearsim.numerics.events`) locates the switching
surfaces and
changes the region there. Because ``f`` is continuous, the vector field is continuous across every
switch: the saltation matrix of the variational equations is the identity, so the tangent vector
needs no jump (except with ``mesh_damping_contact > 0``, whose damping force jumps at the mesh
switch: :func:`gearsim.numerics.events.apply_saltation`).

Adding a nonlinearity: edit :func:`field_state` (the force law) and :func:`field_tangent` (its
Jacobian-vector product) and, if it needs a parameter, add a slot to the packed layout below and
fill it in :func:`pack_parameters`. Both integrators, the batched kernel and every variational
computation see the change.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# ---- the packed parameter vector (one packer: pack_parameters; one layout for every path) ----
# The first N_FIELD entries are the field's parameters, in the order of the tuple ``P`` that
# field_state / field_tangent unpack (derived values precomputed: no work in the inner loop).
P_EPS = 0  # stiffness fluctuation eps
P_XI2 = 1  # 2 xi (mesh damping)
P_B = 2  # half backlash b
P_FM = 3  # mean load Fm
P_FEW2 = 4  # error forcing amplitude Fe w^2
P_CPHI = 5  # cos(phi_e)
P_SPHI = 6  # sin(phi_e)
P_GAM = 7  # friction factor gamma
P_CA = 8  # cos(alpha)
P_SA = 9  # sin(alpha)
P_RPCA = 10  # rho_p cos(alpha)  (0 in the single-DOF model)
P_RPSA = 11  # rho_p sin(alpha)
P_RGCA = 12  # rho_g cos(alpha)
P_RGSA = 13  # rho_g sin(alpha)
P_KAP = 14  # 4 entries: kappa py, pz, gy, gz (0 in the single-DOF model)
P_ZB = 18  # 4 entries: 2 xi_brg
P_GAP = 22  # 4 entries: bearing half clearances
# model-form options (docs/model.md, "Model forms"); each is 0.0 in the base form, so a default
# term adds an exact zero and the default field is bit-identical to the field before the options
# TE rate seen by the mesh damper: -(1 - te_damping) Fe w  (x' + P_VTE sin(w tau + phi_e))
P_VTE = 26
P_XIO = 27  # damping removed outside contact: 2 xi mesh_damping_contact
# friction-arm variation a of Eq 9 (the arm is Lbar (1 + a (theta / pi - 1)), a sawtooth over the
# mesh period, theta = w tau mod 2 pi); the callers pass q = theta / pi - 1 per stage time
P_GAM1 = 28
N_FIELD = 29
# further entries read by the integrators (not by the field)
P_W = 29  # mesh frequency w
P_VRA = 30  # variable-ratio amplitude A_vr w^2
P_VR_ORDER = 31  # variable-ratio order nu
P_DOF6 = 32  # 1.0: 6-DOF model, 0.0: single-DOF
P_ACT = 33  # 4 entries: bearing switching channel active (1.0) or linear (0.0)
# per mesh period, set by the integrator: A w^2 sin / cos(2 pi nu K) for period K, so that the
# variable-ratio forcing is A w^2 sin(nu w (K T + t)) = VRS cos(nu w t) + VRC sin(nu w t)
P_VRS = 37
P_VRC = 38
# kept for static_state and diagnostics
P_ALPHA = 39
P_RHO_P = 40
P_RHO_G = 41
P_XI = 42
P_FE = 43
N_PARAMS = 44

N_STATE = 10
N_SWITCH = 5  # switching channels: mesh, then the four bearing coordinates
MODE_FRICTION = 5  # mode[5]: the friction direction lambda (+1 / -1), frozen per step
N_MODE = 6

# the coordinate each switching channel watches, and the parameter holding its half gap
SWITCH_COORD = np.array([0, 2, 4, 6, 8], dtype=np.int64)
SWITCH_GAP = np.array([P_B, P_GAP, P_GAP + 1, P_GAP + 2, P_GAP + 3], dtype=np.int64)
BEARINGS = ("py", "pz", "gy", "gz")


def pack_parameters(params) -> np.ndarray:
    """The float64 vector every kernel reads (layout: the ``P_*`` constants above).

    ``params`` is a :class:`gearsim.dynamics.parameters.ModelParameters`. The single-DOF model
    packs its
    bearing couplings as zero, so the one field gives the rigid-bearing equations.
    """
    p = np.zeros(N_PARAMS)
    w = params.w
    dof6 = params.model == "6dof"
    ca, sa = math.cos(params.alpha), math.sin(params.alpha)
    p[P_EPS] = params.eps
    p[P_XI2] = 2.0 * params.xi
    p[P_B] = params.b
    p[P_FM] = params.Fm
    p[P_FEW2] = params.Fe * w * w
    p[P_CPHI] = math.cos(params.phi_e)
    p[P_SPHI] = math.sin(params.phi_e)
    p[P_GAM] = params.friction
    p[P_VTE] = -(1.0 - params.te_damping) * params.Fe * w
    p[P_XIO] = 2.0 * params.xi * params.mesh_damping_contact
    p[P_GAM1] = params.friction_arm_var
    p[P_CA] = ca
    p[P_SA] = sa
    if dof6:
        p[P_RPCA] = params.rho_p * ca
        p[P_RPSA] = params.rho_p * sa
        p[P_RGCA] = params.rho_g * ca
        p[P_RGSA] = params.rho_g * sa
        for k, name in enumerate(BEARINGS):
            p[P_KAP + k] = getattr(params, f"kappa_{name}")
            p[P_ZB + k] = 2.0 * getattr(params, f"xi_{name}")
            gap = getattr(params, f"b_{name}")
            p[P_GAP + k] = gap
            p[P_ACT + k] = 1.0 if gap > 0.0 else 0.0
    p[P_W] = w
    p[P_VRA] = params.var_ratio * w * w
    p[P_VR_ORDER] = params.var_ratio_order
    p[P_DOF6] = 1.0 if dof6 else 0.0
    p[P_ALPHA] = params.alpha
    p[P_RHO_P] = params.rho_p
    p[P_RHO_G] = params.rho_g
    p[P_XI] = params.xi
    p[P_FE] = params.Fe
    return p


def n_evolved(p: np.ndarray) -> int:
    """Number of leading states the model evolves: 10 (6-DOF) or 2 (single-DOF: x, x')."""
    return N_STATE if p[P_DOF6] != 0.0 else 2


@njit(cache=True, nogil=True, inline="always")
def field_params(buf, base, stride):
    """The field's parameter tuple ``P`` read from ``buf[base + i * stride]``, i < N_FIELD.

    ``stride`` is 1 for a packed vector and the lane count for the batched kernel's blocks.
    """
    s = stride
    return (
        buf[base], buf[base + s], buf[base + 2 * s], buf[base + 3 * s], buf[base + 4 * s],
        buf[base + 5 * s], buf[base + 6 * s], buf[base + 7 * s], buf[base + 8 * s],
        buf[base + 9 * s], buf[base + 10 * s], buf[base + 11 * s], buf[base + 12 * s],
        buf[base + 13 * s], buf[base + 14 * s], buf[base + 15 * s], buf[base + 16 * s],
        buf[base + 17 * s], buf[base + 18 * s], buf[base + 19 * s], buf[base + 20 * s],
        buf[base + 21 * s], buf[base + 22 * s], buf[base + 23 * s], buf[base + 24 * s],
        buf[base + 25 * s], buf[base + 26 * s], buf[base + 27 * s], buf[base + 28 * s],
    )  # fmt: skip


@njit(cache=True, nogil=True, inline="always")
def dead_zone(x, gap, region):
    """Dead-zone function ``f(x, gap)`` evaluated in the frozen ``region`` (-1, 0, +1)."""
    if region > 0:
        return x - gap
    if region < 0:
        return x + gap
    return 0.0


@njit(cache=True, nogil=True, inline="always")
def region_of(x, gap):
    """Region of ``x`` relative to the gap ``[-gap, gap]``: +1 above, -1 below, 0 inside."""
    if x > gap:
        return 1
    if x < -gap:
        return -1
    return 0


@njit(cache=True, nogil=True, inline="always")
def mode_tuple(mode):
    """Frozen regions ``M = (r0, |r0|, rb0..rb3, |rb0|..|rb3|)`` (floats) from ``mode[0:5]``."""
    return (
        float(mode[0]), float(abs(mode[0])),
        float(mode[1]), float(mode[2]), float(mode[3]), float(mode[4]),
        float(abs(mode[1])), float(abs(mode[2])), float(abs(mode[3])), float(abs(mode[4])),
    )  # fmt: skip


@njit(cache=True, nogil=True, inline="always")
def mesh_force(c, x, v, P, r0, s0):
    """Mesh force ``F = (1 + eps c) f(x, b) + 2 xi x'`` (units of Km b_c), ``c = cos(w tau)``.

    ``r0`` is the frozen mesh region and ``s0 = |r0|`` (so ``f = s0 x - r0 b``).
    """
    return (1.0 + P[P_EPS] * c) * (s0 * x - r0 * P[P_B]) + P[P_XI2] * v


@njit(cache=True, nogil=True, inline="always")
def mesh_force_full(c, s, x, v, P, r0, s0):
    """The mesh force of every model form: :func:`mesh_force` plus the forms' terms.

    ``s = sin(w tau)``; ``P`` the full field tuple (:func:`field_params`). Equal to
    :func:`mesh_force` bit for bit in the base form (the added terms are exact zeros). The Kmax
    trackers (events.py, integrate.py, batch.py) call it through :func:`tracked_force`.
    """
    F = (1.0 + P[P_EPS] * c) * (s0 * x - r0 * P[P_B]) + P[P_XI2] * v
    out = 1.0 - s0
    dv = (P[P_XI2] - P[P_XIO] * out) * P[P_VTE]
    F = F + dv * P[P_CPHI] * s
    F = F + dv * P[P_SPHI] * c
    return F - P[P_XIO] * out * v


@njit(cache=True, nogil=True, inline="always")
def tracked_force(c, s, x, v, P, r0, s0):
    """The mesh force the Kmax trackers record: :func:`mesh_force` in the base form (a branch, so
    the base paths keep their arithmetic), :func:`mesh_force_full` when a form changes the force
    (``te_damping < 1`` or ``mesh_damping_contact > 0``)."""
    if P[P_VTE] != 0.0 or P[P_XIO] != 0.0:
        return mesh_force_full(c, s, x, v, P, r0, s0)
    return mesh_force(c, x, v, P, r0, s0)


def dead_zone_series(x: np.ndarray, gap: float) -> np.ndarray:
    """The dead zone ``f(x, gap)`` of :func:`dead_zone` on arrays (numpy; each sample's own
    region): ``x - gap`` above ``gap``, ``x + gap`` below ``-gap``, 0 inside."""
    x = np.asarray(x, dtype=float)
    return np.where(x > gap, x - gap, np.where(x < -gap, x + gap, 0.0))


def elastic_mesh_force(p: np.ndarray, c, x) -> np.ndarray:
    """The elastic part ``(1 + eps c) f(x, b)`` of the mesh force (numpy, packed ``p``), ``c`` the
    cosine of the mesh phase."""
    return (1.0 + p[P_EPS] * c) * dead_zone_series(x, p[P_B])


def mesh_force_at_phase(p: np.ndarray, c, s, x, v) -> np.ndarray:
    """The mesh force of every model form (numpy, packed ``p``) at mesh phase ``w tau`` given by
    ``c = cos``, ``s = sin``, displacement ``x`` and rate ``v`` (arrays broadcast together).

    The array form of :func:`mesh_force_full`: ``(1 + eps c) f(x, b)`` plus the damper on the
    rate it sees (``x'`` plus the transmission-error rate of ``te_damping``, none inside the
    backlash with ``mesh_damping_contact``). In the base form the added terms are exact zeros:
    ``(1 + eps c) f + 2 xi x'`` bit for bit.
    """
    x = np.asarray(x, dtype=float)
    s0 = (np.abs(x) > p[P_B]).astype(float)
    damper = (p[P_XI2] - p[P_XIO] * (1.0 - s0)) * (v + p[P_VTE] * (s * p[P_CPHI] + c * p[P_SPHI]))
    return elastic_mesh_force(p, c, x) + damper


def mesh_force_series(p: np.ndarray, tau: np.ndarray, x: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The mesh force of every model form along a recorded trajectory (numpy, packed ``p``).

    ``tau`` must be the time within the period or absolute time (the force is T-periodic).
    Used by :func:`gearsim.cell.simulate.trajectory` (its one source of the force for every form).
    """
    ph = p[P_W] * np.asarray(tau, dtype=float)
    return mesh_force_at_phase(p, np.cos(ph), np.sin(ph), x, v)


def section_force(p: np.ndarray, x: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The mesh force on the Poincare section ``tau = k T`` (``cos w tau = 1``, ``sin = 0``
    exactly) at the section states ``x``, ``x'`` = ``v``: the force behind the
    ``kmax_section_*`` readings, every model form included."""
    return mesh_force_at_phase(p, 1.0, 0.0, x, v)


@njit(cache=True, nogil=True, inline="always")
def field_state(c, s, lam, q, vr, y, P, M):
    """Right-hand side of the state with frozen regions: a 10-tuple ``dy/dtau``.

    ``c, s`` = cos, sin of the mesh phase ``w tau``; ``lam`` the friction direction (+/-1);
    ``q = theta / pi - 1`` with ``theta = w tau`` in ``[0, 2 pi]`` (time within the period: the
    friction arm's sawtooth, read only when ``friction_arm_var != 0``; :func:`arm_phase`);
    ``vr`` the variable-ratio forcing ``A w^2 sin(nu w tau)``; ``y`` the state (10-tuple);
    ``P`` the field parameters (:func:`field_params`); ``M`` the frozen regions
    (:func:`mode_tuple`).
    """
    (eps, xi2, b, fm, few2, cphi, sphi, gam, ca, sa, rpca, rpsa, rgca, rgsa,
     k0, k1, k2, k3, z0, z1, z2, z3, g0, g1, g2, g3, vte, xio, gam1) = P  # fmt: skip
    (r0, s0, rb0, rb1, rb2, rb3, sb0, sb1, sb2, sb3) = M
    F = (1.0 + eps * c) * (s0 * y[0] - r0 * b) + xi2 * y[1]
    drive = fm + few2 * (c * cphi - s * sphi) + vr
    a_py = -z0 * y[3] - k0 * (sb0 * y[2] - rb0 * g0) - rpca * F
    a_pz = -z1 * y[5] - k1 * (sb1 * y[4] - rb1 * g1) - rpsa * F
    a_gy = -z2 * y[7] - k2 * (sb2 * y[6] - rb2 * g2) + rgca * F
    a_gz = -z3 * y[9] - k3 * (sb3 * y[8] - rb3 * g3) + rgsa * F
    acc = drive - F * (1.0 + gam * lam) + (a_py - a_gy) * ca + (a_pz - a_gz) * sa
    if vte != 0.0 or xio != 0.0 or gam1 != 0.0:
        # model forms (docs/model.md), all off in the base form: the branch leaves the base
        # arithmetic untouched (bit-identical) and adds the forms' change dFx of the mesh force.
        # One product per addition, so the FMA contraction is unique and the scalar and the
        # batched paths round alike.
        out = 1.0 - s0  # 1 inside the backlash
        dv = (xi2 - xio * out) * vte  # damper times the TE-rate amplitude -(1 - beta) Fe w
        Fn = F + dv * cphi * s  # ... times sin(w tau + phi_e) = s cphi + c sphi
        Fn = Fn + dv * sphi * c
        Fn = Fn - xio * out * y[1]  # damping removed outside contact
        dFx = Fn - F
        a_py = a_py - rpca * dFx
        a_pz = a_pz - rpsa * dFx
        a_gy = a_gy + rgca * dFx
        a_gz = a_gz + rgsa * dFx
        acc = acc - dFx * (1.0 + gam * lam)
        acc = acc - (rpca + rgca) * dFx * ca
        acc = acc - (rpsa + rgsa) * dFx * sa
        # time-varying friction arm (Eq 9): gamma lambda (1 + a q) on the full mesh force
        acc = acc - Fn * (gam * lam) * (gam1 * q)
    return (y[1], acc, y[3], a_py, y[5], a_pz, y[7], a_gy, y[9], a_gz)


@njit(cache=True, nogil=True, inline="always")
def field_tangent(c, lam, q, z, P, M):
    """Jacobian-vector product ``J z`` of the same frozen (piecewise-linear) field: a 10-tuple.

    The Jacobian of the region's field (``q`` as in :func:`field_state`); exact across
    switches (continuous field, identity saltation matrix), except with
    ``mesh_damping_contact > 0``, whose damping force jumps at the mesh switch: the event layer
    applies that saltation matrix at the landed switch (``events.apply_saltation``).
    """
    (eps, xi2, b, fm, few2, cphi, sphi, gam, ca, sa, rpca, rpsa, rgca, rgsa,
     k0, k1, k2, k3, z0, z1, z2, z3, g0, g1, g2, g3, vte, xio, gam1) = P  # fmt: skip
    (r0, s0, rb0, rb1, rb2, rb3, sb0, sb1, sb2, sb3) = M
    dF = (1.0 + eps * c) * s0 * z[0] + xi2 * z[1]
    if xio != 0.0:  # (branches, not added zeros: the base tangent keeps its FMA contraction)
        dF = dF - xio * (1.0 - s0) * z[1]
    d_py = -z0 * z[3] - k0 * sb0 * z[2] - rpca * dF
    d_pz = -z1 * z[5] - k1 * sb1 * z[4] - rpsa * dF
    d_gy = -z2 * z[7] - k2 * sb2 * z[6] + rgca * dF
    d_gz = -z3 * z[9] - k3 * sb3 * z[8] + rgsa * dF
    dacc = -dF * (1.0 + gam * lam) + (d_py - d_gy) * ca + (d_pz - d_gz) * sa
    if gam1 != 0.0:
        dacc = dacc - dF * (gam * lam) * (gam1 * q)
    return (z[1], dacc, z[3], d_py, z[5], d_pz, z[7], d_gy, z[9], d_gz)


@njit(cache=True, nogil=True, inline="always")
def arm_phase(w, t):
    """``q = theta / pi - 1`` at time ``t`` within the mesh period (``theta = w t``).

    ``lambda q`` is the continuous triangle of the friction arm (-1 at the period start, 0 at
    the pitch point); its kinks at ``kT`` and ``kT + T/2`` are landed on by the integrators. The
    RK4 grid reads the same values from :func:`gearsim.numerics.steps.phase_tables` (``Q``).
    """
    return (w * t) * (1.0 / math.pi) - 1.0


@njit(cache=True, nogil=True, inline="always")
def variable_ratio(p, c_nu, s_nu):
    """Variable-ratio forcing from ``cos``/``sin`` of ``nu w t`` within the current period."""
    return p[P_VRS] * c_nu + p[P_VRC] * s_nu


@njit(cache=True, nogil=True)
def period_forcing(vra, nu, k):
    """Variable-ratio phase of period ``k``: ``(A w^2 sin(2 pi nu k), A w^2 cos(2 pi nu k))``."""
    if vra != 0.0:
        a = 2.0 * math.pi * ((nu * k) % 1.0)
        return vra * math.sin(a), vra * math.cos(a)
    return 0.0, 0.0


@njit(cache=True, nogil=True)
def set_period(p, k):
    """Set the per-period slots of ``p`` for absolute period ``k`` (variable-ratio phase)."""
    p[P_VRS], p[P_VRC] = period_forcing(p[P_VRA], p[P_VR_ORDER], k)


@njit(cache=True, nogil=True)
def rhs(t, y, p, mode, dy, tangent):
    """Array form of the field: ``dy = g(t, y)`` with every dead zone frozen in ``mode``.

    ``t`` is the time within the current mesh period (the integrator sets the period's slots
    with :func:`set_period`); ``mode[0:5]`` are the regions (-1, 0, +1) of the mesh and bearing
    dead zones, ``mode[5]`` the friction direction on the current step. If ``tangent`` is true,
    ``y[10:20]`` is a tangent vector and ``dy[10:20]`` receives ``J z``.
    """
    w = p[P_W]
    ph = w * t
    c = math.cos(ph)
    s = math.sin(ph)
    vr = 0.0
    if p[P_VRA] != 0.0:
        pn = p[P_VR_ORDER] * ph
        vr = variable_ratio(p, math.cos(pn), math.sin(pn))
    P = field_params(p, 0, 1)
    M = mode_tuple(mode)
    lam = float(mode[MODE_FRICTION])
    q = arm_phase(w, t)
    ys = (y[0], y[1], y[2], y[3], y[4], y[5], y[6], y[7], y[8], y[9])
    d = field_state(c, s, lam, q, vr, ys, P, M)
    for i in range(N_STATE):
        dy[i] = d[i]
    if tangent:
        z = (y[10], y[11], y[12], y[13], y[14], y[15], y[16], y[17], y[18], y[19])
        dz = field_tangent(c, lam, q, z, P, M)
        for i in range(N_STATE):
            dy[10 + i] = dz[i]


def static_state(params_array: np.ndarray) -> np.ndarray:
    """Static equilibrium under the mean load alone (a default initial condition).

    Mesh: ``f(x, b) = Fm`` so ``x = b + Fm``; bearings: ``kappa f(u) = -/+ rho Fm d_j``
    (at rest, zero in the single-DOF model).
    """
    p = params_array
    y = np.zeros(N_STATE)
    fm = p[P_FM]
    y[0] = p[P_B] + fm
    if p[P_DOF6] != 0.0:
        ca, sa = math.cos(p[P_ALPHA]), math.sin(p[P_ALPHA])
        loads = (-p[P_RHO_P] * fm * ca, -p[P_RHO_P] * fm * sa, p[P_RHO_G] * fm * ca,
                 p[P_RHO_G] * fm * sa)
        for k in range(4):
            u = loads[k] / p[P_KAP + k]
            gap = p[P_GAP + k]
            y[2 + 2 * k] = u + math.copysign(gap, u) if u != 0.0 else 0.0
    return y


def project_tangent(v: np.ndarray, p: np.ndarray) -> np.ndarray:
    """A unit tangent vector on the states the model evolves (frozen states get zero).

    In the single-DOF model the bearing states are frozen; a tangent component there would
    never decay and would pull the Lyapunov estimate to zero.
    """
    out = np.array(v, dtype=float)
    out[n_evolved(p):] = 0.0
    nrm = np.linalg.norm(out)
    return out / nrm if nrm > 0 else out
