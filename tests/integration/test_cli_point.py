"""`gearsim point`: output, --save, and one-line errors with exit status 2."""

import json
import subprocess
import sys

import pyarrow.parquet as pq
import pytest
import yaml

from gearsim.cell.simulate import IntegrationSettings
from gearsim.cli.main import main
from gearsim.dynamics.parameters import ModelParameters
from gearsim.study.config import Study


def test_point_prints_pattern(capsys):
    assert main(["point", "--omega", "1.05", "--set", "b=1.0", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)
    assert row["label"] == "1/2T" and row["label_npq"] == "2-2-0"
    assert 0 < row["dc"] < 1 and row["lyapunov"] < 0


def test_point_save_writes_series_poincare_and_spectrum(tmp_path, capsys):
    out = tmp_path / "pt.parquet"
    assert main(["point", "-w", "1.05", "--save", str(out)]) == 0
    t = pq.read_table(out).to_pandas()
    assert set(t.kind) == {"time_series", "poincare", "spectrum"}
    spec = t[t.kind == "spectrum"]
    # a 2T motion puts its strongest subharmonic line at w / 2
    sub = spec[(spec.frequency > 0.45 * 1.05) & (spec.frequency < 0.55 * 1.05)].amplitude.max()
    floor = spec[(spec.frequency > 0.3 * 1.05) & (spec.frequency < 0.4 * 1.05)].amplitude.max()
    assert sub > 20 * floor


def test_bad_input_is_one_line_exit_2():
    for args in (["point", "-w", "1", "--set", "xi=-1"], ["point", "-w", "nan"],
                 ["point", "-w", "1", "--set", "bogus=1"], ["point", "-w", "1", "--set", "xi"]):
        r = subprocess.run([sys.executable, "-m", "gearsim", *args], capture_output=True,
                           text=True)
        assert r.returncode == 2, args
        assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr
        assert r.stdout == ""


# ----------------------------------------------------------- the study's defaults
def _strict_json(text):
    def refuse(c):
        raise ValueError(f"not JSON: {c}")

    return json.loads(text, parse_constant=refuse)


def test_point_uses_the_study_and_says_so(tmp_path):
    """From any directory, `gearsim point --omega 0.48` simulates the study's parameters with
    the study's settings (0/1T, as the pipeline) and prints where they came from."""
    r = subprocess.run([sys.executable, "-m", "gearsim", "point", "--omega", "0.48"],
                       capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    first, second = r.stdout.splitlines()[:2]
    assert first.startswith("parameters: config/standard_parameters.yaml; integration: rk4 192")
    assert "pattern=0/1T (1-0-0)" in second


def test_point_json_names_source_and_settings(capsys):
    from gearsim.study.config import DEFAULT_STANDARD_PARAMETERS, project_root
    from gearsim.study.config_io import load_standard_parameters

    assert main(["point", "--omega", "0.48", "--set", "xi=0.07", "--json"]) == 0
    row = _strict_json(capsys.readouterr().out)
    assert row["parameters_source"] == "config/standard_parameters.yaml + --set xi=0.07"
    study = yaml.safe_load((project_root() / "config/config.yaml").read_text())["integration"]
    assert row["settings"] == study
    std = load_standard_parameters(project_root() / DEFAULT_STANDARD_PARAMETERS)
    assert Study.load().parameters(w=0.48).model == ModelParameters.from_mapping({**std, "w": 0.48})
    assert Study.load().settings == IntegrationSettings(**study)


def test_point_configfile_is_merged_over_config_yaml(tmp_path, capsys):
    f = tmp_path / "mine.yaml"
    f.write_text("parameters: {xi: 0.09}\nintegration: {steps_per_period: 128}\n")
    assert main(["point", "--omega", "0.48", "--configfile", str(f), "--json"]) == 0
    row = _strict_json(capsys.readouterr().out)
    assert row["parameters_source"] == "config/standard_parameters.yaml + parameters xi=0.09"
    assert row["settings"]["steps_per_period"] == 128 and row["settings"]["method"] == "rk4"
    assert row["settings"]["transient_continuation"] == 40  # the rest from config.yaml


def test_point_out_records_source_and_settings(tmp_path, capsys):
    out = tmp_path / "p.parquet"
    assert main(["point", "-w", "0.48", "--out", str(out)]) == 0
    meta = pq.read_schema(out).metadata
    assert meta[b"gearsim.parameters_source"] == b"config/standard_parameters.yaml"
    assert json.loads(meta[b"gearsim.settings"])["method"] == "rk4"


def test_gear_file_gives_its_speed_and_torque(capsys):
    """`--gear FILE` alone simulates at the file's speed_rpm and torque_Nm (the same point as
    naming them with --rpm / --torque); an option still overrides the file."""
    from gearsim.physical.units import load_gear

    gear = load_gear("config/gears/example_m3.yaml")
    assert main(["point", "--gear", "config/gears/example_m3.yaml", "--json"]) == 0
    alone = json.loads(capsys.readouterr().out)
    model = gear.to_model_parameters()
    assert alone["w"] == model.w and alone["speed_rpm"] == gear.speed_rpm
    assert alone["torque_Nm"] == gear.torque_Nm
    assert main(["point", "--gear", "config/gears/example_m3.yaml", "--rpm",
                 repr(gear.speed_rpm), "--torque", repr(gear.torque_Nm), "--json"]) == 0
    named = json.loads(capsys.readouterr().out)
    assert {k: named[k] for k in ("w", "label", "kmax", "dc")} == \
        {k: alone[k] for k in ("w", "label", "kmax", "dc")}
    assert main(["point", "--gear", "config/gears/example_m3.yaml", "--rpm",
                 repr(gear.speed_rpm / 2), "--json"]) == 0
    half = json.loads(capsys.readouterr().out)
    assert half["w"] == pytest.approx(model.w / 2, rel=1e-12)
    assert main(["point", "--json"]) == 2  # without a gear file, the frequency is asked for
    assert "give --omega" in capsys.readouterr().err


def test_a_diverged_point_has_no_readings(capsys):
    """w = 1.921, b = 0.02125 (a cell the default run finds diverged): no DC, Kmax or Lyapunov
    exponent is printed or recorded, the status says why."""
    assert main(["point", "--omega", "1.921", "--set", "b=0.02125"]) == 0
    line = capsys.readouterr().out.splitlines()[1]
    assert "pattern=diverged" in line and "status=diverged" in line
    assert "DC=none Kmax=none lyapunov=none" in line
    assert main(["point", "--omega", "1.921", "--set", "b=0.02125", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)
    assert row["kmax"] is None and row["dc"] is None and row["lyapunov"] is None
    assert row["x_max"] is None or row["x_max"] > 1.0  # how far it went stays
