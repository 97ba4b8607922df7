"""Periodic orbits by Newton shooting: independent references (analytic, numpy/scipy).

* linear limit (b = 0, eps = 0): multipliers exp(T(-xi +/- i sqrt(1 - xi^2))) and the analytic
  frequency response (single-DOF); 6-DOF against scipy.linalg.expm of the hand-written matrix;
* monodromy matrix against finite differences of the section map computed with scipy's DOP853 at
  1e-12 (equations written out here, restarted at every contact switch) on impacting orbits of
  periods 1, 2 and 4;
* Newton refinement reproduces tightly simulated section points (30 stable cells).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg
from reference import reference_settings
from scipy.integrate import solve_ivp

from gearsim.analysis.orbits import (
    SHOOTING,
    OrbitError,
    find_periodic_orbit,
    grazing_margin,
    multiplier_kind,
    section_map,
)
from gearsim.cell.simulate import simulate_cell
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.numerics.variational import monodromy
from gearsim.study.config_io import load_standard_parameters

STANDARD = ModelParameters.from_mapping(load_standard_parameters("config/standard_parameters.yaml"))
ONE = STANDARD.with_(model="1dof")


# ----------------------------------------------------------------------------- linear limit
@pytest.mark.parametrize("xi,w", [(0.05, 0.7), (0.2, 1.3), (0.06, 2.1)])
def test_linear_single_dof_multipliers_and_frequency_response(xi, w):
    p = ONE.with_(b=0.0, eps=0.0, friction=0.0, xi=xi, w=w)
    orbit = find_periodic_orbit(p, 1, np.zeros(10))
    T = 2 * math.pi / w
    wd = math.sqrt(1 - xi**2)
    expect = np.exp(T * np.array([-xi + 1j * wd, -xi - 1j * wd]))
    got = np.sort_complex(orbit.multipliers)
    assert np.max(np.abs(got - np.sort_complex(expect))) < 1e-10
    # x'' + 2 xi x' + x = Fm + Fe w^2 cos(w t + phi_e): steady response at t = 0
    H = p.Fe * w**2 * np.exp(1j * p.phi_e) / (1 - w**2 + 2j * xi * w)
    assert abs(orbit.state[0] - (p.Fm + H.real)) < 1e-9
    assert abs(orbit.state[1] - (1j * w * H).real) < 1e-9
    assert orbit.residual < 1e-10 and orbit.stable
    assert orbit.critical_kind == "neimark_sacker"


def _linear_6dof_matrix(p: ModelParameters):
    """First-order form y' = A y + f(t) of the 6-DOF equations with b = 0, eps = 0, gamma = 0."""
    ca, sa = math.cos(p.alpha), math.sin(p.alpha)
    d = {"py": ca, "pz": sa, "gy": ca, "gz": sa}
    A = np.zeros((10, 10))
    # F = x + 2 xi x'  (mesh force, linear)
    Fx = np.zeros(10)
    Fx[0], Fx[1] = 1.0, 2 * p.xi
    rows = {}
    for k, (name, rho, sgn) in enumerate(
        [("py", p.rho_p, -1), ("pz", p.rho_p, -1), ("gy", p.rho_g, 1), ("gz", p.rho_g, 1)]
    ):
        i = 2 + 2 * k
        r = np.zeros(10)
        r[i] = -getattr(p, f"kappa_{name}")
        r[i + 1] = -2 * getattr(p, f"xi_{name}")
        r += sgn * rho * d[name] * Fx
        rows[name] = r
        A[i, i + 1] = 1.0
        A[i + 1] = r
    A[0, 1] = 1.0
    A[1] = -Fx + (rows["py"] - rows["gy"]) * ca + (rows["pz"] - rows["gz"]) * sa
    return A


