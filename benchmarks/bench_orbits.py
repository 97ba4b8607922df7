"""(g) Periodic orbits: ms per cell of Newton refinement against the simulated classification,
and the wall time of two-parameter bifurcation curves.

Per cell (side by side, same cells, CPU time): ``simulate_cell`` from rest with the scalar DP5
defaults and with the production RK4 settings (what a plane cell costs), then
``orbit_cells.refine_cell`` from the simulated section state (Newton + multipliers + grazing
margin at the shooting tolerance). Cells: the standard parameter set at w in [0.3, 1.35]
(periodic: 0/1T, 1/1T, 1/2T, 1/4T), single-DOF and 6-DOF.

Curves: ``gearsim.bifcurves.follow_curves`` of every fold, period doubling and grazing located
along w in [0.9, 1.4] at the standard set, followed across the plane's second parameter
(b in [0, 1], xi in [0.04, 0.16]; step 1/20 of the range). ``--quick``: single-DOF only.

Usage: python benchmarks/bench_orbits.py [--quick]
"""

from __future__ import annotations

import argparse
import time

from _common import measure, save, setup_env

setup_env()

import numpy as np  # noqa: E402

from gearsim.bifcurves import bifurcation_points, follow_curves  # noqa: E402
from gearsim.config_io import load_standard_parameters  # noqa: E402
from gearsim.continuation import Continuation, continue_orbit  # noqa: E402
from gearsim.orbit_cells import refine_cell  # noqa: E402
from gearsim.parameters import ModelParameters  # noqa: E402
from gearsim.simulate import IntegrationSettings, simulate_cell  # noqa: E402

STANDARD = ModelParameters.from_mapping(load_standard_parameters("config/standard_parameters.yaml"))
RK4 = IntegrationSettings(method="rk4", transient_continuation=40)


def per_cell(model: str, n_cells: int) -> dict:
    ws = np.linspace(0.3, 1.35, n_cells)
    ps = [STANDARD.with_(w=float(w), model=model) for w in ws]
    sims = [simulate_cell(p) for p in ps]  # warm-up and the start states
    t_dp5 = measure(lambda: [simulate_cell(p) for p in ps], repeats=3)
    t_rk4 = measure(lambda: [simulate_cell(p, settings=RK4) for p in ps], repeats=3)
    todo = [(p, s) for p, s in zip(ps, sims, strict=True) if s.classification.n >= 1]
    t_ref = measure(lambda: [refine_cell(p, s.classification.n, s.final_state)
                             for p, s in todo], repeats=3)
    flags = [refine_cell(p, s.classification.n, s.final_state)["orbit_flag"] for p, s in todo]
    return {
        "model": model,
        "cells": len(ps),
        "periodic": len(todo),
        "flags": flags,
        "simulate_dp5_ms_per_cell": 1e3 * t_dp5["cpu_median_s"] / len(ps),
        "simulate_rk4_ms_per_cell": 1e3 * t_rk4["cpu_median_s"] / len(ps),
        "refine_ms_per_cell": 1e3 * t_ref["cpu_median_s"] / max(len(todo), 1),
        "timings": {"dp5": t_dp5, "rk4": t_rk4, "refine": t_ref},
    }


def curves(model: str, name2: str, range2: tuple[float, float]) -> dict:
    p = STANDARD.with_(model=model)
    c0, w0 = time.process_time(), time.perf_counter()
    br = continue_orbit(p, "w", 0.9, 1.4, n=1, config=Continuation(ds=0.02, switch_depth=1))
    pts = bifurcation_points(br)
    c1, w1 = time.process_time(), time.perf_counter()
    cur = follow_curves(p, pts, name2, range2, step2=(range2[1] - range2[0]) / 20)
    c2, w2 = time.process_time(), time.perf_counter()
    return {
        "model": model, "plane": f"(w, {name2})", "points": len(pts),
        "curves": int(cur["curve"].nunique()) if len(cur) else 0, "curve_points": len(cur),
        "branch_cpu_s": c1 - c0, "branch_wall_s": w1 - w0,
        "curves_cpu_s": c2 - c1, "curves_wall_s": w2 - w1, "reasons": cur.attrs["reasons"],
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    models = ("1dof",) if args.quick else ("1dof", "6dof")
    cells = [per_cell(m, 8 if args.quick else 16) for m in models]
    for c in cells:
        print(f"{c['model']}: {c['periodic']}/{c['cells']} periodic; ms per cell (CPU): simulate "
              f"DP5 {c['simulate_dp5_ms_per_cell']:.1f}, simulate RK4 "
              f"{c['simulate_rk4_ms_per_cell']:.1f}, Newton refinement "
              f"{c['refine_ms_per_cell']:.1f}; flags {c['flags']}")
    cv = []
    for m in models:
        for name2, rng in (("b", (0.0, 1.0)), ("xi", (0.04, 0.16))):
            r = curves(m, name2, rng)
            cv.append(r)
            print(f"{m} {r['plane']}: {r['points']} points -> {r['curves']} curves, "
                  f"{r['curve_points']} curve points; branch {r['branch_cpu_s']:.1f} s CPU "
                  f"({r['branch_wall_s']:.1f} s wall), curves {r['curves_cpu_s']:.1f} s CPU "
                  f"({r['curves_wall_s']:.1f} s wall)")
    path = save("bench_orbits" + ("_quick" if args.quick else ""),
                {"per_cell": cells, "curves": cv})
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
