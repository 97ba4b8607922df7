"""Catalogue integrity: short, empty, duplicated, damaged or foreign tiles and plane
files are refused with one line and exit 2, nothing written; readers refuse any file that is not
a catalogue of our schema; results/catalogue.sqlite stays valid through rebuilds that succeed,
fail or are killed, with queries running throughout."""

from __future__ import annotations

import copy
import json
import os
import shutil
import signal
import sqlite3
import subprocess
import sys
import threading
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest
import yaml
from synthetic_tiles import tile_frame, write_tile

from gearsim.results import catalogue as gc
from gearsim.study import config as gcfg
from gearsim.study import grid as ggrid
from gearsim.study.provenance import plane_record

ROOT = Path(__file__).resolve().parents[2]


class _Result:
    def __init__(self, returncode, stderr, seconds):
        self.returncode, self.stderr, self.seconds = returncode, stderr, seconds


@pytest.fixture()
def gearsim(capsys, monkeypatch):
    """Run the CLI in-process (interpreter start-up excluded from the time) from ``cwd``."""
    from gearsim.cli.main import main

    def run(args, cwd):
        monkeypatch.chdir(cwd)
        capsys.readouterr()
        t0 = time.monotonic()
        code = main([str(a) for a in args])
        return _Result(code, capsys.readouterr().err, time.monotonic() - t0)

    return run


def _refused(r, words):
    assert r.returncode == 2, (r.returncode, r.stderr[-2000:])
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr
    for w in words:
        assert w in r.stderr, (w, r.stderr)


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """A 4 x 6 wb plane in 3 tiles of 2 rows and a 3 x 2 wxi plane in one tile, as files."""
    d = tmp_path_factory.mktemp("integrity")
    over = {
        "tile_rows": 2,
        "planes": {
            "wb": {"x": {"name": "w", "min": 0.1, "max": 2.5, "n": 4},
                   "y": {"name": "b", "min": 0.0, "max": 1.0, "n": 6}, "fixed": {}},
            "wxi": {"x": {"name": "w", "min": 0.1, "max": 2.5, "n": 3},
                    "y": {"name": "xi", "min": 0.04, "max": 0.16, "n": 2}, "fixed": {}},
        },
    }
    cfg_file = d / "study.yaml"
    cfg_file.write_text(yaml.safe_dump(over))
    config_yaml = ROOT / "config/config.yaml"
    cfg = gcfg.load_config([config_yaml, ROOT / "config/tiny.yaml", cfg_file], root=ROOT)
    tiles = {p: [write_tile(cfg, p, t, d / p / f"{t}.parquet") for t in ggrid.tile_ids(cfg, p)]
             for p in ("wb", "wxi")}
    study = gcfg.Study.of(cfg)
    cells = {p: gc.combine_tiles(tiles[p], d / p / "cells.parquet", plane_record(study, p))
             for p in ("wb", "wxi")}
    conf = ["--configfile", config_yaml, ROOT / "config/tiny.yaml", cfg_file]
    return {"dir": d, "cfg": cfg, "tiles": tiles, "cells": cells, "conf": conf}


# ----------------------------------------------------------------------------- tile cases
def _foreign_config(study, d):
    cfg = copy.deepcopy(study["cfg"])
    cfg["parameters"] = {**cfg["parameters"], "xi": 0.15}
    return [write_tile(cfg, "wb", 1, d / "1.parquet"), *study["tiles"]["wb"][::2]]


def _write_frame(study, d, df, tile=1, **prov):
    return [write_tile(study["cfg"], "wb", tile, d / f"{tile}.parquet", df=df, **prov),
            *study["tiles"]["wb"][::2]]


def _dropped_rows_recorded(study, d):
    """A tile whose file lost rows after it was written (provenance says 8 cells)."""
    src = study["tiles"]["wb"][1]
    t = pq.read_table(src)
    pq.write_table(t.slice(0, 5).replace_schema_metadata(t.schema.metadata), d / "1.parquet")
    return [d / "1.parquet", *study["tiles"]["wb"][::2]]