def test_linear_6dof_monodromy_is_matrix_exponential():
    p = STANDARD.with_(b=0.0, eps=0.0, friction=0.0, w=1.3)
    orbit = find_periodic_orbit(p, 1, np.zeros(10))
    A = _linear_6dof_matrix(p)
    T = 2 * math.pi / p.w
    E = scipy.linalg.expm(A * T)
    # the shooting path puts the tangent into DP5's error norm
    # (gearsim.analysis.orbits.TANGENT_ERROR):
    # the monodromy is then as accurate as the state (~2e-11 here)
    assert np.max(np.abs(orbit.monodromy - E)) < 1e-9
    mu = np.linalg.eigvals(E)
    got = orbit.multipliers
    for m in mu:
        assert np.min(np.abs(got - m)) < 1e-9
    # without it the tangent's fast bearing modes are not error-controlled: ~6e4 rtol
    _, M_state, _ = monodromy(p, orbit.state, 1, SHOOTING, tangent_error=False)
    err_state = np.max(np.abs(M_state - E))
    assert 1e-8 < err_state < 2e-7
    fine = find_periodic_orbit(p, 1, orbit.state, SHOOTING.with_(rtol=1e-13, atol=1e-15),
                               grazing=False)
    assert np.max(np.abs(fine.monodromy - E)) < 1e-10
    # forced response: constant part -A^-1 f0, harmonic part Re[(i w - A)^-1 g e^{i w t}]
    f0 = np.zeros(10)
    f0[1] = p.Fm
    g = np.zeros(10, dtype=complex)
    g[1] = p.Fe * p.w**2 * np.exp(1j * p.phi_e)
    y0 = -np.linalg.solve(A, f0) + np.linalg.solve(1j * p.w * np.eye(10) - A, g).real
    assert np.max(np.abs(orbit.state - y0)) < 1e-9


# ------------------------------------------------------------- scipy reference section map
def _scipy_section_map(p: ModelParameters, y0, n: int, rtol=1e-12, atol=1e-14):
    """P^n of the single-DOF equations, written out here; DOP853 restarted at every switch.

    x'' + 2 xi x' + (1 + eps cos w t) f(x, b) (1 + gamma lam) = Fm + Fe w^2 cos(w t + phi_e),
    f the dead zone, lam = +1 on the first half of each mesh period and -1 on the second.
    """
    w, b = p.w, p.b
    T = 2 * math.pi / w

    def region(x):
        return 1 if x > b else (-1 if x < -b else 0)

    def field(t, y, r, lam):
        x, v = y
        f = x - b if r > 0 else (x + b if r < 0 else 0.0)
        F = (1 + p.eps * math.cos(w * t)) * f + 2 * p.xi * v
        return [v, p.Fm + p.Fe * w * w * math.cos(w * t + p.phi_e) - F * (1 + p.friction * lam)]

    y = np.array(y0[:2], dtype=float)
    for k in range(n):
        for half, lam in ((0, 1.0), (1, -1.0)):
            t = k * T + half * T / 2
            t_end = t + T / 2
            r = region(y[0])
            while t < t_end - 1e-13:
                evs = []
                for bnd in ((b, -b) if b > 0 else (0.0,)):
                    def ev(tt, yy, *_, bnd=bnd):
                        return yy[0] - bnd
                    ev.terminal = True
                    evs.append(ev)
                sol = solve_ivp(field, (t, t_end), y, method="DOP853", rtol=rtol, atol=atol,
                                events=evs, args=(r, lam))
                y = sol.y[:, -1].copy()
                t = sol.t[-1]
                if sol.status == 1:  # a switch: step off the boundary into the new region
                    v = y[1]
                    bnd = b if abs(y[0] - b) < abs(y[0] + b) else -b
                    r = (1 if v > 0 else 0) if bnd > 0 else (0 if v > 0 else -1)
                    if b == 0:
                        r = 1 if v > 0 else -1
                    # advance a hair so the event does not fire again at the same point
                    dt = 1e-10
                    y = y + dt * np.array(field(t, y, r, lam))
                    t += dt
    return y


