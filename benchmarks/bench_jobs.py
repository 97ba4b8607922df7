"""The fixed cost of a workflow job: CPU seconds of job commands and of the workflow's parse,
a git revision's package and this one alternating, on the same tables.

    python benchmarks/bench_jobs.py --rev REV [--rounds 5] [--results DIR]
    python benchmarks/bench_jobs.py --rev REV --workflow [--rounds 2]

A run has ~60 jobs (the tiny and default configurations alike: figures, diagrams, maps, tables,
report), each a new Python process that imports what its command needs, and every SLURM job
parses the workflow again; this measures that overhead, not the numerics. ``--results`` is a
directory where the tiny configuration's sweeps and planes were computed (its ``config/`` and
``results/``); without it they are computed first (Snakemake, this checkout, ~1 minute). Each
round runs every command once per version, in turn, in fresh processes (CPU time of the
children, user + system); the table gives the medians and their ratio. Both versions run with the
same interpreter and libraries, each with its own package source (``git archive``) and Numba
cache (warmed first). ``--workflow`` measures whole runs instead: the tiny configuration's default
target (tables, catalogue, figures, diagrams, report, explorer) with ``--cores 2`` in a fresh
directory per version and round, the versions alternating: CPU seconds of all its processes and
wall seconds.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import loadavg, save

ROOT = Path(__file__).resolve().parents[1]

#: name -> arguments after ``python -m ...`` (``{snakefile}``, ``{wd}``, ``{out}`` filled in)
COMMANDS: dict[str, list[str]] = {
    "sweep diagram job": ["gearsim.cli.main", "figures", "--sweep-diagrams", "--sweep",
                          "standard=results/sweeps/standard.parquet", "--configfile",
                          "config/tiny.yaml", "--outdir", "{out}"],
    "plane maps job": ["gearsim.cli.main", "figures", "--maps", "--plane",
                       "wb=results/wb/cells.parquet", "--configfile", "config/tiny.yaml",
                       "--outdir", "{out}"],
    "sweep job start (--help)": ["gearsim.cli.main", "sweep", "--help"],
    "tile job start (--help)": ["gearsim.cli.main", "simulate-tile", "--help"],
    "workflow parse (snakemake -n)": ["snakemake", "-s", "{snakefile}", "-d", "{wd}",
                                      "--configfile", "config/tiny.yaml", "-n", "--cores", "1",
                                      "-q"],
}


def export(rev: str, dest: Path) -> Path:
    """``git archive`` of the package, the Snakefile, workflow/ and docs/ (the calibration record
    the report reads) at ``rev`` into ``dest``."""
    dest.mkdir(parents=True, exist_ok=True)
    tar = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "src", "Snakefile", "workflow",
                          "docs"], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(dest)], input=tar, check=True)
    return dest


def env_for(tree: Path, cache: Path) -> dict:
    return {**os.environ, "PYTHONPATH": str(tree / "src"), "NUMBA_CACHE_DIR": str(cache),
            "NUMBA_NUM_THREADS": "1", "MPLBACKEND": "Agg"}


def child_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run(args: list[str], env: dict, cwd: Path) -> tuple[float, float]:
    """(CPU s, wall s) of one command in a fresh process; a failure stops the benchmark."""
    c0, w0 = child_cpu(), time.perf_counter()
    r = subprocess.run([sys.executable, "-m", *args], env=env, cwd=cwd, capture_output=True,
                       text=True)
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(args)} failed:\n{r.stderr[-2000:]}")
    return child_cpu() - c0, time.perf_counter() - w0


def make_results(wd: Path) -> None:
    """The tiny configuration's standard sweep and wb plane, computed by this checkout."""
    (wd / "config").mkdir(parents=True, exist_ok=True)
    for f in (ROOT / "config").glob("*.yaml"):
        shutil.copy(f, wd / "config" / f.name)
    print("computing the tiny configuration's tables ...", flush=True)
    subprocess.run([sys.executable, "-m", "snakemake", "-s", str(ROOT / "Snakefile"), "-d",
                    str(wd), "--configfile", "config/tiny.yaml", "--cores", "2",
                    "results/sweeps/standard.parquet", "results/wb/cells.parquet", "-q"],
                   env=env_for(ROOT, ROOT / ".numba_cache"), cwd=wd, check=True)


