"""Dimensionless equations of motion of the curve-face gear pair (Numba kernels, nothing else).

State vector ``y`` (length 10; 20 when the tangent vector of the variational equations rides along):

====  =========================================================
0, 1  mesh displacement ``x = X_n / b_c`` and its rate ``x'``
2, 3  pinion bearing displacement ``u_py`` (Y) and rate
4, 5  pinion bearing displacement ``u_pz`` (Z) and rate
6, 7  gear bearing displacement ``u_gy`` (Y) and rate
8, 9  gear bearing displacement ``u_gz`` (Z) and rate
====  =========================================================

Equations (``d_y = cos alpha``, ``d_z = sin alpha``, ``' = d/dtau``)::

    F     = (1 + eps cos(w tau)) f(x, b) + 2 xi x'                 mesh force / (Km b_c)
    u_pj'' = -2 xi_pj u_pj' - kappa_pj f(u_pj, b_pj) - rho_p F d_j   j = y, z
    u_gj'' = -2 xi_gj u_gj' - kappa_gj f(u_gj, b_gj) + rho_g F d_j
    x''   = Fm + Fe w^2 cos(w tau + phi_e) + A_vr w^2 sin(nu w tau)
            - F (1 + gamma lambda(tau))
            + (u_py'' - u_gy'') d_y + (u_pz'' - u_gz'') d_z

``f(x, b)`` is the dead zone (x - b above b, 0 inside, x + b below -b);
``lambda = sign(sin(w tau))`` is the friction direction (it flips at the pitch point, mid
mesh cycle). With ``P_DOF6 = 0`` the bearings are rigid and the single-DOF form
``x'' + 2 xi x' + (1 + eps cos w tau) f(x, b) = ...`` remains.

Piecewise-smooth handling: every dead zone is evaluated in a *frozen region* (``mode``) chosen at
the start of a step; the integrator locates the switching surfaces and changes ``mode`` there.
Because ``f`` is continuous, the vector field is continuous across every switch: the saltation
matrix of the variational equations is the identity, so the tangent vector needs no jump.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# ---- layout of the packed parameter vector (see ModelParameters.to_array) ----
P_W = 0
P_FM = 1
P_FE = 2
P_EPS = 3
P_XI = 4
P_B = 5
P_PHI_E = 6
P_GAMMA = 7
P_ALPHA = 8
P_VR_AMP = 9
P_VR_ORDER = 10
P_RHO_P = 11
P_RHO_G = 12
P_DOF6 = 13
P_KAPPA = 14  # 4 entries: py, pz, gy, gz
P_XI_BRG = 18  # 4 entries
P_B_BRG = 22  # 4 entries
# derived entries, precomputed once so the right-hand side needs only cos/sin of the mesh phase
P_COS_ALPHA = 26
P_SIN_ALPHA = 27
P_COS_PHI_E = 28
P_SIN_PHI_E = 29
# absolute time of t = 0 for terms that are not T-periodic (set by the integrator per period)
P_T0 = 30
N_PARAMS = 31

N_STATE = 10
N_SWITCH = 5  # switching channels: mesh, then the four bearing coordinates
MODE_FRICTION = 5  # mode[5]: the friction direction lambda (+1 / -1), frozen per step
N_MODE = 6

# the coordinate each switching channel watches, and the parameter holding its half gap
SWITCH_COORD = np.array([0, 2, 4, 6, 8], dtype=np.int64)
SWITCH_GAP = np.array([P_B, P_B_BRG, P_B_BRG + 1, P_B_BRG + 2, P_B_BRG + 3], dtype=np.int64)


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


@njit(cache=True, nogil=True)
def mesh_force(t, x, v, p, region):
    """Dimensionless mesh force ``F = (1 + eps cos(w t)) f(x, b) + 2 xi x'`` (units of Km b_c)."""
    return (1.0 + p[P_EPS] * math.cos(p[P_W] * t)) * dead_zone(x, p[P_B], region) + 2.0 * p[
        P_XI
    ] * v


