"""(g) Coexisting attractors: CPU per start with and without early labelling; projection.

Workload: cells of the default (w, b) plane -- every 8th w centre of the 400-point axis (50
values, w = 0.103 ... 2.5) at 8 values of b (rows j = 25, 75, ..., 375) -- with the forward
continuation state of each cell (from the batched forward chains, the plane's own seeds) and
16 seeded Sobol starts (the pipeline's attractor-tile task, ``cell_group_records``' call):

* ``early``: :func:`gearsim.analysis.attractors.find_attractors_many` (recurrence-based labelling);
* ``full``: the same with ``early=False`` (every start runs the full transient + measurement).

Both get the same starts; the basin fractions are compared (they must be equal). CPU time
(process_time) per start and per cell, periods integrated per start, share of starts labelled
early. Projection: both default 400 x 400 planes (320 000 cells) on 2 cores, i.e. CPU per cell
x 320 000 / 2 (the tiles run two at a time or two workers per tile; dask overhead not counted),
plus the grid that fits 15 minutes.

Settings: the integration block of config/config.yaml (RK4, 256 steps per period, transient
150 from a start, 40 from the continuation state).

Usage: python benchmarks/bench_attractors.py [--quick]
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

from _common import loadavg, save, setup_env

setup_env()

import numpy as np  # noqa: E402
import yaml  # noqa: E402

from gearsim.analysis.attractors import find_attractors_many  # noqa: E402
from gearsim.cell import chains  # noqa: E402
from gearsim.cell.simulate import IntegrationSettings  # noqa: E402
from gearsim.dynamics.parameters import ModelParameters  # noqa: E402
from gearsim.study.config_io import load_standard_parameters  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="2 rows instead of 8")
    ap.add_argument("--starts", type=int, default=16)
    args = ap.parse_args()
    cfg = yaml.safe_load((ROOT / "config/config.yaml").read_text())
    st = IntegrationSettings(**cfg["integration"])
    base = ModelParameters.from_mapping(
        load_standard_parameters(ROOT / "config/standard_parameters.yaml")
    )
    ws = 0.1 + (np.arange(400) + 0.5) * 2.4 / 400
    bs = (np.arange(400) + 0.5) / 400
    rows_j = [25, 75, 125, 175, 225, 275, 325, 375][: 2 if args.quick else 8]
    chains.warm_up()
    cells, fwd = [], []
    for j in rows_j:
        chain = [base.with_(w=float(w), b=float(bs[j])) for w in ws]
        res = chains.simulate_rows([chain], settings=st)[0]
        keep = range(0, 400, 8)
        cells += [chain[i] for i in keep]
        fwd += [res[i].final_state for i in keep]
    out = {"cells": len(cells), "starts": args.starts, "rows_j": rows_j,
           "settings": st.to_dict(), "load_before": loadavg()}  # fmt: skip
    runs = {}
    for mode in ("early", "full"):
        find_attractors_many(cells[:2], starts=2, seed=0, settings=st, forward=fwd[:2])  # warm
        c0, w0 = time.process_time(), time.perf_counter()
        found = find_attractors_many(cells, starts=args.starts, seed=1, settings=st,
                                     forward=fwd, early=(mode == "early"))  # fmt: skip
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        n_starts = sum(ca.n_starts for ca in found)
        periods = sum(int(ca.start_periods_run.sum()) for ca in found)
        runs[mode] = {
            "cpu_s": cpu, "wall_s": wall,
            "cpu_per_cell_ms": 1e3 * cpu / len(cells),
            "cpu_per_start_ms": 1e3 * cpu / n_starts,
            "periods_per_start": periods / n_starts,
            "labelled_early": float(sum(int(ca.early.sum()) for ca in found) / n_starts),
            "attractors_per_cell": float(np.mean([len(ca.attractors) for ca in found])),
            "multistable_cells": float(np.mean([
                sum(a.steady.status == "ok" for a in ca.attractors) >= 2 for ca in found])),
        }  # fmt: skip
        runs[mode]["_found"] = found
    differ = []
    for c, (x, y) in enumerate(zip(runs["early"]["_found"], runs["full"]["_found"],
                                   strict=True)):  # fmt: skip
        fx = sorted((a.basin_fraction, a.label, a.steady.info.get("label_npq", ""))
                    for a in x.attractors)  # fmt: skip
        fy = sorted((a.basin_fraction, a.label, a.steady.info.get("label_npq", ""))
                    for a in y.attractors)  # fmt: skip
        if fx != fy:
            differ.append({"w": cells[c].w, "b": cells[c].b, "early": fx, "full": fy,
                           "starts_differing": int(np.sum(x.start_labels != y.start_labels))})
    same = not differ
    out["cells_differing"] = differ
    for m in runs.values():
        m.pop("_found")
    out.update(runs)
    out["basin_fractions_equal"] = same
    out["speedup_cpu"] = runs["full"]["cpu_s"] / runs["early"]["cpu_s"]
    cpu_cell = runs["early"]["cpu_per_cell_ms"] / 1e3
    proj = 320_000 * cpu_cell / 2
    fit = int(math.isqrt(int(15 * 60 * 2 / cpu_cell / 2)))  # n x n per plane, both planes
    out["projection"] = {
        "two_400x400_planes_wall_s_2_cores": proj,
        "target_s": 900,
        "largest_square_grid_in_15_min": fit,
    }
    out["load_after"] = loadavg()
    path = save("attractors", out)
    print(f"{len(cells)} cells x {args.starts} starts: "
          f"early {runs['early']['cpu_per_start_ms']:.2f} ms/start "
          f"({runs['early']['periods_per_start']:.0f} periods, "
          f"{100 * runs['early']['labelled_early']:.0f}% labelled early), "
          f"full {runs['full']['cpu_per_start_ms']:.2f} ms/start "
          f"({runs['full']['periods_per_start']:.0f} periods); "
          f"x{out['speedup_cpu']:.2f}; basins equal: {same} "
          f"({len(cells) - len(differ)}/{len(cells)} cells)")
    for d in differ:
        print(f"  differs: w = {d['w']:.4f}, b = {d['b']:.4f}: early {d['early']} / full "
              f"{d['full']}")
    print(f"projection: 2 x 400 x 400 at {args.starts} starts = {proj / 60:.1f} min on 2 cores "
          f"(target 15); largest n x n per plane in 15 min: {fit}")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
