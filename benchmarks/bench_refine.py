"""Verified motions: how many cells of the default planes the Newton refinement and the Floquet
margins touch, and what they cost (docs/decisions.md, "Verified motions" and "Floquet margin of
every cell").

Rows of a default plane at its own resolution (400 ``w`` centres, forward continuation, the
study's settings; give 8 rows: one full SIMD block, as in a tile), simulated three times in one
process: refinement off, ``floquet: slow`` (refinement only) and ``floquet: margin`` (the
default: refinement and the margin of every periodic cell, :func:`gearsim.cell.verify.
fill_margins` after the batched driver, as the tile runner does). Prints per run the CPU time
of the simulation and of the margins, the motions and statuses, the refined cells and the
refinement's own CPU, the windows followed on (docs/model.md, "Passages"), and the load average.

Usage: python benchmarks/bench_refine.py wxi 25,75,125,175,225,275,325,375
       python benchmarks/bench_refine.py wb 25,75,125,175,225,275,325,375
"""

from __future__ import annotations

import json
import os
import sys
import time
from collections import Counter

import numpy as np

AXES = {"wb": ("b", 0.0, 1.0), "wxi": ("xi", 0.04, 0.16)}


def run(plane: str, rows_idx: list[int], mode: str) -> dict:
    import gearsim.cell.verify as verify
    from gearsim.cell.chains import simulate_rows
    from gearsim.study.config import Study

    name, lo, hi = AXES[plane]
    base, st = Study.load().parameters().model, Study.load().settings
    st = st.with_(floquet="slow" if mode == "off" else mode)
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

    follow = {"calls": 0, "kept": 0, "cpu_s": 0.0}
    orig_follow = verify.follow_motion

    def followed(*a, **k):
        t = time.process_time()
        r = orig_follow(*a, **k)
        follow["calls"] += 1
        follow["kept"] += r is not None
        follow["cpu_s"] += time.process_time() - t
        return r

    verify.refine = timed
    verify.follow_motion = followed
    if mode == "off":
        verify.needs_refinement = lambda cls, floquet="slow": False
    try:
        rows = [[base.with_(w=float(w), **{name: float(y)}) for w in ws] for y in ys]
        t0 = time.process_time()
        res = simulate_rows(rows, settings=st)
        t1 = time.process_time()
        verify.fill_margins([r for row in res for r in row], st)
        t2 = time.process_time()
    finally:
        verify.refine, verify.needs_refinement = orig_refine, orig_needs
        verify.follow_motion = orig_follow
    cls = [r.classification for row in res for r in row]
    return {"plane": plane, "rows": rows_idx, "mode": mode, "cells": len(cls),
            "cpu_s": round(t1 - t0, 2), "margin_cpu_s": round(t2 - t1, 2),
            "motions": Counter(c.motion for c in cls), "status": Counter(c.status for c in cls),
            "periodic": sum(c.n > 0 for c in cls),
            "with_mu_max": int(sum(np.isfinite(c.mu_max) for c in cls)),
            "refined": sum(bool(c.refined) for c in cls),
            "refinement": {k: round(v, 3) for k, v in stats.items()},
            "followed": {k: round(v, 3) for k, v in follow.items()},
            "load": [round(v, 2) for v in os.getloadavg()]}  # fmt: skip


if __name__ == "__main__":
    plane = sys.argv[1]
    rows_idx = [int(v) for v in sys.argv[2].split(",")]
    run(plane, rows_idx[:1], "margin")  # warm the kernels
    for mode in ("off", "slow", "margin"):
        print(json.dumps(run(plane, rows_idx, mode)))
