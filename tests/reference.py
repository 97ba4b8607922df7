"""Independent references for the core tests.

* ``linear_steady_state``: the analytic periodic response of the linear limit
  (b = 0, eps = 0, no bearing clearance) from one complex linear solve, written from the
  equations in docs/model.md (mass, damping and stiffness matrices by hand).
* ``solve_ivp_reference``: the same equations in plain NumPy (true dead zones, no frozen
  regions) integrated by scipy's DOP853 with terminal events on x = +/-b, restarted at each
  switch so that every switch time is located by scipy's own root finder.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from gearsim.cell.simulate import IntegrationSettings


def linear_matrices(p):
    """M q'' + C q' + K q = f(t) for q = [x, u_py, u_pz, u_gy, u_gz] (linear limit)."""
    dy, dz = math.cos(p.alpha), math.sin(p.alpha)
    d = np.array([dy, dz])
    M = np.eye(5)
    C = np.zeros((5, 5))
    K = np.zeros((5, 5))
    # x row: x'' - (u_p'' - u_g'') . d + F = drive, F = x + 2 xi x'
    M[0, 1:3] = -d
    M[0, 3:5] = d
    C[0, 0] = 2 * p.xi
    K[0, 0] = 1.0
    kap = [p.kappa_py, p.kappa_pz, p.kappa_gy, p.kappa_gz]
    xib = [p.xi_py, p.xi_pz, p.xi_gy, p.xi_gz]
    for k in range(4):
        row = 1 + k
        sign = 1.0 if k < 2 else -1.0  # pinion gets -rho_p F d, gear +rho_g F d
        rho = p.rho_p if k < 2 else p.rho_g
        C[row, row] = 2 * xib[k]
        K[row, row] = kap[k]
        C[row, 0] += sign * rho * d[k % 2] * 2 * p.xi
        K[row, 0] += sign * rho * d[k % 2]
    return M, C, K


def linear_steady_state(p):
    """Return (q_static, Q) with q(tau) = q_static + Re(Q exp(i w tau)) the periodic response."""
    M, C, K = linear_matrices(p)
    f0 = np.zeros(5)
    f0[0] = p.Fm
    f1 = np.zeros(5, dtype=complex)
    f1[0] = p.Fe * p.w**2 * np.exp(1j * p.phi_e)
    q_static = np.linalg.solve(K, f0)
    Q = np.linalg.solve(-(p.w**2) * M + 1j * p.w * C + K, f1)
    return q_static, Q


def dead_zone(x, gap):
    return np.where(x > gap, x - gap, np.where(x < -gap, x + gap, 0.0))


def rhs_numpy(t, y, p):
    """The 6-DOF equations with true (unfrozen) dead zones; bearings without clearance."""
    w = p.w
    ca, sa = math.cos(p.alpha), math.sin(p.alpha)
    x, v = y[0], y[1]
    F = (1 + p.eps * math.cos(w * t)) * float(dead_zone(x, p.b)) + 2 * p.xi * v
    drive = p.Fm + p.Fe * w * w * math.cos(w * t + p.phi_e)
    u = y[2:10:2]
    ud = y[3:10:2]
    kap = [p.kappa_py, p.kappa_pz, p.kappa_gy, p.kappa_gz]
    xib = [p.xi_py, p.xi_pz, p.xi_gy, p.xi_gz]
    dirs = [ca, sa, ca, sa]
    acc = np.empty(4)
    for k in range(4):
        load = -p.rho_p * F * dirs[k] if k < 2 else p.rho_g * F * dirs[k]
        acc[k] = -2 * xib[k] * ud[k] - kap[k] * u[k] + load
    if p.model == "1dof":
        acc[:] = 0.0
    xdd = drive - F + (acc[0] - acc[2]) * ca + (acc[1] - acc[3]) * sa
    out = np.empty(10)
    out[0] = v
    out[1] = xdd
    out[2:10:2] = ud
    out[3:10:2] = acc
    return out


def solve_ivp_reference(p, y0, n_periods, rtol=1e-11, atol=1e-13):
    """Integrate with DOP853 restarting at every switch; return (section states, switch times)."""
    T = 2 * math.pi / p.w
    sections = [np.array(y0, dtype=float)]
    switches = []
    y = np.array(y0, dtype=float)
    t = 0.0

    def ev_up(t, y, p):
        return y[0] - p.b

    def ev_lo(t, y, p):
        return y[0] + p.b

    ev_up.terminal = True
    ev_lo.terminal = True
    for k in range(1, n_periods + 1):
        t_end = k * T
        while t < t_end:
            sol = solve_ivp(
                rhs_numpy, (t, t_end), y, method="DOP853", rtol=rtol, atol=atol,
                events=(ev_up, ev_lo), args=(p,),
            )
            t_new = sol.t[-1]
            y = sol.y[:, -1].copy()
            if sol.status == 1:
                # step just past the root so the restarted solver does not re-trigger at t_new
                switches.append(t_new)
                sol2 = solve_ivp(rhs_numpy, (t_new, min(t_new + 1e-9, t_end)), y,
                                 method="DOP853", rtol=rtol, atol=atol, args=(p,))
                t_new, y = sol2.t[-1], sol2.y[:, -1].copy()
            t = t_new
        sections.append(y.copy())
    return np.array(sections), np.array(switches)


#: What the numerics tests were written for: adaptive DP5 unless a method is given, 256 RK4 steps
#: per mesh period, a 16-period continuation transient. The study's production settings (RK4, 192
#: steps, 40 periods: IntegrationSettings' defaults, docs/decisions.md) are tested where the
#: pipeline is; a test of the numerics keeps its own fixed reference settings.
REFERENCE_SETTINGS = {"method": "dp5", "steps_per_period": 256, "transient_continuation": 16}


def reference_settings(**changes) -> IntegrationSettings:
    """:data:`REFERENCE_SETTINGS` with ``changes``."""
    return IntegrationSettings(**{**REFERENCE_SETTINGS, **changes})
