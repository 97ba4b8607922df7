"""Continuation of periodic orbits: located bifurcations against independent references.

* Mathieu-type limit (b = 0, eps > 0, single-DOF, linear): the first parametric-resonance tongue
  (w ~ 2) is bounded by two period doublings of the forced 1T orbit; they match the first-order
  harmonic-balance boundary ``(1 - nu^2)^2 = eps^2 / 4 - 4 xi^2 nu^2`` (``nu = w / 2``) to
  O(eps^2) and lie inside a brute-force bracket: the homogeneous equation, integrated with scipy
  DOP853 over 300 periods, decays just outside and grows just inside.
* Standard single-DOF set: every located period doubling lies inside the grid interval (spacing
  0.002, the standard sweep's) where the simulated (forward-continued) period changes from n to
  2n.
* A fold is a turning point of the branch with a multiplier +1 (to 1e-7).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from reference import reference_settings
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from gearsim.analysis.continuation import continue_orbit
from gearsim.analysis.continuation_options import Continuation
from gearsim.cell.simulate import simulate_cell
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.study.config_io import load_standard_parameters

STANDARD = ModelParameters.from_mapping(load_standard_parameters("config/standard_parameters.yaml"))
ONE = STANDARD.with_(model="1dof")


def _growth(eps, xi, w, periods=300):
    """Largest log growth per period of x'' + 2 xi x' + (1 + eps cos w t) x = 0 (scipy)."""
    T = 2 * math.pi / w

    def f(t, y):
        return [y[1], -2 * xi * y[1] - (1 + eps * math.cos(w * t)) * y[0]]

    out = -np.inf
    for y0 in ([1.0, 0.0], [0.0, 1.0]):
        sol = solve_ivp(f, (0, periods * T), y0, method="DOP853", rtol=1e-10, atol=1e-14)
        out = max(out, math.log(np.linalg.norm(sol.y[:, -1])) / periods)
    return out


def test_mathieu_tongue_boundaries():
    eps, xi = 0.2, 0.01
    p = ONE.with_(b=0.0, eps=eps, xi=xi, friction=0.0, Fe=0.01, w=1.7)
    df = continue_orbit(p, "w", 1.7, 2.3, n=1,
                        config=Continuation(ds=0.02, ds_max=0.04, switch_depth=0, grazing=False))
    pds = sorted(df.loc[(df.event == "period_doubling") & (df.branch == 0), "value"])
    assert len(pds) == 2
    lo, hi = pds

    # first-order boundaries (1 - nu^2)^2 = eps^2 / 4 - 4 xi^2 nu^2, below and above nu = 1
    w_lo = 2 * brentq(lambda nu: (1 - nu**2) - math.sqrt(eps**2 / 4 - 4 * xi**2 * nu**2),
                      0.8, 1.0)
    w_hi = 2 * brentq(lambda nu: (nu**2 - 1) - math.sqrt(eps**2 / 4 - 4 * xi**2 * nu**2),
                      1.0, 1.2)
    assert abs(lo - w_lo) < 0.25 * eps**2 and abs(hi - w_hi) < 0.25 * eps**2
    # brute-force bracket: stable 0.01 outside each boundary, unstable 0.01 inside
    assert _growth(eps, xi, lo - 0.01) < 0 < _growth(eps, xi, lo + 0.01)
    assert _growth(eps, xi, hi + 0.01) < 0 < _growth(eps, xi, hi - 0.01)
    # unstable between them, stable outside
    br = df[(df.branch == 0) & (df.event == "")]
    inside = br[(br.value > lo + 1e-6) & (br.value < hi - 1e-6)]
    outside = br[(br.value < lo - 1e-6) | (br.value > hi + 1e-6)]
    assert len(inside) and not inside.stable.any()
    assert len(outside) and outside.stable.all()
    # located to the multiplier: -1 at both points
    for _, r in df[df.event == "period_doubling"].iterrows():
        mu = np.array(r.mu_re) + 1j * np.array(r.mu_im)
        assert np.min(np.abs(mu + 1)) < 1e-7


@pytest.fixture(scope="module")
def standard_branches():
    return continue_orbit(ONE, "w", 0.9, 1.4, n=1,
                          config=Continuation(ds=0.02, ds_max=0.05, switch_depth=2))


def _simulated_periods(ws, settings):
    out = []
    u0 = None
    for w in ws:
        res = simulate_cell(ONE.with_(w=float(w)), u0, settings=settings)
        out.append(res.classification.n)
        u0 = res.final_state
    return np.array(out)


