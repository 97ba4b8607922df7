"""Build the results table of benchmarks/CHANGELOG.md (the log) from benchmarks/results/*.json.

Usage: python benchmarks/summarize.py   (rewrites the block between the RESULTS markers)
"""

from __future__ import annotations

import json
from pathlib import Path

HERE = Path(__file__).resolve().parent
BEGIN, END = "<!-- RESULTS BEGIN -->", "<!-- RESULTS END -->"


def load(name):
    p = HERE / "results" / f"{name}.json"
    return json.loads(p.read_text()) if p.exists() else None


def f(x, nd=1):
    return f"{x:.{nd}f}"


def mcs(v):
    return f(v["cell_steps_per_s_cpu"] / 1e6, 2)


def table() -> str:
    out = []
    k = load("kernel")
    if k:
        sc, bt = k["scalar"], k["batched"]
        loads = sorted({tuple(v["load_after"]) for v in list(sc.values()) + list(bt.values())})
        out += [
            "### (a) Kernel throughput, million cell-steps per second per core (CPU time)",
            "",
            "| kernel | state only | with tangent |",
            "|---|---|---|",
            f"| scalar `integrate_periods` RK4 (256/period) | {mcs(sc['rk4_state'])}"
            f" | {mcs(sc['rk4_tangent'])} |",
            f"| scalar `integrate_periods` DP5 (1e-9/1e-12) | {mcs(sc['dp5_state'])}"
            f" | {mcs(sc['dp5_tangent'])} |",
        ]
        for n, v in bt.items():
            out.append(f"| batched RK4, {n} lanes | | {f(v['cell_steps_per_s_cpu'] / 1e6)} |")
        c = load("cell")
        if c:
            kp = c["settings"]["defaults"]["kernel_8_lanes_ms_per_period"]
            st = 8 * 256 / (kp["state"] * 1e-3) / 1e6
            tg = 8 * 256 / (kp["tangent"] * 1e-3) / 1e6
            out.append(f"| batched RK4, 8 lanes (bench_cell, 30 periods) | {f(st)} | {f(tg)} |")
        out += ["", f"Load average during (a): {loads[0]} ... {loads[-1]}.", ""]
    c = load("cell")
    if c:
        d = c["settings"]["defaults"]
        out += [
            "### (b) Milliseconds per cell (CPU), IntegrationSettings() defaults",
            "",
            f"Workload: {c['workload']}; settings transient {d['integration']['transient']}, "
            f"continuation transient {d['integration']['transient_continuation']}, chunk "
            f"{d['integration']['chunk']}, max {d['integration']['max_periods']} periods.",
            "",
            "| path | start | transient | measurement | classification | total |",
            "|---|---|---|---|---|---|",
        ]
        for m in ("dp5", "rk4"):
            for start in ("fresh", "continuation"):
                r = d[f"scalar_{m}"][start]
                out.append(
                    f"| scalar simulate_cell {m.upper()} | {start} | {f(r['transient_ms'], 2)} | "
                    f"{f(r['measure_ms'], 2)} | {f(r['classify_ms'], 2)} | "
                    f"**{f(r['total_ms'], 2)}** |"
                )
        b = d["batched_8_rows"]
        sp = b["kernel_split_model_ms_per_cell"]
        out.append(
            f"| batched simulate_rows, 8 rows | continuation | {f(sp['transient_continuation'], 3)}"
            f" | {f(sp['measure_continuation'], 3)} | {f(b['classify_and_driver_ms_per_cell'], 3)}"
            f" (driver incl.) | **{f(b['total_ms_per_cell'], 2)}** |"
        )
        out.append(
            f"| batched, 8 independent cells | fresh | {f(sp['transient_fresh'], 3)} | | | "
            f"**{f(b['fresh_ms_per_cell'], 2)}** (one block) |"
        )
        lab = d["batched_vs_scalar_labels_b0.3"]
        out += [
            "",
            f"Batched kernel time per cell {f(b['kernel_ms_per_cell'], 3)} ms of "
            f"{f(b['total_ms_per_cell'], 3)} ms ({f(b['periods_per_cell'])} periods, "
            f"{b['steps_per_cell']:.0f} RK4 steps per cell). Labels of the b = 0.3 row: batched = "
            f"scalar RK4 in {lab['equal_rk4']}/{lab['cells']}, = scalar DP5 in "
            f"{lab['equal_dp5']}/{lab['cells']} cells.",
            "",
        ]
    s = load("solve_ivp")
    if s:
        out += [
            "### (c) solve_ivp (RK45, rtol 1e-8, atol 1e-10, events) vs batched, fresh cells",
            "",
            "| w | b | label (all three equal?) | solve_ivp s | DP5 simulate_cell s |"
            " batched ms (in a full block) | ratio ivp/batched |",
            "|---|---|---|---|---|---|---|",
        ]
        for r in s["cells"]:
            out.append(
                f"| {r['w']} | {r['b']} | {r['label_batched']} ({'yes' if r['equal'] else 'NO'}) | "
                f"{f(r['ivp_s'], 2)} | {f(r['dp5_simulate_cell_s'], 3)} | "
                f"{f(r['batched_full_block_s'] * 1e3, 2)} | {r['ratio_ivp_over_batched']:.0f} |"
            )
        out += [
            "",
            f"Equal classification {s['equal_classification']}; median ratio "
            f"**{s['ratio_median_equal_cells']:.0f}x** (a cell alone in a block, 7 idle lanes: "
            f"{s['ratio_single_lane_median_equal_cells']:.0f}x; solve_ivp / scalar DP5: "
            f"{s['ratio_ivp_over_dp5_median']:.0f}x).",
            "",
        ]
    dk = load("dask")
    if dk:
        r = dk["results"]
        out += [
            "### (d) One vs two dask workers on one tile, (f) peak memory per worker",
            "",
            f"Tile: {dk['tile_rows']} rows of the default (w, b) plane; batched "
            f"{dk['batched_cells']} cells, scalar (pipeline's DP5 row task) {dk['scalar_cells']}.",
            "",
            "| path | workers | wall s | task CPU s | work / critical path | peak RSS per worker MB"
            " | load |",
            "|---|---|---|---|---|---|---|",
        ]
        for key in ("batched_1", "batched_2", "scalar_1", "scalar_2"):
            v = r[key]
            rss = ", ".join(f"{x:.0f}" for x in v["worker_maxrss_mb"].values())
            out.append(
                f"| {key.split('_')[0]} | {key.split('_')[1]} | {f(v['wall_s'], 2)} | "
                f"{f(v['task_cpu_s'], 2)} | {f(v.get('cpu_speedup', float('nan')), 2)} | {rss} | "
                f"{v['load']} |"
            )
        out += [
            "",
            f"Wall-time speed-up 2/1 workers: batched {f(dk['batched_speedup_2_over_1'], 2)}, "
            f"scalar {f(dk['scalar_speedup_2_over_1'], 2)} (under the load shown: other jobs "
            "hold the cores); work / critical path in CPU time (the speed-up on idle cores): "
            f"batched {f(dk.get('batched_cpu_speedup_2', float('nan')), 2)}, scalar "
            f"{f(dk.get('scalar_cpu_speedup_2', float('nan')), 2)}.",
            "",
        ]
    w = load("workflow")
    if w:
        out += [
            "### (e) Workflow wall time, `snakemake --cores 2`",
            "",
            "| configuration | integration | wall | load | notes |",
            "|---|---|---|---|---|",
        ]
        for r in w["runs"]:
            out.append(
                f"| {r['config']} | {r['integration']} | {r['wall_s']:.0f} s | {r['load']} | "
                f"{r['notes']} |"
            )
        out.append("")
    return "\n".join(out)


def main():
    readme = HERE / "CHANGELOG.md"
    text = readme.read_text()
    block = f"{BEGIN}\n{table()}\n{END}"
    if BEGIN in text:
        head, rest = text.split(BEGIN, 1)
        text = head + block + rest.split(END, 1)[1]
    else:
        text = text.replace("RESULTS_TABLE", block)
    readme.write_text(text)


if __name__ == "__main__":
    main()