def _random_middle(data: bytes) -> bytes:
    """Random bytes over the data pages; the header and the footer (schema, row counts,
    provenance) stay valid, so only reading the pages finds the damage."""
    n = len(data)
    return data[:8] + os.urandom(n // 2 - 8) + data[n // 2:]


def _bytes(study, d, data: bytes):
    (d / "1.parquet").write_bytes(data)
    return [d / "1.parquet", *study["tiles"]["wb"][::2]]


TILE_CASES = [
    ("foreign-config", _foreign_config, ["configuration hash", "1.parquet"]),
    ("other-code", lambda s, d: _write_frame(s, d, None, code_version="0123456789abcdef"),
     ["code version", "0123456789abcdef"]),
    ("truncated-rows", _dropped_rows_recorded, ["5 cells stored but 8 recorded"]),
    ("rows-dropped-honestly",
     lambda s, d: _write_frame(s, d, tile_frame(s["cfg"], "wb", 1).iloc[:5]),
     ["3 of 24 cells", "missing", "(1, 3)"]),
    ("empty-tile", lambda s, d: _write_frame(s, d, tile_frame(s["cfg"], "wb", 1).iloc[:0]),
     ["empty (0 cells)"]),
    ("zero-bytes", lambda s, d: _bytes(s, d, b""), ["empty file"]),
    ("cut-file", lambda s, d: _bytes(s, d, s["tiles"]["wb"][1].read_bytes()[:2000]),
     ["not a readable Parquet file"]),
    ("garbage", lambda s, d: _bytes(s, d, b"not parquet at all" * 50),
     ["not a readable Parquet file"]),
    ("random-bytes", lambda s, d: _bytes(s, d, os.urandom(len(s["tiles"]["wb"][1].read_bytes()))),
     ["not a readable Parquet file"]),
    ("random-pages", lambda s, d: _bytes(s, d, _random_middle(s["tiles"]["wb"][1].read_bytes())),
     ["not a readable Parquet file"]),
    ("duplicated-tile", lambda s, d: [*s["tiles"]["wb"], s["tiles"]["wb"][1]],
     ["duplicated tile", "(0, 2)"]),
    ("copy-under-another-number",
     lambda s, d: [s["tiles"]["wb"][0], shutil.copy(s["tiles"]["wb"][0], d / "1.parquet"),
                   s["tiles"]["wb"][2]], ["also in", "duplicated tile"]),
    ("missing-tile", lambda s, d: s["tiles"]["wb"][:2], ["8 of 24 cells", "missing"]),
    ("other-plane", lambda s, d: [*s["tiles"]["wb"][:2], s["tiles"]["wxi"][0]],
     ["belongs to plane 'wxi'"]),
    ("off-grid", lambda s, d: _write_frame(
        s, d, tile_frame(s["cfg"], "wb", 1).assign(x=lambda f: f["x"] * 1.01)),
     ["another grid"]),
    ("no-provenance", lambda s, d: [pq.write_table(
        pq.read_table(s["tiles"]["wb"][1]).replace_schema_metadata(None), d / "1.parquet")
        or d / "1.parquet", *s["tiles"]["wb"][::2]], ["no gearsim provenance"]),
]


@pytest.mark.parametrize("case", TILE_CASES, ids=[c[0] for c in TILE_CASES])
def test_bad_tile_is_refused(study, tmp_path, gearsim, case):
    _, make, words = case
    tiles = make(study, tmp_path)
    out = tmp_path / "out" / "cells.parquet"
    r = gearsim(["catalogue", "cells", "--plane", "wb", "--tiles", *tiles, *study["conf"],
                  "--out", out], cwd=ROOT)  # the config names config/standard_parameters.yaml
    _refused(r, ["gearsim catalogue: error:", *words])
    assert not out.exists()
    assert not list((tmp_path / "out").glob(".*")) if (tmp_path / "out").exists() else True


def test_good_tiles_combine_in_order(study):
    df = pq.read_table(study["cells"]["wb"]).to_pandas()
    assert len(df) == 24 and list(zip(df["j"], df["i"], strict=True)) == sorted(
        zip(df["j"], df["i"], strict=True))
    assert df["p"].dtype == "Int64"
    assert [p["tile"] for p in gc.read_metadata(study["cells"]["wb"], gc.TILES_KEY)] == [0, 1, 2]


def test_tiles_in_any_order_give_the_same_plane(study, tmp_path):
    out = gc.combine_tiles(study["tiles"]["wb"][::-1], tmp_path / "c.parquet",
                           plane_record(gcfg.Study.of(study["cfg"]), "wb"))
    a = pq.read_table(out).to_pandas()
    b = pq.read_table(study["cells"]["wb"]).to_pandas()
    assert a.drop(columns=["poincare_x", "poincare_v", "final_state"]).equals(
        b.drop(columns=["poincare_x", "poincare_v", "final_state"]))


# ----------------------------------------------------------------------- plane-file cases
def _cells_without_rows(study, d):
    t = pq.read_table(study["cells"]["wb"])
    pq.write_table(t.slice(0, 20).replace_schema_metadata(t.schema.metadata), d / "c.parquet")
    return [d / "c.parquet"]


def _cells_foreign_tile(study, d):
    t = pq.read_table(study["cells"]["wb"])
    meta = dict(t.schema.metadata)
    tiles = json.loads(meta[gc.TILES_KEY])
    tiles[1]["config_hash"] = "ffffffffffffffff"
    meta[gc.TILES_KEY] = json.dumps(tiles).encode()
    pq.write_table(t.replace_schema_metadata(meta), d / "c.parquet")
    return [d / "c.parquet"]


BUILD_CASES = [
    ("rows-removed", _cells_without_rows, ["20 cells stored but its tiles recorded 24"]),
    ("foreign-tile-record", _cells_foreign_tile, ["configuration hash ffffffffffffffff"]),
    ("a-tile-not-a-plane", lambda s, d: [s["tiles"]["wb"][0]], ["no plane record"]),
    ("same-plane-twice", lambda s, d: [s["cells"]["wb"], shutil.copy(s["cells"]["wb"], d)],
     ["given twice"]),
    ("garbage", lambda s, d: [(d / "c.parquet").write_bytes(b"x" * 999) and d / "c.parquet"],
     ["not a readable Parquet file"]),
]


@pytest.mark.parametrize("case", BUILD_CASES, ids=[c[0] for c in BUILD_CASES])
def test_bad_plane_file_is_refused(study, tmp_path, gearsim, case):
    _, make, words = case
    files = make(study, tmp_path)
    out, pub = tmp_path / "build.sqlite", tmp_path / "catalogue.sqlite"
    pub.write_bytes(b"previous")
    r = gearsim(["catalogue", "build", "--cells", *files, "--out", out, "--publish", pub],
                 cwd=tmp_path)
    _refused(r, ["gearsim catalogue: error:", *words])
    assert not out.exists() and pub.read_bytes() == b"previous"
    assert not [p for p in tmp_path.iterdir() if ".tmp-" in p.name]


def test_good_build_has_every_cell_once(study, tmp_path, gearsim):
    out = tmp_path / "build.sqlite"
    r = gearsim(["catalogue", "build", "--cells", study["cells"]["wb"], study["cells"]["wxi"],
                  "--out", out, "--publish", tmp_path / "catalogue.sqlite"], cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    con = gc.open_catalogue(tmp_path / "catalogue.sqlite")
    rows = con.execute("SELECT p.name, COUNT(*), COUNT(DISTINCT c.i || ',' || c.j), "
                       "SUM(c.label = '2/1T') FROM cells c JOIN planes p ON p.id = c.plane_id "
                       "GROUP BY p.name ORDER BY p.name").fetchall()
    assert rows == [("wb", 24, 24, 12), ("wxi", 6, 6, 3)]
    # the published file is the built one (hard link), not a second copy
    assert os.path.samefile(out, tmp_path / "catalogue.sqlite")


# ---------------------------------------------------------------------------- readers
def _other_sqlite(path: Path) -> Path:
    con = sqlite3.connect(path)
    con.execute("CREATE TABLE cells (id INTEGER PRIMARY KEY, label TEXT)")
    con.commit()
    con.close()
    return path


def _old_version(path: Path) -> Path:
    gc.build_catalogue(path)
    con = sqlite3.connect(path)
    con.execute("PRAGMA user_version = 1")
    con.commit()
    con.close()
    return path


def _dropped_table(path: Path) -> Path:
    gc.build_catalogue(path)
    con = sqlite3.connect(path)
    con.execute("DROP TABLE column_dictionary")
    con.commit()
    con.close()
    return path


READER_FILES = [
    ("missing", lambda p: p, ["catalogue not found"]),
    ("empty-file", lambda p: p.write_bytes(b"") and p or p, ["not a gearsim catalogue"]),
    ("garbage", lambda p: p.write_bytes(b"not a database" * 300) and p,
     ["not a database"]),
    ("other-sqlite", _other_sqlite, ["not a gearsim catalogue", "application_id"]),
    ("old-schema", _old_version, ["schema version 1", "reads version 4", "rebuild"]),
    ("damaged", _dropped_table, ["lacks table 'column_dictionary'"]),
]


@pytest.mark.parametrize("case", READER_FILES, ids=[c[0] for c in READER_FILES])
@pytest.mark.parametrize("command", ["query", "export"])
def test_readers_refuse_what_is_not_a_catalogue(tmp_path, gearsim, case, command):
    _, make, words = case
    db = make(tmp_path / "catalogue.sqlite")
    before = db.read_bytes() if db.exists() else None
    if command == "query":
        args = ["query", "--catalogue", db, "SELECT COUNT(*) FROM cells"]
    else:
        args = ["export", "--catalogue", db, "--plane", "wb", "--format", "csv", "--out",
                tmp_path / "wb.csv"]
    r = gearsim(args, cwd=tmp_path)
    _refused(r, [f"gearsim {command}: error:", *words])
    assert (db.read_bytes() if db.exists() else None) == before
    assert not (tmp_path / "wb.csv").exists()


# -------------------------------------------------------- the last good catalogue survives
class Reader(threading.Thread):
    """Queries ``db`` as fast as it can; records every answer and every failure."""

    def __init__(self, db: Path):
        super().__init__(daemon=True)
        self.db, self.stop, self.counts, self.errors = db, threading.Event(), [], []

    def run(self):
        from gearsim.results.query import execute

        while not self.stop.is_set():
            try:
                _, rows = execute(self.db, "SELECT COUNT(*) FROM cells")
                self.counts.append(rows[0][0])
            except Exception as exc:  # noqa: BLE001 - any failure is what the test counts
                self.errors.append(repr(exc))


def _build_cmd(files, out, pub):
    return [sys.executable, "-m", "gearsim", "catalogue", "build", "--cells", *map(str, files),
            "--out", str(out), "--publish", str(pub)]


def test_catalogue_stays_valid_through_rebuilds(study, tmp_path):
    """Snakemake's sequence (declared output deleted, job run) for a good rebuild, one that fails
    mid-build on a damaged plane file, and one killed mid-build; queries run throughout."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    build, pub = tmp_path / "catalogue.d/build.sqlite", tmp_path / "catalogue.sqlite"
    gc.build_catalogue(build, [study["cells"]["wb"]], publish_to=pub)
    reader = Reader(pub)
    reader.start()
    try:
        # 1. a rebuild that fails after the first plane went in: wxi's file is damaged
        bad = tmp_path / "wxi.parquet"
        bad.write_bytes(study["cells"]["wxi"].read_bytes()[:-200])
        build.unlink()
        r = subprocess.run(_build_cmd([study["cells"]["wb"], bad], build, pub), env=env,
                           capture_output=True, text=True, timeout=60)
        assert r.returncode == 2 and "wxi.parquet" in r.stderr, r.stderr
        assert not build.exists()
        # 2. a rebuild killed mid-build (SIGKILL as soon as its temporary file exists)
        big_cfg = copy.deepcopy(study["cfg"])
        big_cfg["planes"]["wb"]["x"]["n"] = 300
        big_cfg["planes"]["wb"]["y"]["n"] = 200
        big_cfg["tile_rows"] = 100
        big_tiles = [write_tile(big_cfg, "wb", t, tmp_path / f"big/{t}.parquet") for t in (0, 1)]
        big = gc.combine_tiles(big_tiles, tmp_path / "big/cells.parquet",
                               plane_record(gcfg.Study.of(big_cfg), "wb"))
        proc = subprocess.Popen(_build_cmd([big], build, pub), env=env,
                                stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 60
        while not list(build.parent.glob(".build.sqlite.tmp-*")) and proc.poll() is None:
            assert time.monotonic() < deadline
            time.sleep(0.005)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        assert proc.returncode == -signal.SIGKILL
        assert not build.exists()
        time.sleep(0.3)
        # 3. a good rebuild with both planes: readers switch from 24 to 30 cells
        r = subprocess.run(_build_cmd([study["cells"]["wb"], study["cells"]["wxi"]], build, pub),
                           env=env, capture_output=True, text=True, timeout=60)
        assert r.returncode == 0, r.stderr
        time.sleep(0.3)
    finally:
        reader.stop.set()
        reader.join(10)
    assert reader.errors == []
    assert set(reader.counts) == {24, 30}
    first_new = reader.counts.index(30)
    assert set(reader.counts[:first_new]) == {24} and set(reader.counts[first_new:]) == {30}
    assert len(reader.counts) > 20
    # the killed build's temporary file was removed by the next build
    assert [p.name for p in build.parent.iterdir()] == ["build.sqlite"]


def test_unwritable_output_is_one_line(study, tmp_path, gearsim):
    """The output's directory is a file (as on a full or broken disk, the write fails)."""
    (tmp_path / "blocker").write_text("a file where a directory should be")
    pub = tmp_path / "catalogue.sqlite"
    pub.write_bytes(b"previous")
    r = gearsim(["catalogue", "build", "--cells", study["cells"]["wb"], "--out",
                 tmp_path / "blocker/build.sqlite", "--publish", pub], cwd=tmp_path)
    _refused(r, ["blocker"])
    assert pub.read_bytes() == b"previous"


@pytest.mark.slow
def test_snakemake_rebuilds_keep_the_catalogue_readable(tiny_run, tmp_path):
    """The real workflow: a forced rebuild that succeeds and one that fails mid-build (a sweep
    file damaged after the planes went in), queries on results/catalogue.sqlite throughout."""
    from workflow_helpers import smk

    wd = tmp_path / "wd"
    shutil.copytree(tiny_run[0], wd, symlinks=True,
                    ignore=shutil.ignore_patterns(".snakemake"))
    pub = wd / "results/catalogue.sqlite"
    target = "results/catalogue.d/build.sqlite"
    n_cells = gc.open_catalogue(pub).execute("SELECT COUNT(*) FROM cells").fetchone()[0]
    reader = Reader(pub)
    reader.start()
    try:
        smk(wd, target, "--cores", "1", "--configfile", "config/tiny.yaml",
            "--forcerun", "catalogue")
        assert (wd / target).exists() and os.path.samefile(wd / target, pub)
        sweep = wd / "results/sweeps/b015.parquet"
        good = sweep.read_bytes()
        sweep.write_bytes(good[: len(good) // 2])
        r = smk(wd, target, "--cores", "1", "--configfile", "config/tiny.yaml", check=False)
        assert r.returncode != 0
        log = (wd / "logs/catalogue.log").read_text()
        assert "b015.parquet: not a readable Parquet file" in log, log
        assert not (wd / target).exists()
        time.sleep(0.3)
    finally:
        reader.stop.set()
        reader.join(10)
    assert reader.errors == []
    assert set(reader.counts) == {n_cells} and len(reader.counts) > 20
    assert gc.open_catalogue(pub).execute("SELECT COUNT(*) FROM cells").fetchone()[0] == n_cells


@pytest.mark.slow
def test_snakemake_rebuilds_a_damaged_catalogue(tiny_run, tmp_path):
    """results/catalogue.sqlite overwritten in place with random bytes (the build file, its
    hard link, with it): the next run says so in one line, keeps the damaged file aside and
    rebuilds the catalogue from the verified Parquet files; readers refuse it meanwhile."""
    from workflow_helpers import smk

    wd = tmp_path / "wd"
    shutil.copytree(tiny_run[0], wd, symlinks=True,
                    ignore=shutil.ignore_patterns(".snakemake"))
    pub = wd / "results/catalogue.sqlite"
    target = "results/catalogue.d/build.sqlite"
    n_cells = gc.open_catalogue(pub).execute("SELECT COUNT(*) FROM cells").fetchone()[0]
    os.link(wd / target, pub.with_suffix(".tmp-link"))
    os.replace(pub.with_suffix(".tmp-link"), pub)  # published = built, as the rule leaves it
    with open(pub, "r+b") as f:
        f.write(os.urandom(pub.stat().st_size))
    with pytest.raises(gc.CatalogueError, match="damaged"):
        gc.open_catalogue(pub)
    smk(wd, target, "--cores", "1", "--configfile", "config/tiny.yaml")  # parse + no-op run
    r = smk(wd, target, "--cores", "1", "--configfile", "config/tiny.yaml", "-n")
    assert "damaged" not in r.stderr  # the first run already rebuilt it
    assert gc.open_catalogue(pub).execute("SELECT COUNT(*) FROM cells").fetchone()[0] == n_cells
    kept = list((wd / "results/catalogue.d/damaged").iterdir())
    assert len(kept) == 1
