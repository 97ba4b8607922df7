"""Helpers to run the Snakemake workflow from tests in throw-away working directories."""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

from gearsim.study import config as gcfg

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = Path(sys.executable).parent / "snakemake"


def _env():
    env = dict(os.environ)
    env.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".numba_cache"))
    env["NUMBA_NUM_THREADS"] = "1"
    return env


def make_workdir(path: Path) -> Path:
    """A fresh working directory with a copy of config/ (results land there, not in the repo)."""
    (path / "config").mkdir(parents=True, exist_ok=True)
    for f in (ROOT / "config").glob("*.yaml"):
        shutil.copy(f, path / "config" / f.name)
    return path


def smk(workdir: Path, *args: str, check: bool = True, timeout: float = 2400):
    # timeout: a hang guard only (the tiny workflow took 15 min of wall time beside the other
    # pytest-xdist worker on a loaded machine)
    cmd = [str(SNAKEMAKE), "-s", str(ROOT / "Snakefile"), "-d", str(workdir), *args]
    r = subprocess.run(cmd, cwd=workdir, env=_env(), capture_output=True, text=True,
                       timeout=timeout)
    if check and r.returncode != 0:
        raise AssertionError(f"{' '.join(cmd)} failed:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}")
    return r


def targets(workdir: Path, *configs: str) -> list[str]:
    """This stage's final outputs (other stages' rules are tested by their owners)."""
    cfg = gcfg.load_config([workdir / "config/config.yaml", *(workdir / c for c in configs)],
                         root=workdir)
    out = [f"results/{p}/cells.parquet" for p in cfg["planes"]]
    out += [f"results/sweeps/{s}.parquet" for s in cfg["sweeps"]]
    out += [f"results/points/{f}.parquet" for f in cfg["points"]]
    return [*out, "results/catalogue.d/build.sqlite"]


def job_counts(output: str) -> dict[str, int]:
    counts: dict[str, int] = {}
    block = output.split("Job stats:", 1)[1] if "Job stats:" in output else ""
    for line in block.splitlines()[3:]:
        parts = line.split()
        if len(parts) != 2 or not parts[1].isdigit():
            break
        counts[parts[0]] = int(parts[1])
    return counts


def smk_in(workdir, *args, check=True, timeout=900):
    """Snakemake run in ``workdir`` as a user runs it: from that directory, without
    --directory (which would override the study's folder and is refused)."""
    cmd = [str(SNAKEMAKE), "-s", str(ROOT / "Snakefile"), *args]
    r = subprocess.run(cmd, cwd=workdir, env=_env(), capture_output=True, text=True,
                       timeout=timeout)
    if check and r.returncode != 0:
        raise AssertionError(f"{' '.join(cmd)} failed:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}")
    return r


def tiny_run_once(tmp_path_factory):
    """The whole workflow on config/tiny.yaml (2 cores, 4-row tiles), run once for the whole
    session: under pytest-xdist the first worker that asks runs it in the session's shared temp
    folder, holding a file lock, and a worker asking meanwhile waits for it and reads the same
    run (its record: targets, exit code, output). ``(workdir, targets, CompletedProcess)``."""
    base = tmp_path_factory.getbasetemp()
    root = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base
    wd, record = root / "tiny_run", root / "tiny_run.json"
    with open(root / "tiny_run.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        if not record.exists():
            make_workdir(wd)
            tg = targets(wd, "config/tiny.yaml")
            r = smk(wd, *tg, "--cores", "2", "--configfile", "config/tiny.yaml")
            record.write_text(json.dumps({"targets": tg, "returncode": r.returncode,
                                          "stdout": r.stdout, "stderr": r.stderr}))
    rec = json.loads(record.read_text())
    done = subprocess.CompletedProcess(["snakemake"], rec["returncode"], rec["stdout"],
                                       rec["stderr"])
    return wd, rec["targets"], done
