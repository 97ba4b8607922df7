"""The calibration package's shared pieces against hand-built references: the vector map, the
bisection by steps, the sweep builder's frequency-scale mapping, a form record's own run."""

from __future__ import annotations

import json
import math
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

from gearsim.calibration.search import FreeParameter, bisect_bool, params_from_vector
from gearsim.cell.simulate import IntegrationSettings, simulate_cell
from gearsim.dynamics.parameters import ModelParameters


def test_params_from_vector_derived_coordinates_on_the_given_base():
    base = ModelParameters(rho_p=0.4, rho_g=0.1, model="6dof")
    free = (FreeParameter("Fe_over_Fm", 1, 3), FreeParameter("phi_e_deg", -90, 0),
            FreeParameter("kappa_ratio", 20, 200), FreeParameter("b_brg", 0, 0.2),
            FreeParameter("xi", 0.04, 0.08))
    p = params_from_vector([2.0, -30.0, 50.0, 0.05, 0.07], free, base, Fm=0.2, b=1.5,
                           model="1dof", xi=0.01)
    assert (p.Fm, p.b, p.model) == (0.2, 1.5, "1dof")
    assert p.Fe == pytest.approx(0.4) and p.phi_e == pytest.approx(-math.pi / 6)
    assert (p.kappa_py, p.kappa_pz) == (pytest.approx(20.0), pytest.approx(20.0))
    assert (p.kappa_gy, p.kappa_gz) == (pytest.approx(5.0), pytest.approx(5.0))
    assert (p.b_py, p.b_pz, p.b_gy, p.b_gz) == (0.05, 0.05, 0.05, 0.05)
    assert p.xi == 0.07  # the search coordinate wins over a fixed value
    # the base decides what the vector does not: another base, other bearing stiffnesses
    q = params_from_vector([2.0, -30.0, 50.0, 0.05, 0.07], free, base.with_(rho_p=0.2), Fm=0.2,
                           b=1.5)
    assert q.kappa_py == pytest.approx(10.0) and q.model == "6dof"


def test_bisect_bool_by_steps_is_the_written_out_loop():
    calls = []

    def sub(x):
        calls.append(x)
        return x < 0.1436

    lo, hi = 0.09, 0.15
    for _ in range(6):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if mid < 0.1436 else (lo, mid)
    assert bisect_bool(sub, 0.09, 0.15, steps=6) == 0.5 * (lo + hi)
    assert len(calls) == 6
    assert bisect_bool(sub, 0.09, 0.15, steps=0) == 0.12
    with pytest.raises(ValueError):
        bisect_bool(sub, 0.0, 1.0)
    with pytest.raises(ValueError):
        bisect_bool(sub, 0.0, 1.0, 0.1, steps=3)


def test_w_sweep_maps_the_axis_onto_the_simulated_frequency():
    """``w_factor`` r: cells simulated at w = r * axis value, each from the previous cell's
    final state (a chain of ``simulate_cell`` written out here); ``value`` is the axis."""
    from gearsim.calibration.sweeps import w_sweep

    st = IntegrationSettings(method="dp5", rtol=1e-7, transient=30, transient_continuation=10,
                             chunk=8, max_periods=16)
    p = ModelParameters(model="1dof")
    grid, r = np.array([0.6, 0.7, 0.8]), 0.93
    df = w_sweep(p, grid, st, w_factor=r)
    np.testing.assert_array_equal(df["value"], grid)
    np.testing.assert_array_equal(df["w_sim"], grid * r)
    u0, k = None, 0
    for i, w in enumerate(grid):
        ref = simulate_cell(p.with_(w=float(w) * r), u0, settings=st, start_period=k)
        np.testing.assert_array_equal(np.asarray(df["final_state"].iloc[i]), ref.final_state)
        assert df["label_npq"].iloc[i] == ref.row()["label_npq"]
        assert df["x_min"].iloc[i] == ref.row()["x_min"]
        u0, k = ref.final_state, ref.final_period


