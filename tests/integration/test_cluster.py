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


def _tile(cwd: Path, configs: list[Path], out: str, *extra: str,
          tile: int = 1) -> pd.DataFrame:
    cmd = [str(GEARSIM), "simulate-tile", "--plane", "wb", "--tile", str(tile),
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


#: A tile of 32 rows (one dask task per row): long enough to lose its scheduler or a worker
#: after the first rows are back and well before the last.
LONG_TILE = {"tile_rows": 32,
             "planes": {"wb": {"x": {"name": "w", "min": 0.3, "max": 2.1, "n": 8},
                               "y": {"name": "b", "min": 0.0, "max": 1.0, "n": 32}},
                        "wxi": {"y": {"name": "xi", "min": 0.04, "max": 0.16, "n": 32}}}}


def _scheduler(cwd: Path, port: int = 0) -> tuple[subprocess.Popen, str]:
    sched_file = cwd / f"scheduler-{time.monotonic_ns()}.json"
    proc = subprocess.Popen(
        [str(DASK), "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard",
         "--scheduler-file", str(sched_file)],
        cwd=cwd, env=_env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return proc, _wait_for(sched_file)["address"]


def _worker(cwd: Path, address: str) -> subprocess.Popen:
    """One single-threaded worker (and its nanny) in a process group of its own."""
    return subprocess.Popen(
        [str(DASK), "worker", address, "--nworkers", "1", "--nthreads", "1", "--no-dashboard",
         "--host", "127.0.0.1"], cwd=cwd, env=_env(), stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL, start_new_session=True)


def _tile_with(cwd: Path, configs: list[Path], out: str, fault) -> tuple[int, str, float]:
    """Run the tile on the scheduler of ``configs``; call ``fault()`` once the first rows are
    back. (exit code, stderr, seconds from the fault to the end)."""
    cmd = [str(GEARSIM), "simulate-tile", "--plane", "wb", "--tile", "0",
           "--configfile", *map(str, configs), "--out", out]
    log = cwd / f"{out}.log"
    with log.open("w") as err:
        proc = subprocess.Popen(cmd, cwd=cwd, env=_env(), stdout=subprocess.DEVNULL, stderr=err)
        deadline = time.monotonic() + 300
        while "cells (" not in log.read_text():  # the first progress line
            assert proc.poll() is None and time.monotonic() < deadline, log.read_text()
            time.sleep(0.05)
        assert "256/256" not in log.read_text()
        fault()
        t_fault = time.monotonic()
        proc.wait(timeout=300)
    return proc.returncode, log.read_text(), time.monotonic() - t_fault


@pytest.fixture(scope="module")
def long_tile(tmp_path_factory):
    """The configuration files of the 64-row tile and its cells computed in-process."""
    cwd = tmp_path_factory.mktemp("long_tile")
    (cwd / "long.yaml").write_text(yaml.safe_dump(LONG_TILE))
    configs = [ROOT / "config/config.yaml", ROOT / "config/tiny.yaml", cwd / "long.yaml"]
    cmd = [str(GEARSIM), "simulate-tile", "--plane", "wb", "--tile", "0", "--configfile",
           *map(str, configs), "--out", "inproc.parquet", "--no-cluster"]
    r = subprocess.run(cmd, cwd=cwd, env=_env(), capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return configs, pd.read_parquet(cwd / "inproc.parquet")


@pytest.mark.slow
def test_scheduler_lost_mid_tile_stops_in_one_line_and_a_rerun_gives_the_same_cells(
        tmp_path, long_tile):
    """The scheduler killed (SIGKILL) while the tile's rows run: the job stops at once in one
    line, exit 2, with nothing written; the same command, once a scheduler listens at the same
    address again, writes the cells of the fault-free tile."""
    configs, inproc = long_tile
    procs = []
    try:
        sched, address = _scheduler(tmp_path)
        procs += [sched, _worker(tmp_path, address), _worker(tmp_path, address)]
        _wait_for_workers(address, 2)
        remote_cfg = tmp_path / "remote.yaml"
        remote_cfg.write_text(yaml.safe_dump({"cluster": {"scheduler_address": address}}))
        code, err, after = _tile_with(tmp_path, [*configs, remote_cfg], "tile.parquet",
                                      sched.kill)
        lines = [ln for ln in err.splitlines()
                 if "cells (" not in ln and " on scheduler " not in ln]
        assert code == 2 and lines == [
            f"gearsim simulate-tile: error: lost dask scheduler {address} mid-job; nothing was "
            "written: start the scheduler again, then run the same command"], err
        # a lost connection cancels the client's futures at once: the bound is the client's
        # shutdown, not a timeout
        assert after < 30, after
        assert sorted(p.name for p in tmp_path.iterdir() if "parquet" in p.name) == [
            "tile.parquet.log"]
        # the workers close with their scheduler: a new scheduler at the same address, new
        # workers, and the same command
        sched2, again = _scheduler(tmp_path, port=int(address.rsplit(":", 1)[1]))
        assert again == address
        procs += [sched2, _worker(tmp_path, address), _worker(tmp_path, address)]
        _wait_for_workers(address, 2)
        rerun, log = _tile(tmp_path, [*configs, remote_cfg], "tile.parquet", tile=0)
    finally:
        for p in reversed(procs):
            _stop(p)
    assert "256/256 cells" in log
    _same(rerun, inproc)


@pytest.mark.slow
def test_worker_lost_and_replaced_mid_tile_gives_the_same_cells(tmp_path, long_tile):
    """One of two workers killed (SIGKILL, with its nanny) while the tile runs, a new one
    started: the scheduler hands the lost rows to the workers it has, and the tile equals
    the fault-free one."""
    configs, inproc = long_tile
    procs = []
    try:
        sched, address = _scheduler(tmp_path)
        lost = _worker(tmp_path, address)
        procs += [sched, lost, _worker(tmp_path, address)]
        _wait_for_workers(address, 2)
        remote_cfg = tmp_path / "remote.yaml"
        remote_cfg.write_text(yaml.safe_dump({"cluster": {"scheduler_address": address}}))

        def replace_a_worker():
            os.killpg(lost.pid, signal.SIGKILL)
            lost.wait()
            procs.append(_worker(tmp_path, address))

        code, err, _ = _tile_with(tmp_path, [*configs, remote_cfg], "tile.parquet",
                                  replace_a_worker)
    finally:
        for p in reversed(procs):
            _stop(p)
    assert code == 0, err
    assert "256/256 cells" in err
    _same(pd.read_parquet(tmp_path / "tile.parquet"), inproc)


def test_jobs_of_an_earlier_run_in_this_folder_stop_a_run_in_one_line(tmp_path, monkeypatch):
    """A `squeue` on PATH that lists jobs: those of a Snakemake run in this folder (the plugin's
    rule_ comment, this working directory) stop the run in one line naming them and what to
    run; other folders' jobs, other jobs, and a job step's own Snakemake (SLURM_JOB_ID) pass."""
    from gearsim.errors import UsageError
    from gearsim.study import cluster

    here, other = tmp_path / "run", tmp_path / "other"
    here.mkdir()
    other.mkdir()
    rows = [f"11|RUNNING|rule_tiles_attractor_tile_simulate_tile|{here}",
            f"12|PENDING|rule_tables_audit_plane_cells|{here}",
            f"13|RUNNING|rule_tiles_attractor_tile_simulate_tile|{other}",
            f"14|RUNNING||{here}"]
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "squeue").write_text("#!/bin/sh\nprintf '%s\\n' " +
                                    " ".join(f"'{r}'" for r in rows) + "\n")
    (bin_dir / "squeue").chmod(0o755)
    monkeypatch.setenv("PATH", f"{bin_dir}:{os.environ['PATH']}")
    monkeypatch.delenv("SLURM_JOB_ID", raising=False)
    cluster._earlier_run_jobs.cache_clear()
    monkeypatch.chdir(other)
    with pytest.raises(UsageError) as err:
        cluster.earlier_run_jobs()
    assert str(err.value) == (
        f"SLURM job 13 (rule_tiles_attractor_tile_simulate_tile) of an earlier run in {other} "
        "is RUNNING: wait until `squeue --me` no longer lists them or cancel them (scancel 13), "
        "then run the same command again")
    monkeypatch.chdir(here)
    with pytest.raises(UsageError,
                       match=r"SLURM job 11 .* is RUNNING and 1 more: .*scancel 11 12\)"):
        cluster.earlier_run_jobs()
    monkeypatch.setenv("SLURM_JOB_ID", "11")  # the job step's Snakemake of job 11 itself
    assert cluster.earlier_run_jobs() == 0
    monkeypatch.delenv("SLURM_JOB_ID")
    monkeypatch.chdir(tmp_path)
    assert cluster.earlier_run_jobs() == 0
