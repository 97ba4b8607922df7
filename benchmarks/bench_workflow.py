"""(e) Wall time of the workflow: ``snakemake --cores 2`` in a scratch copy of the repository.

    python benchmarks/bench_workflow.py run --name quick_rk4 --configfile config/quick.yaml \\
        --set-integration-method rk4
    python benchmarks/bench_workflow.py collect DIR --name NAME --notes "..."   # a finished run

``run`` exports HEAD (``git archive``) to a temporary directory, writes an override config
(``integration.method``, ``tile_rows``) if asked, runs Snakemake there with PYTHONPATH pointing
at that copy's ``src`` and its own NUMBA_CACHE_DIR (so the shared checkout and its results are
untouched), and records the wall time, load average and the per-job benchmark files
(``logs/benchmarks/**/*.tsv``: seconds and max RSS per job) in results/workflow.json.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import RESULTS, loadavg, machine

ROOT = Path(__file__).resolve().parents[1]


def job_table(d: Path) -> dict:
    jobs = {}
    for f in sorted((d / "logs" / "benchmarks").rglob("*.tsv")):
        rows = list(csv.DictReader(f.open(), delimiter="\t"))
        if rows:
            r = rows[-1]
            jobs[str(f.relative_to(d / "logs" / "benchmarks"))] = {
                "s": float(r["s"]),
                "max_rss_mb": float(r["max_rss"]),
                "cpu_time_s": float(r.get("cpu_time", "nan") or "nan"),
            }
    return jobs


def record(entry: dict) -> None:
    path = RESULTS / "workflow.json"
    data = json.loads(path.read_text()) if path.exists() else {"benchmark": "workflow", "runs": []}
    data["machine"] = machine()
    data["runs"] = [r for r in data["runs"] if r["name"] != entry["name"]] + [entry]
    RESULTS.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=1) + "\n")
    print(path)


def summarize_jobs(jobs: dict) -> dict:
    tiles = [v for k, v in jobs.items() if "/tile_" in k]
    out = {"jobs": len(jobs)}
    if tiles:
        out["tiles"] = len(tiles)
        out["tile_wall_s_median"] = sorted(v["s"] for v in tiles)[len(tiles) // 2]
        out["tile_max_rss_mb"] = max(v["max_rss_mb"] for v in tiles)
    out["max_rss_mb"] = max((v["max_rss_mb"] for v in jobs.values()), default=float("nan"))
    return out


def cmd_collect(args) -> None:
    d = Path(args.dir)
    t0 = float((d / "t_start").read_text())
    t1 = float((d / "t_end").read_text())
    jobs = job_table(d)
    if not jobs and (d / "studies").is_dir():  # a configuration with a folder ran in studies/NAME/
        jobs = next((t for s in sorted((d / "studies").iterdir()) if (t := job_table(s))), {})
    record(
        {
            "name": args.name,
            "config": args.config,
            "integration": args.integration,
            "wall_s": t1 - t0,
            "load": args.load,
            "notes": args.notes,
            "summary": summarize_jobs(jobs),
            "jobs": jobs,
        }
    )


def cmd_run(args) -> None:
    d = Path(tempfile.mkdtemp(prefix=f"gearsim_wf_{args.name}_"))
    subprocess.run(f"git -C {ROOT} archive HEAD | tar -x -C {d}", shell=True, check=True)
    configs = list(args.configfile)
    override = {}
    if args.set_integration_method:
        override["integration"] = {"method": args.set_integration_method}
    if args.tile_rows:
        override["tile_rows"] = args.tile_rows
    if override:
        import yaml

        (d / "config" / "bench_override.yaml").write_text(yaml.safe_dump(override))
        configs.append("config/bench_override.yaml")
    env = dict(
        os.environ,
        PYTHONPATH=str(d / "src"),
        NUMBA_CACHE_DIR=str(d / ".numba_cache"),
        NUMBA_NUM_THREADS="1",
    )
    cmd = ["snakemake", "--cores", str(args.cores)]
    if configs:
        cmd += ["--configfile", *configs]
    load0 = loadavg()
    t0 = time.time()
    (d / "t_start").write_text(repr(t0))
    with (d / "snake.log").open("w") as log:
        rc = subprocess.run(cmd, cwd=d, env=env, stdout=log, stderr=subprocess.STDOUT).returncode
    t1 = time.time()
    (d / "t_end").write_text(repr(t1))
    jobs = job_table(d)
    if not jobs and (d / "studies").is_dir():  # a configuration with a folder ran in studies/NAME/
        jobs = next((t for s in sorted((d / "studies").iterdir()) if (t := job_table(s))), {})
    record(
        {
            "name": args.name,
            "config": " + ".join(configs) or "config/config.yaml",
            "integration": args.set_integration_method or "config",
            "wall_s": t1 - t0,
            "load": [load0, loadavg()],
            "returncode": rc,
            "notes": args.notes,
            "dir": str(d),
            "summary": summarize_jobs(jobs),
            "jobs": jobs,
        }
    )
    print(f"{args.name}: rc={rc} wall {t1 - t0:.0f} s in {d}")


def rule_times(log: Path) -> dict:
    """Per rule: jobs and the sum of job wall seconds, from a Snakemake log (its time stamps)."""
    import re
    from datetime import datetime

    stamp = re.compile(r"^\[(\w{3} \w{3} +\d+ \d\d:\d\d:\d\d \d{4})\]$")
    now, start, rule_of, out = None, {}, {}, {}
    pending, t_first = None, None
    for line in log.read_text().splitlines():
        m = stamp.match(line.strip())
        if m:
            now = datetime.strptime(m.group(1), "%a %b %d %H:%M:%S %Y").timestamp()
            t_first = now if t_first is None else t_first
            continue
        t = line.strip()
        if t.startswith(("rule ", "localrule ")) and t.endswith(":"):
            pending = t.split()[1].rstrip(":")
        elif t.startswith("jobid:") and pending:
            jid = t.split()[1]
            start[jid], rule_of[jid] = now, pending
            pending = None
        elif t.startswith("Finished jobid:"):
            jid = t.split()[2]
            if jid in start:
                r = out.setdefault(rule_of[jid], {"jobs": 0, "wall_s": 0.0, "first_start_s": 1e99,
                                                  "last_end_s": 0.0})  # fmt: skip
                r["jobs"] += 1
                r["wall_s"] += now - start[jid]
                # seconds from the run's first time stamp: the stages' order on the critical path
                r["first_start_s"] = min(r["first_start_s"], start[jid] - t_first)
                r["last_end_s"] = max(r["last_end_s"], now - t_first)
    return out


def cmd_rules(args) -> None:
    """Per-rule job seconds of a finished run directory (Snakemake log + benchmark files)."""
    d = Path(args.dir)
    logs = sorted((d / ".snakemake" / "log").glob("*.snakemake.log"))
    if not logs and d.parent.name == "studies":  # a study: Snakemake's log is the project's
        logs = sorted((d.parent.parent / ".snakemake" / "log").glob("*.snakemake.log"))
    if not logs:
        raise SystemExit(f"no Snakemake log in {d}/.snakemake/log")
    rules = rule_times(logs[-1])
    cpu: dict[str, float] = {}
    # benchmark file -> rule: sweeps/<name>, points/<set>, orbits/standard, orbits/<plane>_curves,
    # <plane>/tile_<k>, <plane>/attractors_<k>, <plane>/audit, <plane>/orbits
    by_path = {"sweeps": "sweep", "points": "points", "standard": "standard_continuation",
               "curves": "bifurcation_curves", "tile": "simulate_tile",
               "attractors": "attractor_tile", "audit": "audit", "orbits": "refine_orbits",
               "figure_data": "figure_data"}
    for k, v in job_table(d).items():
        parent, stem = Path(k).parent.name, Path(k).stem
        if parent == "orbits":  # orbits/standard (the continuation), orbits/<plane>_curves
            name = by_path.get(stem) or by_path.get(stem.rsplit("_", 1)[-1], stem)
        else:
            name = by_path.get(parent) or by_path.get(stem.rsplit("_", 1)[-1]) or by_path.get(
                stem.split("_", 1)[0], stem)
        cpu[name] = cpu.get(name, 0.0) + (v["cpu_time_s"] if v["cpu_time_s"] == v["cpu_time_s"]
                                          else 0.0)  # fmt: skip
    print(f"{'rule':24s} {'jobs':>5s} {'job wall s':>11s} {'first start':>12s} {'last end':>9s}"
          f" {'CPU s':>7s}")  # fmt: skip
    for r, v in sorted(rules.items(), key=lambda kv: kv[1]["first_start_s"]):
        c = cpu.get(r)
        print(f"{r:24s} {v['jobs']:5d} {v['wall_s']:11.0f} {v['first_start_s']:12.0f} "
              f"{v['last_end_s']:9.0f} {'' if c is None else round(c):>7}")
    print("benchmark-file CPU seconds (jobs with a `benchmark:`):",
          {k: round(v) for k, v in sorted(cpu.items())})  # fmt: skip
    if args.json:
        Path(args.json).write_text(json.dumps({"rules": rules, "cpu_s": cpu}, indent=1) + "\n")


def main(argv=None):
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("--name", required=True)
    r.add_argument("--configfile", nargs="*", default=[])
    r.add_argument("--set-integration-method", choices=["dp5", "rk4"])
    r.add_argument("--tile-rows", type=int)
    r.add_argument("--cores", type=int, default=2)
    r.add_argument("--notes", default="")
    c = sub.add_parser("collect")
    c.add_argument("dir")
    c.add_argument("--name", required=True)
    c.add_argument("--config", required=True)
    c.add_argument("--integration", required=True)
    c.add_argument("--load", default="")
    c.add_argument("--notes", default="")
    q = sub.add_parser("rules")
    q.add_argument("dir")
    q.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    {"run": cmd_run, "collect": cmd_collect, "rules": cmd_rules}[args.cmd](args)


if __name__ == "__main__":
    sys.exit(main())
