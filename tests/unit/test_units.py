"""Physical units: gear files, the conversion both ways, physical columns and axes, the CLI."""

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from gearsim.cli.main import main
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.physical import units
from gearsim.physical.geometry import GearGeometry
from gearsim.study.config_io import load_standard_parameters

ROOT = Path(__file__).resolve().parents[2]
STANDARD_GEAR = ROOT / "config/gears/standard.yaml"

# hand-computed standard gear (docs/units.md): ISO q', c' = 0.8 / q', 20 mm face width,
# Km = 1.5 c' b_w; solid steel disks on R_p = 36 mm, R_g = 72 mm, so Me = 0.4 M_p
Q = 0.04723 + 0.15551 / 18 + 0.25791 / 36  # mm um / N
KM = 1.5 * 0.8 / Q * 20.0 * 1e6  # N/(mm um) * mm = N/um -> N/m
MP = 7850.0 * math.pi * 0.036**2 * 0.020  # kg
WN = math.sqrt(KM / (0.4 * MP))  # rad/s
BC = 10e-6  # m


def test_standard_gear_file_reproduces_the_standard_set():
    given = load_standard_parameters(ROOT / "config/standard_parameters.yaml")
    gear = units.load_gear(STANDARD_GEAR)
    assert gear == GearGeometry()  # the dataclass defaults are the standard gear
    p = gear.to_model_parameters()
    for name, value in given.items():
        if name == "model":
            assert p.model == value
            continue
        # standard_parameters.yaml gives 10 significant digits
        assert getattr(p, name) == pytest.approx(value, rel=1e-9, abs=1e-12), name
    assert gear.not_reproduced(ModelParameters.from_mapping(given)) == []


def test_hand_computed_conversions():
    # a 20-tooth pinion at 6000 rpm meshes at 20 * 6000 / 60 = 2000 Hz
    g = GearGeometry(zp=20, zg=40, speed_rpm=6000.0)
    assert g.mesh_frequency_hz == pytest.approx(2000.0, rel=1e-15)
    row = units.physical_columns({"w": g.to_model_parameters().w}, g)
    assert row["mesh_frequency_Hz"] == pytest.approx(2000.0, rel=1e-12)
    assert row["speed_rpm"] == pytest.approx(6000.0, rel=1e-12)
    # the standard gear: w = 2 pi f_h / w_n, Fm = T / (R_p Km b_c), Fe = E / b_c, b = B / b_c
    s = GearGeometry(speed_rpm=6000.0, torque_Nm=16.0, te_amplitude_um=3.0, half_backlash_um=2.5)
    assert s.mesh_stiffness == pytest.approx(KM, rel=1e-12)
    assert s.natural_frequency == pytest.approx(WN, rel=1e-12)
    p = s.to_model_parameters()
    assert p.w == pytest.approx(2 * math.pi * 1800.0 / WN, rel=1e-12)
    assert p.Fm == pytest.approx(16.0 / (0.036 * KM * BC), rel=1e-12)
    assert p.Fe == pytest.approx(0.3, rel=1e-12) and p.b == pytest.approx(0.25, rel=1e-12)
    # physical axes use the same factors
    assert units.to_dimensionless("speed_rpm", 6000.0, s) == ("w", pytest.approx(p.w, rel=1e-12))
    assert units.to_dimensionless("torque_Nm", 16.0, s)[1] == pytest.approx(p.Fm, rel=1e-12)
    assert units.to_dimensionless("half_backlash_um", 2.5, s)[1] == pytest.approx(0.25)
    assert units.to_dimensionless("mesh_frequency_Hz", 1800.0, s)[1] == pytest.approx(p.w)


