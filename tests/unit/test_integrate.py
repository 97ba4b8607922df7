"""The compiled integrators against scipy's DOP853 with event location."""

import numpy as np
import pytest
from reference import reference_settings, solve_ivp_reference

from gearsim.cell.simulate import IntegrationSettings, run_periods
from gearsim.dynamics.model import static_state
from gearsim.dynamics.parameters import ModelParameters
from gearsim.numerics.integrate import METHOD_DP5

# impacting cells: one-sided at b = 1 (1-1-0, 2-2-0), double-sided at b = 0.15 / 0.3
CELLS = [
    dict(w=0.8, b=1.0),
    dict(w=1.05, b=1.0),
    dict(w=0.8, b=0.15),
    dict(w=1.2, b=0.3),
]
N_PERIODS = 12


def _ours(p, y0, method, **kw):
    st = reference_settings(method=method, **kw)
    r = run_periods(p, y0, N_PERIODS + 1, st, event_capacity=10_000)
    T = 2 * np.pi / p.w
    keep = ((r.events_code // 4) == 0) & (r.events_t < N_PERIODS * T)
    return r.summaries.section, r.events_t[keep]


@pytest.fixture(scope="module", params=range(len(CELLS)))
def reference(request):
    p = ModelParameters(**CELLS[request.param])
    y0 = static_state(p.to_array())
    y0[0] += 0.3  # start away from equilibrium so the transient impacts too
    sections, switches = solve_ivp_reference(p, y0, N_PERIODS)
    assert len(switches) >= 4, "cell must impact for the test to mean anything"
    return p, y0, sections, switches, switch_time_tolerance(p, y0, switches)


#: State perturbation that measures the conditioning of the switch times.
PERTURBATION = 1e-10


def switch_time_tolerance(p, y0, switches):
    """Per switch, how precisely the problem fixes its time: 1e-8 plus the shift of that switch
    when the start moves by 10 x :data:`PERTURBATION` (measured as 10 times the shift for
    :data:`PERTURBATION`). Both integrators hold the state to ~1e-10 per period (DP5 at rtol
    1e-11, RK4 at 2048 steps), and rounding differences of another instruction set (AVX2 or
    AVX-512 code) are far smaller; the double-sided impacting cells amplify any of them along the
    horizon (up to ~800 x at w = 0.8, b = 0.15 by the 12th period), the one-sided ones barely."""
    y1 = np.array(y0, dtype=float)
    y1[0] += PERTURBATION
    _, moved = solve_ivp_reference(p, y1, N_PERIODS)
    if len(moved) != len(switches):  # a grazing switch appears or goes: no per-switch bound
        return np.full(len(switches), 1e-8)
    return 1e-8 + 10.0 * np.abs(moved - switches)


def test_dp5_poincare_points_and_switch_times(reference):
    p, y0, sections, switches, tol = reference
    sec, sw = _ours(p, y0, "dp5", rtol=1e-11, atol=1e-13)
    np.testing.assert_allclose(sec[: N_PERIODS + 1], sections, rtol=0, atol=1e-6)
    assert len(sw) == len(switches)
    assert np.all(np.abs(sw - switches) < tol)


def test_rk4_poincare_points_and_switch_times(reference):
    p, y0, sections, switches, tol = reference
    sec, sw = _ours(p, y0, "rk4", steps_per_period=2048, hmax=0.05)
    np.testing.assert_allclose(sec[: N_PERIODS + 1], sections, rtol=0, atol=1e-6)
    assert len(sw) == len(switches)
    assert np.all(np.abs(sw - switches) < tol)


def test_defaults_are_the_studys_rk4_and_dp5_is_method_zero():
    assert IntegrationSettings().method == "rk4" and METHOD_DP5 == 0


@pytest.mark.parametrize("method", ["dp5", "rk4"])
def test_friction_jump_does_not_leave_noise_on_the_section(method):
    """lambda flips at T/2: frozen per step, a periodic orbit's section points repeat exactly.

    (Evaluating sign(sin(w tau)) per stage let rounding of w tau pick the wrong side at the jump,
    leaving ~1e-7 noise that broke the period test.)
    """
    p = ModelParameters(w=0.34, b=0.9375, friction=1e-3)
    st = reference_settings(method=method)
    r = run_periods(p, static_state(p.to_array()), 300, st)
    d = np.abs(np.diff(r.summaries.section[-100:, 0]))
    assert d.max() < 1e-11
    # and friction does change the motion (the option is live)
    r0 = run_periods(p.with_(friction=0.0), static_state(p.to_array()), 300, st)
    assert abs(r0.summaries.section[-1, 0] - r.summaries.section[-1, 0]) > 1e-6


@pytest.mark.timeout(120)
@pytest.mark.parametrize("method", ["rk4", "dp5"])
def test_late_start_in_a_long_chain_does_not_stall(method):
    """A double-sided cell at tau ~ 6.8e4 (period 19518 of a plane row): time runs relative to
    the period start, so switch landings keep full resolution (absolute time stalled RK4)."""
    p = ModelParameters(
        w=1.813, b=0.01625, rho_p=0.4, rho_g=0.1, kappa_py=40.0, kappa_pz=40.0, kappa_gy=10.0,
        kappa_gz=10.0, xi_gy=0.0075, xi_gz=0.0075,
    )
    u0 = np.array([
        -0.4549628796441339, 1.172058567753086, 0.004264165539223804, -0.027711671070399988,
        0.0015520293302666245, -0.010086223411437, -0.006157172126949306, 0.04117271081464423,
        -0.002241027381470986, 0.014985641200633485,
    ])
    st = reference_settings(method=method).tightened()
    late = run_periods(p, u0, 3, st, start_period=19518, event_capacity=1000)
    early = run_periods(p, u0, 3, st, start_period=0, event_capacity=1000)
    assert late.periods_done == 3 and late.n_events > 0
    # the motion does not depend on where the chain started (all forcing is T-periodic here)
    np.testing.assert_allclose(late.summaries.section, early.summaries.section, atol=1e-9)
    T = 2 * np.pi / p.w
    np.testing.assert_allclose(late.events_t - 19518 * T, early.events_t, atol=1e-8)


@pytest.mark.parametrize("form", [{}, {"te_damping": 0.5, "mesh_damping_contact": 0.3}])
def test_trajectory_mesh_force_is_the_force_of_the_model_form(form):
    """The recorded mesh force, written out from the equations (docs/model.md, Model forms):
    ``(1 + eps cos w tau) f(x, b) + 2 xi (1 - delta [inside the backlash]) (x' - (1 - beta) Fe w
    sin(w tau + phi_e))``; in today's form (beta = 1, delta = 0) bit for bit the old formula."""
    from gearsim.cell.simulate import trajectory

    p = ModelParameters(w=0.8, b=0.15, **form)
    tr = trajectory(p, periods=3, samples_per_period=16, transient=5,
                    settings=reference_settings(method="rk4"))
    x, v, tau = tr.state[:, 0], tr.state[:, 1], tr.tau
    f = np.where(x > p.b, x - p.b, np.where(x < -p.b, x + p.b, 0.0))
    inside = np.abs(x) <= p.b
    assert inside.any() and (~inside).any()  # both branches of the dead zone are sampled
    rate = v - (1.0 - p.te_damping) * p.Fe * p.w * np.sin(p.w * tau + p.phi_e)
    damper = 2.0 * p.xi * (1.0 - p.mesh_damping_contact * inside) * rate
    expected = (1.0 + p.eps * np.cos(p.w * tau)) * f + damper
    if form:
        np.testing.assert_allclose(tr.mesh_force, expected, rtol=1e-13, atol=1e-13)
    else:
        old = (1.0 + p.eps * np.cos(p.w * tau)) * f + 2.0 * p.xi * v
        np.testing.assert_array_equal(tr.mesh_force, old)
