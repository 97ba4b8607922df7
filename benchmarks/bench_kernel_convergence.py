"""A kernel change that moves results in the last bits, against the RK4 step's own error.

The scalar RK4 integrator (the batched kernel's algorithm for one cell, bit-identical to it) of
this checkout and of a git revision (``--rev``, exported with ``git archive``) run the cells of
``bench_kernel`` (32 cells, w in [0.6, 2.4], b in {0.15, 0.3, 1.0}, after a 100-period
transient) from the same states for ``--periods`` periods at the study's 192 steps a period;
this checkout also at 384. Reported per quantity (the state at each period's end, the
per-period force and displacement extremes): the largest |new - old| after the first period and
after the last, beside the step error |N192 - N384| of the same quantity, and their largest
ratio per cell. A change is within the step's error when that ratio is far below 1.

Usage: python benchmarks/bench_kernel_convergence.py --rev REV [--periods 40]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import numpy as np
from _common import loadavg, run_json_worker, save
from bench_kernel_ab import export

ROOT = Path(__file__).resolve().parents[1]
HERE = Path(__file__).resolve().parent

WORKER = r"""
import json, sys
import numpy as np
from gearsim.cell.simulate import IntegrationSettings, run_periods
from bench_kernel import cells
y0 = np.load(sys.argv[1]); m, steps = int(sys.argv[2]), int(sys.argv[3])
st = IntegrationSettings(method="rk4", steps_per_period=steps)
res = []
for p, y in zip(cells(len(y0)), y0):
    r = run_periods(p, y[:10], m, st, start_period=100)
    s = r.summaries
    ends = np.vstack([s.section[1:, :2], r.state[None, :2]])
    res.append(np.column_stack([ends, s.fmax, s.fmin, s.xmax, s.xmin]).tolist())
print(json.dumps(res))
"""
NAMES = ("x", "x'", "fmax", "fmin", "xmax", "xmin")


def run(src: Path, cache: Path, y0: Path, periods: int, steps: int) -> np.ndarray:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(src), str(HERE)]),
               NUMBA_CACHE_DIR=str(cache), NUMBA_NUM_THREADS="1")
    return np.array(run_json_worker(WORKER, [y0, periods, steps], env))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rev", required=True, help="git revision of the old kernel")
    ap.add_argument("--periods", type=int, default=40)
    args = ap.parse_args(argv)
    from bench_kernel import cells, start_states

    with tempfile.TemporaryDirectory(prefix="gearsim_conv_") as tmp:
        tmp = Path(tmp)
        y0 = tmp / "y0.npy"
        np.save(y0, start_states(cells(32)))
        old_src = export(args.rev, tmp / "old")
        cache_new = Path(os.environ.get("NUMBA_CACHE_DIR", tmp / "cache_new"))
        old = run(old_src, tmp / "cache_old", y0, args.periods, 192)
        new = run(ROOT / "src", cache_new, y0, args.periods, 192)
        fine = run(ROOT / "src", cache_new, y0, args.periods, 384)
    out = {"rev_old": args.rev, "periods": args.periods, "cells": len(old), "quantities": {}}
    for c, name in enumerate(NAMES):
        row = {}
        for label, k in (("first", 0), ("last", -1)):
            d = np.abs(new[:, k, c] - old[:, k, c])
            e = np.abs(new[:, k, c] - fine[:, k, c])
            ratio = np.where(e > 0, d / np.where(e > 0, e, 1.0), np.where(d > 0, np.inf, 0.0))
            row[label] = {"max_change": float(d.max()), "max_step_error": float(e.max()),
                          "max_ratio": float(ratio.max()), "cells_changed": int((d > 0).sum())}
            print(f"{name:5s} period {label:5s}: |new - old| <= {d.max():.1e} "
                  f"({(d > 0).sum()} of {len(d)} cells changed), step error |N192 - N384| <= "
                  f"{e.max():.1e}; largest ratio per cell {ratio.max():.1e}")
        out["quantities"][name] = row
    out["load_end"] = loadavg()
    print(save("kernel_convergence", out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