def test_round_trip_dimensionless_physical_dimensionless():
    base = GearGeometry()
    std = base.to_model_parameters()
    for changes in ({}, {"w": 0.48, "Fm": 0.3, "Fe": 0.5, "b": 0.15, "xi": 0.09},
                    {"w": 2.4, "eps": 0.1, "phi_e": 0.3, "friction": 0.01, "kappa_py": 8.0,
                     "kappa_pz": 8.0, "kappa_gy": 2.0, "kappa_gz": 2.0, "xi_py": 0.05,
                     "xi_pz": 0.05, "b_py": 0.1, "b_pz": 0.1, "b_gy": 0.1, "b_gz": 0.1}):
        target = std.with_(**changes)
        back = GearGeometry.from_dimensionless(target, base).to_model_parameters()
        for name, value in target.to_dict().items():
            if name != "model":
                assert getattr(back, name) == pytest.approx(value, rel=1e-12, abs=1e-15), name
    # columns: a DataFrame of w, Fm, Fe, b -> physical -> dimensionless
    rng = np.random.default_rng(3)
    df = pd.DataFrame({"w": rng.uniform(0.1, 2.5, 50), "Fm": rng.uniform(0, 1, 50),
                       "Fe": rng.uniform(0, 1, 50), "b": rng.uniform(0, 1, 50)})
    phys = units.physical_columns(df, base)
    assert list(phys.columns[:4]) == ["w", "Fm", "Fe", "b"]  # beside the dimensionless ones
    back = units.dimensionless_columns(phys[["speed_rpm", "torque_Nm", "te_amplitude_um",
                                             "half_backlash_um"]], base)
    for name in ("w", "Fm", "Fe", "b"):
        np.testing.assert_allclose(back[name], df[name], rtol=1e-12, atol=0)
    for name in units.PHYSICAL_AXES:
        assert units.to_physical(name, units.to_dimensionless(name, 0.7, base)[1],
                                 base) == pytest.approx(0.7, rel=1e-12)


def test_result_columns_in_physical_units():
    g = GearGeometry()
    f0 = KM * BC
    row = {"w": 0.5, "kmax_peak_mean": 1.8, "kmin_peak_mean": 0.2, "x_min": 0.9, "x_max": 1.7,
           "lyapunov": -0.02, "xi": 0.05, "label": "0/1T"}
    params = g.to_model_parameters().with_(Fm=0.2)
    out = units.physical_columns(row, g, params)
    assert out["label"] == "0/1T" and out["w"] == 0.5  # the row is kept
    assert out["torque_Nm"] == pytest.approx(0.2 * 0.036 * f0, rel=1e-12)
    assert out["mean_mesh_force_N"] == pytest.approx(0.2 * f0, rel=1e-12)
    assert out["peak_mesh_force_N"] == pytest.approx(1.8 * 0.2 * f0, rel=1e-12)
    assert out["min_mesh_force_N"] == pytest.approx(0.2 * 0.2 * f0, rel=1e-12)
    assert out["x_min_um"] == pytest.approx(9.0) and out["x_max_um"] == pytest.approx(17.0)
    assert out["dte_pp_um"] == pytest.approx(8.0)
    assert out["lyapunov_per_s"] == pytest.approx(-0.02 * WN, rel=1e-12)
    assert out["mesh_damping_Ns_per_m"] == pytest.approx(0.1 * math.sqrt(KM * 0.4 * MP))
    assert out["half_backlash_um"] == pytest.approx(10.0)  # b from the fallback set
    assert "te_amplitude_um" not in out  # Fe is not a column of the row
    # a trajectory: tau in 1/w_n, x and mesh force scaled
    tr = pd.DataFrame({"tau": [0.0, WN], "x": [1.0, 2.0], "xdot": [0.1, 0.2],
                       "mesh_force": [0.1, 0.3], "frequency": [0.5, 1.0]})
    t = units.physical_columns(tr, g)
    np.testing.assert_allclose(t["time_s"], [0.0, 1.0], rtol=1e-12)
    np.testing.assert_allclose(t["x_um"], [10.0, 20.0], rtol=1e-12)
    np.testing.assert_allclose(t["xdot_m_per_s"], [0.1 * BC * WN, 0.2 * BC * WN], rtol=1e-12)
    np.testing.assert_allclose(t["mesh_force_N"], [0.1 * f0, 0.3 * f0], rtol=1e-12)
    np.testing.assert_allclose(t["frequency_Hz"], [0.5 * WN / (2 * math.pi),
                                                   WN / (2 * math.pi)], rtol=1e-12)
    assert set(units.COLUMNS) >= set(out) - set(row)


