"""Bad input at every user-facing entry point: one line naming what is wrong, exit status 2,
no traceback, nothing written (issue: trust)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _run(args, cwd, timeout=60):
    env = dict(os.environ)
    env.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".numba_cache"))
    env["GEARSIM_SCHEDULER_TIMEOUT"] = env.get("GEARSIM_SCHEDULER_TIMEOUT", "5")
    return subprocess.run([sys.executable, "-m", "gearsim", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout)


def _plane(**x):
    axis = {"name": "w", "min": 0.1, "max": 2.5, "n": 8}
    axis.update(x)
    return {"planes": {"wb": {"x": axis}}}


# (id, extra config as a dict or raw YAML text, CLI arguments after the config, words expected)
CONFIG_CASES = [
    ("unknown-top-key", {"bogus": 1}, [], ["bogus"]),
    ("unknown-axis-key", _plane(extra=1), [], ["extra"]),
    ("wrong-type", {"tile_rows": "eight"}, [], ["tile_rows"]),
    ("nan-bound", "planes:\n  wb:\n    x: {name: w, min: .nan, max: 2.5, n: 8}\n", [], ["min"]),
    ("inf-bound", "planes:\n  wb:\n    x: {name: w, min: 0.1, max: .inf, n: 8}\n", [], ["max"]),
    ("zero-resolution", _plane(n=0), [], ["n"]),
    ("negative-resolution", _plane(n=-5), [], ["n"]),
    ("empty-range", _plane(min=1.0, max=1.0), [], ["planes.wb.x"]),
    ("reversed-range", _plane(min=2.5, max=0.1), [], ["planes.wb.x"]),
    ("unknown-axis-parameter", _plane(name="omega"), [], ["omega"]),
    ("tile-larger-than-grid", {"tile_rows": 100000}, [], ["tile_rows"]),
    ("bad-tolerance", {"integration": {"rtol": -1.0}}, [], ["rtol"]),
    ("unknown-integration-key", {"integration": {"speed": "max"}}, [], ["speed"]),
    ("unknown-parameter-override", {"parameters": {"zeta": 1.0}}, [], ["zeta"]),
    ("parameter-out-of-range", {"parameters": {"xi": -0.1}}, [], ["xi"]),
    ("unknown-plane", {}, ["--plane", "nope"], ["nope"]),
    ("tile-out-of-range", {}, ["--tile", "999"], ["999"]),
    ("corrupt-yaml", "planes: [unclosed\n", [], ["yaml"]),
]


@pytest.mark.parametrize("case", CONFIG_CASES, ids=[c[0] for c in CONFIG_CASES])
def test_bad_config_for_simulate_tile(tmp_path, case):
    _, extra, cli, words = case
    bad = tmp_path / "bad.yaml"
    bad.write_text(extra if isinstance(extra, str) else json.dumps(extra))
    out = tmp_path / "tile.parquet"
    args = ["simulate-tile", "--plane", "wb", "--tile", "0", "--no-cluster",
            "--configfile", str(ROOT / "config/config.yaml"), str(ROOT / "config/tiny.yaml"),
            str(bad), "--out", str(out)]
    # later flags win in argparse, so a case's --plane/--tile replaces the defaults above
    r = _run([*args, *cli], cwd=tmp_path)
    _assert_clean_rejection(r, words)
    assert not out.exists() and not (tmp_path / "results").exists()


def test_missing_config_file(tmp_path):
    r = _run(["simulate-tile", "--plane", "wb", "--tile", "0", "--no-cluster",
              "--configfile", str(tmp_path / "nope.yaml"), "--out", str(tmp_path / "o.parquet")],
             cwd=tmp_path)
    _assert_clean_rejection(r, ["nope.yaml"])


@pytest.mark.timeout(60)  # the connection attempt is bounded, not dask's default retries
def test_unreachable_scheduler_fails_fast(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(json.dumps({"cluster": {"scheduler_address": "tcp://127.0.0.1:9"}}))
    out = tmp_path / "tile.parquet"
    r = _run(["simulate-tile", "--plane", "wb", "--tile", "0", "--configfile",
              str(ROOT / "config/config.yaml"), str(ROOT / "config/tiny.yaml"), str(bad),
              "--out", str(out)], cwd=tmp_path, timeout=50)
    # the tile's header line may precede the error; the error itself is one line, last
    _assert_clean_rejection(r, ["127.0.0.1:9"], last_line_only=True)
    assert not out.exists()


@pytest.fixture()
def catalogue(tmp_path):
    from gearsim.results.catalogue import build_catalogue

    db = tmp_path / "catalogue.sqlite"
    build_catalogue(db)  # an empty catalogue of the current schema (readers refuse others)
    return db


QUERY_CASES = [
    ("delete", "DELETE FROM cells", ["select"]),
    ("drop", "DROP TABLE cells", ["select"]),
    ("two-statements", "SELECT 1; DROP TABLE cells", ["one"]),
    ("insert", "INSERT INTO cells (label) VALUES ('x')", ["select"]),
    ("attach", "ATTACH DATABASE 'x.db' AS x", ["select"]),
    ("pragma-write", "PRAGMA user_version = 3", ["select"]),
    ("syntax", "SELEC * FROM cells", ["select"]),
    ("unknown-table", "SELECT * FROM nope", ["nope"]),
]


@pytest.mark.parametrize("case", QUERY_CASES, ids=[c[0] for c in QUERY_CASES])
def test_query_rejects_anything_that_is_not_one_read(catalogue, case):
    _, sql, words = case
    before = catalogue.read_bytes()
    r = _run(["query", "--db", str(catalogue), sql], cwd=catalogue.parent)
    _assert_clean_rejection(r, words)
    assert catalogue.read_bytes() == before
    assert not (catalogue.parent / "x.db").exists()


def test_query_missing_and_corrupt_catalogue(tmp_path):
    r = _run(["query", "--db", str(tmp_path / "none.sqlite"), "SELECT 1"], cwd=tmp_path)
    _assert_clean_rejection(r, ["none.sqlite"])
    assert not (tmp_path / "none.sqlite").exists()
    bad = tmp_path / "bad.sqlite"
    bad.write_bytes(b"this is not a database" * 100)
    r = _run(["query", "--db", str(bad), "SELECT * FROM cells"], cwd=tmp_path)
    _assert_clean_rejection(r, ["not a database"])


POINT_CASES = [
    ("nan-omega", ["point", "--omega", "nan"], ["w"]),
    ("zero-omega", ["point", "--omega", "0"], ["w"]),
    ("negative-damping", ["point", "-w", "1", "--set", "xi=-1"], ["xi"]),
    ("unknown-parameter", ["point", "-w", "1", "--set", "zeta=1"], ["zeta"]),
    ("not-a-number", ["point", "-w", "1", "--set", "b=wide"], ["b"]),
    ("missing-params-file", ["point", "-w", "1", "--params", "none.yaml"], ["none.yaml"]),
    ("unknown-sweep", ["sweep", "--name", "nosuch", "--configfile",
                       str(ROOT / "config/config.yaml")], ["nosuch"]),
]


@pytest.mark.parametrize("case", POINT_CASES, ids=[c[0] for c in POINT_CASES])
def test_bad_cli_flags(tmp_path, case):
    _, args, words = case
    r = _run([*args, "--save" if args[0] == "point" else "--out", str(tmp_path / "o.parquet")],
             cwd=tmp_path)
    _assert_clean_rejection(r, words)
    assert not (tmp_path / "o.parquet").exists()


def _assert_clean_rejection(r, words, last_line_only=False):
    err = r.stderr.strip()
    assert r.returncode == 2, (r.returncode, r.stdout[-500:], r.stderr[-2000:])
    assert "Traceback" not in r.stderr, r.stderr[-2000:]
    if last_line_only:
        err = err.splitlines()[-1]
        assert "error" in err
    assert len(err.splitlines()) == 1, err
    low = err.lower()
    for w in words:
        assert w.lower() in low, (w, err)
