"""Device check: the study's lanes on one GPU beside the host's cores, in one prepared run.

One command on a GPU machine (written for one H200 and its 16 host cores, under 9 minutes),
its JSON (``gpu.json`` under ``--out``) rewritten after every stage, so a run cut off keeps
what it measured:

1. ``env``: the GPU (name, compute capability, memory), numba / numba-cuda, the host CPU
   (``lscpu``), its cores and load.
2. ``compile``: the CUDA lane kernel's first launch in a fresh process with an empty cache
   (cold: the compile of the kernel and the ``@njit`` layers it calls) and again with that
   cache (warm).
3. ``kernel_cells``: the kernel test cells (tests/unit/test_cuda_lanes.py) on both devices:
   the largest difference of the records and states, equal impact counts and status.
4. ``lane_steps``: lane-steps per second of the kernel at 400, 16 k, 131 k and 1 M lanes (cells
   of the (w, b) plane's ranges), with the event layer and without it (``events=False``: a
   flagged step is not redone: the step's own rate); the CPU kernel on 1 core and on every
   core (threads: the kernel releases the GIL) on the same kind of lanes. ``registers``: the
   kernel at 131 k lanes compiled with 168, 128, 96 and 64 registers a thread beside the
   default (ptxas gives it 255 and spills at sm_90): which limit the kernel should carry.
5. ``planes``: both 400 x 400 planes' continuation chains (800 rows) in one lanes object on the
   GPU (``gearsim.study.tiles.simulate_rows_batched``, the tile's own path, as rule
   simulate_tiles_together runs it: chains, the period test's verdict inside the launch, the
   classification on the host, the Floquet lanes; the launches counted); the first ``K`` cells
   of every row where the whole rows would not fit the stage's budget (a first pass of 16 cells
   sizes ``K``; a chain's first ``K`` cells do not depend on the rest), projected to 400. The CPU
   path on a sample of whole rows on every core (processes): cells per second on 1 core and
   on all, the labels compared on the cells both ran.
6. ``coexistence``: every cell's coexisting attractors, 16 starts per cell (the finder,
   :func:`gearsim.analysis.attractors.find_attractors`, its probing pool as wide as the GPU
   holds, :meth:`gearsim.numerics.backend.CudaLanes.pool_lanes`, or ``--gpu-lanes``)
   on the GPU in chunks of cells until the stage's budget, projected to both planes' 320 000
   cells; the CPU finder on a sample of at least 100 000 starts on every core; each cell's
   attractor labels compared on the cells both ran.
7. ``summary``: both planes and every cell's coexistence on the GPU (measured or projected)
   against the same on the host's cores, and the ratios the issue's targets name.

Run on the device machine (its image has numba, numba-cuda, numpy, scipy, pandas, pyarrow,
pyyaml; the configuration's schema check needs jsonschema, carried as wheels). Here, once::

    echo /.whl/ >> .git/info/exclude
    python3 -m pip download --no-deps --only-binary=:all: --python-version 3.12 \\
      --implementation cp --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 \\
      -d .whl jsonschema==4.26.0 jsonschema-specifications==2025.9.1 referencing==0.37.0 \\
      rpds-py==2026.9.1

then the device tool's ``run`` (``carry: [".whl"]``, ``timeout_s: 600``)::

    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \\
      --target /tmp/site .whl/*.whl && export PYTHONPATH=/tmp/site:src \\
      NUMBA_CACHE_DIR=/tmp/nbcache PYTHONUNBUFFERED=1 && \\
      python3 benchmarks/bench_gpu.py --out $OUT

Without a GPU, the whole script runs end to end under Numba's CUDA simulator at toy sizes::

    NUMBA_ENABLE_CUDASIM=1 python benchmarks/bench_gpu.py --smoke --out /tmp/gpu-smoke
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from _common import machine, setup_env

setup_env()

import numpy as np  # noqa: E402
from _bench_gpu_study import (  # noqa: E402
    Report,
    _cores,
    _settings,
    _start_lanes,
    _study,
    stage_coexistence,
    stage_planes,
)

ROOT = Path(__file__).resolve().parents[1]


# ============================================================================ stages
def stage_env(args) -> dict:
    from gearsim.numerics.backend import select

    rec = {"device": select("cuda").record(), "host": machine(), "cores": _cores()}
    from numba import cuda

    d = cuda.get_current_device()
    rec["compute_capability"] = list(getattr(d, "compute_capability", ()))
    try:
        free, total = cuda.current_context().get_memory_info()
        rec["gpu_memory_free_total_gib"] = [round(free / 2**30, 1), round(total / 2**30, 1)]
    except Exception as exc:  # the simulator has no memory info
        rec["gpu_memory"] = str(exc)[:100]
    return rec


_COMPILE = """
import time, numpy as np
t0 = time.perf_counter()
from gearsim.numerics.backend import select
gpu = select("cuda")
from gearsim.dynamics.parameters import ModelParameters
from gearsim.dynamics.model import static_state
from gearsim.numerics.batch import Lanes, steps_per_period
from gearsim.numerics.settings import IntegrationSettings
st = IntegrationSettings(method="rk4")
p = ModelParameters(w=1.0, b=0.3)
N = steps_per_period(p, st)
lanes = Lanes(8, 1, gpu)
lanes.begin_call()
for l in range(8):
    lanes.load_params(l, p, N); lanes.load_state(l, static_state(p.to_array())); lanes.status[l] = 0