@pytest.mark.parametrize("w,n", [(0.86, 1), (1.02, 2), (1.35, 4)])
def test_monodromy_against_scipy_finite_differences(w, n):
    p = ONE.with_(w=w)
    orbit = find_periodic_orbit(p, n)
    assert orbit.grazing.switches >= n  # impacting orbit
    y = orbit.state
    # the reference map reproduces the fixed point
    assert np.max(np.abs(_scipy_section_map(p, y, n) - y[:2])) < 1e-8
    h = 1e-5
    J = np.zeros((2, 2))
    for j in range(2):
        e = np.zeros(10)
        e[j] = h
        J[:, j] = (_scipy_section_map(p, y + e, n) - _scipy_section_map(p, y - e, n)) / (2 * h)
    err = np.max(np.abs(J - orbit.monodromy)) / max(1.0, np.max(np.abs(J)))
    assert err < 1e-6, (J, orbit.monodromy)


def _dop853_section_map_6dof(params: ModelParameters, y0, n: int, rtol=1e-13, atol=1e-15):
    """P^n of the 6-DOF model by scipy DOP853 (mesh switches x = +/- b located as events and
    restarted, friction flip at T/2); the field values come from gearsim.dynamics.model.rhs with the
    region frozen between events, so this checks the integrator and the variational solution,
    not the field (tests/integration/test_one_source.py checks that)."""
    from gearsim.dynamics.model import MODE_FRICTION, N_MODE, rhs

    p = params.to_array()
    w, b = params.w, params.b
    T = 2 * math.pi / w
    mode = np.ones(N_MODE, dtype=np.int64)
    dy = np.zeros(20)
    yy = np.zeros(20)

    def field(t, y, r, lam):
        mode[:] = 1
        mode[0] = r
        mode[MODE_FRICTION] = lam
        yy[:10] = y
        rhs(t % T, yy, p, mode, dy, False)
        return dy[:10].copy()

    y = np.array(y0[:10], dtype=float)
    for k in range(n):
        for half, lam in ((0, 1), (1, -1)):
            t = k * T + half * T / 2
            t_end = t + T / 2
            r = 1 if y[0] > b else (-1 if y[0] < -b else 0)
            while t < t_end - 1e-13:
                evs = []
                for bnd in (b, -b):
                    def ev(tt, yv, *_, bnd=bnd):
                        return yv[0] - bnd
                    ev.terminal = True
                    evs.append(ev)
                sol = solve_ivp(field, (t, t_end), y, method="DOP853", rtol=rtol, atol=atol,
                                events=evs, args=(r, lam))
                y = sol.y[:, -1].copy()
                t = sol.t[-1]
                if sol.status == 1:
                    bnd = b if abs(y[0] - b) < abs(y[0] + b) else -b
                    r = (1 if y[1] > 0 else 0) if bnd > 0 else (0 if y[1] > 0 else -1)
                    dt = 1e-11
                    y = y + dt * field(t, y, r, lam)
                    t += dt
    return y


def test_monodromy_6dof_against_scipy_dop853_finite_differences():
    """Impacting 6-DOF 1T orbit (w = 0.86): the shooting monodromy against Richardson central
    differences (h = 1e-3, 5e-4; error O(h^4), ~4e-10 here) of the DOP853 map."""
    p = STANDARD.with_(w=0.86)
    orbit = find_periodic_orbit(p, 1)
    assert orbit.grazing.switches >= 1
    y = orbit.state
    assert np.max(np.abs(_dop853_section_map_6dof(p, y, 1) - y)) < 1e-9

    def cd(j, h):
        e = np.zeros(10)
        e[j] = h
        return (_dop853_section_map_6dof(p, y + e, 1)
                - _dop853_section_map_6dof(p, y - e, 1)) / (2 * h)

    J = np.column_stack([(4 * cd(j, 5e-4) - cd(j, 1e-3)) / 3 for j in range(10)])
    assert np.max(np.abs(orbit.monodromy - J)) < 2e-9 * max(1.0, np.max(np.abs(J)))