@njit(cache=True, nogil=True)
def rhs(t, y, p, mode, dy, tangent):
    """Right-hand side ``dy = g(t, y)`` with every dead zone frozen in ``mode``.

    ``t`` is measured from ``p[P_T0]`` (the integrator passes time within the mesh period and the
    period's absolute start in ``p[P_T0]``; with ``p[P_T0] = 0`` it is absolute time).

    ``mode[0:5]`` are the regions (-1, 0, +1) of the mesh and bearing dead zones, ``mode[5]`` the
    friction direction ``lambda = sign(sin(w tau))`` on the current step.

    If ``tangent`` is true, ``y[10:20]`` is a tangent vector and ``dy[10:20]`` receives the
    Jacobian-vector product of the same frozen (piecewise-linear) field.
    """
    w = p[P_W]
    ph = w * t
    c = math.cos(ph)
    sn = math.sin(ph)
    stiff = 1.0 + p[P_EPS] * c
    xi = p[P_XI]
    x = y[0]
    v = y[1]
    F = stiff * dead_zone(x, p[P_B], mode[0]) + 2.0 * xi * v
    fric = 1.0
    if p[P_GAMMA] != 0.0:
        # lambda = sign(sin(w tau)) is frozen per step like the dead zones: the integrator lands
        # on the half-period times where it flips, so a step never straddles the jump and a
        # stage exactly on it cannot pick the wrong side through rounding of w tau
        fric = 1.0 + p[P_GAMMA] * mode[MODE_FRICTION]
    # cos(ph + phi_e) by the addition theorem (phi_e's cos/sin are precomputed)
    drive = p[P_FM] + p[P_FE] * w * w * (c * p[P_COS_PHI_E] - sn * p[P_SIN_PHI_E])
    if p[P_VR_AMP] != 0.0:
        drive += p[P_VR_AMP] * w * w * math.sin(p[P_VR_ORDER] * w * (t + p[P_T0]))
    acc = drive - F * fric
    dy[0] = v
    s_mesh = 1.0 if mode[0] != 0 else 0.0
    if p[P_DOF6] != 0.0:
        ca = p[P_COS_ALPHA]
        sa = p[P_SIN_ALPHA]
        rp = p[P_RHO_P]
        rg = p[P_RHO_G]
        a_py = (
            -2.0 * p[P_XI_BRG] * y[3]
            - p[P_KAPPA] * dead_zone(y[2], p[P_B_BRG], mode[1])
            - rp * F * ca
        )
        a_pz = (
            -2.0 * p[P_XI_BRG + 1] * y[5]
            - p[P_KAPPA + 1] * dead_zone(y[4], p[P_B_BRG + 1], mode[2])
            - rp * F * sa
        )
        a_gy = (
            -2.0 * p[P_XI_BRG + 2] * y[7]
            - p[P_KAPPA + 2] * dead_zone(y[6], p[P_B_BRG + 2], mode[3])
            + rg * F * ca
        )
        a_gz = (
            -2.0 * p[P_XI_BRG + 3] * y[9]
            - p[P_KAPPA + 3] * dead_zone(y[8], p[P_B_BRG + 3], mode[4])
            + rg * F * sa
        )
        acc += (a_py - a_gy) * ca + (a_pz - a_gz) * sa
        dy[1] = acc
        dy[2] = y[3]
        dy[3] = a_py
        dy[4] = y[5]
        dy[5] = a_pz
        dy[6] = y[7]
        dy[7] = a_gy
        dy[8] = y[9]
        dy[9] = a_gz
        if tangent:
            dF = stiff * s_mesh * y[10] + 2.0 * xi * y[11]
            d_py = (
                -2.0 * p[P_XI_BRG] * y[13]
                - p[P_KAPPA] * (1.0 if mode[1] != 0 else 0.0) * y[12]
                - rp * dF * ca
            )
            d_pz = (
                -2.0 * p[P_XI_BRG + 1] * y[15]
                - p[P_KAPPA + 1] * (1.0 if mode[2] != 0 else 0.0) * y[14]
                - rp * dF * sa
            )
            d_gy = (
                -2.0 * p[P_XI_BRG + 2] * y[17]
                - p[P_KAPPA + 2] * (1.0 if mode[3] != 0 else 0.0) * y[16]
                + rg * dF * ca
            )
            d_gz = (
                -2.0 * p[P_XI_BRG + 3] * y[19]
                - p[P_KAPPA + 3] * (1.0 if mode[4] != 0 else 0.0) * y[18]
                + rg * dF * sa
            )
            dy[10] = y[11]
            dy[11] = -dF * fric + (d_py - d_gy) * ca + (d_pz - d_gz) * sa
            dy[12] = y[13]
            dy[13] = d_py
            dy[14] = y[15]
            dy[15] = d_pz
            dy[16] = y[17]
            dy[17] = d_gy
            dy[18] = y[19]
            dy[19] = d_gz
    else:
        dy[1] = acc
        for k in range(2, 10):
            dy[k] = 0.0
        if tangent:
            dF = stiff * s_mesh * y[10] + 2.0 * xi * y[11]
            dy[10] = y[11]
            dy[11] = -dF * fric
            for k in range(12, 20):
                dy[k] = 0.0


def static_state(params_array: np.ndarray) -> np.ndarray:
    """Static equilibrium under the mean load alone (a default initial condition).

    Mesh: ``f(x, b) = Fm`` so ``x = b + Fm``; bearings: ``kappa f(u) = -/+ rho Fm d_j``.
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
            u = loads[k] / p[P_KAPPA + k]
            gap = p[P_B_BRG + k]
            y[2 + 2 * k] = u + math.copysign(gap, u) if u != 0.0 else 0.0
    return y
