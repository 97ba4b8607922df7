"""(g) Periodic orbits: ms per cell of Newton refinement against the simulated classification,
the wall time of the two-parameter bifurcation curves of both default planes against the
plane's tile time, and the monodromy accuracy option.

Per cell (side by side, same cells, CPU time): ``simulate_cell`` from rest with the scalar DP5
defaults and with the production RK4 settings (what a plane cell costs), then
``orbit_cells.refine_cell`` from the simulated section state (Newton + multipliers + grazing
margin at the shooting tolerance). Cells: the standard parameter set at w in [0.3, 1.35]
(periodic: 0/1T, 1/1T, 1/2T, 1/4T), single-DOF and 6-DOF.

Curves (``--curves``): what the pipeline runs (workflow/rules/orbits.smk): the standard
continuation along the plane's x range (w in [0.1, 2.5], branch switching to period 4), then
``follow_curves`` of every fold, period doubling and grazing across each default plane's y
range (step 1/10 of the range, orbits of period <= 2: the defaults of ``gearsim
bifurcation-curves``) with the secant re-location, in ``--workers`` processes; beside
it the plane's tile time, estimated from 8 of its 400 rows simulated exactly as a tile does
(``tiles.simulate_rows_batched``, rows spread over the plane) times 50. ``--method window``
measures the previous re-location (a windowed continuation per curve point) instead.

Usage: python benchmarks/bench_orbits.py [--quick] [--curves [--workers 2] [--method M]]
"""

from __future__ import annotations

import argparse
import time

from _common import measure, save, setup_env

setup_env()

import numpy as np  # noqa: E402

from gearsim.analysis.bifcurves import follow_curves  # noqa: E402
from gearsim.analysis.continuation import continue_orbit  # noqa: E402
from gearsim.analysis.continuation_options import Continuation  # noqa: E402
from gearsim.analysis.exact_landmarks import bifurcation_points  # noqa: E402
from gearsim.analysis.orbit_cells import refine_cell  # noqa: E402
from gearsim.cell.simulate import IntegrationSettings, simulate_cell  # noqa: E402
from gearsim.dynamics.parameters import ModelParameters  # noqa: E402
from gearsim.study.config import Study  # noqa: E402
from gearsim.study.config_io import load_standard_parameters  # noqa: E402

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


def plane_tile_estimate(plane: str, rows: int = 8) -> dict:
    """Wall / CPU time of ``rows`` rows of a default plane (batched RK4, as in a tile), and the
    whole plane's estimate (x 400 / rows)."""
    from gearsim.study.config import study_config
    from gearsim.study.grid import tile_ids
    from gearsim.study.tiles import row_specs, simulate_rows_batched

    cfg = study_config()
    specs = [s for t in tile_ids(cfg, plane) for s in row_specs(Study.of(cfg), plane, t)]
    ny = len(specs)
    pick = [specs[int(k)] for k in np.linspace(0, ny - 1, rows).round()]
    c0, w0 = time.process_time(), time.perf_counter()
    simulate_rows_batched(pick)
    c1, w1 = time.process_time(), time.perf_counter()
    return {"plane": plane, "rows": rows, "rows_total": ny, "cells_per_row": len(specs[0]
            .x_values), "rows_cpu_s": c1 - c0, "rows_wall_s": w1 - w0,
            "plane_cpu_s_est": (c1 - c0) * ny / rows, "plane_wall_s_est": (w1 - w0) * ny / rows}