def test_period_doublings_lie_in_the_simulated_grid_interval(standard_branches):
    df = standard_branches
    pds = df[df.event == "period_doubling"]
    assert len(pds) >= 3  # 1 -> 2, 2 -> 4, 4 -> 8 on the standard single-DOF set
    # near a period doubling the stable orbit's multiplier is close to -1 (0.993 one grid step
    # away): the simulated transient needs thousands of periods to die out before the period
    # test, or a decaying alternation passes for period 2n
    st = reference_settings(transient=3000, transient_continuation=3000, max_periods=128,
                             n_max=16)
    h = 0.002  # the standard sweep's grid spacing (1201 values over [0.1, 2.5])
    for _, r in pds.iterrows():
        n = int(r.period)
        grid = 0.1 + h * np.arange(math.floor((r.value - 0.1) / h) - 6,
                                   math.floor((r.value - 0.1) / h) + 8)
        periods = _simulated_periods(grid, st)
        last_n = max(i for i in range(len(grid)) if periods[i] == n and
                     all(periods[j] != 2 * n for j in range(i)))
        first_2n = min(i for i in range(last_n, len(grid)) if periods[i] == 2 * n)
        assert grid[last_n] <= r.value <= grid[first_2n], (r.value, grid, periods)


def test_fold_is_a_turning_point_with_multiplier_one(standard_branches):
    df = standard_branches
    folds = df[df.event == "fold"]
    assert len(folds) >= 2
    for i, r in folds.iterrows():
        # rows are in branch order: the regular points on either side of the located fold
        # both lie on the same side of it (the branch turns back)
        before, after = df.loc[i - 1], df.loc[i + 1]
        assert before.branch == after.branch == r.branch
        assert (before.value - r.value) * (after.value - r.value) > 0
        mu = np.array(r.mu_re) + 1j * np.array(r.mu_im)
        assert np.min(np.abs(mu - 1)) < 1e-7
        # stability changes across a fold
        assert before.stable != after.stable


def test_grazing_points_have_a_turning_point_on_the_boundary(standard_branches):
    df = standard_branches
    g = df[df.event == "grazing"]
    assert len(g) >= 1
    assert (g.grazing_margin < 1e-7).all()


def test_bad_parameter_name():
    with pytest.raises(ParameterError, match="'name'"):
        continue_orbit(ONE, "omega", 0.9, 1.0, n=1)


def test_exact_landmarks_pair_grid_intervals_with_located_points():
    import pandas as pd

    from gearsim.analysis.exact_landmarks import exact_landmarks, report_lines

    def lm(kind, lo, hi, fr, to, n_from, n_to, direction=1):
        return {"kind": kind, "value": 0.5 * (lo + hi), "lo": lo, "hi": hi, "from_npq": fr,
                "to_npq": to, "n_from": n_from, "n_to": n_to, "direction": direction}

    grid = pd.DataFrame([
        lm("grazing", 0.566, 0.568, "1-0-0", "1-1-0", 1, 1),
        lm("jump", 0.658, 0.660, "1-1-0", "1-1-0", 1, 1),
        lm("period_doubling", 0.986, 0.988, "1-1-0", "2-2-0", 1, 2),
        lm("period_doubling", 1.330, 1.332, "2-1-0", "4-2-0", 2, 4),
    ])
    points = pd.DataFrame([
        {"kind": "grazing", "value": 0.56712345, "period": 1, "stable": True},
        {"kind": "fold", "value": 0.6591, "period": 1, "stable": False},
        {"kind": "period_doubling", "value": 0.98799, "period": 1, "stable": True},
        {"kind": "period_doubling", "value": 1.3335, "period": 2, "stable": True},  # outside
        {"kind": "period_doubling", "value": 1.7, "period": 2, "stable": True},  # elsewhere
    ])
    t = exact_landmarks(points, grid=grid, slack=0.002).set_index("key")
    assert t.loc["grazing_1", "exact"] == 0.56712345 and t.loc["grazing_1", "inside"]
    assert t.loc["jump", "exact_kind"] == "fold" and t.loc["jump", "inside"]
    assert t.loc["pd_1_2", "exact"] == 0.98799 and t.loc["pd_1_2", "inside"]
    assert t.loc["pd_2_4", "exact"] == 1.3335 and not t.loc["pd_2_4", "inside"]
    assert not np.isfinite(t.loc["chaos_onset", "exact"])  # no exact point for chaos onset
    lines = report_lines(t.reset_index())
    assert len(lines) == 2 + len(t) and "0.56712345" in "".join(lines)


def test_parameter_steps_cross_a_parameter_span_in_steps_of_the_parameter():
    """``parameter_steps``: ds is a step of the parameter at the start (the arclength step
    divided by the start tangent's parameter component), so the first step moves the
    parameter by ds (the predictor exactly, the corrector across the tangent slightly); with
    arclength steps the parameter moves by ds times that component, less where the state
    moves fast. Near the fold at w ~ 0.68 the state moves ~2x faster than w."""
    ds = 0.0012
    cfg = dict(ds=ds, ds_max=2.5 * ds, ds_min=1e-4 * ds, max_points=3, switch_depth=0,
               grazing=False)
    par = continue_orbit(ONE, "w", 0.675, 0.69, n=1,
                         config=Continuation(**cfg, parameter_steps=True))
    arc = continue_orbit(ONE, "w", 0.675, 0.69, n=1, config=Continuation(**cfg))
    step_par = float(par["value"].iloc[1] - par["value"].iloc[0])
    step_arc = float(arc["value"].iloc[1] - arc["value"].iloc[0])
    assert step_par == pytest.approx(ds, rel=0.05)
    assert step_arc < 0.5 * ds