t1 = time.perf_counter()
lanes.run(N, 1, 0.0, 1e6, True)
print("LAUNCH", time.perf_counter() - t1, t1 - t0)
"""


def stage_compile(args) -> dict:
    cache = Path(args.out) / "nbcache-cold"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=os.pathsep.join(
        [str(ROOT / "src")] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    out = {}
    for name in ("cold", "warm"):
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-c", _COMPILE], env=env, capture_output=True,
                              text=True, timeout=300)
        wall = time.perf_counter() - t0
        line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("LAUNCH")), "")
        if proc.returncode != 0 or not line:
            raise RuntimeError(f"{name}: {proc.stderr.strip().splitlines()[-1:]}")
        first, imports = map(float, line.split()[1:])
        out[name] = {"first_launch_s": round(first, 3), "imports_s": round(imports, 3),
                     "process_s": round(wall, 3)}
    return out


def stage_kernel_cells(args) -> dict:
    sys.path.insert(0, str(ROOT / "tests"))
    from reference import reference_settings

    from gearsim.cell.simulate import initial_tangent, run_periods
    from gearsim.dynamics.model import static_state
    from gearsim.numerics.batch import O_LYAP, steps_per_period

    sys.path.insert(0, str(ROOT / "tests" / "unit"))
    from test_cuda_lanes import CELLS

    st = reference_settings(method="rk4")
    m = 2 if args.smoke else 40
    out = {"periods": m, "groups": []}
    for nu, cells in ((0.0, [c for c in CELLS if c.var_ratio == 0.0]),
                      (1.0, [c for c in CELLS if c.var_ratio != 0.0])):
        ys = np.array([np.concatenate([run_periods(p, static_state(p.to_array()), 60, st).state,
                                       initial_tangent(p)]) for p in cells])
        N = steps_per_period(cells[0], st)
        runs = {}
        for dev in ("cpu", "cuda"):
            lanes = _start_lanes(dev, cells, ys, m, N)
            t0 = time.perf_counter()
            lanes.run(N, m, nu, 1.0e6, True)
            runs[dev] = (lanes, time.perf_counter() - t0)
        a, b = runs["cpu"][0], runs["cuda"][0]
        out["groups"].append({
            "cells": len(cells), "cpu_s": round(runs["cpu"][1], 3),
            "gpu_s": round(runs["cuda"][1], 3),
            "max_diff_section": float(np.abs(a.sec - b.sec).max()),
            "max_diff_records": float(np.abs(a.fout[..., :O_LYAP] - b.fout[..., :O_LYAP]).max()),
            "max_diff_lyap": float(np.abs(a.fout[..., O_LYAP] - b.fout[..., O_LYAP]).max()),
            "max_diff_state": float(max(np.abs(a.state(l) - b.state(l)).max()
                                        for l in range(len(cells)))),
            "impacts_equal": bool((a.nface == b.nface).all() and (a.nback == b.nback).all()),
            "impacts": int(a.nface.sum() + a.nback.sum()),
            "status_equal": bool((a.ist == b.ist).all()),
        })  # fmt: skip
    return out


def _plane_lanes(n, seed=0):
    """``n`` cells of the (w, b) plane's ranges on one step grid, and their static states."""
    from gearsim.dynamics.model import static_state
    from gearsim.numerics.batch import steps_per_period

    study = _study()
    base = study.parameters(plane="wb").model
    rng = np.random.default_rng(seed)
    st = _settings()
    ws = rng.uniform(0.6, 2.5, n)  # one step grid: N = steps_per_period (no hmax raise)
    bs = rng.uniform(0.0, 1.0, n)
    proto = [base.with_(w=float(w), b=float(b)) for w, b in zip(ws[:64], bs[:64], strict=True)]
    N = steps_per_period(proto[0], st)
    return base, ws, bs, N, static_state


