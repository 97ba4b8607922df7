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


def _wait_for_workers(address: str, n: int, timeout: float = 120) -> None:
    """Both worker processes start at once but register one by one: the tile is asked to run
    only when the scheduler holds all of them, so that its log names the full cluster."""
    from distributed import Client

    with Client(address, timeout=timeout) as client:
        client.wait_for_workers(n, timeout=timeout)


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
        _wait_for_workers(address, 2)
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


@pytest.mark.slow
def test_tile_cluster_has_the_cpus_slurm_gave_the_job(tmp_path):
    """Inside a SLURM job step (SLURM_CPUS_PER_TASK), the tile's LocalCluster has one worker per
    CPU SLURM gave, whatever --workers says; the cells are the same."""
    base = [ROOT / "config/config.yaml", ROOT / "config/tiny.yaml"]
    small = tmp_path / "small.yaml"
    small.write_text(yaml.safe_dump({"planes": {"wb": {"x": {"name": "w", "min": 0.3,
                                                             "max": 2.1, "n": 6}}}}))
    env = {**_env(), "SLURM_JOB_ID": "1", "SLURM_CPUS_PER_TASK": "3"}
    cmd = [str(GEARSIM), "simulate-tile", "--plane", "wb", "--tile", "1", "--configfile",
           *map(str, [*base, small]), "--out", "slurm.parquet", "--workers", "2"]
    r = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "3 workers, 3 threads" in r.stderr, r.stderr
    inproc, _ = _tile(tmp_path, [*base, small], "inproc.parquet", "--no-cluster")
    _same(pd.read_parquet(tmp_path / "slurm.parquet"), inproc)


def test_job_cpus_inside_and_outside_slurm(monkeypatch):
    from gearsim.study import cluster

    for k in ("SLURM_JOB_ID", "SLURM_CPUS_PER_TASK"):
        monkeypatch.delenv(k, raising=False)
    assert cluster.job_cpus() is None and cluster.local_workers(5) == 5
    # the jobstep plugin keeps SLURM_JOB_ID but drops the rest: the step's CPU binding counts
    monkeypatch.setenv("SLURM_JOB_ID", "7")
    assert cluster.job_cpus() == len(os.sched_getaffinity(0))
    monkeypatch.setenv("SLURM_CPUS_PER_TASK", "4")
    assert cluster.job_cpus() == 4 and cluster.local_workers(1) == 4


def _fake_sinfo(tmp_path: Path, monkeypatch, lines: str, rc: int = 0) -> None:
    """A `sinfo` on PATH that prints ``lines`` (as `sinfo --format='%P %c %m'` would)."""
    from gearsim.study import cluster

    (tmp_path / "sinfo").write_text(f"#!/bin/sh\nprintf '{lines}'\nexit {rc}\n")
    (tmp_path / "sinfo").chmod(0o755)
    monkeypatch.setenv("PATH", f"{tmp_path}:{os.environ['PATH']}")
    monkeypatch.delenv("SBATCH_PARTITION", raising=False)
    cluster.node_limits.cache_clear()


def test_threads_and_memory_fit_the_partitions_nodes(tmp_path, monkeypatch):
    from gearsim.errors import UsageError
    from gearsim.study import cluster

    # two node sizes in the default partition, a larger one elsewhere
    _fake_sinfo(tmp_path, monkeypatch,
                "debug* 2 3900\\ndebug* 4 7800\\nbig 64 256000+\\n")
    assert cluster.node_limits("") == (4, 7800)
    assert cluster.fit_threads(8) == 4 and cluster.fit_threads(3) == 3
    assert cluster.fit_memory(1000, 4) == 1000
    with pytest.raises(UsageError, match=r"catalogue needs 8000 MB per CPU x 1 CPUs .* 7800 MB"):
        cluster.fit_memory(8000, 1, "catalogue")
    monkeypatch.setenv("SBATCH_PARTITION", "big")
    assert cluster.fit_threads(8) == 8 and cluster.fit_memory(8000, 8) == 8000
    monkeypatch.setenv("SBATCH_PARTITION", "nope")
    with pytest.raises(UsageError, match="SLURM has no partition 'nope'"):
        cluster.fit_threads(8)


def test_no_controller_means_nothing_to_fit(tmp_path, monkeypatch):
    from gearsim.study import cluster

    _fake_sinfo(tmp_path, monkeypatch, "", rc=1)  # sinfo present, controller down
    assert cluster.node_limits("") is None and cluster.fit_threads(8) == 8
    assert cluster.fit_memory(8000, 8) == 8000