def test_monodromy_6dof_against_finite_differences_of_the_map():
    p = STANDARD.with_(w=1.02)
    orbit = find_periodic_orbit(p, 2)
    h = 1e-6
    J = np.zeros((10, 10))
    for j in range(10):
        e = np.zeros(10)
        e[j] = h
        J[:, j] = (section_map(p, orbit.state + e, 2, jacobian=False)[0]
                   - section_map(p, orbit.state - e, 2, jacobian=False)[0]) / (2 * h)
    assert np.max(np.abs(J - orbit.monodromy)) < 1e-5 * max(1.0, np.max(np.abs(J)))


# ---------------------------------------------------------------- simulation agreement
def test_newton_reproduces_simulated_section_points_on_30_stable_cells():
    tight = reference_settings(rtol=1e-11, atol=1e-13, transient=400, max_periods=64, n_max=8)
    ws = np.linspace(0.3, 1.33, 30)
    worst = 0.0
    checked = 0
    for w in ws:
        p = ONE.with_(w=float(w))
        res = simulate_cell(p, settings=tight)
        n = res.classification.n
        if n < 1:
            continue
        orbit = find_periodic_orbit(p, n, res.final_state, grazing=False)
        assert orbit.stable
        worst = max(worst, float(np.max(np.abs(orbit.state[:2] - res.final_state[:2]))))
        checked += 1
    assert checked >= 28
    assert worst < 1e-8


# ----------------------------------------------------------------------- details
def test_grazing_margin_is_distance_of_turning_point_to_the_boundary():
    # no contact change: x stays above b; the margin is min x - b from a dense scipy solution
    p = ONE.with_(w=0.6)
    orbit = find_periodic_orbit(p, 1)
    T = 2 * math.pi / p.w
    ts = np.linspace(0, T, 20001)

    def f(t, y):
        x, v = y
        F = (1 + p.eps * math.cos(p.w * t)) * (x - p.b) + 2 * p.xi * v
        lam = 1.0 if (t % T) < T / 2 else -1.0
        return [v, p.Fm + p.Fe * p.w**2 * math.cos(p.w * t + p.phi_e) - F * (1 + p.friction * lam)]

    sol = solve_ivp(f, (0, T), orbit.state[:2], method="DOP853", rtol=1e-12, atol=1e-14,
                    t_eval=ts)
    assert sol.y[0].min() > p.b
    i = int(np.argmin(sol.y[0]))
    # refine the minimum on the dense output by a parabola through the neighbours
    x0, x1, x2 = sol.y[0][i - 1: i + 2]
    xmin = x1 - 0.125 * (x2 - x0) ** 2 / (x2 - 2 * x1 + x0)
    gm = grazing_margin(p, orbit.state, 1)
    assert gm.switches == 0
    assert abs(gm.margins["x=+b"] - (xmin - p.b)) < 1e-9
    assert gm.signed["x=+b"] > 0


def test_multiplier_kinds():
    assert multiplier_kind(complex(1.2, 0)) == "fold"
    assert multiplier_kind(complex(-1.1, 0)) == "period_doubling"
    assert multiplier_kind(complex(0.5, 0.9)) == "neimark_sacker"


def test_bad_input():
    with pytest.raises(ParameterError, match="'n'"):
        find_periodic_orbit(ONE, 0, np.zeros(10))
    with pytest.raises(ParameterError, match="var_ratio"):
        find_periodic_orbit(ONE.with_(var_ratio=0.1), 1, np.zeros(10))


def test_newton_fails_loudly_when_it_cannot_converge():
    with pytest.raises(OrbitError):
        find_periodic_orbit(ONE.with_(w=1.53), 1, np.array([0.5, 0.1] + [0.0] * 8), max_iter=2)


def test_refine_cells_flags_disagreement_with_the_simulation():
    import pandas as pd

    from gearsim.analysis.orbit_cells import refine_cells

    rows = []
    for i, (w, n_claim) in enumerate([(0.86, None), (1.02, None), (1.02, 1)]):
        res = simulate_cell(ONE.with_(w=w))
        n = res.classification.n if n_claim is None else n_claim
        rows.append({"plane": "t", "i": i, "j": 0, "x": w, "y": ONE.b, "n": n, "status": "ok",
                     "label": res.classification.label, "final_state": res.final_state.tolist()})
    out = refine_cells(pd.DataFrame(rows), ONE, "w", "b")
    assert list(out.orbit_flag) == ["", "", "unstable"]  # 1.02 is period 2: its 1T is unstable
    assert out.orbit_converged.all()
    assert (out.orbit_shift.iloc[:2] < 1e-6).all()
    assert out.orbit_kind.iloc[2] == "period_doubling" and out.orbit_mu_max.iloc[2] > 1
    assert (out.orbit_ms > 0).all()


