"""(b) Milliseconds per cell, transient and classification apart; fresh start and continuation.

Workload: a plane row of the (w, b) plane, every 8th cell centre of the 400-point w axis
(w = 0.103 ... 2.5; 50 cells: every regime of the standard sweep), at b = 0.15, 0.3, ..., a
forward continuation chain (the pipeline's row task). For each path:

* scalar ``simulate_cell`` (DP5, the default settings; and RK4 at 256 steps per period): the
  logic of simulate_cell with timers around the transient, the measuring chunks and the
  classification (period test + classify_motion); labels checked equal to simulate_cell's;
* batched ``simulate_rows`` with 8 lanes (8 rows of b): end-to-end CPU time per cell, and its
  split into kernel time (transient / measurement, from the kernel's CPU time per period with
  and without the tangent vector) and driver + classification time.

Settings: IntegrationSettings() defaults, and the integration block of config/config.yaml.
CPU time (process_time) is the per-core measure; the load average is recorded.

Usage: python benchmarks/bench_cell.py [--quick]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

from _common import loadavg, save, setup_env

setup_env()

import numpy as np  # noqa: E402
import yaml  # noqa: E402

from gearsim.cell import chain, chains  # noqa: E402
from gearsim.cell.classify import classify_motion, estimate_period  # noqa: E402
from gearsim.cell.simulate import (  # noqa: E402
    IntegrationSettings,
    initial_tangent,
    run_periods,
    simulate_cell,
)
from gearsim.dynamics.model import static_state  # noqa: E402
from gearsim.dynamics.parameters import ModelParameters  # noqa: E402
from gearsim.numerics import batch, lanes_layout  # noqa: E402
from gearsim.numerics.integrate import PeriodSummaries  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def config_settings() -> IntegrationSettings:
    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    return IntegrationSettings(**cfg["integration"])


def row_cells(b: float, stride: int) -> list[ModelParameters]:
    ws = 0.1 + (np.arange(400) + 0.5) * 2.4 / 400
    return [ModelParameters(w=float(w), b=b) for w in ws[::stride]]


def timed_cell(params, u0, st, start_period):
    """simulate_cell's logic with CPU timers: (transient_s, measure_s, classify_s, result)."""
    c = time.process_time
    transient = st.transient if u0 is None else st.transient_continuation
    p = params.to_array()
    y = static_state(p) if u0 is None else np.asarray(u0, float)[:10].copy()
    k = start_period
    h = 0.0
    t0 = c()
    r = run_periods(params, y, transient, st, start_period=k, parray=p)
    y, k, h = r.state, k + r.periods_done, r.h_last
    t1 = c()
    yt = np.concatenate([y, initial_tangent(params)])
    parts, measured, n, t_cls = [], 0, 0, 0.0
    while measured < st.max_periods:
        m = min(st.chunk, st.max_periods - measured)
        r = run_periods(params, yt, m, st, start_period=k, tangent=True, h_init=h, parray=p)
        parts.append(r.summaries)
        yt, k, h = r.state, k + r.periods_done, r.h_last
        measured += r.periods_done
        a = c()
        s = PeriodSummaries.concat(parts)
        n = estimate_period(
            s.section[:, 0],
            s.section[:, 1],
            float(s.xmax.max() - s.xmin.min()),
            params.w,
            st.n_max,
            st.period_rtol,
        )
        t_cls += c() - a
        if n > 0:
            break
    t2 = c()
    s = PeriodSummaries.concat(parts)
    window = s.tail(n * max(1, min(len(s), 4 * max(n, 8)) // n)) if n > 0 else s
    cls = classify_motion(
        window,
        params,
        n=n,
        lyap_threshold=st.lyap_threshold,
    )
    t3 = c()
    return t1 - t0, (t2 - t1) - t_cls, t_cls + (t3 - t2), cls, yt[:10], k


def scalar_chain(cells, st):
    rows = []
    u0, k = None, 0
    for i, p in enumerate(cells):
        tt, tm, tc, cls, y, k1 = timed_cell(p, u0, st, k)
        if i < 3:  # the instrumented logic is simulate_cell's
            ref = simulate_cell(p, u0, settings=st, start_period=k)
            assert ref.classification.label == cls.label, (p.w, ref.classification.label, cls.label)
        rows.append(
            {
                "w": p.w,
                "fresh": u0 is None,
                "transient_ms": tt * 1e3,
                "measure_ms": tm * 1e3,
                "classify_ms": tc * 1e3,
                "label": cls.label,
            }
        )
        u0, k = y, k1
    return rows


def scalar_fresh(cells, st):
    rows = []
    for p in cells:
        tt, tm, tc, cls, _, _ = timed_cell(p, None, st, 0)
        rows.append(
            {
                "w": p.w,
                "fresh": True,
                "transient_ms": tt * 1e3,
                "measure_ms": tm * 1e3,
                "classify_ms": tc * 1e3,
                "label": cls.label,
            }
        )
    return rows


def summarize_scalar(rows):
    out = {}
    for fresh in (True, False):
        sel = [r for r in rows if r["fresh"] == fresh]
        if not sel:
            continue
        key = "fresh" if fresh else "continuation"
        out[key] = {
            f: statistics.mean(r[f] for r in sel)
            for f in ("transient_ms", "measure_ms", "classify_ms")
        }
        out[key]["total_ms"] = sum(out[key].values())
        out[key]["cells"] = len(sel)
    return out


def kernel_period_cost(st, lanes=8):
    """CPU seconds per period of one 8-lane kernel call, with and without the tangent vector."""
    cells = [ModelParameters(w=float(w), b=0.3) for w in np.linspace(0.6, 2.4, lanes)]
    y0 = np.array(
        [np.concatenate([static_state(p.to_array()), initial_tangent(p)]) for p in cells]
    )
    out = {}
    for tangent in (False, True):
        L = batch.Lanes(lanes, 64)
        for i, p in enumerate(cells):
            L.load_params(i, p, 256)
            L.load_state(i, y0[i])
            L.ist[lanes_layout.IST_ST, i] = 0
        L.run(256, 2, 0.0, 1e6, tangent)
        ts = []
        for _ in range(5):
            L.ist[lanes_layout.IST_ST, :lanes] = 0
            L.ist[lanes_layout.IST_DONE] = 0
            a = time.process_time()
            L.run(256, 30, 0.0, 1e6, tangent)
            ts.append((time.process_time() - a) / 30)
        out["tangent" if tangent else "state"] = statistics.median(ts)
    return out


def batched_tile(bs, cells_w, st):
    rows = [[p.with_(b=b) for p in cells_w] for b in bs]
    times = {"kernel": 0.0, "decide": 0.0}
    run0, decide0 = batch.Lanes.run, chain.decide

    def run(self, *a, **k):
        t = time.process_time()
        run0(self, *a, **k)
        times["kernel"] += time.process_time() - t

    def decide(*a, **k):
        t = time.process_time()
        decide0(*a, **k)
        times["decide"] += time.process_time() - t

    batch.Lanes.run, chain.decide = run, decide
    try:
        t = time.process_time()
        res = chains.simulate_rows(rows, settings=st)
        total = time.process_time() - t
    finally:
        batch.Lanes.run, chain.decide = run0, decide0
    n = sum(len(r) for r in rows)
    per = {
        "cells": n,
        "total_ms_per_cell": total / n * 1e3,
        "kernel_ms_per_cell": times["kernel"] / n * 1e3,
        "classify_and_driver_ms_per_cell": (total - times["kernel"]) / n * 1e3,
        "periods_per_cell": statistics.mean(c.periods for r in res for c in r),
        "steps_per_cell": statistics.mean(c.steps for r in res for c in r),
    }
    return per, res


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    stride = 16 if args.quick else 8
    out = {
        "workload": f"(w, b) plane row, every {stride}th w centre, forward continuation",
        "settings": {},
    }
    sets = [("defaults", IntegrationSettings())]
    if config_settings() != IntegrationSettings():
        sets.append(("config_yaml", config_settings()))
    else:
        out["config_yaml_integration_equals_defaults"] = True
    for sname, st in sets:
        res = {"integration": st.to_dict()}
        cells = row_cells(0.3, stride)
        fresh_cells = cells[:: max(1, len(cells) // 6)]
        for method in ("dp5", "rk4"):
            s = st.with_(method=method)
            simulate_cell(cells[0], settings=s)  # warm the compiled kernels
            chain = scalar_chain(cells, s)
            rows = [r for r in chain if not r["fresh"]] + scalar_fresh(fresh_cells, s)
            res[f"scalar_{method}"] = summarize_scalar(rows)
            res[f"scalar_{method}"]["labels"] = [r["label"] for r in chain]
            print(
                sname,
                method,
                {
                    k: round(v["total_ms"], 2)
                    for k, v in res[f"scalar_{method}"].items()
                    if isinstance(v, dict)
                },
                "load",
                loadavg(),
                flush=True,
            )
        kc = kernel_period_cost(st)
        res["kernel_8_lanes_ms_per_period"] = {k: v * 1e3 for k, v in kc.items()}
        bs = [0.15, 0.25, 0.3, 0.35, 0.45, 0.6, 0.8, 1.0]
        chains.simulate_rows([[cells[0].with_(b=b)] for b in bs[:1]], settings=st)  # warm
        per, rb = batched_tile(bs, cells, st)
        # model split of the kernel time: per lane, transient periods vs measured periods
        tr_fresh = st.transient
        tr_cont = st.transient_continuation
        meas = statistics.mean(c.periods for r in rb for c in r[1:]) - tr_cont
        per["kernel_split_model_ms_per_cell"] = {
            "transient_fresh": tr_fresh * kc["state"] / 8 * 1e3,
            "transient_continuation": tr_cont * kc["state"] / 8 * 1e3,
            "measure_continuation": meas * kc["tangent"] / 8 * 1e3,
        }
        # fresh starts: independent cells (each 150 transient periods), 8 lanes
        t = time.process_time()
        chains.simulate_cells(fresh_cells, settings=st)
        per["fresh_ms_per_cell"] = (time.process_time() - t) / len(fresh_cells) * 1e3
        res["batched_8_rows"] = per
        same = sum(
            a.classification.label == b
            for a, b in zip(rb[2], res["scalar_rk4"]["labels"], strict=True)
        )
        same_dp5 = sum(
            a.classification.label == b
            for a, b in zip(rb[2], res["scalar_dp5"]["labels"], strict=True)
        )
        res["batched_vs_scalar_labels_b0.3"] = {
            "equal_rk4": same,
            "equal_dp5": same_dp5,
            "cells": len(cells),
        }
        print(
            sname,
            "batched",
            {k: (round(v, 3) if isinstance(v, float) else v) for k, v in per.items()},
            "labels equal rk4/dp5",
            same,
            same_dp5,
            "/",
            len(cells),
            "load",
            loadavg(),
            flush=True,
        )
        out["settings"][sname] = res
    print(save("cell", out))


if __name__ == "__main__":
    sys.exit(main())