def stage_lane_steps(args) -> dict:
    from gearsim.cell.simulate import initial_tangent
    from gearsim.numerics import cuda_lanes
    from gearsim.numerics.steps import phase_tables

    sizes = (8, 24) if args.smoke else (400, 16_384, 131_072, 1_048_576)
    m = 1 if args.smoke else 4
    base, ws, bs, N, static_state = _plane_lanes(max(sizes))
    tabs = phase_tables(N, 0.0)
    y_of = {}

    def lanes_for(n, device):
        cells = [base.with_(w=float(ws[l]), b=float(bs[l])) for l in range(n)]
        ys = []
        for p in cells:
            key = (p.w, p.b)
            if key not in y_of:
                y_of[key] = np.concatenate([static_state(p.to_array()), initial_tangent(p)])
            ys.append(y_of[key])
        return _start_lanes(device, cells, ys, m, N)

    out = {"N": N, "periods": m, "gpu": []}
    for n in sizes:
        row = {"lanes": n}
        for events in (True, False):
            lanes = lanes_for(n, "cuda")
            t0 = time.perf_counter()
            kernel = cuda_lanes.advance_device(lanes.blk, lanes.ist, N, m, tabs, 0.0, 1.0e6,
                                               lanes.sec, lanes.nface, lanes.nback, lanes.fout,
                                               True, events)
            wall = time.perf_counter() - t0
            key = "events" if events else "free_events"
            row[key] = {"kernel_s": round(kernel, 4), "with_copies_s": round(wall, 4),
                        "lane_steps_per_s": n * m * N / kernel}
        row["event_share"] = 1.0 - row["free_events"]["kernel_s"] / row["events"]["kernel_s"]
        out["gpu"].append(row)
        Report.current.data["stages"]["lane_steps"] = dict(out, partial=True)
        Report.current.save()
    # the CPU kernel: one core, then every core (threads; Lanes.run releases the GIL)
    n1 = min(max(sizes), 64 if args.smoke else 4096)
    lanes = lanes_for(n1, "cpu")
    lanes.run(N, 1, 0.0, 1.0e6, True)  # compiled (or loaded) before timing
    lanes = lanes_for(n1, "cpu")
    t0 = time.perf_counter()
    lanes.run(N, m, 0.0, 1.0e6, True)
    one = n1 * m * N / (time.perf_counter() - t0)
    cores = _cores()
    parts = [lanes_for(n1, "cpu") for _ in range(cores)]
    t0 = time.perf_counter()
    with ThreadPoolExecutor(cores) as ex:
        list(ex.map(lambda L: L.run(N, m, 0.0, 1.0e6, True), parts))
    allc = cores * n1 * m * N / (time.perf_counter() - t0)
    out["cpu"] = {"lanes_per_core": n1, "cores": cores, "lane_steps_per_s_1core": one,
                  "lane_steps_per_s_all": allc}
    top = out["gpu"][-1]["events"]["lane_steps_per_s"]
    out["gpu_over_1core"] = top / one
    out["gpu_over_all_cores"] = top / allc
    return out