def test_a_form_record_carries_its_own_run_and_the_table_prefers_it(tmp_path):
    from gearsim.calibration.fit_record import Run
    from gearsim.calibration.form_search import collect_forms

    run = Run().record()
    head = subprocess.run(["git", "-C", str(Path(__file__).parent), "rev-parse", "--short",
                           "HEAD"], capture_output=True, text=True)
    if head.returncode == 0:
        assert run["code"].split("+")[0] == head.stdout.strip()
    load = [float(v) for v in run["load"].split()]
    assert len(load) == 3 and load[0] == pytest.approx(os.getloadavg()[0], abs=5.0)
    assert run["wall_s"] >= 0 and run["user_s"] >= 0 and run["end"] >= run["start"]
    # forms-table: a record's own run wins over the log of the process that ran it; a record
    # without one takes the log's
    (tmp_path / "single_dof.json").write_text(json.dumps({"form": "single_dof", "J": 1.0,
                                                          "run": run}))
    (tmp_path / "fixed_start.json").write_text(json.dumps({"form": "fixed_start", "J": 2.0}))
    (tmp_path / "streamA.log").write_text(
        "=== single_dof start 2026-11-30T02:39:00Z load 0.32 1.43 1.80 code f3f7786\n"
        "=== fixed_start start 2026-11-30T03:00:00Z load 1.00 1.00 1.00 code f3f7786\n"
        "10.00 s wall 9.00 s user\n=== fixed_start end 2026-11-30T03:00:10Z rc 0\n")
    forms = collect_forms(["single_dof", "fixed_start"], tmp_path)
    assert forms["records"]["single_dof"]["run"] == run
    assert forms["records"]["fixed_start"]["run"]["wall_s"] == 10.0
    with pytest.raises(KeyError):
        collect_forms(["te_rate"], tmp_path)


_C = np.array([0.7, -1.2, 0.3, 1.5])


def _rosen_batch(calls):
    """An ill-conditioned ellipsoid (axes 1 : 1000) plus 1, minimum 1 at _C."""
    def batch(xs):
        calls.append(len(xs))
        return [1.0 + float(np.sum(np.logspace(0, 3, 4) * (x - _C) ** 2)) for x in xs]
    return batch


def test_cmaes_finds_the_ellipsoid_minimum_and_stops_on_a_flat_curve():
    from gearsim.calibration.search import run_cmaes

    calls: list[int] = []
    bounds = [(-2.0, 2.0)] * 4
    res = run_cmaes(_rosen_batch(calls), bounds, seed=3, x0=[-1.0, 1.5, 0.5, -0.5],
                    max_evals=20000, flat_evals=400, flat_rtol=1e-3)
    # the known minimum: J = 1 at _C (a flat curve at 1e-3 relative: J within ~1e-3 of it)
    assert res["J"] - 1.0 < 2e-3
    np.testing.assert_allclose(res["x"], _C, atol=0.05)
    assert res["stopped_by"] == "flat" and res["nfev"] < 20000
    assert res["nfev"] == sum(calls)
    # the curve: nondecreasing evaluations, nonincreasing best J, its last point the result
    c = np.asarray(res["curve"])
    assert np.all(np.diff(c[:, 0]) > 0) and np.all(np.diff(c[:, 1]) <= 0)
    assert c[-1, 1] == res["J"] and c[-1, 0] == res["nfev"]
    # flat: the last restart did not lower the best J by flat_rtol; over its evaluations too
    then = c[c[:, 0] <= c[-1, 0] - 400][-1, 1]
    assert then - c[-1, 1] <= 1e-3 * then
    # the same seed gives the same search; every point stays in the box
    seen: list[dict] = []
    again = run_cmaes(_rosen_batch([]), bounds, seed=3, x0=[-1.0, 1.5, 0.5, -0.5],
                      max_evals=20000, flat_evals=400, flat_rtol=1e-3,
                      on_generation=lambda info: seen.append(
                          {**info, "curve": list(info["curve"]), "runs": list(info["runs"])}))
    assert again["curve"] == res["curve"]
    # after every generation: the search so far, its last report the result
    assert [g["nfev"] for g in seen] == [n for n, _ in res["curve"]]
    assert all(g["curve"][-1] == [g["nfev"], g["best_J"]] for g in seen)
    assert seen[-1]["x"] == res["x"] and seen[-1]["best_J"] == res["J"]
    assert all(g["cpu_s"] >= 0 and g["t"] >= 0 for g in seen)
    assert len(seen[-1]["runs"]) == len(res["runs"]) - 1  # the last run ends after it


