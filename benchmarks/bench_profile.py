"""(i) Where the cycles go: per stage of a plane tile and of an attractor task, beside the kernel.

One run measures, side by side on the same machine state:

* **kernel** - ``kernel.advance`` alone on 24 lanes already on their motion (the bench_kernel
  set: w in [0.6, 2.4], b in {0.15, 0.3, 1.0}), with and without the tangent vector:
  cell-steps per CPU second;
* **simulate tile** - one worker's share of a default-config tile (``--rows`` plane rows of the
  ``--plane`` plane, every x cell, the batched driver ``tiles.simulate_rows_batched``), with the
  time inside the compiled kernel, the period test, the classification (``finish_cell``), the
  per-cell set-up (parameters, regions), the record building and the Parquet write measured
  separately; the rest is the driver loop. Lane use = lane-steps of lanes that took part /
  lane-steps the SIMD blocks computed (idle padding and frozen lanes are the difference);
* **attractor task** - one task of ``gearsim attractor-tile`` (64 cells x ``starts`` starts of
  the same rows) through the lane pool: the kernel, the chunk checks (certified ellipsoids,
  recurrence), the finished runs (classification, refinement), the forward motions'
  certificates, the neighbours' seeds and the assembly (nested calls: the kernel runs inside
  several of them).

Effective rate = cell-steps of the cells (their ``steps`` column: grid steps plus the event
layer's trial steps) / CPU seconds of the whole stage. The ratio effective / kernel says how near
the pipeline runs to the kernel's rate (the target is >= 0.8).

Usage: python benchmarks/bench_profile.py [--plane wb] [--j0 240] [--rows 24] [--name profile]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections import defaultdict
from contextlib import contextmanager

from _common import loadavg, save, setup_env

setup_env()

import numpy as np  # noqa: E402

from gearsim.analysis.attractors import pool as apool  # noqa: E402
from gearsim.cell import chain, chains, simulate  # noqa: E402
from gearsim.dynamics.parameters import ModelParameters  # noqa: E402
from gearsim.numerics import batch, lanes_layout  # noqa: E402
from gearsim.numerics import kernel as kernel_module  # noqa: E402
from gearsim.results import catalogue  # noqa: E402
from gearsim.study import tiles  # noqa: E402
from gearsim.study.config import Study, study_config  # noqa: E402

T_CPU: dict[str, float] = defaultdict(float)
CALLS: dict[str, int] = defaultdict(int)
LANE: dict[str, int] = defaultdict(int)  # per stage: lane-steps computed / of taking part
TANGENT: dict[str, int] = defaultdict(int)  # lane-steps with the tangent vector
STAGE = ["-"]


@contextmanager
def stage(name):
    STAGE.append(name)
    try:
        yield
    finally:
        STAGE.pop()


def timed(name, fn, *, per_stage=False):
    def wrapper(*a, **k):
        key = f"{STAGE[-1]}:{name}" if per_stage else name
        c0 = time.process_time()
        try:
            return fn(*a, **k)
        finally:
            T_CPU[key] += time.process_time() - c0
            CALLS[key] += 1

    return wrapper


def instrument() -> None:
    adv = kernel_module.advance

    def kernel(blk, ist, N, m, *rest):
        act = int(np.sum(ist[lanes_layout.IST_ST] == 0))
        LANE[f"{STAGE[-1]}:computed"] += (ist.shape[1] // batch.LANES) * batch.LANES * N * m
        LANE[f"{STAGE[-1]}:useful"] += act * N * m
        if rest[-1]:
            TANGENT[STAGE[-1]] += act * N * m
        return adv(blk, ist, N, m, *rest)

    kernel_module.advance = timed("kernel", kernel, per_stage=True)
    simulate.estimate_period = timed("period test", simulate.estimate_period, per_stage=True)
    chain.finish_cell = timed("classification (finish_cell)", chain.finish_cell,
                             per_stage=True)  # fmt: skip
    chain.begin_cell = timed("cell set-up (params, regions)", chain.begin_cell,
                            per_stage=True)  # fmt: skip
    tiles.cell_records = timed("records", tiles.cell_records)
    # the attractor task's stages: the pool's chunk checks and finished runs, the forward
    # motions' certificates before the pool, the neighbours' seeds, the final assembly
    P = apool._Judge
    P.probed = timed("chunk checks (certified, recurrence)", P.probed)
    P.finished = timed("finished runs (classification, refinement)", P.finished)
    apool._precertify = timed("forward motions' certificates", apool._precertify)
    apool.continue_orbits = timed("neighbours' seeds (Newton)", apool.continue_orbits)
    apool.assemble = timed("assembly (merge)", apool.assemble)


def use(st):
    return LANE[f"{st}:useful"] / max(LANE[f"{st}:computed"], 1)


def kernel_rate(tangent: bool, periods: int = 20, repeats: int = 3) -> float:
    """Cell-steps per CPU second of kernel.advance on 24 lanes (bench_kernel's cells)."""
    ws = np.linspace(0.6, 2.4, 24)
    cs = [ModelParameters(w=float(w), b=(0.15, 0.3, 1.0)[i % 3]) for i, w in enumerate(ws)]
    st = simulate.IntegrationSettings(method="rk4")
    y0 = []
    for p in cs:
        r = simulate.run_periods(p, simulate.static_state(p.to_array()), 100, st)
        y0.append(np.concatenate([r.state, simulate.initial_tangent(p)]))
    best = []
    for _ in range(repeats):
        lanes = batch.Lanes(len(cs), periods)
        for l, p in enumerate(cs):
            lanes.load_params(l, p, 256)
            lanes.load_state(l, y0[l])
            lanes.ist[lanes_layout.IST_ST, l] = 0
            lanes.ist[lanes_layout.IST_POS, l] = 0
            lanes.ist[lanes_layout.IST_K, l] = 100
        c0 = time.process_time()
        lanes.run(256, periods, 0.0, 1e6, tangent)
        best.append(time.process_time() - c0)
    return len(cs) * periods * 256 / float(np.median(best))


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--plane", default="wb")
    ap.add_argument("--j0", type=int, default=240, help="first plane row (a multiple of --rows)")
    ap.add_argument("--rows", type=int, default=24, help="rows (one worker's lanes)")
    ap.add_argument("--cells", type=int, default=64, help="cells of the attractor task")
    ap.add_argument("--name", default="profile")
    args = ap.parse_args(argv)
    config = study_config([])
    config["tile_rows"] = args.rows  # one worker's share as a tile
    args.tile = args.j0 // args.rows
    chains.warm_up()
    out = {"plane": args.plane, "tile": args.tile, "rows": args.rows, "load_start": loadavg()}
    k_state, k_tan = kernel_rate(False), kernel_rate(True)
    out["kernel_state_per_s"], out["kernel_tangent_per_s"] = k_state, k_tan
    print(f"kernel (24 lanes, CPU): {k_state / 1e6:.2f} M cell-steps/s without tangent, "
          f"{k_tan / 1e6:.2f} with  load {loadavg()}", flush=True)  # fmt: skip
    instrument()

    # ---- simulate tile: one worker's group of rows
    specs = tiles.row_specs(Study.of(config), args.plane, args.tile)[: args.rows]
    c0, w0 = time.process_time(), time.perf_counter()
    with stage("tile"):
        recs = tiles.simulate_rows_batched(specs)
    c1 = time.process_time()
    df = tiles.records_to_frame(recs)
    t_frame = time.process_time() - c1
    c1 = time.process_time()
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as d:
        catalogue.write_parquet(df, Path(d) / "t.parquet", {catalogue.PROVENANCE_KEY: {}})
    t_parquet = time.process_time() - c1
    cpu = time.process_time() - c0
    wall = time.perf_counter() - w0
    steps = int(df["steps"].sum())
    tile = {
        "cells": len(df), "cpu_s": cpu, "wall_s": wall, "cell_steps": steps,
        "effective_per_s": steps / cpu, "lane_use": use("tile"),
        "tangent_share": TANGENT["tile"] / max(LANE["tile:useful"], 1),
        "stages_cpu_s": {k.split(":", 1)[1]: v for k, v in T_CPU.items() if k.startswith("tile:")},
        "calls": {k.split(":", 1)[1]: v for k, v in CALLS.items() if k.startswith("tile:")},
    }  # fmt: skip
    tile["stages_cpu_s"]["records"] = T_CPU.pop("records", 0.0)
    tile["stages_cpu_s"]["frame (records_to_frame)"] = t_frame
    tile["stages_cpu_s"]["Parquet write"] = t_parquet
    known = sum(tile["stages_cpu_s"].values())
    tile["stages_cpu_s"]["driver loop (rest)"] = cpu - known
    out["tile"] = tile
    # the kernel's rate for the same mix of tangent / state-only lane-steps (time-weighted)
    ts = tile["tangent_share"]
    k_mix = 1.0 / (ts / k_tan + (1.0 - ts) / k_state)
    tile["kernel_mix_per_s"] = k_mix
    tile["effective_over_kernel_mix"] = steps / cpu / k_mix
    print(f"\nsimulate tile {args.plane}/{args.tile}, {args.rows} rows, {len(df)} cells: "
          f"{cpu:.2f} s CPU ({wall:.2f} wall), {steps / 1e6:.1f} M cell-steps")
    print(f"  effective {steps / cpu / 1e6:.2f} M/s; kernel at the same tangent share ({ts:.2f}) "
          f"{k_mix / 1e6:.2f} M/s; ratio {steps / cpu / k_mix:.2f}; lane use "
          f"{tile['lane_use']:.3f}")
    for k, v in sorted(tile["stages_cpu_s"].items(), key=lambda kv: -kv[1]):
        print(f"  {k:34s} {v:8.3f} s  {100 * v / cpu:5.1f} %")

    # ---- attractor task: the first task of the tile whose rows were simulated above
    from scipy.stats import qmc  # noqa: F401  (the Sobol starts' import, ~0.5 s once per worker)

    from gearsim.study.attractor_tiles import cell_group_records, task_specs

    T_CPU.clear()
    CALLS.clear()
    LANE.clear()
    TANGENT.clear()
    spec = task_specs(Study.of(config), args.plane, args.tile, df)[0]
    spec = dataclasses.replace(spec, cells=spec.cells[: args.cells],
                               forward_rows=spec.forward_rows[: args.cells])
    c0, w0 = time.process_time(), time.perf_counter()
    with stage("attr"):
        recs = cell_group_records(spec)
    cpu = time.process_time() - c0
    periods = int(sum({(r["i"], r["j"]): r["periods_run"] for r in recs}.values()))
    # the stages nest (the kernel runs inside the certificates and the seeds too): each line is
    # the CPU inside that call, the kernel line all kernel time of the task
    g = {("kernel (all of it)" if k == "attr:kernel" else k.split(":", 1)[-1]): v
         for k, v in T_CPU.items()}
    att = {
        "cells": len(spec.cells), "starts": spec.starts, "cpu_s": cpu,
        "wall_s": time.perf_counter() - w0, "periods_run": periods,
        "lane_use": use("attr"), "stages_cpu_s": g,
        "tangent_share": TANGENT["attr"] / max(LANE["attr:useful"], 1),
    }  # fmt: skip
    out["attractor_task"] = att
    out["load_end"] = loadavg()
    print(f"\nattractor task: {att['cells']} cells x {att['starts']} starts: {cpu:.2f} s CPU, "
          f"{periods} start-periods ({1e3 * cpu / max(periods, 1):.3f} ms CPU per "
          f"start-period)\n  lane use {att['lane_use']}\n  tangent share "
          f"{att['tangent_share']}")
    for k, v in sorted(att["stages_cpu_s"].items(), key=lambda kv: -kv[1]):
        print(f"  {k:52s} {v:8.3f} s  {100 * v / cpu:5.1f} %")
    print(f"load {loadavg()}")
    print(save(args.name, out))


if __name__ == "__main__":
    sys.exit(main())