def stage_registers(args) -> dict:
    """The kernel compiled with a register limit per thread (ptxas: 255 registers and spills
    without one, at sm_90): occupancy against spills, at 131 k lanes."""
    from numba import cuda

    from gearsim.cell.simulate import initial_tangent
    from gearsim.numerics import cuda_lanes
    from gearsim.numerics.steps import phase_tables

    n = 24 if args.smoke else 131_072
    m = 1 if args.smoke else 4
    base, ws, bs, N, static_state = _plane_lanes(n)
    cells = [base.with_(w=float(ws[l]), b=float(bs[l])) for l in range(n)]
    ys = [np.concatenate([static_state(p.to_array()), initial_tangent(p)]) for p in cells]
    tabs = phase_tables(N, 0.0)
    out = {"lanes": n, "periods": m, "threads_per_block": cuda_lanes.THREADS, "limits": []}
    for limit in (None, 168, 128, 96, 64):
        # (the simulator's jit takes no register limit: there every row runs the one kernel)
        kw = {} if cuda_lanes.SIMULATED else {"max_registers": limit}
        kernel = cuda_lanes.advance_kernel if limit is None else \
            cuda.jit(**kw)(cuda_lanes.advance_kernel.py_func)
        row = {"max_registers": limit}
        for rep in ("first", "second"):  # the first launch compiles
            lanes = _start_lanes("cuda", cells, ys, m, N)
            t = cuda_lanes.advance_device(lanes.blk, lanes.ist, N, m, tabs, 0.0, 1.0e6,
                                          lanes.sec, lanes.nface, lanes.nback, lanes.fout, True,
                                          True, kernel)
            row[f"{rep}_kernel_s"] = round(t, 4)
        row["lane_steps_per_s"] = n * m * N / row["second_kernel_s"]
        out["limits"].append(row)
        Report.current.data["stages"]["registers"] = dict(out, partial=True)
        Report.current.save()
    return out


def stage_summary(args) -> dict:
    s = Report.current.data["stages"]
    pl, co = s.get("planes", {}), s.get("coexistence", {})
    out = {}
    if pl.get("ok") and co.get("ok"):
        gpu = pl["gpu"]["projected_full_s"] + co["gpu"]["projected_full_s"]
        cpu = pl["cpu"]["projected_full_s_all"] + co["cpu"]["projected_full_s_all"]
        out = {
            "gpu_both_planes_and_coexistence_s": gpu,
            "cpu_all_cores_same_s": cpu,
            "target_gpu_at_most_s": 180,
            "finder_gpu_over_1core": co["gpu_over_1core"], "target_finder": 30,
            "plane_gpu_over_1core": pl["gpu_over_1core"], "target_plane": 20,
            "labels_equal_plane": pl["labels"]["equal_share"],
            "labels_equal_coexistence": co["labels"]["equal_share"], "target_labels": 0.999,
        }  # fmt: skip
    c = s.get("compile", {})
    if c.get("ok"):
        out["compile_cold_s"] = c["cold"]["first_launch_s"]
        out["compile_warm_s"] = c["warm"]["first_launch_s"]
        out["target_compile_cold_s"] = 90
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=os.environ.get("OUT", str(ROOT / "benchmarks/results")),
                    help="folder of gpu.json (default: $OUT, else benchmarks/results)")
    ap.add_argument("--smoke", action="store_true",
                    help="toy sizes (the simulator: NUMBA_ENABLE_CUDASIM=1)")
    ap.add_argument("--plane-budget", type=float, default=120.0,
                    help="seconds for the planes' GPU pass (default 120)")
    ap.add_argument("--finder-budget", type=float, default=150.0,
                    help="seconds for the coexistence's GPU chunks (default 150)")
    ap.add_argument("--finder-cells", type=int, default=8_000,
                    help="cells per GPU finder chunk (16 starts each; default 8000)")
    ap.add_argument("--gpu-lanes", type=int, default=0,
                    help="lanes of the finder's probing pool on the GPU (default 0: the "
                    "device's, multiprocessors x 1024, an H200's 135 168)")
    ap.add_argument("--cpu-finder-cells", type=int, default=6_250,
                    help="cells of the CPU finder's sample (default 6250: 100 000 starts)")
    ap.add_argument("--skip", nargs="*", default=[], help="stages to leave out")
    args = ap.parse_args()
    if args.smoke:
        os.environ["GEARSIM_BENCH_SMOKE"] = "1"
    rep = Report(Path(args.out))
    Report.current = rep
    rep.data["args"] = vars(args)
    for name, fn in (("env", stage_env), ("compile", stage_compile),
                     ("kernel_cells", stage_kernel_cells), ("lane_steps", stage_lane_steps),
                     ("registers", stage_registers), ("planes", stage_planes),
                     ("coexistence", stage_coexistence), ("summary", stage_summary)):
        if name not in args.skip:
            rep.stage(name, fn, args)
    rep.data["finished"] = time.time()
    rep.save()


if __name__ == "__main__":
    main()