def curves_default(workers: int, method: str, out_dir: str | None = None) -> dict:
    """The pipeline's curves of both default planes (standard continuation + follow_curves)."""
    from gearsim.study.config import Study, study_config

    cfg = study_config()
    out: dict = {"workers": workers, "method": method}
    c0, w0 = time.process_time(), time.perf_counter()
    br = continue_orbit(STANDARD.with_(w=0.1), "w", 0.1, 2.5, n=1,
                        config=Continuation(ds=0.02, ds_max=0.05, switch_depth=2,
                                            max_points=600))
    pts = bifurcation_points(br)
    c1, w1 = time.process_time(), time.perf_counter()
    out["continuation"] = {"cpu_s": c1 - c0, "wall_s": w1 - w0, "points": len(pts),
                           "reasons": br.attrs["reasons"]}
    if out_dir:
        from pathlib import Path

        from gearsim.analysis.continuation import write_branches

        Path(out_dir).mkdir(parents=True, exist_ok=True)
        write_branches(br, Path(out_dir) / "standard.parquet")
    for plane in ("wb", "wxi"):
        pl = cfg["planes"][plane]
        yn, y0, y1 = pl["y"]["name"], float(pl["y"]["min"]), float(pl["y"]["max"])
        base = Study.of(cfg).parameters(plane=plane).model
        at = min(max(float(getattr(base, yn)), y0), y1)
        p = base.with_(**{yn: at, "w": 0.1})
        import resource

        ch0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        c0, w0 = time.process_time(), time.perf_counter()
        cur = follow_curves(p, pts, yn, (y0, y1), step2=(y1 - y0) / 10, workers=workers,
                            method=method, range1=(float(pl["x"]["min"]), float(pl["x"]["max"])),
                            max_period=2)
        c1, w1 = time.process_time(), time.perf_counter()
        ch1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        child_cpu = (ch1.ru_utime + ch1.ru_stime) - (ch0.ru_utime + ch0.ru_stime)
        if out_dir:
            from pathlib import Path

            cur.assign(plane=plane).to_parquet(Path(out_dir) / f"{plane}_curves.parquet")
        out[plane] = {"curves": int(cur["curve"].nunique()) if len(cur) else 0,
                      "curve_points": len(cur), "wall_s": w1 - w0,
                      "cpu_s_parent": c1 - c0, "cpu_s_workers": child_cpu,
                      "cpu_s": c1 - c0 + child_cpu, "relocations": cur.attrs["relocations"],
                      "reasons": cur.attrs["reasons"], "tiles": plane_tile_estimate(plane)}
    return out


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
    ap.add_argument("--curves", action="store_true",
                    help="only the default planes' curves against their tile time")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--method", choices=("secant", "window"), default="secant")
    ap.add_argument("--out-dir", default=None,
                    help="also write the continuation and curves as Parquet here")
    args = ap.parse_args()
    load = open("/proc/loadavg").read().split()[:3]
    if args.curves:
        r = curves_default(args.workers, args.method, args.out_dir)
        r["loadavg_start"] = load
        c = r["continuation"]
        print(f"load {' '.join(load)}; standard continuation: {c['points']} points, "
              f"{c['wall_s']:.1f} s wall ({c['cpu_s']:.1f} s CPU)")
        for plane in ("wb", "wxi"):
            q = r[plane]
            t = q["tiles"]
            print(f"{plane}: {q['curves']} curves, {q['curve_points']} points, "
                  f"{q['wall_s']:.1f} s wall, {q['cpu_s']:.1f} s CPU ({args.workers} workers, "
                  f"{args.method}); "
                  f"relocations {q['relocations']}; plane tiles (estimate from {t['rows']} "
                  f"rows) {t['plane_wall_s_est']:.0f} s wall, {t['plane_cpu_s_est']:.0f} s CPU")
        r["loadavg_end"] = open("/proc/loadavg").read().split()[:3]
        print(f"wrote {save('bench_orbits_curves_' + args.method, r)}")
        return
    models = ("1dof",) if args.quick else ("1dof", "6dof")
    cells = [per_cell(m, 8 if args.quick else 16) for m in models]
    for c in cells:
        print(f"{c['model']}: {c['periodic']}/{c['cells']} periodic; ms per cell (CPU): simulate "
              f"DP5 {c['simulate_dp5_ms_per_cell']:.1f}, simulate RK4 "
              f"{c['simulate_rk4_ms_per_cell']:.1f}, Newton refinement "
              f"{c['refine_ms_per_cell']:.1f}; flags {c['flags']}")
    cv = []
    if args.quick:
        for name2, rng in (("b", (0.0, 1.0)), ("xi", (0.04, 0.16))):
            r = curves("1dof", name2, rng)
            cv.append(r)
            print(f"1dof {r['plane']}: {r['points']} points -> {r['curves']} curves, "
                  f"{r['curve_points']} curve points; branch {r['branch_cpu_s']:.1f} s CPU "
                  f"({r['branch_wall_s']:.1f} s wall), curves {r['curves_cpu_s']:.1f} s CPU "
                  f"({r['curves_wall_s']:.1f} s wall)")
    path = save("bench_orbits" + ("_quick" if args.quick else ""),
                {"per_cell": cells, "curves": cv, "loadavg": load})
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