def test_cli_orbit_json_and_bad_input(capsys):
    import json

    from gearsim.cli.main import main

    assert main(["orbit", "--omega", "1.02", "--period", "2", "--set", "model=1dof",
                 "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    ref = find_periodic_orbit(ONE.with_(w=1.02), 2)
    assert d["period"] == 2 and d["stable"] is True
    assert "standard_parameters.yaml" in d["parameters_source"]
    got = np.array([m["re"] + 1j * m["im"] for m in d["multipliers"]])
    assert np.allclose(got, ref.multipliers, atol=1e-9)
    assert all(abs(m["abs"] - abs(m["re"] + 1j * m["im"])) < 1e-12 for m in d["multipliers"])
    assert abs(d["grazing_margin"] - ref.grazing.smallest) < 1e-9
    assert main(["orbit", "--omega", "1.02", "--period", "0", "--set", "model=1dof"]) == 2
    assert "'n'" in capsys.readouterr().err


def test_cli_continue_writes_branches_points_and_figure(tmp_path, capsys):
    import json

    import pandas as pd

    from gearsim.cli.main import main

    out = tmp_path / "c.parquet"
    assert main(["continue", "--name", "w", "--from", "0.95", "--to", "1.05", "--period", "1",
                 "--set", "model=1dof", "--switch-depth", "0", "--out", str(out),
                 "--json"]) == 0
    printed = capsys.readouterr()
    d = json.loads(printed.out)
    # where the tables go is said before the continuation starts (its first progress line)
    first = printed.err.splitlines()[0]
    assert first.endswith(f"continue w: writing {out} (+ its _points table) and "
                          f"{tmp_path / 'c.png'}"), first
    assert [e["event"] for e in d["events"]] == ["period_doubling"]
    assert abs(d["events"][0]["value"] - 0.9994041849) < 1e-8
    assert out.is_file() and (tmp_path / "c.png").is_file()
    assert len(pd.read_parquet(tmp_path / "c_points.parquet")) == 1
    assert main(["continue", "--name", "w", "--from", "1", "--to", "1", "--period", "1"]) == 2


def test_continue_of_a_sweep_starts_from_the_sweeps_parameter_set(capsys):
    """`--of-sweep NAME` (the workflow's standard continuation) resolves the study's sweep set,
    its `fixed` values on top, with the continued parameter at --from; an unknown sweep is one
    line naming the configured ones."""
    import argparse

    from gearsim.cli.commands import continue_orbit
    from gearsim.cli.main import main
    from gearsim.study.config import Study

    p = argparse.ArgumentParser()
    continue_orbit.add_arguments(p)
    study = Study.load((), {"sweeps": {"standard": {"name": "w", "min": 0.5, "max": 1.5,
                                                    "fixed": {"xi": 0.0731, "b": 0.61}}}})
    want = study.parameters(sweep="standard", w=0.8).model
    args = p.parse_args(["--name", "w", "--from", "0.8", "--to", "1.0", "--of-sweep", "standard",
                         "--config-json", '{"sweeps": {"standard": {"name": "w", "min": 0.5, '
                         '"max": 1.5, "fixed": {"xi": 0.0731, "b": 0.61}}}}'])
    got = continue_orbit.resolve(args).params
    assert got == want and got.xi == 0.0731 and got.b == 0.61 and got.w == 0.8
    assert main(["continue", "--name", "w", "--from", "0.8", "--to", "1", "--of-sweep",
                 "nosuch"]) == 2
    err = capsys.readouterr().err
    assert "--of-sweep nosuch" in err and "standard" in err