def test_physical_axes_and_fixed_values():
    g = GearGeometry()
    ax = units.dimensionless_axis({"name": "torque_Nm", "min": 8.0, "max": 32.0, "n": 25}, g,
                                  "sweeps.torque")
    k = 1.0 / (0.036 * KM * BC)
    assert ax["name"] == "Fm" and ax["n"] == 25
    assert ax["min"] == pytest.approx(8 * k, rel=1e-12)
    assert ax["max"] == pytest.approx(32 * k, rel=1e-12)
    same = {"name": "xi", "min": 0.04, "max": 0.16, "n": 3}
    assert units.dimensionless_axis(same, None) == same
    fixed = units.dimensionless_mapping({"speed_rpm": 6000, "xi": 0.05,
                                         "half_backlash_um": [1.5, 2.5]}, g)
    assert fixed["xi"] == 0.05 and fixed["b"] == pytest.approx([0.15, 0.25])
    assert fixed["w"] == pytest.approx(2 * math.pi * 1800.0 / WN, rel=1e-12)
    with pytest.raises(ParameterError, match=r"'planes.p.x.name'.*needs a gear file"):
        units.dimensionless_axis({"name": "speed_rpm", "min": 1, "max": 2}, None, "planes.p.x")
    with pytest.raises(ParameterError, match="w is given twice"):
        units.dimensionless_mapping({"speed_rpm": 6000, "w": 0.3}, g)
    with pytest.raises(ParameterError, match="unknown physical axis 'rpm'"):
        units.axis_factor("rpm", g)


def test_gear_file_errors_name_the_key_and_range(tmp_path):
    cases = [
        ("zp: 2.5\n", "'zp'", "[5, 1000]"),
        ("torque_Nm: -3\n", "'torque_Nm'", "[0, 1e+06]"),
        ("speed_rpm: 0\n", "'speed_rpm'", "(0, 1e+06]"),
        ("half_backlash_um: abc\n", "'half_backlash_um'", "[0, 10000]"),
        ("zp: 20\n", "'zg' / 'zp'", "n2 / n1"),
        ("torque: 16\n", "unknown key 'torque'", "torque_Nm"),
    ]
    for i, (text, key, rng) in enumerate(cases):
        path = tmp_path / f"g{i}.yaml"
        path.write_text(text)
        with pytest.raises(ParameterError) as exc:
            units.load_gear(path)
        msg = str(exc.value)
        assert key in msg and rng in msg and str(path) in msg and "\n" not in msg, msg
    (tmp_path / "list.yaml").write_text("- 1\n- 2\n")
    with pytest.raises(ParameterError, match="expected a mapping"):
        units.load_gear(tmp_path / "list.yaml")
    with pytest.raises(ParameterError, match="file not found"):
        units.load_gear(tmp_path / "missing.yaml")


