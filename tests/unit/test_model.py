"""The model against independent references: the analytic linear response and rigid bearings."""

import math

import numpy as np
import pytest
from reference import linear_steady_state, reference_settings

from gearsim.cell.simulate import trajectory
from gearsim.dynamics.parameters import ModelParameters


def _linear_params(**kw):
    base = dict(w=0.83, b=0.0, eps=0.0, Fm=0.1, Fe=0.17, xi=0.05, phi_e=-0.6)
    base.update(kw)
    return ModelParameters(**base)


@pytest.mark.parametrize("w", [0.3, 0.83, 1.7, 2.4])
@pytest.mark.parametrize("method", ["dp5", "rk4"])
def test_linear_limit_matches_analytic_frequency_response(w, method):
    p = _linear_params(w=w)
    qs, Q = linear_steady_state(p)
    y0 = np.zeros(10)
    y0[0::2] = qs + Q.real
    y0[1::2] = (1j * w * Q).real
    st = reference_settings(method=method, rtol=1e-11, atol=1e-13, steps_per_period=2048)
    tr = trajectory(p, y0, periods=5, samples_per_period=16, settings=st)
    exact = qs[:, None] + (Q[:, None] * np.exp(1j * w * tr.tau[None, :])).real
    amp = np.abs(Q).max()
    err = np.abs(tr.state[:, 0::2].T - exact).max() / amp
    assert err < 1e-6, f"relative error {err:.2e}"


def test_linear_response_is_not_trivially_satisfied():
    """A wrong forcing phase must fail the same comparison (the test can fail)."""
    p = _linear_params()
    qs, Q = linear_steady_state(p)
    y0 = np.zeros(10)
    y0[0::2] = qs + Q.real
    y0[1::2] = (1j * p.w * Q).real
    tr = trajectory(p.with_(phi_e=p.phi_e + 0.1), y0, periods=5, samples_per_period=16)
    exact = qs[:, None] + (Q[:, None] * np.exp(1j * p.w * tr.tau[None, :])).real
    assert np.abs(tr.state[:, 0::2].T - exact).max() / np.abs(Q).max() > 1e-3


def test_single_dof_equals_six_dof_with_decoupled_bearings():
    """rho_p = rho_g = 0 decouples the bearings exactly: x(t) must be identical."""
    common = dict(w=1.02, b=0.3, rho_p=0.0, rho_g=0.0)
    y0 = np.zeros(10)
    y0[0] = 0.45
    st = reference_settings(method="rk4")
    a = trajectory(ModelParameters(model="6dof", **common), y0, periods=20, settings=st)
    b = trajectory(ModelParameters(model="1dof", **common), y0, periods=20, settings=st)
    np.testing.assert_allclose(a.state[:, :2], b.state[:, :2], rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.events_tau, b.events_tau, rtol=0, atol=1e-12)


def test_single_dof_is_the_rigid_bearing_limit():
    """Stiff bearings (kappa -> inf) converge to the single-DOF motion, error ~ 1/kappa."""
    y0 = np.zeros(10)
    y0[0] = 0.45
    st = reference_settings(method="dp5", rtol=1e-10, atol=1e-12, hmax=0.01)
    rigid = trajectory(ModelParameters(w=0.7, b=0.3, model="1dof"), y0, periods=6, settings=st)
    errs = []
    for kappa in (1e3, 1e4):
        kw = {f"kappa_{j}": kappa for j in ("py", "pz", "gy", "gz")}
        kw.update({f"xi_{j}": 0.5 for j in ("py", "pz", "gy", "gz")})
        six = trajectory(ModelParameters(w=0.7, b=0.3, **kw), y0, periods=6, settings=st)
        errs.append(np.abs(six.state[:, 0] - rigid.state[:, 0]).max())
    assert errs[1] < errs[0] / 5
    assert errs[1] < 2e-3


def test_static_equilibrium_is_steady_without_forcing():
    p = ModelParameters(Fe=0.0, eps=0.0, w=1.0, b=0.5)
    from gearsim.dynamics.model import static_state

    y0 = static_state(p.to_array())
    tr = trajectory(p, y0, periods=3)
    assert np.abs(tr.state - y0).max() < 1e-10
    assert math.isclose(y0[0], p.b + p.Fm)
