"""Batched kernel before and after the one-source refactor, side by side in one run.

The old kernel is the package as of a git revision (``--rev``, e.g. the commit before a kernel
change), exported with ``git archive`` into a temporary directory; the new one is this
checkout's ``src``. Each version runs in its own interpreter (own Numba cache, warmed first) on the
same cells, alternating old / new (the order swapped every round) for several rounds so that both
see the same machine load. Reported: batched RK4 cell-steps per second per core (CPU time), with
and without the tangent vector, and the new/old ratio (target: >= 0.95) of the medians over the
rounds and of the best rounds (the best round is the least disturbed by other jobs on a loaded
machine).

With ``--paired K`` both versions stay loaded in two worker processes and take turns run by run
(K pairs of one timed run each, the order swapped every pair): on a loaded machine the ratio of
two neighbouring runs drifts far less than runs minutes apart. Reported: each version's best and
median run, and the median and quartiles of the K paired ratios new/old. ``--build znver3``
runs the AVX2 build (``NUMBA_CPU_NAME`` and :func:`gearsim.numerics.cache.avx2_features`).

Usage: python benchmarks/bench_kernel_ab.py --rev REV [--rounds 3] [--quick]
       python benchmarks/bench_kernel_ab.py --rev REV --paired 30 [--build znver3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from _common import loadavg, run_json_worker, save

ROOT = Path(__file__).resolve().parents[1]
HERE = Path(__file__).resolve().parent

# Runs inside each version's interpreter: prints one JSON line of timings.
WORKER = r"""
import json, sys, time
import numpy as np
from gearsim.numerics import batch, lanes_layout
from gearsim.dynamics.model import static_state
from gearsim.dynamics.parameters import ModelParameters
from gearsim.cell.simulate import IntegrationSettings, run_periods
try:
    from gearsim.cell.simulate import initial_tangent as _it
    tangent0 = lambda p: _it(p)
except ImportError:
    tangent0 = lambda p: batch.initial_tangent()
n, periods, repeats = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
ws = np.linspace(0.6, 2.4, n)
cs = [ModelParameters(w=float(w), b=(0.15, 0.3, 1.0)[i % 3]) for i, w in enumerate(ws)]
st = IntegrationSettings(method="rk4")
y0 = []
for p in cs:
    r = run_periods(p, static_state(p.to_array()), 100, st)
    y0.append(np.concatenate([r.state, tangent0(p)]))
y0 = np.array(y0)
lanes = batch.Lanes(n, periods)
N = 256
from bench_kernel import load_lanes
def setup():
    load_lanes(lanes, cs, y0, N)
