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
   core (threads: the kernel releases the GIL) on the same kind of lanes.
5. ``planes``: both 400 x 400 planes' continuation chains (800 rows) in one lanes object on the
   GPU (``gearsim.study.tiles.simulate_rows_batched``, the tile's own path: chains, the period
   test, the classification on the host, the Floquet lanes); the first ``K`` cells of every
   row where the whole rows would not fit the stage's budget (a first pass of 16 cells sizes
   ``K``; a chain's first ``K`` cells do not depend on the rest), projected to 400. The CPU
   path on a sample of whole rows on every core (processes): cells per second on 1 core and
   on all, the labels compared on the cells both ran.
6. ``coexistence``: every cell's coexisting attractors, 16 starts per cell (the finder,
   :func:`gearsim.analysis.attractors.find_attractors`, its probing pool ``--gpu-lanes`` wide)
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
import functools
import json
import multiprocessing
import os
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from pathlib import Path

from _common import loadavg, machine, setup_env

setup_env()

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


# ============================================================================ helpers
class Report:
    """The JSON record, rewritten (atomically) after every stage."""

    current: Report  # the run's record (stages save their partial results into it)

    def __init__(self, out: Path):
        self.path = out / "gpu.json"
        out.mkdir(parents=True, exist_ok=True)
        self.data: dict = {"stages": {}, "started": time.time()}

    def stage(self, name: str, fn, *args):
        t0 = time.perf_counter()
        print(f"[bench_gpu] {name} ...", flush=True)
        try:
            rec = fn(*args)
            rec["ok"] = True
        except Exception as exc:  # a stage that fails is recorded, the next ones still run
            rec = {"ok": False, "error": f"{type(exc).__name__}: {str(exc)[:500]}"}
        rec["wall_s"] = round(time.perf_counter() - t0, 3)
        rec["load"] = loadavg()
        self.data["stages"][name] = rec
        self.save()
        print(f"[bench_gpu] {name}: {json.dumps(rec)[:600]}", flush=True)
        return rec

    def save(self) -> None:
        tmp = self.path.with_suffix(".tmp")
        tmp.write_text(json.dumps(self.data, indent=1, default=str))
        os.replace(tmp, self.path)


@functools.cache
def _study():
    from gearsim.study.config import Study

    return Study.load([])


#: ``--smoke``: short runs (the simulator steps every lane in Python); inherited by the workers
SMOKE = {"steps_per_period": 32, "hmax": 1.0, "transient": 4, "transient_continuation": 4,
         "chunk": 4, "max_periods": 8, "tangent_lead": 2}


def _settings():
    """The study's integration settings (``--smoke``: :data:`SMOKE` over them)."""
    from gearsim.numerics.settings import IntegrationSettings

    st = _study().settings
    if os.environ.get("GEARSIM_BENCH_SMOKE") == "1":
        st = IntegrationSettings(**{**st.to_dict(), **SMOKE})
    return st


def _cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()


def _start_lanes(device, cells, ys, periods, N):
    from gearsim.numerics.batch import Lanes

    lanes = Lanes(len(cells), periods, device=device)
    lanes.begin_call()
    for l, p in enumerate(cells):
        lanes.load_params(l, p, N)
        lanes.load_state(l, ys[l])
        lanes.status[l] = 0
        lanes.position[l] = 0
    return lanes


# ============================================================================ stages
def stage_env(args) -> dict:
    from gearsim.numerics import device

    dev = device.select("cuda")
    rec = {"device": dev.record(), "host": machine(), "cores": _cores()}
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
from gearsim.numerics import device
device.select("cuda")
from gearsim.dynamics.parameters import ModelParameters
from gearsim.dynamics.model import static_state
from gearsim.numerics.batch import Lanes, steps_per_period
from gearsim.numerics.settings import IntegrationSettings
st = IntegrationSettings(method="rk4")
p = ModelParameters(w=1.0, b=0.3)
N = steps_per_period(p, st)
lanes = Lanes(8, 1, device="cuda")
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