def test_cmaes_evaluates_the_start_in_its_first_population():
    from gearsim.calibration.search import run_cmaes

    batches: list[list[np.ndarray]] = []

    def batch(xs):
        batches.append([np.asarray(x) for x in xs])
        return [float(np.sum((np.asarray(x) - 0.3) ** 2)) for x in xs]

    x0 = [1.5, -0.25, 0.75]
    res = run_cmaes(batch, [(-2.0, 2.0)] * 3, seed=5, x0=x0, sigma0=0.4, max_evals=30)
    first = batches[0]
    assert any(np.array_equal(x, x0) for x in first)
    assert sum(len(b) for b in batches) == res["nfev"] == res["curve"][-1][0]
    assert len(first) == 1 + res["runs"][0]["popsize"]
    # a start on a bound is evaluated on it (cma's bound transform would move it inside)
    batches.clear()
    run_cmaes(batch, [(0.0, 1.0)] * 3, seed=5, x0=[0.0, 0.5, 1.0], max_evals=1)
    assert any(np.array_equal(x, [0.0, 0.5, 1.0]) for x in batches[0])
    # the curve's first point is at most the start's J
    assert res["curve"][0][1] <= float(np.sum((np.asarray(x0) - 0.3) ** 2))


def test_cmaes_restarts_with_a_doubled_population_and_keeps_the_box():
    from gearsim.calibration.search import run_cmaes

    seen = []

    def rastrigin(xs):
        seen.extend(xs)
        return [float(10 * len(x) + np.sum(x**2 - 10 * np.cos(2 * np.pi * x))) for x in xs]

    res = run_cmaes(rastrigin, [(-5.12, 5.12)] * 3, seed=1, x0=[3.0, 3.0, 3.0], sigma0=0.05,
                    max_evals=6000, flat_evals=300, restarts=6)
    pops = [r["popsize"] for r in res["runs"]]
    assert len(pops) >= 2 and all(b == 2 * a for a, b in zip(pops, pops[1:], strict=False))
    x = np.asarray(seen)
    assert x.min() >= -5.12 and x.max() <= 5.12
    assert sum(r["nfev"] for r in res["runs"]) == res["nfev"]
    assert res["J"] <= min(r["best_J"] for r in res["runs"])


class _Interrupt(Exception):
    pass


def test_cmaes_resumed_from_its_checkpoint_is_the_uninterrupted_search(tmp_path):
    """A search cut off mid-run (in its second restart) and resumed from its checkpoint makes
    exactly the evaluations, curve, runs and result of the same seed's uninterrupted search; a
    finished search resumed with a larger budget continues it; another search's checkpoint is
    refused."""
    from gearsim.calibration.search import run_cmaes
    from gearsim.errors import UsageError

    def rastrigin(xs):
        return [float(10 * len(x) + np.sum(x**2 - 10 * np.cos(2 * np.pi * x))) for x in xs]

    kw = dict(seed=4, x0=[3.0, 3.0, 3.0], sigma0=0.05, max_evals=3000, flat_evals=200,
              restarts=5)
    bounds = [(-5.12, 5.12)] * 3
    ref_x: list[np.ndarray] = []
    ref = run_cmaes(lambda xs: (ref_x.extend(xs), rastrigin(xs))[1], bounds, **kw)
    assert len(ref["runs"]) >= 2  # the cut below falls inside a restart
    cut = ref["runs"][0]["nfev"] + ref["runs"][1]["nfev"] // 2
    ck = tmp_path / "search.pkl"
    seen: list[np.ndarray] = []

    def cut_off(xs):
        if len(seen) >= cut:
            raise _Interrupt
        seen.extend(xs)
        return rastrigin(xs)

    with pytest.raises(_Interrupt):
        run_cmaes(cut_off, bounds, checkpoint=ck, **kw)
    assert ck.is_file()
    rest: list[np.ndarray] = []
    res = run_cmaes(lambda xs: (rest.extend(xs), rastrigin(xs))[1], bounds, checkpoint=ck, **kw)
    assert res["resumed"] == 1
    np.testing.assert_array_equal(np.asarray(seen + rest), np.asarray(ref_x))
    assert res["curve"] == ref["curve"] and res["x"] == ref["x"] and res["J"] == ref["J"]
    assert res["runs"] == ref["runs"] and res["stopped_by"] == ref["stopped_by"]
    # a search stopped at its budget continues with a larger one, as one longer search would
    short = dict(kw, max_evals=400)
    ck2 = tmp_path / "short.pkl"
    a = run_cmaes(rastrigin, bounds, checkpoint=ck2, **short)
    assert a["stopped_by"] == "max_evals"
    b = run_cmaes(rastrigin, bounds, checkpoint=ck2, **kw)
    assert b["curve"] == ref["curve"] and b["nfev"] == ref["nfev"]
    # another search's checkpoint: one clear error naming the file
    with pytest.raises(UsageError, match="short.pkl"):
        run_cmaes(rastrigin, bounds, checkpoint=ck2, **dict(kw, seed=5))
