"""Lyapunov exponents and spectra against exact values.

References are independent of gearsim's integrators: eigenvalues of the linear system's matrix
written out here (numpy), the monodromy matrix of the Mathieu-type equation integrated with
scipy's DOP853, and a two-trajectory (Benettin) estimate computed with scipy's DOP853 on the
single-DOF equations written out here.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from reference import reference_settings
from scipy.integrate import solve_ivp

from gearsim.cell.simulate import simulate_cell
from gearsim.dynamics.parameters import ModelParameters
from gearsim.numerics.variational import lyapunov_spectrum, monodromy, tangent_map, trace_mean
from gearsim.study.config_io import load_standard_parameters

ROOT = Path(__file__).resolve().parents[2]
RK4 = reference_settings(method="rk4")


def _linear_matrix(p: ModelParameters) -> np.ndarray:
    """The 6-DOF equations in permanent contact (eps = 0, no clearances) as y' = A y + c."""
    ca, sa = math.cos(p.alpha), math.sin(p.alpha)
    A = np.zeros((10, 10))
    F = np.zeros(10)  # mesh force F = x + 2 xi x' (+ const)
    F[0], F[1] = 1.0, 2.0 * p.xi
    acc_b = []
    for k, (name, rho, sign, d) in enumerate(
        [("py", p.rho_p, -1, ca), ("pz", p.rho_p, -1, sa), ("gy", p.rho_g, 1, ca),
         ("gz", p.rho_g, 1, sa)]
    ):
        row = np.zeros(10)
        row[3 + 2 * k] = -2.0 * getattr(p, f"xi_{name}")
        row[2 + 2 * k] = -getattr(p, f"kappa_{name}")
        row += sign * rho * d * F
        A[2 + 2 * k, 3 + 2 * k] = 1.0
        A[3 + 2 * k] = row
        acc_b.append(row)
    A[0, 1] = 1.0
    A[1] = -F + (acc_b[0] - acc_b[2]) * ca + (acc_b[1] - acc_b[3]) * sa
    return A


@pytest.mark.parametrize("xi", [0.05, 0.1, 0.2])
def test_linear_single_dof_exponent_is_minus_xi(xi):
    p = ModelParameters(w=0.7, b=1.0, Fe=0.01, eps=0.0, xi=xi, model="1dof")
    for st in (reference_settings(), RK4):
        r = simulate_cell(p, settings=st, spectrum=120)
        assert r.classification.label == "0/1T"  # always in contact: a linear system
        assert r.classification.lyapunov == pytest.approx(-xi, abs=1e-3)
        np.testing.assert_allclose(r.spectrum.exponents, [-xi, -xi], atol=1e-3)
        assert r.spectrum.ok()


@pytest.mark.parametrize("xi", [0.05, 0.2])
def test_linear_six_dof_exponents_are_the_eigenvalues(xi):
    p = ModelParameters(w=0.7, b=1.0, Fe=0.01, eps=0.0, xi=xi)
    ev = np.linalg.eigvals(_linear_matrix(p))
    re = np.sort(ev.real)[::-1]
    r = simulate_cell(p, settings=RK4, spectrum=1000)  # complex pairs converge like 1/time
    assert r.classification.label == "0/1T"
    assert r.classification.lyapunov == pytest.approx(re[0], abs=1e-3)
    np.testing.assert_allclose(r.spectrum.exponents, re, atol=1e-3)
    assert r.spectrum.trace == pytest.approx(np.trace(_linear_matrix(p)), abs=1e-12)
    assert r.spectrum.ok()


def test_mathieu_exponents_equal_floquet_from_scipy():
    """b = 0, eps > 0: x'' + 2 xi x' + (1 + eps cos w t) x = forcing (linear, time-periodic)."""
    w, eps, xi = 1.5, 0.3, 0.05
    p = ModelParameters(w=w, b=0.0, eps=eps, xi=xi, Fe=0.0, model="1dof")
    T = 2 * math.pi / w

    def homog(t, y):
        x, v, x2, v2 = y
        k = 1 + eps * math.cos(w * t)
        return [v, -2 * xi * v - k * x, v2, -2 * xi * v2 - k * x2]

    sol = solve_ivp(homog, (0, T), [1, 0, 0, 1], method="DOP853", rtol=1e-12, atol=1e-14)
    M = sol.y[:, -1].reshape(2, 2).T
    mu = np.linalg.eigvals(M)
    ref = np.sort(np.log(np.abs(mu)) / T)[::-1]
    st = reference_settings(rtol=1e-11, atol=1e-13)
    r = simulate_cell(p, settings=st, spectrum=200)
    np.testing.assert_allclose(r.spectrum.exponents, ref, atol=1e-3)
    # the monodromy of the map itself (gearsim's variational layer) equals scipy's
    y_end, Mg, status = monodromy(p, r.final_state, 1, st, start_period=r.final_period)
    assert status == 0
    np.testing.assert_allclose(np.sort(np.abs(np.linalg.eigvals(Mg))), np.sort(np.abs(mu)),
                               rtol=1e-6)


