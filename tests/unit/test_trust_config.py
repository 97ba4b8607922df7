"""Hostile configuration and flags: bounded work, closed
validation gaps, one line and exit status 2 for every case, nothing written, no computation
started. Library-level checks run in-process; entry points through ``python -m gearsim``."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gearsim.dynamics.parameters import ParameterError, check_value
from gearsim.errors import ConfigError
from gearsim.safe_yaml import MAX_YAML_BYTES, MAX_YAML_NODES, load_yaml
from gearsim.study import config as gcfg
from gearsim.study.point_job import strict_json

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "config/config.yaml"
TINY = ROOT / "config/tiny.yaml"


def _bomb(levels: int = 9) -> str:
    text = 'a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]\n'
    prev = "a"
    for k in "bcdefghijklmnop"[:levels - 1]:
        text += f"{k}: &{k} [" + ",".join([f"*{prev}"] * 9) + "]\n"
        prev = k
    return text


def _run(args, cwd, timeout=60):
    env = dict(os.environ)
    env.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".numba_cache"))
    env["GEARSIM_SCHEDULER_TIMEOUT"] = "5"
    return subprocess.run([sys.executable, "-m", "gearsim", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout)


def _clean_rejection(r, words, forbidden=()):
    err = r.stderr.strip()
    assert r.returncode == 2, (r.returncode, r.stdout[-500:], r.stderr[-2000:])
    assert "Traceback" not in r.stderr, r.stderr[-2000:]
    assert len(err.splitlines()) == 1, err
    for w in words:
        assert w.lower() in err.lower(), (w, err)
    for w in forbidden:
        assert w not in err, (w, err)
    assert r.stdout == "", r.stdout


# ------------------------------------------------------------------------------ YAML reading
YAML_CASES = [
    ("alias-bomb", _bomb().encode(), ["more than", str(MAX_YAML_NODES)]),
    ("recursive-alias", b"a: &a [*a, 1]\n", ["recursive"]),
    ("binary", bytes(range(256)) * 8, ["binary"]),
    ("latin1", "xi: 0.05  # caf\xe9\n".encode("latin-1"), ["utf-8"]),
    ("oversized", b"# " + b"x" * (MAX_YAML_BYTES + 10) + b"\n", ["larger than"]),
    ("syntax", b"planes: [unclosed\n", ["not valid yaml", "line"]),
]


@pytest.mark.parametrize("case", YAML_CASES, ids=[c[0] for c in YAML_CASES])
def test_unsafe_yaml_is_refused_without_expanding(tmp_path, case):
    _, data, words = case
    f = tmp_path / "in.yaml"
    f.write_bytes(data)
    with pytest.raises(ParameterError) as exc:
        load_yaml(f)
    msg = str(exc.value)
    assert "\n" not in msg and "lol" not in msg and len(msg) < 300
    for w in words:
        assert w.lower() in msg.lower(), (w, msg)


def test_yaml_within_limits_is_read(tmp_path):
    f = tmp_path / "ok.yaml"
    f.write_text("base: &b {x: 1}\nuse: [*b, *b]\n")
    assert load_yaml(f) == {"base": {"x": 1}, "use": [{"x": 1}, {"x": 1}]}
    assert load_yaml(CONFIG)["integration"]["method"] == "rk4"


# -------------------------------------------------------------------- configuration values
def _plane(name="wb", **x):
    axis = {"name": "w", "min": 0.1, "max": 2.5, "n": 8}
    axis.update(x)
    return {"planes": {name: {"x": axis, "y": {"name": "b", "min": 0, "max": 1, "n": 8}}}}


CONFIG_CASES = [
    ("nan-audit-fraction", "audit: {fraction: .nan}\n", ["audit.fraction", "finite"]),
    ("nan-audit-threshold", "audit: {threshold: .nan}\n", ["audit.threshold", "finite"]),
    ("inf-parameter", "parameters: {Fm: .inf}\n", ["parameters.Fm"]),
    ("subnormal-parameter", "parameters: {xi: 1.0e-320}\n", ["parameters.xi", "subnormal"]),
    ("huge-steps", "integration: {steps_per_period: 1.0e+12}\n", ["steps_per_period"]),
    ("steps-beyond-limit", {"integration": {"steps_per_period": 10**6}}, ["steps_per_period",
                                                                          "65536"]),
    ("transient-beyond-limit", {"integration": {"transient": 10**7}}, ["transient"]),
    ("plane-1e10-cells", {"planes": {"wb": {"x": {"name": "w", "min": 0.1, "max": 2.5,
                                                  "n": 100000},
                                            "y": {"name": "b", "min": 0, "max": 1,
                                                  "n": 100000}}}},
     ["planes.wb", "4000000"]),
    ("axis-beyond-limit", _plane(n=10**6), ["planes.wb.x.n"]),
    ("sweep-beyond-limit", {"sweeps": {"s": {"name": "w", "min": 0.1, "max": 2, "n": 10**7}}},
     ["sweeps.s.n"]),
    ("name-trailing-newline", {"planes": {"wb\n": _plane()["planes"]["wb"]}}, ["planes"]),
    ("name-300-chars", {"sweeps": {"s" * 300: {"name": "w", "min": 0.1, "max": 2, "n": 4}}},
     ["sweeps"]),
    ("name-with-slash", {"points": {"../x": [0.5]}}, ["points"]),
    ("study-name", {"study": "my study;rm"}, ["study"]),
    ("folder-name", {"folder": "../results"}, ["folder"]),
    ("folder-not-the-study", {"study": "mine", "folder": "other"}, ["folder", "study"]),
    ("point-without-w", {"points": {"p1": {"b": 0.15}}}, ["points.p1.w", "missing"]),
    ("point-bad-value", {"points": {"p1": {"w": [0.5, -1.0]}}}, ["points.p1.w"]),
    ("missing-standard-parameters", {"standard_parameters": "config/standard_paramters.yaml"},
     ["standard_parameters", "standard_paramters.yaml", "null"]),
    ("not-a-mapping", "- 1\n- 2\n", ["mapping", "list"]),
    ("bad-scheduler-type", {"cluster": {"scheduler_address": 5}}, ["scheduler_address"]),
]


def _write(tmp_path, extra) -> Path:
    f = tmp_path / "bad.yaml"
    if isinstance(extra, str):
        f.write_text(extra)
    else:
        f.write_text(json.dumps(extra))
    return f


@pytest.mark.parametrize("case", CONFIG_CASES, ids=[c[0] for c in CONFIG_CASES])
def test_bad_config_is_refused_at_validation(tmp_path, case):
    _, extra, words = case
    with pytest.raises(ConfigError) as exc:
        gcfg.study_config([TINY, _write(tmp_path, extra)], root=ROOT)
    msg = str(exc.value)
    assert "\n" not in msg.strip() and len(msg) < 400, msg
    for w in words:
        assert w.lower() in msg.lower(), (w, msg)


#: the cases also run through a command (by name: a case added to the list moves no index)
CLI_CASES = ("nan-audit-fraction", "nan-audit-threshold", "inf-parameter", "name-trailing-newline",
             "point-without-w", "missing-standard-parameters", "folder-name")


@pytest.mark.parametrize("case", [c for c in CONFIG_CASES if c[0] in CLI_CASES],
                         ids=lambda c: c[0])
def test_bad_config_cli_one_line_nothing_written(tmp_path, case):
    _, extra, words = case
    out = tmp_path / "tile.parquet"
    r = _run(["simulate-tile", "--plane", "wb", "--tile", "0", "--no-cluster", "--configfile",
              str(TINY), str(_write(tmp_path, extra)), "--out", str(out)], cwd=tmp_path)
    _clean_rejection(r, words[:1])
    assert not out.exists() and not (tmp_path / "results").exists()


def test_alias_bomb_as_configfile_and_params(tmp_path):
    """A bomb is refused (the run is bounded by the subprocess timeout, not killed by it), and
    no message prints an expanded value."""
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text(_bomb())
    for args in (["point", "-w", "1", "--params", str(bomb)],
                 ["point", "-w", "1", "--configfile", str(bomb)],
                 ["sweep", "--name", "standard", "--configfile", str(bomb)]):
        r = _run(args, cwd=tmp_path, timeout=30)
        _clean_rejection(r, ["bomb.yaml", "more than"], forbidden=("lol",))


def test_builtin_defaults_only_with_explicit_null(tmp_path):
    cfg = gcfg.study_config([TINY, _write(tmp_path, {"standard_parameters": None})], root=ROOT)
    assert gcfg.Study.of(cfg, ROOT).parameters().source == "builtin-defaults"


def test_subnormal_and_nonfinite_values_refused_everywhere():
    for bad in (1e-320, -5e-324, math.nan, math.inf):
        with pytest.raises(ParameterError):
            check_value("w", bad)
    assert check_value("b", 0.0) == 0.0


# ------------------------------------------------------------------------------ CLI flags
def _cli_cases(tmp_path, write=True):
    binary = tmp_path / "binary.yaml"
    listing = tmp_path / "list.yaml"
    if write:
        binary.write_bytes(bytes(range(256)))
        listing.write_text("- 1\n- 2\n")
        (tmp_path / "adir").mkdir(exist_ok=True)
    tile = ["simulate-tile", "--plane", "wb", "--tile", "0", "--configfile", str(TINY)]
    sweep = ["sweep", "--points", "fig6", "--configfile", str(TINY)]
    return [
        ("set-w-and-omega", ["point", "--set", "w=2", "--omega", "1"], ["--omega", "w"]),
        ("set-twice", ["point", "-w", "1", "--set", "xi=0.1", "--set", "xi=0.2"], ["twice"]),
        ("denormal-omega", ["point", "--omega", "1e-320"], ["subnormal"]),
        ("params-binary", ["point", "-w", "1", "--params", str(binary)], ["binary"]),
        ("params-not-mapping", ["point", "-w", "1", "--params", str(listing)], ["dimensionless"]),
        ("configfile-binary", ["point", "-w", "1", "--configfile", str(binary)], ["binary"]),
        ("configfile-not-mapping", [*tile, "--no-cluster", "--configfile", str(listing)],
         ["mapping"]),
        ("configfile-is-directory", ["point", "-w", "1", "--configfile", str(tmp_path / "adir")],
         ["directory"]),
        ("save-missing-dir", ["point", "-w", "1", "--save", str(tmp_path / "no/p.parquet")],
         ["does not exist"]),
        ("out-onto-directory", ["point", "-w", "1", "--out", str(tmp_path / "adir")],
         ["directory"]),
        ("tile-out-onto-directory", [*tile, "--no-cluster", "--out", str(tmp_path / "adir")],
         ["directory"]),
        ("tile-out-under-a-file", [*tile, "--no-cluster", "--out", str(binary / "t.parquet")],
         ["not a directory"]),
        ("workers-beyond-limit", [*tile, "--workers", "100000"], ["--workers", "256"]),
        ("workers-zero", [*tile, "--workers", "0"], ["--workers"]),
        ("malformed-scheduler", [*tile, "--scheduler", "tcp:/nohost::"], ["malformed"]),
        ("scheduler-garbage", [*tile, "--scheduler", "\x7f" * 3], ["malformed"]),
        ("config-json-not-mapping", [*tile, "--no-cluster", "--config-json", "[1, 2]"],
         ["mapping"]),
        ("ramp-step-zero", [*sweep, "--ramp-step", "0"], ["--ramp-step"]),
        ("samples-zero", [*sweep, "--samples-per-period", "0"], ["--samples-per-period"]),
    ]


CLI_IDS = [c[0] for c in _cli_cases(Path("unused"), write=False)]


@pytest.mark.parametrize("case_id", CLI_IDS)
def test_bad_flags_one_line_exit_2_before_computing(tmp_path, case_id):
    case = {c[0]: c for c in _cli_cases(tmp_path)}[case_id]
    _, args, words = case
    r = _run(args, cwd=tmp_path)
    _clean_rejection(r, words)
    assert not (tmp_path / "results").exists()
    assert not any((tmp_path / "adir").iterdir())


def test_json_is_strict():
    row = strict_json({"a": float("nan"), "b": np.float64(np.inf), "c": np.int64(3),
                       "d": {"e": -np.inf}, "f": "x"})
    assert row == {"a": None, "b": None, "c": 3, "d": {"e": None}, "f": "x"}
    json.dumps(row, allow_nan=False)