# ---- planes
def _plane_specs(cols: int | None, rows_per_plane: int | None = None):
    from gearsim.study.grid import tile_ids
    from gearsim.study.tiles import row_specs

    study = _study()
    specs = []
    for plane in ("wb", "wxi"):
        for t in tile_ids(study.config, plane):
            specs += row_specs(study, plane, t)
    if rows_per_plane is not None:
        keep = []
        for plane in ("wb", "wxi"):
            ps = [s for s in specs if s["plane"] == plane]
            step = max(1, len(ps) // rows_per_plane)
            keep += ps[::step][:rows_per_plane]
        specs = keep
    if cols is not None:
        specs = [dict(s, x_values=s["x_values"][:cols]) for s in specs]
    settings = _settings().to_dict()
    return [dict(s, settings=settings) for s in specs]


def _cpu_rows(specs):
    """A CPU worker: a group of plane rows on the CPU path; its records and CPU seconds."""
    from gearsim.numerics import device

    device.select("cpu")
    from gearsim.study.tiles import simulate_rows_batched

    t0 = time.process_time()
    recs = simulate_rows_batched(specs)
    return [_plane_key(r) for r in recs], time.process_time() - t0


def _plane_key(r):
    return (r["plane"], int(r["j"]), int(r["i"]), str(r.get("motion")), str(r.get("label")))


def _scale_plane(args, specs):
    if args.smoke:
        return [dict(s, x_values=s["x_values"][:3]) for s in specs[:: max(1, len(specs) // 4)]]
    return specs


def stage_planes(args) -> dict:
    from gearsim.numerics import device
    from gearsim.study.tiles import row_groups, simulate_rows_batched

    device.select("cuda")
    full = _scale_plane(args, _plane_specs(None))
    nx = len(full[0]["x_values"])
    cells_full = nx * len(full)
    out = {"rows": len(full), "cells_full": cells_full}
    # a first pass of a few cells a row sizes the pass that fits the budget
    k0 = min(nx, 2 if args.smoke else 16)
    t0 = time.perf_counter()
    simulate_rows_batched([dict(s, x_values=s["x_values"][:k0]) for s in full])
    t_first = time.perf_counter() - t0
    per_col = t_first / k0
    k = int(min(nx, max(k0, args.plane_budget / max(per_col, 1e-9))))
    out["first_pass"] = {"cols": k0, "wall_s": round(t_first, 3)}
    t0 = time.perf_counter()
    recs = simulate_rows_batched([dict(s, x_values=s["x_values"][:k]) for s in full])
    wall = time.perf_counter() - t0
    gpu = {_plane_key(r)[:3]: _plane_key(r)[3:] for r in recs}
    out["gpu"] = {"cols": k, "cells": len(recs), "wall_s": round(wall, 3),
                  "cells_per_s": len(recs) / wall,
                  "projected_full_s": round(wall * nx / k, 1)}  # fmt: skip
    Report.current.data["stages"]["planes"] = dict(out, partial=True)
    Report.current.save()
    # the CPU path: a sample of whole rows on every core
    cores = _cores()
    rows = 4 if args.smoke else max(8 * cores, 64)  # 8-row SIMD groups, one per core
    sample = _scale_plane(args, _plane_specs(None, rows_per_plane=rows // 2))
    groups = row_groups(sample, cores)
    ctx = multiprocessing.get_context("spawn")
    _cpu_rows(groups[0][:1] if not args.smoke else [sample[0]])  # compile before the pool
    t0 = time.perf_counter()
    with ProcessPoolExecutor(cores, mp_context=ctx) as ex:
        res = list(ex.map(_cpu_rows, groups))
    wall = time.perf_counter() - t0
    keys = [k for r, _ in res for k in r]
    cpu_s = sum(c for _, c in res)
    out["cpu"] = {"cells": len(keys), "cores": cores, "wall_s": round(wall, 3),
                  "cells_per_s_all": len(keys) / wall, "cells_per_s_1core": len(keys) / cpu_s,
                  "projected_full_s_all": round(cells_full / (len(keys) / wall), 1)}
    same = diff = 0
    differing = []
    for kk in keys:
        g = gpu.get(kk[:3])
        if g is None:
            continue
        if g == kk[3:]:
            same += 1
        else:
            diff += 1
            differing.append([*kk[:3], list(kk[3:]), list(g)])
    out["labels"] = {"compared": same + diff, "equal": same,
                     "equal_share": same / max(1, same + diff), "differing": differing[:200]}
    out["gpu_over_1core"] = out["gpu"]["cells_per_s"] / out["cpu"]["cells_per_s_1core"]
    return out


# ---- coexistence
SPREAD = 97  # the finder's cell order: every 97th cell of both planes, then the next offset


def _cell_order():
    """Every cell of both planes as ``(plane, j, i)``, spread: a prefix samples all rows."""
    study = _study()
    keys = [(plane, j, i) for plane in ("wb", "wxi")
            for j in range(int(study.config["planes"][plane]["y"]["n"]))
            for i in range(int(study.config["planes"][plane]["x"]["n"]))]
    return [k for off in range(SPREAD) for k in keys[off::SPREAD]]


def _cell_params(keys):
    """``(plane, j, i, parameters dict)`` of the cells ``keys``."""
    from gearsim.study.grid import axis_values

    study = _study()
    planes = {}
    for plane in {k[0] for k in keys}:
        pl = study.config["planes"][plane]
        planes[plane] = (study.parameters(plane=plane).model, pl["x"]["name"],
                         axis_values(pl["x"]), pl["y"]["name"], axis_values(pl["y"]))
    out = []
    for plane, j, i in keys:
        base, xn, xs, yn, ys = planes[plane]
        out.append((plane, j, i, base.with_(**{xn: float(xs[i]), yn: float(ys[j])}).to_dict()))
    return out


def _find(cells, lanes: int, device_kind: str):
    from gearsim.numerics import device

    device.select(device_kind)
    from gearsim.analysis.attractors.api import find_attractors
    from gearsim.analysis.attractors.options import FinderOptions
    from gearsim.dynamics.parameters import ModelParameters

    st = _settings()
    plist = [ModelParameters.from_mapping(c[3]) for c in cells]
    t0 = time.process_time()
    found = find_attractors(plist, FinderOptions(starts=16, seed=0, lanes=lanes), settings=st)
    labels = {tuple(c[:3]): sorted(str(a.steady.label) for a in ca.attractors)
              for c, ca in zip(cells, found, strict=True)}
    return labels, time.process_time() - t0


def _cpu_find(cells):
    return _find(cells, 256, "cpu")


def stage_coexistence(args) -> dict:
    order = _cell_order()
    total = len(order)
    chunk = 4 if args.smoke else args.finder_cells
    out = {"cells_full": total, "starts_per_cell": 16, "chunks": []}
    gpu_labels: dict = {}
    t_all = 0.0
    for k in range(0, total, chunk):
        cells = _cell_params(order[k : k + chunk])
        t0 = time.perf_counter()
        labels, _ = _find(cells, 4 if args.smoke else args.gpu_lanes, "cuda")
        wall = time.perf_counter() - t0
        t_all += wall
        gpu_labels.update(labels)
        out["chunks"].append({"cells": len(cells), "wall_s": round(wall, 2),
                              "starts_per_s": 16 * len(cells) / wall})
        out["gpu"] = {"cells": len(gpu_labels), "wall_s": round(t_all, 2),
                      "starts_per_s": 16 * len(gpu_labels) / t_all,
                      "projected_full_s": round(t_all * total / len(gpu_labels), 1)}
        Report.current.data["stages"]["coexistence"] = dict(out, partial=True)
        Report.current.save()
        if args.smoke or t_all + wall > args.finder_budget:
            break
    # the CPU finder: a sample (>= 100 000 starts) of the cells the GPU ran, every core
    cores = _cores()
    n_cpu = len(gpu_labels) if args.smoke else min(len(gpu_labels), args.cpu_finder_cells)
    cells = _cell_params(order[:n_cpu])
    per = max(1, -(-len(cells) // (cores * 4)))
    groups = [cells[k : k + per] for k in range(0, len(cells), per)]
    ctx = multiprocessing.get_context("spawn")
    _cpu_find(cells[:1])  # compile before the pool
    t0 = time.perf_counter()
    with ProcessPoolExecutor(cores, mp_context=ctx) as ex:
        res = list(ex.map(_cpu_find, groups))
    wall = time.perf_counter() - t0
    cpu_labels = {k: v for r, _ in res for k, v in r.items()}
    cpu_s = sum(c for _, c in res)
    starts = 16 * len(cpu_labels)
    out["cpu"] = {"cells": len(cpu_labels), "starts": starts, "cores": cores,
                  "wall_s": round(wall, 2), "starts_per_s_all": starts / wall,
                  "starts_per_s_1core": starts / cpu_s,
                  "projected_full_s_all": round(16 * total / (starts / wall), 1)}
    differing = [[*k, cpu_labels[k], gpu_labels.get(k)] for k in cpu_labels
                 if gpu_labels.get(k) != cpu_labels[k]]
    same = len(cpu_labels) - len(differing)
    out["labels"] = {"compared": len(cpu_labels), "equal": same,
                     "equal_share": same / max(1, len(cpu_labels)),
                     "differing": differing[:200]}
    out["gpu_over_1core"] = out["gpu"]["starts_per_s"] / out["cpu"]["starts_per_s_1core"]
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
    ap.add_argument("--gpu-lanes", type=int, default=131_072,
                    help="lanes of the finder's probing pool on the GPU (default 131072)")
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
                     ("planes", stage_planes), ("coexistence", stage_coexistence),
                     ("summary", stage_summary)):
        if name not in args.skip:
            rep.stage(name, fn, args)
    rep.data["finished"] = time.time()
    rep.save()


if __name__ == "__main__":
    main()