def test_cli_bad_gear_input_exits_2_with_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("module_mm: 4\nface_width_mm: -20\n")
    assert main(["gear", "--gear", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "'face_width_mm'" in err and "(0, 1000]" in err
    assert main(["point", "--gear", str(STANDARD_GEAR), "--rpm", "6000", "--torque", "-1"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--torque" in err and "'torque_Nm'" in err
    assert main(["point", "--rpm", "6000"]) == 2
    assert "need a gear file" in capsys.readouterr().err
    assert main(["point"]) == 2
    assert "--omega" in capsys.readouterr().err


def test_every_committed_gear_file_loads():
    files = sorted((ROOT / "config/gears").glob("*.yaml"))
    assert len(files) >= 2
    for path in files:
        p = units.load_gear(path).to_model_parameters()
        assert 0.0 < p.w <= 2.5 and p.rho_p == pytest.approx(0.4), path.name
    g = units.load_gear(ROOT / "config/gears/example_m3.yaml")
    assert g.mesh_frequency_hz == pytest.approx(24 * 12000 / 60)  # 4800 Hz
    assert g.pitch_radius_p == pytest.approx(0.036)  # 3 mm x 24 / 2
    assert g.te_phase_deg == GearGeometry().te_phase_deg  # left out: the standard gear's


def test_gear_command_prints_the_set_and_the_meaning(tmp_path, capsys):
    assert main(["gear", "--gear", str(STANDARD_GEAR)]) == 0
    out = capsys.readouterr().out
    assert "Fm" in out and "0.1184623614" in out and "speed_rpm" in out
    # the physical meaning of w = 0.48 on the standard gear: 0.48 w_n / (2 pi) 60 / 18 rpm
    assert main(["gear", "--gear", str(STANDARD_GEAR), "--set", "w=0.48", "--yaml"]) == 0
    doc = yaml.safe_load(capsys.readouterr().out)
    assert doc["speed_rpm"] == pytest.approx(0.48 * WN / (2 * math.pi) * 60 / 18, rel=1e-10)
    # the printed gear file reads back as the same gear
    path = tmp_path / "g.yaml"
    doc.pop("description")
    path.write_text(yaml.safe_dump(doc))
    assert units.load_gear(path).to_model_parameters().w == pytest.approx(0.48, rel=1e-10)
    # a set no gear of this geometry gives: said so
    assert main(["gear", "--set", "rho_p=0.2"]) == 0
    assert "not reproduced" in capsys.readouterr().out and "rho_p" in \
        units.describe(GearGeometry(), ModelParameters(rho_p=0.2))


def test_point_with_gear_prints_physical_columns(tmp_path, capsys):
    args = ["point", "--gear", str(STANDARD_GEAR), "--rpm", "6000", "--torque", "16",
            "--method", "rk4"]
    assert main(args + ["--json"]) == 0
    row = json.loads(capsys.readouterr().out)
    g = replace(GearGeometry(), speed_rpm=6000.0, torque_Nm=16.0)
    assert row["speed_rpm"] == pytest.approx(6000.0, rel=1e-12)
    assert row["mesh_frequency_Hz"] == pytest.approx(1800.0, rel=1e-12)
    assert row["torque_Nm"] == pytest.approx(16.0, rel=1e-12)
    assert row["w"] == pytest.approx(g.to_model_parameters().w, rel=1e-12)
    fm = 16.0 / (0.036 * KM * BC)
    assert row["peak_mesh_force_N"] == pytest.approx(row["kmax_peak_mean"] * fm * KM * BC)
    assert row["dte_pp_um"] == pytest.approx((row["x_max"] - row["x_min"]) * 10.0)
    # independent check: the peak force is the largest mesh force of the saved trajectory
    save = tmp_path / "p.parquet"
    assert main(args + ["--save", str(save)]) == 0
    out = capsys.readouterr().out
    assert "physical (" in out and "speed=6000.0 rpm" in out and "torque=16 N m" in out
    ts = pd.read_parquet(save).query("kind == 'time_series'")
    t = units.physical_columns(ts, g)
    assert t["mesh_force_N"].max() == pytest.approx(row["peak_mesh_force_N"], rel=2e-3)
    assert t["x_um"].max() - t["x_um"].min() == pytest.approx(row["dte_pp_um"], rel=2e-3)
    # RMS about the mean: between 0 and half the peak-to-peak value (a non-constant motion)
    rms = units.dte_rms_um(pd.read_parquet(save), g)
    assert 0.0 < rms < 0.5 * row["dte_pp_um"]


def test_dte_rms_of_a_sine_is_amplitude_over_root_two():
    g = GearGeometry()  # b_c = 10 um
    tau = np.linspace(0.0, 3 * 2 * np.pi / 0.7, 3 * 128 + 1)  # three periods, both endpoints
    x = 1.0 + 0.5 * np.sin(0.7 * tau) + 0.2 * np.cos(2.1 * tau)
    expected = 10.0 * math.sqrt(0.5**2 / 2 + 0.2**2 / 2)
    frame = pd.DataFrame({"kind": "time_series", "tau": tau, "x": x})
    assert units.dte_rms_um(frame, g) == pytest.approx(expected, rel=1e-12)
    assert units.dte_rms_um(x[:-1], g) == pytest.approx(expected, rel=1e-12)


def test_pipeline_config_in_physical_units_converts_in_place():
    config = {
        "gear": "config/gears/standard.yaml",
        "parameters": {"half_backlash_um": 2.5},
        "planes": {"tw": {"x": {"name": "speed_rpm", "min": 2000, "max": 40000, "n": 30},
                          "y": {"name": "torque_Nm", "min": 5, "max": 30, "n": 30},
                          "fixed": {"xi": 0.05}}},
        "sweeps": {"torque": {"name": "torque_Nm", "min": 4.0, "max": 40.0, "n": 91,
                              "direction": "forward", "fixed": {"speed_rpm": 6000}}},
        "points": {"mine": {"speed_rpm": [6000, 12000], "b": 0.5}, "fig5": [0.48]},
    }
    out = units.dimensionless_config(config, root=ROOT)
    assert out is config
    k_t, k_rpm = 1.0 / (0.036 * KM * BC), 2 * math.pi * 18 / 60 / WN
    x, y = config["planes"]["tw"]["x"], config["planes"]["tw"]["y"]
    assert x["name"] == "w" and x["min"] == pytest.approx(2000 * k_rpm, rel=1e-12)
    assert x["physical"] == {"name": "speed_rpm", "unit": "rpm", "min": 2000, "max": 40000}
    assert y["name"] == "Fm" and y["max"] == pytest.approx(30 * k_t, rel=1e-12)
    assert config["planes"]["tw"]["fixed"] == {"xi": 0.05}
    sw = config["sweeps"]["torque"]
    assert sw["name"] == "Fm" and sw["n"] == 91 and sw["direction"] == "forward"
    assert sw["min"] == pytest.approx(4 * k_t, rel=1e-12)
    assert sw["fixed"]["w"] == pytest.approx(6000 * k_rpm, rel=1e-12)
    assert config["parameters"] == {"b": pytest.approx(0.25)}
    assert config["points"]["mine"]["w"] == pytest.approx([6000 * k_rpm, 12000 * k_rpm])
    assert config["points"]["fig5"] == [0.48]
    label, vals = units.axis_label_values(y, np.array([y["min"], y["max"]]))
    assert label == "torque_Nm [N m]"
    np.testing.assert_allclose(vals, [5.0, 30.0], rtol=1e-12)
    assert units.axis_label_values({"name": "xi", "min": 0, "max": 1}, [0.5]) == ("xi", [0.5])
    before = json.dumps(config, sort_keys=True)
    units.dimensionless_config(config, root=ROOT)  # idempotent
    assert json.dumps(config, sort_keys=True) == before
    with pytest.raises(ParameterError, match="config key 'sweeps.s.name'.*needs a gear file"):
        units.dimensionless_config({"sweeps": {"s": {"name": "torque_Nm", "min": 1, "max": 2,
                                                     "n": 3}}})
    with pytest.raises(ParameterError, match=r"config key 'gear'.*nope\.yaml") as exc:
        units.dimensionless_config({"gear": "nope.yaml"}, root=ROOT)
    assert "file not found" in str(exc.value)


def test_torque_sweep_study_example_loads_in_dimensionless_units(tmp_path, capsys):
    """config/torque_sweep.yaml (the README's example) through the pipeline's config loader."""
    from gearsim.study.config import ConfigError, Study, study_config

    config = study_config([ROOT / "config/torque_sweep.yaml"], root=ROOT)
    assert config["study"] == "torque" and list(config["sweeps"]) == ["torque"]
    assert config["planes"] == {}
    sw = config["sweeps"]["torque"]
    k_t, k_rpm = 1.0 / (0.036 * KM * BC), 2 * math.pi * 18 / 60 / WN
    assert sw["name"] == "Fm" and sw["physical"]["name"] == "torque_Nm"
    assert (sw["min"], sw["max"]) == (pytest.approx(2 * k_t, rel=1e-12),
                                      pytest.approx(40 * k_t, rel=1e-12))
    assert sw["fixed"] == {"w": pytest.approx(12000 * k_rpm, rel=1e-12)}
    p = Study.of(config, ROOT).parameters()
    assert p.source == "gear file config/gears/standard.yaml"
    assert p.model.to_dict() == GearGeometry().to_model_parameters().to_dict()
    # physical units without a gear file, or a bad gear file: one line naming the key
    bad = tmp_path / "bad.yaml"
    bad.write_text("study: mine\nsweeps:\n  t: {name: torque_Nm, min: 1, max: 2, n: 3}\n")
    with pytest.raises(ConfigError, match=r"'sweeps.t.name'.*needs a gear file"):
        study_config([bad], root=ROOT)
    bad.write_text(f"study: mine\ngear: {tmp_path / 'g.yaml'}\n")
    (tmp_path / "g.yaml").write_text("zp: 17\n")
    with pytest.raises(ConfigError, match=r"config key 'gear'.*'zg' / 'zp'"):
        study_config([bad], root=ROOT)
    # a sweep's frame: 'value' is the swept parameter; the rest from the sweep's base set
    frame = pd.DataFrame({"parameter": ["Fm", "Fm"], "value": [2 * k_t, 40 * k_t],
                          "kmax_peak_mean": [2.0, 1.1]})
    base = Study.of(config, ROOT).parameters(sweep="torque").model
    phys = units.physical_columns(frame, GearGeometry(), base)
    np.testing.assert_allclose(phys["torque_Nm"], [2.0, 40.0], rtol=1e-12)
    np.testing.assert_allclose(phys["speed_rpm"], [12000.0, 12000.0], rtol=1e-12)
    np.testing.assert_allclose(phys["peak_mesh_force_N"], [2.0 * 2 / 0.036, 1.1 * 40 / 0.036],
                               rtol=1e-12)
