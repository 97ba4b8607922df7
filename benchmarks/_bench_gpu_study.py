"""The study stages of benchmarks/bench_gpu.py (both planes, every cell's coexistence) and the
helpers its stages share: the JSON record, the study, the settings, lanes of given cells."""

from __future__ import annotations

import dataclasses
import functools
import json
import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from _common import loadavg


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
    from gearsim.numerics.backend import select
    from gearsim.numerics.batch import Lanes

    lanes = Lanes(len(cells), periods, select(device))
    lanes.begin_call()
    for l, p in enumerate(cells):
        lanes.load_params(l, p, N)
        lanes.load_state(l, ys[l])
        lanes.status[l] = 0
        lanes.position[l] = 0
    return lanes


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
            ps = [s for s in specs if s.plane == plane]
            step = max(1, len(ps) // rows_per_plane)
            keep += ps[::step][:rows_per_plane]
        specs = keep
    if cols is not None:
        specs = [dataclasses.replace(s, x_values=s.x_values[:cols]) for s in specs]
    settings = _settings()
    return [dataclasses.replace(s, settings=settings) for s in specs]


def _count_launches() -> dict:
    """Count the GPU launches (and their kernel seconds) from now on."""
    from gearsim.numerics import cuda_lanes

    seen = {"n": 0, "kernel_s": 0.0}
    real = getattr(cuda_lanes.advance_device, "__wrapped__", cuda_lanes.advance_device)

    def counted(*a, **kw):
        t = real(*a, **kw)
        seen["n"] += 1
        seen["kernel_s"] += t
        return t

    counted.__wrapped__ = real
    cuda_lanes.advance_device = counted
    return seen


def _cpu_rows(specs):
    """A CPU worker: a group of plane rows on the CPU path; its records and CPU seconds."""
    from gearsim.study.tiles import simulate_rows_batched

    t0 = time.process_time()
    recs = simulate_rows_batched(specs)  # the CPU backend
    return [_plane_key(r) for r in recs], time.process_time() - t0


def _plane_key(r):
    return (r["plane"], int(r["j"]), int(r["i"]), str(r.get("motion")), str(r.get("label")))


def _scale_plane(args, specs):
    if args.smoke:
        return [dataclasses.replace(s, x_values=s.x_values[:3])
                for s in specs[:: max(1, len(specs) // 4)]]
    return specs


def stage_planes(args) -> dict:
    from gearsim.numerics.backend import select
    from gearsim.study.tiles import row_groups, simulate_rows_batched

    gpu = select("cuda")
    full = _scale_plane(args, _plane_specs(None))
    nx = len(full[0].x_values)
    cells_full = nx * len(full)
    out = {"rows": len(full), "cells_full": cells_full}
    # a first pass of a few cells a row sizes the pass that fits the budget
    k0 = min(nx, 2 if args.smoke else 16)
    t0 = time.perf_counter()
    simulate_rows_batched([dataclasses.replace(s, x_values=s.x_values[:k0]) for s in full],
                          backend=gpu)
    t_first = time.perf_counter() - t0
    per_col = t_first / k0
    k = int(min(nx, max(k0, args.plane_budget / max(per_col, 1e-9))))
    out["first_pass"] = {"cols": k0, "wall_s": round(t_first, 3)}
    launches = _count_launches()
    t0 = time.perf_counter()
    recs = simulate_rows_batched([dataclasses.replace(s, x_values=s.x_values[:k]) for s in full],
                                 backend=gpu)
    wall = time.perf_counter() - t0
    gpu = {_plane_key(r)[:3]: _plane_key(r)[3:] for r in recs}
    # both planes' chains in one lanes object, the period test's verdict inside the launch:
    # the host sees a chain at its phase changes only (launches), not every measuring chunk
    out["gpu"] = {"cols": k, "cells": len(recs), "wall_s": round(wall, 3),
                  "cells_per_s": len(recs) / wall, "launches": launches["n"],
                  "kernel_s": round(launches["kernel_s"], 3),
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
    from gearsim.analysis.attractors.api import find_attractors
    from gearsim.analysis.attractors.options import FinderOptions
    from gearsim.dynamics.parameters import ModelParameters

    st = _settings()
    plist = [ModelParameters.from_mapping(c[3]) for c in cells]
    t0 = time.process_time()
    from gearsim.numerics.backend import select

    found = find_attractors(plist, FinderOptions(starts=16, seed=0, lanes=lanes), settings=st,
                            backend=select(device_kind))
    labels = {tuple(c[:3]): sorted(str(a.steady.label) for a in ca.attractors)
              for c, ca in zip(cells, found, strict=True)}
    return labels, time.process_time() - t0


def _cpu_find(cells):
    return _find(cells, 256, "cpu")


def stage_coexistence(args) -> dict:
    order = _cell_order()
    total = len(order)
    chunk = 4 if args.smoke else args.finder_cells
    from gearsim.numerics.backend import select

    out = {"cells_full": total, "starts_per_cell": 16, "chunks": [],
           "pool_lanes": select("cuda").pool_lanes(4 if args.smoke else args.gpu_lanes or 256)}
    gpu_labels: dict = {}
    t_all = 0.0
    for k in range(0, total, chunk):
        cells = _cell_params(order[k : k + chunk])
        t0 = time.perf_counter()
        # the probing pool: --gpu-lanes, else the device's width (gearsim.numerics.backend.
        # CudaLanes.pool_lanes: multiprocessors x POOL_LANES_PER_SM)
        labels, _ = _find(cells, 4 if args.smoke else args.gpu_lanes or 256, "cuda")
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