out = {}
for tangent in (False, True):
    setup()
    lanes.run(N, 1, 0.0, 1e6, tangent)  # compile / load the cache
    cpu = []
    for _ in range(repeats):
        setup()  # lane set-up (Python) is not the kernel: outside the timing
        c0 = time.process_time()
        lanes.run(N, periods, 0.0, 1e6, tangent)
        cpu.append(time.process_time() - c0)
        steps = int(lanes.ist[lanes_layout.IST_STEPS, :n].sum())
    grid = n * periods * N
    out["tangent" if tangent else "state"] = {
        "cpu_median_s": sorted(cpu)[len(cpu) // 2], "cpu_min_s": min(cpu),
        "cell_steps": grid, "steps_with_fixups": steps,
        "cell_steps_per_s_cpu": grid / sorted(cpu)[len(cpu) // 2],
    }
print(json.dumps(out))
"""


# One persistent worker per version for --paired: set-up and compile, then one timed run per
# line read from stdin ("state" or "tangent"), its CPU seconds printed.
PAIRED_WORKER = WORKER.split("out = {}")[0] + r"""
for tangent in (False, True):
    setup()
    lanes.run(N, 1, 0.0, 1e6, tangent)
print("ready", flush=True)
for line in sys.stdin:
    tangent = line.strip() == "tangent"
    setup()
    c0 = time.process_time()
    lanes.run(N, periods, 0.0, 1e6, tangent)
    print(time.process_time() - c0, flush=True)
"""


def paired(srcs: dict, caches: dict, build: str, n: int, periods: int, pairs: int) -> dict:
    """Old and new workers alive together, one timed run each in turn (see the docstring)."""
    from gearsim.numerics.cache import avx2_features

    procs = {}
    for v in ("old", "new"):
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(srcs[v]), str(HERE)]),
                   NUMBA_CACHE_DIR=str(caches[v]), NUMBA_NUM_THREADS="1")
        env.pop("NUMBA_CPU_NAME", None)
        env.pop("NUMBA_CPU_FEATURES", None)
        if build != "host":
            env["NUMBA_CPU_NAME"] = build
            env["NUMBA_CPU_FEATURES"] = avx2_features()
        procs[v] = subprocess.Popen([sys.executable, "-c", PAIRED_WORKER, str(n), str(periods),
                                     "1"], env=env, stdin=subprocess.PIPE,
                                    stdout=subprocess.PIPE, text=True)
    for p in procs.values():
        while p.stdout.readline().strip() != "ready":
            pass
    grid = n * periods * 256
    out = {}
    for kind in ("state", "tangent"):
        t: dict[str, list[float]] = {"old": [], "new": []}
        for i in range(pairs):
            for v in (("old", "new") if i % 2 == 0 else ("new", "old")):
                procs[v].stdin.write(kind + "\n")
                procs[v].stdin.flush()
                t[v].append(float(procs[v].stdout.readline()))
        ratios = sorted(o / w for o, w in zip(t["old"], t["new"], strict=True))
        q = statistics.quantiles(ratios, n=4)
        out[kind] = {"old_best": grid / min(t["old"]), "new_best": grid / min(t["new"]),
                     "old_median": grid / statistics.median(t["old"]),
                     "new_median": grid / statistics.median(t["new"]),
                     "paired_ratio_median": statistics.median(ratios),
                     "paired_ratio_quartiles": [q[0], q[2]], "cpu_s": t}
        r = out[kind]
        print(f"{build} {kind:8s} old best {r['old_best'] / 1e6:.1f} M/s (median "
              f"{r['old_median'] / 1e6:.1f})  new best {r['new_best'] / 1e6:.1f} M/s (median "
              f"{r['new_median'] / 1e6:.1f})  paired new/old x{r['paired_ratio_median']:.3f} "
              f"(quartiles {q[0]:.3f}-{q[2]:.3f}, {pairs} pairs)  load {loadavg()}", flush=True)
    for p in procs.values():
        p.stdin.close()
        p.wait()
    return out


def export(rev: str, dest: Path, paths: tuple[str, ...] = ("src",)) -> Path:
    """``git archive`` of ``paths`` at ``rev`` into ``dest``; returns the src directory."""
    dest.mkdir(parents=True, exist_ok=True)
    tar = subprocess.run(["git", "-C", str(ROOT), "archive", rev, *paths], check=True,
                         capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(dest)], input=tar, check=True)
    return dest / "src"


def run_version(src: Path, cache: Path, n: int, periods: int, repeats: int) -> dict:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(src), str(HERE)]),
               NUMBA_CACHE_DIR=str(cache), NUMBA_NUM_THREADS="1")
    return run_json_worker(WORKER, [n, periods, repeats], env)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rev", required=True, help="git revision of the old kernel")
    ap.add_argument("--rounds", type=int, default=3, help="alternating old/new rounds")
    ap.add_argument("--quick", action="store_true", help="fewer periods")
    ap.add_argument("--paired", type=int, default=0, help="pairs of runs, workers kept alive")
    ap.add_argument("--build", default="host", help="NUMBA_CPU_NAME for --paired (host: none)")
    args = ap.parse_args(argv)
    n, periods, repeats = 32, (40 if args.quick else 200), 9
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        versions = {"old": export(args.rev, tmp / "old"), "new": ROOT / "src"}
        caches = {"old": tmp / "cache_old", "new": tmp / "cache_new"}
        if args.paired:
            res = paired(versions, caches, args.build, n, 100, args.paired)
            print(save("kernel_ab_paired", {"rev_old": args.rev, "build": args.build, "lanes": n,
                                            "periods": 100, "result": res,
                                            "load_end": loadavg()}))
            return 0
        rounds: dict[str, list[dict]] = {"old": [], "new": []}
        for r in range(args.rounds):
            for name in (("old", "new") if r % 2 == 0 else ("new", "old")):
                res = run_version(versions[name], caches[name], n, periods, repeats)
                rounds[name].append(res)
                print(f"round {r} {name}: state {res['state']['cell_steps_per_s_cpu'] / 1e6:.2f}"
                      f" M/s, tangent {res['tangent']['cell_steps_per_s_cpu'] / 1e6:.2f} M/s"
                      f"  load {loadavg()}", flush=True)
    summary = {}
    for kind in ("state", "tangent"):
        rates = {v: [x[kind]["cell_steps_per_s_cpu"] for x in rounds[v]] for v in ("old", "new")}
        med = {v: statistics.median(r) for v, r in rates.items()}
        best = {v: max(r) for v, r in rates.items()}
        summary[kind] = {"old_cell_steps_per_s": med["old"], "new_cell_steps_per_s": med["new"],
                         "new_over_old": med["new"] / med["old"],
                         "old_best": best["old"], "new_best": best["new"],
                         "new_over_old_best": best["new"] / best["old"]}
        print(f"{kind:8s} median: old {med['old'] / 1e6:.2f} M/s  new {med['new'] / 1e6:.2f} M/s"
              f"  ratio {med['new'] / med['old']:.3f};  best: old {best['old'] / 1e6:.2f}  new "
              f"{best['new'] / 1e6:.2f}  ratio {best['new'] / best['old']:.3f}")
    path = save("kernel_ab", {"rev_old": args.rev, "lanes": n, "periods": periods,
                              "rounds": rounds, "summary": summary, "load_end": loadavg()})
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
