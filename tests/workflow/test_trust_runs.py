"""Interruption, determinism and catalogue integrity on the tiny configuration (issue: trust).

* A run killed with SIGKILL mid-tile (snakemake, its jobs and the dask workers: the whole process
  group) and started again completes, and no partial Parquet file is ever visible.
* The resumed run used one worker and 2-row tiles, the reference run two workers and 4-row tiles:
  the cell tables must be bit-identical (each row is one deterministic continuation chain; the
  worker and tile layout only decide where it runs). This holds for the scalar DP5 and RK4 paths;
  the batched RK4 kernel groups rows into SIMD lanes and is compared to a stated tolerance in
  tests/unit/test_batch.py.
* The catalogue passes PRAGMA integrity_check and foreign_key_check, has one row per cell and the
  run provenance, and is rebuilt (never appended) when its rule runs again.
"""

from __future__ import annotations

import glob
import os
import shutil
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pyarrow.parquet as pq
import pytest

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")
TARGET = "results/catalogue.d/build.sqlite"

pytestmark = pytest.mark.slow


def _env():
    env = dict(os.environ)
    env.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".numba_cache"))
    env["NUMBA_NUM_THREADS"] = "1"
    return env


def _workdir(path: Path, source: Path) -> Path:
    """A working directory with the same config files as ``source`` (the reference run)."""
    (path / "config").mkdir(parents=True)
    for f in (source / "config").glob("*.yaml"):
        shutil.copy(f, path / "config" / f.name)
    return path


def _cmd(wd: Path, *extra: str) -> list[str]:
    return [SNAKEMAKE, TARGET, "-s", str(ROOT / "Snakefile"), "-d", str(wd),
            "--configfile", "config/tiny.yaml", *extra]


def _run(wd: Path, *extra: str) -> subprocess.CompletedProcess:
    r = subprocess.run(_cmd(wd, *extra), cwd=wd, env=_env(), capture_output=True, text=True,
                       timeout=1200)
    assert r.returncode == 0, (r.stdout[-3000:], r.stderr[-3000:])
    return r


def _cells(db: Path) -> pd.DataFrame:
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    df = pd.read_sql("SELECT p.name AS plane, c.* FROM cells c JOIN planes p ON p.id = c.plane_id",
                     con)
    con.close()
    volatile = ["id", "plane_id", "run_id", "elapsed_s"]
    return df.drop(columns=volatile).sort_values(["plane", "j", "i"]).reset_index(drop=True)


@pytest.fixture(scope="module")
def reference(tiny_run):
    """The session's end-to-end run of config/tiny.yaml: two workers, 4-row tiles."""
    return tiny_run[0]


@pytest.fixture(scope="module")
def resumed(tmp_path_factory, reference):
    wd = _workdir(tmp_path_factory.mktemp("killed"), reference)
    proc = subprocess.Popen(_cmd(wd, "--cores", "1", "--config", "tile_rows=2"), cwd=wd,
                            env=_env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    # kill as soon as a tile job has finished at least one row but before the catalogue exists
    deadline = time.monotonic() + 600
    killed_mid_tile = False
    while time.monotonic() < deadline and proc.poll() is None:
        logs = glob.glob(str(wd / "logs/*/tile_*.log"))
        if any("cells/s" in Path(f).read_text() for f in logs):
            os.killpg(proc.pid, signal.SIGKILL)
            killed_mid_tile = True
            break
        time.sleep(0.1)
    proc.wait()
    assert killed_mid_tile, "the run ended before it could be interrupted"
    assert not (wd / TARGET).exists()
    # no partial Parquet file is visible under an output name: whatever exists reads cleanly
    visible = glob.glob(str(wd / "results/**/*.parquet"), recursive=True)
    for f in visible:
        pq.read_table(f)
    # the documented resume: clear the stale lock the kill left behind, run again
    subprocess.run([SNAKEMAKE, "-s", str(ROOT / "Snakefile"), "-d", str(wd), "--unlock",
                    "--configfile", "config/tiny.yaml"], cwd=wd, env=_env(), check=True,
                   capture_output=True)
    _run(wd, "--cores", "1", "--config", "tile_rows=2")
    return wd


def test_interrupted_run_resumes_to_an_identical_catalogue(reference, resumed):
    a = _cells(reference / TARGET).drop(columns=["tile"], errors="ignore")
    b = _cells(resumed / TARGET).drop(columns=["tile"], errors="ignore")
    assert len(a) == len(b) == 128
    different = [c for c in a.columns if not a[c].equals(b[c])]
    assert different == [], different


def test_catalogue_integrity(reference):
    db = reference / TARGET
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    con.execute("PRAGMA foreign_keys = ON")
    assert con.execute("PRAGMA foreign_key_check").fetchall() == []
    fks = {r[2] for r in con.execute("PRAGMA foreign_key_list(cells)")}
    assert {"planes", "runs"} <= fks
    total, distinct = con.execute(
        "SELECT COUNT(*), COUNT(DISTINCT plane_id || ':' || i || ':' || j) FROM cells"
    ).fetchone()
    assert total == distinct == 128
    missing = con.execute(
        "SELECT COUNT(*) FROM runs WHERE config_hash IS NULL OR code_version IS NULL"
    ).fetchone()[0]
    assert missing == 0
    assert con.execute("SELECT COUNT(*) FROM runs").fetchone()[0] > 0
    con.close()


def test_catalogue_is_rebuilt_not_appended(reference):
    db = reference / TARGET
    before = _cells(db)
    _run(reference, "--cores", "1", "--forcerun", "catalogue")
    after = _cells(db)
    assert len(after) == len(before) == 128
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    con.close()
