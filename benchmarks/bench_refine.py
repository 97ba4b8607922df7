"""Verified motions: how many cells of the default planes the Newton refinement touches, and
what it costs (docs/decisions.md, "Verified motions").

Rows of a default plane at its own resolution (400 ``w`` centres, forward continuation, the
study's settings), simulated twice in one process: refinement off and on. Prints per run the
CPU time, the motions and statuses, the refined cells and the refinement's own CPU.

Usage: python benchmarks/bench_refine.py wxi 20,120,220,320
       python benchmarks/bench_refine.py wb 50,150,250,350
"""

from __future__ import annotations

import json
import sys
import time
from collections import Counter

import numpy as np

AXES = {"wb": ("b", 0.0, 1.0), "wxi": ("xi", 0.04, 0.16)}


def run(plane: str, rows_idx: list[int], refine: bool) -> dict:
    import gearsim.cell.verify as verify
    from gearsim.cell.chains import simulate_rows
    from gearsim.study.config import standard_parameters, study_settings

    name, lo, hi = AXES[plane]
    base, st = standard_parameters(), study_settings()
    ys = lo + (np.array(rows_idx) + 0.5) * (hi - lo) / 400
    ws = 0.1 + (np.arange(400) + 0.5) * 2.4 / 400
    stats = {"calls": 0, "cpu_s": 0.0, "accepted": 0}
    orig_refine, orig_needs = verify.refine, verify.needs_refinement

    def timed(*a, **k):
        t = time.process_time()
        r = orig_refine(*a, **k)
        stats["calls"] += 1
        stats["cpu_s"] += time.process_time() - t
        stats["accepted"] += r is not None
        return r

    verify.refine = timed
    if not refine:
        verify.needs_refinement = lambda cls, floquet="slow": False
    try:
        rows = [[base.with_(w=float(w), **{name: float(y)}) for w in ws] for y in ys]
        t0 = time.process_time()
        res = simulate_rows(rows, settings=st)
        cpu = time.process_time() - t0
    finally:
        verify.refine, verify.needs_refinement = orig_refine, orig_needs
    cls = [r.classification for row in res for r in row]
    return {"plane": plane, "rows": rows_idx, "refine": refine, "cells": len(cls),
            "cpu_s": round(cpu, 2), "motions": Counter(c.motion for c in cls),
            "status": Counter(c.status for c in cls), "refined": sum(bool(c.refined) for c in cls),
            "refinement": {k: round(v, 3) for k, v in stats.items()}}  # fmt: skip


if __name__ == "__main__":
    plane = sys.argv[1]
    rows_idx = [int(v) for v in sys.argv[2].split(",")]
    run(plane, rows_idx[:1], True)  # warm the kernels
    for refine in (False, True):
        print(json.dumps(run(plane, rows_idx, refine)))
