"""(j) Scaling with the plane size, and 1 vs 2 workers: the pipeline's own commands, timed.

For each size ``n`` a plane ``scale`` of ``n x n`` cells over the default (w, b) region
(w 0.1..2.5, b 0..1, config/config.yaml otherwise) is run with the pipeline's commands:
one ``gearsim simulate-tile`` process per tile (``tile_rows`` of the default config), one after
the other, then ``gearsim catalogue cells`` (the plane's cells.parquet). Each process runs under
``/usr/bin/time``: wall time, user + system CPU and the peak resident set size (``%M``, kB).
The size rows run the tiles in-process (``--no-cluster``, one core): ``/usr/bin/time`` does not
see the CPU of dask's worker processes (they are not its waited-for children), so only
in-process tiles give the whole CPU. The 1 vs 2 workers rows use ``--workers 1|2`` and
compare wall times (``--workers 1`` without a scheduler runs in-process, 2 starts a LocalCluster).

Reported per size: cells, wall, CPU, cells per CPU second, CPU per cell relative to the largest
size (1.00 = linear), the peak memory of a tile job and of the cells step. The tile job's
memory grows with the row length ``n`` (a tile holds ``tile_rows x n`` records), the cells step
with ``n^2`` (it holds the plane).

Usage: python benchmarks/bench_scaling.py [--sizes 100 200 400 800] [--workers 2]
       [--compare-workers 200] [--name scaling]
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import loadavg, save, setup_env

setup_env()

ROOT = Path(__file__).resolve().parents[1]


def timed(cmd: list[str]) -> dict:
    t = subprocess.run(["/usr/bin/time", "-f", "%e %U %S %M", *cmd], cwd=ROOT,
                       capture_output=True, text=True)  # fmt: skip
    if t.returncode != 0:
        raise SystemExit(f"failed: {' '.join(cmd)}\n{t.stderr[-2000:]}")
    wall, usr, sys_, rss = t.stderr.strip().splitlines()[-1].split()
    return {"wall_s": float(wall), "cpu_s": float(usr) + float(sys_), "rss_mb": int(rss) / 1024}


def run_plane(n: int, workers: int, tmp: Path, tile_rows: int) -> dict:
    """``workers`` 0: tiles in-process (``--no-cluster``)."""
    over = {
        "planes": {
            "scale": {
                "x": {"name": "w", "min": 0.1, "max": 2.5, "n": n},
                "y": {"name": "b", "min": 0.0, "max": 1.0, "n": n},
                "fixed": {},
            }
        }
    }
    cj = json.dumps(over)
    n_tiles = math.ceil(n / tile_rows)
    tiles, jobs = [], []
    load0 = loadavg()
    w0 = time.perf_counter()
    for t in range(n_tiles):
        out = tmp / f"n{n}_w{workers}_{t}.parquet"
        out.unlink(missing_ok=True)
        jobs.append(timed(["gearsim", "simulate-tile", "--plane", "scale", "--tile", str(t),
                           "--config-json", cj, "--out", str(out),
                           *(["--workers", str(workers)] if workers else ["--no-cluster"])]))
        tiles.append(str(out))
    cells_out = tmp / f"n{n}_w{workers}_cells.parquet"
    cells_out.unlink(missing_ok=True)
    cells = timed(["gearsim", "catalogue", "cells", "--plane", "scale", "--tiles", *tiles,
                   "--config-json", cj, "--out", str(cells_out)])  # fmt: skip
    wall = time.perf_counter() - w0
    for f in tiles:
        Path(f).unlink(missing_ok=True)
    return {
        "n": n, "cells": n * n, "workers": workers, "tiles": n_tiles, "wall_s": wall,
        "tile_wall_s": sum(j["wall_s"] for j in jobs),
        "cpu_s": sum(j["cpu_s"] for j in jobs) + cells["cpu_s"],
        "tile_rss_mb_max": max(j["rss_mb"] for j in jobs), "cells_step": cells,
        "load_before": load0, "load_after": loadavg(),
    }  # fmt: skip


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 200, 400, 800])
    ap.add_argument("--workers", type=int, default=0, help="0: in-process tiles (whole CPU)")
    ap.add_argument("--compare-workers", type=int, default=200, metavar="N",
                    help="plane size of the 1 vs 2 workers comparison (0: skip)")  # fmt: skip
    ap.add_argument("--name", default="scaling")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT / "src"))
    from gearsim.study.config import study_config

    tile_rows = int(study_config([])["tile_rows"])
    out = {"tile_rows": tile_rows, "rows": [], "workers_compare": []}
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        for n in args.sizes:
            r = run_plane(n, args.workers, tmp, tile_rows)
            out["rows"].append(r)
            print(f"{n:4d}^2 = {n * n:7d} cells: wall {r['wall_s']:7.1f} s, CPU {r['cpu_s']:7.1f} s"
                  f" ({n * n / r['cpu_s']:6.0f} cells/CPU-s), tile job peak "
                  f"{r['tile_rss_mb_max']:6.0f} MB, cells step {r['cells_step']['rss_mb']:6.0f} MB"
                  f" ({r['cells_step']['wall_s']:.1f} s), load {r['load_after']}",
                  flush=True)  # fmt: skip
        if args.compare_workers:
            for w in (1, 2):
                r = run_plane(args.compare_workers, w, tmp, tile_rows)
                out["workers_compare"].append(r)
                print(f"workers {w}: {args.compare_workers}^2 wall {r['wall_s']:.1f} s "
                      f"(tile jobs {r['tile_wall_s']:.1f} s), CPU {r['cpu_s']:.1f} s, "
                      f"load {r['load_after']}", flush=True)  # fmt: skip
    big = out["rows"][-1]
    for r in out["rows"]:
        r["cpu_per_cell_rel"] = (r["cpu_s"] / r["cells"]) / (big["cpu_s"] / big["cells"])
    print(save(args.name, out))


if __name__ == "__main__":
    sys.exit(main())
