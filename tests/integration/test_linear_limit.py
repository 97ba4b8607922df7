"""The linear limit of the mesh (cell.growth): its Floquet multiplier against scipy, the growth of
a large motion of the full model against it, and the long-run rule on plane cells.

References: the monodromy of the single-DOF linear Mathieu-type equation written out here and
integrated with scipy's DOP853; the amplitude of the full (nonlinear, 6-DOF) model started far
outside the backlash; 4 000-period runs of the same starts by the scalar integrator.
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from gearsim.cell.growth import LONG_RUN, grows, linear_multipliers
from gearsim.cell.simulate import run_periods, simulate_cell
from gearsim.dynamics.model import static_state
from gearsim.dynamics.parameters import ModelParameters
from gearsim.study.config import Study

ST = Study.load().settings

#: a wb plane cell of the default run in the parametric tongue (mu_lin 1.018) whose window reads
#: quasi-periodic (Kmax 0.40) and the state its forward chain starts it from (the left
#: neighbour's window end, itself quasi-periodic)
TONGUE = dict(w=1.885, b=0.02375)
TONGUE_U0 = [-0.05639463242082944, -0.3058747730129229, 0.0014277356174121263,
             0.0001452540900357301, 0.0005196532671415246, 5.286816517861959e-05,
             -0.000865914110544346, -0.0019563730542224585, -0.00031516696167034646,
             -0.0007120615588599467]
#: a bounded chaotic wb cell away from the tongue and its forward-continuation start
BOUNDED = dict(w=1.519, b=0.95125)
BOUNDED_U0 = [0.7383030830150809, 0.008700769117431756, -0.00030498370861931865,
              -0.015455274457362889, -0.00011100499187393824, -0.005625259864914677,
              -0.002584768728846375, 0.004981088414862557, -0.0009407788797654878,
              0.001812967917264589]


def _mathieu_multiplier(w: float, eps: float, xi: float) -> float:
    """|mu|max of x'' + 2 xi x' + (1 + eps cos(w t)) x = 0 over one period 2 pi / w (DOP853)."""
    T = 2.0 * math.pi / w

    def f(t, y):
        return [y[1], -2.0 * xi * y[1] - (1.0 + eps * math.cos(w * t)) * y[0]]

    cols = [solve_ivp(f, (0.0, T), e, method="DOP853", rtol=1e-12, atol=1e-14).y[:, -1]
            for e in ([1.0, 0.0], [0.0, 1.0])]  # fmt: skip
    return float(np.max(np.abs(np.linalg.eigvals(np.column_stack(cols)))))


@pytest.mark.parametrize("w", [1.7, 1.9, 1.97, 2.05, 2.2])
def test_mu_lin_is_the_floquet_multiplier_of_the_mathieu_equation(w):
    # single-DOF form, no friction: the linear limit is the damped Mathieu equation; b, the
    # load and the error forcing do not enter it
    p = ModelParameters(model="1dof", w=w, eps=0.3175, xi=0.0609, b=0.3, Fm=0.12, Fe=0.21,
                        friction=0.0)  # fmt: skip
    ref = _mathieu_multiplier(w, p.eps, p.xi)
    # RK4 at the study's steps per period: global error ~ (w h)^4 ~ 1e-7 of the multiplier;
    # DP5 steps on the state's error (rtol 1e-9), the tangent rides along: ~4e-7 measured
    mu_rk4 = linear_multipliers([p], ST)[0]
    mu_dp5 = linear_multipliers([p], ST.with_(method="dp5"))[0]
    assert mu_rk4 == pytest.approx(ref, rel=1e-6)
    assert mu_dp5 == pytest.approx(ref, rel=2e-6)
    # the tongue of the principal parametric resonance: width ~ eps / 2 about w = 2,
    # narrowed by the damping
    assert (ref > 1.0) == (1.85 < w < 2.1)


def test_a_large_motion_of_the_full_model_grows_at_the_linear_limits_rate():
    """6-DOF standard set, w = 1.95, b = 0.1: started at x = 50 (500 backlashes) the motion is
    nearly linear; its amplitude grows per period by mu_lin (Floquet theory of the linear limit:
    the forced response is ~0.3, the free part dominates)."""
    p = Study.load().parameters(w=1.95, b=0.1).model
    mu = linear_multipliers([p], ST)[0]
    assert mu > 1.0
    y0 = static_state(p.to_array())
    y0[0] = 50.0
    run = run_periods(p, y0, 120, ST)
    assert run.status == 0
    a = run.summaries.xmax - run.summaries.xmin
    # rate from periods 40-60 to 100-120 (past the non-dominant modes)
    rate = (math.log(a[100:].max()) - math.log(a[40:60].max())) / 60.0
    assert rate == pytest.approx(math.log(mu), rel=0.02)


def test_grows_reads_a_late_growth_and_not_a_bounded_run():
    k = np.arange(LONG_RUN)
    late = 1.0 + 1e-6 * np.exp(0.0035 * k)  # flat for 3 000 periods, then the free part wins
    assert grows(late, -late)
    flat = 1.0 + 0.05 * np.sin(0.37 * k)
    assert not grows(flat, -flat)


def test_a_tongue_cell_read_quasi_periodic_is_diverged_by_its_long_run():
    p = Study.load().parameters(plane="wb", **TONGUE).model
    res = simulate_cell(p, np.array(TONGUE_U0), settings=ST)
    c = res.classification
    assert c.mu_lin > 1.0
    # the window alone did not see the growth: a small flat motion
    assert c.kmax < 1.0 and c.x_max - c.x_min < 1.0
    assert (c.motion, c.status, c.label) == ("diverged", "diverged", "diverged")
    assert 0 < c.long_run <= LONG_RUN
    # the reference: the same state left to run (scalar integrator) leaves the bound or grows
    long = run_periods(p, res.final_state, LONG_RUN, ST)
    a = long.summaries.xmax - long.summaries.xmin
    assert long.status != 0 or a[-100:].max() > 100 * a[:100].max()


def test_a_bounded_chaotic_cell_away_from_the_tongue_keeps_its_label():
    p = Study.load().parameters(plane="wb", **BOUNDED).model
    res = simulate_cell(p, np.array(BOUNDED_U0), settings=ST)
    c = res.classification
    assert c.motion == "chaos" and c.mu_lin < 1.0 and math.isnan(c.long_run)


def test_every_cloud_of_a_tongue_cell_is_checked_by_its_long_run():
    """w = 2.065, b = 0.00125 (mu_lin 1.0007, standard set, 16 starts): the finder's clouds are
    checked even where no start diverged (before the rule: four quasi-periodic attractors and no
    diverged start; 4 000-period runs of three of them grow). Every cloud left carries its
    bounded long run; the reference: its first start run 4 400 periods by the scalar
    integrator stays inside the bound without growing."""
    from gearsim.analysis.attractors import FinderOptions, find_attractors

    p = Study.load().parameters(w=2.065, b=0.00125).model
    assert linear_multipliers([p], ST)[0] > 1.0
    ca = find_attractors(p, FinderOptions(starts=16), settings=ST)
    assert ca.diverged_fraction > 0
    for a in ca.attractors:
        if a.steady.period > 0:
            continue
        assert a.steady.info["long_run"] == LONG_RUN
        i = int(np.nonzero(ca.start_labels == a.index)[0][0])
        run = run_periods(p, ca.starts[i], LONG_RUN + 400, ST)
        assert run.status == 0
        assert not grows(run.summaries.xmax[400:], run.summaries.xmin[400:])