def test_b0_has_no_impacts():
    """Zero backlash: the mesh spring is linear, a crossing of x = 0 is no impact."""
    p = ModelParameters(w=1.5, b=0.0, eps=0.3, xi=0.05, Fe=0.3, Fm=0.05)
    r = simulate_cell(p, settings=RK4)
    c = r.classification
    assert c.n >= 1 and c.p == 0 and c.q == 0 and c.I == 0 and c.dc == 0.0
    assert c.label == f"0/{c.n}T"
    assert r.classification.x_min < 0 < r.classification.x_max  # it does cross x = 0


def _standard_1dof(w):
    values = load_standard_parameters(ROOT / "config" / "standard_parameters.yaml")
    values = {k: v for k, v in values.items() if k in ModelParameters.names()}
    values.update(w=w, model="1dof")
    return ModelParameters.from_mapping(values)


def test_chaotic_exponent_agrees_with_two_trajectory_estimate():
    p = _standard_1dof(1.53)
    r = simulate_cell(p, settings=RK4)
    assert r.classification.motion == "chaos"
    b, w = p.b, p.w

    def f(t, y, lam):  # lam: the friction direction of the half period
        x, v = y
        fx = x - b if x > b else (x + b if x < -b else 0.0)
        F = (1 + p.eps * math.cos(w * t)) * fx + 2 * p.xi * v
        drive = p.Fm + p.Fe * w * w * math.cos(w * t + p.phi_e)
        return [v, drive - F * (1 + p.friction * lam)]

    T = 2 * math.pi / w

    def ev_up(t, y, lam):
        return y[0] - b

    def ev_lo(t, y, lam):
        return y[0] + b

    ev_up.terminal = ev_lo.terminal = True

    def segment(y, a, bb, lam):
        """DOP853 from a to bb, restarted at every contact switch (x = +/-b) it locates."""
        t = a
        while t < bb:
            sol = solve_ivp(f, (t, bb), y, method="DOP853", rtol=1e-12, atol=1e-14,
                            events=(ev_up, ev_lo), args=(lam,))
            t, y = sol.t[-1], sol.y[:, -1]
            if sol.status == 1:  # step just past the root so the restart does not re-trigger
                sol = solve_ivp(f, (t, min(t + 1e-9, bb)), y, method="DOP853", rtol=1e-12,
                                atol=1e-14, args=(lam,))
                t, y = sol.t[-1], sol.y[:, -1]
        return y

    def flow(y, ta):  # one period, split where the friction direction flips (T/2)
        return segment(segment(y, ta, ta + T / 2, 1.0), ta + T / 2, ta + T, -1.0)

    y = np.array(r.final_state[:2])
    d0 = 1e-6
    z = y + np.array([d0, 0.0])
    total = 0.0
    n = 400  # finite-time exponents of a chaotic motion fluctuate: average long
    t0 = r.final_period * T
    q = np.zeros(10)
    q[0] = 1.0
    var_total = 0.0
    for k in range(n):
        ta = t0 + k * T
        ya = flow(y, ta)
        za = flow(z, ta)
        d = np.linalg.norm(za - ya)
        total += math.log(d / d0)
        # gearsim's variational equations along the same (scipy) orbit: the tangent map
        _, mq, status = tangent_map(p, np.concatenate([y, np.zeros(8)]), 1, RK4, q[:, None],
                                    start_period=r.final_period + k)
        assert status == 0
        g = np.linalg.norm(mq[:, 0])
        var_total += math.log(g)
        q = mq[:, 0] / g
        y, z = ya, ya + (za - ya) * (d0 / d)
    ref = total / (n * T)
    print(f"two-trajectory (scipy) {ref:.5f}, variational on the same orbit "
          f"{var_total / (n * T):.5f}")
    assert ref > 0.01
    # the same orbit, the same window: finite differences (scipy) vs variational (gearsim)
    assert var_total / (n * T) == pytest.approx(ref, rel=0.1)
    # on gearsim's own orbit (another finite window of the same attractor: fluctuations)
    spec = lyapunov_spectrum(p, r.final_state, n, RK4, start_period=r.final_period)
    print(f"spectrum on gearsim's orbit {spec.exponents}, per-cell {r.classification.lyapunov}")
    assert spec.exponents[0] == pytest.approx(ref, rel=0.25)
    assert spec.exponents.sum() == pytest.approx(trace_mean(p), abs=1e-3)
    assert r.classification.lyapunov > 0.005  # the per-cell indicator says chaos