def warm(trees: dict, envs: dict) -> None:
    """Compile each version's kernels into its cache and write its .pyc files (not measured)."""
    for k in trees:
        subprocess.run([sys.executable, "-m", "gearsim.cli.main", "compile"], env=envs[k],
                       cwd=ROOT, check=True, capture_output=True)


def workflow_runs(trees: dict, envs: dict, tmp: Path, rounds: int) -> dict:
    """CPU and wall seconds of whole tiny-configuration runs, the versions alternating."""
    out: dict = {k: {"cpu_s": [], "wall_s": []} for k in trees}
    for r in range(rounds):
        order = list(trees) if r % 2 == 0 else list(trees)[::-1]
        for k in order:
            wd = tmp / f"wf_{r}_{k}"
            (wd / "config").mkdir(parents=True)
            for f in (ROOT / "config").glob("*.yaml"):
                shutil.copy(f, wd / "config" / f.name)
            c, w = run(["snakemake", "-s", str(trees[k] / "Snakefile"), "-d", str(wd),
                        "--configfile", "config/tiny.yaml", "--cores", "2", "-q"], envs[k], wd)
            out[k]["cpu_s"].append(c)
            out[k]["wall_s"].append(w)
            print(f"round {r + 1}/{rounds} {k}: {c:.1f} CPU-s, {w:.1f} s wall", flush=True)
            shutil.rmtree(wd, ignore_errors=True)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rev", required=True, help="git revision to compare with")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--results", type=Path, help="directory of a tiny-configuration run")
    ap.add_argument("--workflow", action="store_true", help="whole tiny-configuration runs")
    a = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="bench_jobs_"))
    try:
        if a.workflow:
            trees = {a.rev: export(a.rev, tmp / "old"), "this": ROOT}
            envs = {k: env_for(t, tmp / f"cache_{i}") for i, (k, t) in enumerate(trees.items())}
            warm(trees, envs)
            load0 = loadavg()
            runs = workflow_runs(trees, envs, tmp, a.rounds)
            load1 = loadavg()
            med = {k: statistics.median(v["cpu_s"]) for k, v in runs.items()}
            print(f"whole tiny run, CPU s (median): {a.rev[:10]} {med[a.rev]:.1f}, this "
                  f"{med['this']:.1f}, ratio {med['this'] / med[a.rev]:.2f}; load {load0} -> "
                  f"{load1}")
            path = save("bench_jobs_workflow", {"rev": a.rev, "rounds": a.rounds,
                                                "load": [load0, load1], "runs": runs})
            print(f"saved {path}")
            return 0
        wd = a.results.resolve() if a.results else tmp / "wd"
        if a.results is None:
            make_results(wd)
        trees = {a.rev: export(a.rev, tmp / "old"), "this": ROOT}
        envs = {k: env_for(t, tmp / f"cache_{i}") for i, (k, t) in enumerate(trees.items())}
        warm(trees, envs)
        cpu: dict = {k: {n: [] for n in COMMANDS} for k in trees}
        wall: dict = {k: {n: [] for n in COMMANDS} for k in trees}
        load0 = loadavg()
        for r in range(a.rounds + 1):  # round 0 warms the file cache, not counted
            for name, cmd in COMMANDS.items():
                for k, t in trees.items():
                    args = [s.format(snakefile=t / "Snakefile", wd=wd, out=tmp / f"out_{k}")
                            for s in cmd]
                    c, w = run(args, envs[k], wd)
                    if r:
                        cpu[k][name].append(c)
                        wall[k][name].append(w)
            print(f"round {r}/{a.rounds} done", flush=True)
        load1 = loadavg()
        rows = {}
        print(f"\n{'command':34s} {a.rev[:10]:>10s} {'this':>8s} {'ratio':>6s}   (CPU s, median)")
        for name in COMMANDS:
            old, new = (statistics.median(cpu[k][name]) for k in trees)
            rows[name] = {"cpu_s": {k: cpu[k][name] for k in trees},
                          "wall_s": {k: wall[k][name] for k in trees},
                          "median_cpu_s": {a.rev: old, "this": new}, "ratio": new / old}
            print(f"{name:34s} {old:10.2f} {new:8.2f} {new / old:6.2f}")
        print(f"load {load0} -> {load1}")
        path = save("bench_jobs", {"rev": a.rev, "rounds": a.rounds, "load": [load0, load1],
                                   "commands": rows})
        print(f"saved {path}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
