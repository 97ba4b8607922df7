"""(d) One vs two dask workers on one tile; (f) peak memory per worker.

A tile of the default (w, b) plane (config/config.yaml, tile_rows raised to 16 so that two
workers each get a full 8-lane block; every ``stride``-th w centre) is simulated on a
LocalCluster (gearsim.study.cluster.open_client: processes, one thread each) with 1 and with 2
workers:

* ``batched``: the rows are split into groups of 8; one task per group runs
  :func:`gearsim.cell.chains.simulate_rows` (what the pipeline should do, see README);
* ``scalar``: the pipeline's current task, :func:`gearsim.study.tiles.simulate_row` per row
  (continuation_chain with DP5), on fewer cells (it is ~25x slower).

Wall time of the map (cluster start-up excluded), speed-up 1 -> 2 workers, and the peak resident
memory (ru_maxrss) of every worker process after its tasks.

Usage: python benchmarks/bench_dask.py [--quick]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

from _common import loadavg, save, setup_env

setup_env()

ROOT = Path(__file__).resolve().parents[1]


def rows_task(specs):
    """One dask task: a group of plane rows through the batched path."""
    import resource
    import time as _t

    from gearsim.cell import chains

    t0 = _t.process_time()
    rows = []
    for spec in specs:
        rows.append(spec.cells())
    st = specs[0].settings
    res = chains.simulate_rows(rows, settings=st)
    labels = [c.classification.label for r in res for c in r]
    from distributed import get_worker

    return {
        "cells": len(labels),
        "cpu_s": _t.process_time() - t0,
        "labels": labels,
        "worker": get_worker().address,
        "maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def scalar_task(spec):
    import resource
    import time as _t

    from gearsim.study.tiles import simulate_row

    t0 = _t.process_time()
    recs = simulate_row(spec)
    from distributed import get_worker

    return {
        "cells": len(recs),
        "cpu_s": _t.process_time() - t0,
        "worker": get_worker().address,
        "labels": [r["label"] for r in recs],
        "maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def warm(_):
    from gearsim.cell import chains
    from gearsim.cell.simulate import simulate_cell
    from gearsim.dynamics.parameters import ModelParameters

    chains.simulate_cells([ModelParameters(w=1.0)])
    simulate_cell(ModelParameters(w=1.0))
    return 0


def run(n_workers, fn, items):
    from distributed import wait

    from gearsim.study.cluster import open_client

    with open_client(workers=n_workers) as client:
        client.wait_for_workers(n_workers)
        client.gather(client.map(warm, range(n_workers * 2), pure=False))
        t = time.perf_counter()
        futs = client.map(fn, items, pure=False)
        wait(futs)
        wall = time.perf_counter() - t
        res = client.gather(futs)
        rss = client.run(
            lambda: (
                __import__("resource").getrusage(__import__("resource").RUSAGE_SELF).ru_maxrss
                / 1024
            )
        )
    return wall, res, rss


def cpu_speedup(res):
    """Work / critical path in CPU time: the 2-worker speed-up on an otherwise idle machine."""
    per = {}
    for r in res:
        per[r["worker"]] = per.get(r["worker"], 0.0) + r["cpu_s"]
    return sum(per.values()) / max(per.values())


def specs_for(config, stride, rows):
    from gearsim.study import tiles
    from gearsim.study.config import Study

    cfg = dict(config)
    cfg["tile_rows"] = rows
    # rows 10*rows ... (b around 0.4 for 16 rows)
    specs = tiles.row_specs(Study.of(cfg, ROOT), "wb", 10)
    return [dataclasses.replace(s, x_values=s.x_values[::stride]) for s in specs]


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    from gearsim.study.config import load_config

    config = load_config([ROOT / "config" / "config.yaml"], root=ROOT)
    out = {"plane": "wb", "tile_rows": 16, "results": {}}
    # batched: 16 rows as two groups of 8
    stride = 4 if args.quick else 2
    specs = specs_for(config, stride, 16)
    groups = [specs[:8], specs[8:]]
    out["batched_cells"] = sum(len(s.x_values) for s in specs)
    for nw in (1, 2):
        wall, res, rss = run(nw, rows_task, groups)
        cpu = sum(r["cpu_s"] for r in res)
        out["results"][f"batched_{nw}"] = {
            "wall_s": wall,
            "task_cpu_s": cpu,
            "cpu_speedup": cpu_speedup(res),
            "worker_maxrss_mb": rss,
            "load": loadavg(),
            "ms_per_cell_wall": wall / out["batched_cells"] * 1e3,
        }
        print(
            "batched",
            nw,
            "workers: wall",
            round(wall, 2),
            "s, task cpu",
            round(cpu, 2),
            "rss MB",
            {k[-5:]: round(v) for k, v in rss.items()},
            "load",
            loadavg(),
            flush=True,
        )
    r1, r2 = out["results"]["batched_1"], out["results"]["batched_2"]
    out["batched_speedup_2_over_1"] = r1["wall_s"] / r2["wall_s"]
    # scalar pipeline path
    sstride = 32 if args.quick else 16
    sspecs = specs_for(config, sstride, 16)
    out["scalar_cells"] = sum(len(s.x_values) for s in sspecs)
    for nw in (1, 2):
        wall, res, rss = run(nw, scalar_task, sspecs)
        cpu = sum(r["cpu_s"] for r in res)
        out["results"][f"scalar_{nw}"] = {
            "wall_s": wall,
            "task_cpu_s": cpu,
            "cpu_speedup": cpu_speedup(res),
            "worker_maxrss_mb": rss,
            "load": loadavg(),
            "ms_per_cell_wall": wall / out["scalar_cells"] * 1e3,
        }
        print(
            "scalar",
            nw,
            "workers: wall",
            round(wall, 2),
            "s, task cpu",
            round(cpu, 2),
            "rss MB",
            {k[-5:]: round(v) for k, v in rss.items()},
            "load",
            loadavg(),
            flush=True,
        )
    s1, s2 = out["results"]["scalar_1"], out["results"]["scalar_2"]
    out["scalar_speedup_2_over_1"] = s1["wall_s"] / s2["wall_s"]
    out["batched_cpu_speedup_2"] = out["results"]["batched_2"]["cpu_speedup"]
    out["scalar_cpu_speedup_2"] = out["results"]["scalar_2"]["cpu_speedup"]
    print(
        "speed-up 2/1 workers (wall): batched",
        round(out["batched_speedup_2_over_1"], 2),
        "scalar",
        round(out["scalar_speedup_2_over_1"], 2),
        "| work/critical path (cpu):",
        round(out["batched_cpu_speedup_2"], 2),
        round(out["scalar_cpu_speedup_2"], 2),
    )
    print(save("dask", out))


if __name__ == "__main__":
    sys.exit(main())
