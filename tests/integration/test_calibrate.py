"""Calibration objective, threshold bisection, the standard-parameter file (fast, tiny grids)."""

import json
import math

import numpy as np
import pytest
from sweep_tables import paper_like

import gearsim.calibration.calibrate as cal
import gearsim.calibration.standard as std
import gearsim.calibration.sweeps as thr
from gearsim.analysis.landmarks import find_landmarks
from gearsim.cli.main import main
from gearsim.dynamics.parameters import ModelParameters
from gearsim.physical.geometry import GearGeometry
from gearsim.study.config_io import load_standard_parameters


def test_params_from_vector_maps_free_parameters():
    p = cal.search_params([1.5, 0.2, -30.0, 0.06, 0.01], Fm=0.2, b=2.0)
    assert p.Fe == pytest.approx(0.3) and p.Fm == 0.2 and p.b == 2.0
    assert p.phi_e == pytest.approx(math.radians(-30.0)) and p.model == "1dof"
    assert (p.eps, p.xi, p.friction) == (0.2, 0.06, 0.01)
    free = (cal.FreeParameter("kappa", 1, 100), cal.FreeParameter("rho", 0.1, 1))
    q = cal.search_params([50.0, 0.3], free, model="6dof")
    assert q.kappa_gz == 50.0 and q.rho_g == 0.3 and q.model == "6dof"


def test_score_landmarks_perfect_and_penalised():
    st = cal.ObjectiveSettings()
    J, rms, worst, found, extra, matched = cal.score_landmarks(find_landmarks(paper_like()), st)
    assert found == 12 and extra == 0
    assert rms < 0.011 and worst <= 0.0151 and J == pytest.approx(rms)
    df = paper_like()
    df = df[(df["value"] < 1.35) | (df["value"] >= 1.37)]
    J2, rms2, *_ = cal.score_landmarks(find_landmarks(df), st)
    assert rms2 > rms and J2 > J  # a missing landmark costs miss_penalty


def test_evaluate_tiny_grid_runs_and_reports():
    st = cal.ObjectiveSettings(w_min=0.4, w_max=0.6, dw=0.05, xi_check=False)
    ev = cal.evaluate(ModelParameters(model="1dof"), st)
    assert len(ev.sweep) == 4 and math.isfinite(ev.J)
    s = ev.summary()
    assert set(s["landmarks"]) == {pl.key for pl in cal.PAPER_LANDMARKS}
    json.dumps(s)


def test_backlash_threshold_bisection(monkeypatch):
    calls = []

    def fake(params, grid, settings):
        calls.append(params.b)
        return params.b < 0.3 * params.Fm / 0.1

    monkeypatch.setattr(thr, "double_sided_anywhere", fake)
    b1 = thr.backlash_threshold(ModelParameters(Fm=0.1, Fe=0.17), tol=1e-3)
    assert b1 == pytest.approx(0.3, abs=1e-3)
    # the threshold scales with Fm: Fm = 0.4125 / b*(Fm=1) gives b* = 0.4125
    b_at_1 = thr.backlash_threshold(ModelParameters(Fm=1.0, Fe=1.7), tol=1e-4)
    assert b_at_1 == pytest.approx(3.0, abs=1e-3)


def test_damping_threshold_bisection(monkeypatch):
    monkeypatch.setattr(thr, "has_subharmonics", lambda df: bool(df.attrs["xi"] < 0.1436))
    monkeypatch.setattr(thr, "w_sweep",
                        lambda p, grid, settings=None: _frame(p.xi))
    assert thr.damping_threshold(ModelParameters(), tol=1e-4) == pytest.approx(0.1436, abs=1e-4)


def _frame(xi):
    import pandas as pd

    df = pd.DataFrame({"motion": ["periodic"], "n": [1]})
    df.attrs["xi"] = xi
    return df


def test_differential_evolution_smoke(tmp_path):
    st = cal.ObjectiveSettings(w_min=0.45, w_max=0.55, dw=0.05, xi_check=False)
    free = (cal.FreeParameter("eps", 0.1, 0.3), cal.FreeParameter("xi", 0.05, 0.06))
    rec = cal.calibrate(free=free, st=st, popsize=1, maxiter=1, seed=1, log_dir=str(tmp_path))
    assert rec["nfev"] >= 4 and len(rec["x"]) == 2 and rec["seed"] == 1
    logged = [json.loads(line) for f in tmp_path.glob("evals-*.jsonl") for line in open(f)]
    assert len(logged) == rec["nfev"]
    json.dumps(rec)


def test_standard_file_round_trip_and_table1(tmp_path, capsys):
    p = ModelParameters(Fm=0.2, Fe=0.35)
    g = GearGeometry.from_dimensionless(p)
    doc = std.standard_document(p, g, {"Fe": ("calibrated", "fit")})
    path = tmp_path / "std.yaml"
    std.write_standard_parameters(path, doc)
    values = load_standard_parameters(path)
    assert values["Fe"] == pytest.approx(0.35) and values["model"] == "6dof"
    assert doc["dimensionless"]["Fe"]["provenance"] == "calibrated"
    assert doc["dimensional"]["bearing_stiffness_N_per_m"]["unit"] == "N/m"
    md, csv = tmp_path / "t.md", tmp_path / "t.csv"
    assert main(["table1", "--params", str(path), "--md", str(md), "--csv", str(csv)]) == 0
    text = md.read_text()
    assert "| Fe | 0.35 | - | calibrated | fit |" in text and "mesh_stiffness" in text
    assert csv.read_text().startswith("section,name,value,unit,provenance,note")
    with pytest.raises(ValueError):
        std.standard_document(p, g, {"Fe": ("guessed", "")})


def test_committed_standard_file_is_valid():
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "config/standard_parameters.yaml"
    values = load_standard_parameters(path)
    p = ModelParameters.from_mapping(values)
    assert p.b > 0.4125 and p.var_ratio == 0.0
    import yaml

    doc = yaml.safe_load(path.read_text())
    for sec in ("dimensionless", "dimensional", "derived"):
        for name, e in doc[sec].items():
            assert e["provenance"] in ("paper", "ISO formula", "calibrated", "assumed",
                                       "derived"), name


def test_calibrate_cli_bad_workers():
    assert main(["calibrate", "--stage", "search", "--workers", "0"]) == 2
    np.testing.assert_equal(1, 1)


def test_bisect_bool_finds_a_known_threshold():
    from gearsim.calibration.search import bisect_bool

    calls = []

    def below(x):
        calls.append(x)
        return x < 0.1436

    got = bisect_bool(below, 0.0, 0.3, 0.001)
    assert abs(got - 0.1436) <= 0.0005
    assert len(calls) == 9  # ceil(log2(0.3 / 0.001))


def test_fidelity_and_objective_settings_share_one_grid_and_integration():
    from dataclasses import replace

    from gearsim.calibration.calibrate import ObjectiveSettings
    from gearsim.calibration.fidelity import FidelitySettings
    from gearsim.calibration.sweeps import CALIBRATION_SIM, SweepSettings

    sim = replace(CALIBRATION_SIM, rtol=1e-8)
    f, o = FidelitySettings(dw=0.02, sim=sim), ObjectiveSettings(dw=0.02, sim=sim)
    assert isinstance(f, SweepSettings) and isinstance(o, SweepSettings)
    np.testing.assert_array_equal(f.grid(), o.grid())
    g = f.grid()
    assert g[0] == pytest.approx(0.3 + 0.5 * 2.2 / 110) and len(g) == 110
    assert f.integration() == o.integration() and f.integration().rtol == 1e-8
