"""Scale-out: a tile computed on real ``dask scheduler`` / ``dask worker`` processes equals the
LocalCluster result (and the in-process one)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
DASK = BIN / "dask"
GEARSIM = BIN / "gearsim"

pytestmark = pytest.mark.skipif(not DASK.exists(), reason="dask CLI not installed")


def _env():
    env = dict(os.environ)
    env.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".numba_cache"))
    env["NUMBA_NUM_THREADS"] = "1"
    return env


def _wait_for(path: Path, timeout: float = 60) -> dict:
    t0 = time.time()
    while time.time() - t0 < timeout:
        if path.exists():
            try:
                return json.loads(path.read_text())
            except json.JSONDecodeError:
                pass
        time.sleep(0.2)
    raise TimeoutError(f"{path} not written")


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def _tile(cwd: Path, configs: list[Path], out: str, *extra: str) -> pd.DataFrame:
    cmd = [str(GEARSIM), "simulate-tile", "--plane", "wb", "--tile", "1",
           "--configfile", *map(str, configs), "--out", out, *extra]
    r = subprocess.run(cmd, cwd=cwd, env=_env(), capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return pd.read_parquet(cwd / out), r.stderr


def _same(a: pd.DataFrame, b: pd.DataFrame) -> None:
    cols = [c for c in a.columns if c != "elapsed_s"]
    pd.testing.assert_frame_equal(a[cols], b[cols])


@pytest.mark.slow
def test_tile_on_scheduler_equals_local_cluster(tmp_path):
    base = [ROOT / "config/config.yaml", ROOT / "config/tiny.yaml"]
    small = tmp_path / "small.yaml"
    small.write_text(yaml.safe_dump({"planes": {"wb": {"x": {"name": "w", "min": 0.3,
                                                             "max": 2.1, "n": 6}}}}))
    sched_file = tmp_path / "scheduler.json"
    procs = []
    try:
        procs.append(subprocess.Popen(
            [str(DASK), "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
             "--scheduler-file", str(sched_file)],
            cwd=tmp_path, env=_env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        address = _wait_for(sched_file)["address"]
        assert address.startswith("tcp://127.0.0.1:")
        procs.append(subprocess.Popen(
            [str(DASK), "worker", address, "--nworkers", "2", "--nthreads", "1",
             "--no-dashboard", "--host", "127.0.0.1"],
            cwd=tmp_path, env=_env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        remote_cfg = tmp_path / "remote.yaml"
        remote_cfg.write_text(yaml.safe_dump({"cluster": {"scheduler_address": address}}))
        remote, log = _tile(tmp_path, [*base, small, remote_cfg], "remote.parquet")
        assert f"scheduler {address}: 2 workers" in log
    finally:
        for p in reversed(procs):
            _stop(p)
    local, log = _tile(tmp_path, [*base, small], "local.parquet", "--workers", "2")
    assert "2 workers, 2 threads" in log and "24/24 cells" in log
    assert len(remote) == 6 * 4
    _same(remote, local)
    inproc, _ = _tile(tmp_path, [*base, small], "inproc.parquet", "--no-cluster")
    _same(inproc, local)


def test_unreachable_scheduler_is_one_line(tmp_path):
    env = {**_env(), "GEARSIM_SCHEDULER_TIMEOUT": "2s"}
    r = subprocess.run(
        [str(GEARSIM), "simulate-tile", "--plane", "wb", "--tile", "0", "--configfile",
         str(ROOT / "config/config.yaml"), str(ROOT / "config/tiny.yaml"),
         "--scheduler", "tcp://127.0.0.1:9"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "cannot reach dask scheduler" in r.stderr
    assert r.stderr.strip().count("\n") == 0, r.stderr  # one line
