"""(l) Less work per cell: the evidence behind each numerical shortcut.

Subcommands (results as JSON in benchmarks/results/, plane frames in benchmarks/.scratch/):

* ``cells --spp 128 160 192 256``: the 30-cell convergence set
  (tests/integration/test_convergence.py) with
  RK4 at each steps-per-period value: labels, and the section-point error of a fixed 200-period
  run from the static state against DP5 at ``IntegrationSettings.tightened()`` (periodic cells;
  relative to the orbit's x range).
* ``plane --config config/quick.yaml --plane wb --tag spp128 --set steps_per_period=128``: a
  whole plane in-process with the pipeline's tile records (``tiles.simulate_rows_batched`` on
  every row, the rows are independent chains) and its CPU seconds; the frame is written to
  ``benchmarks/.scratch/<plane>_<n>_<tag>.parquet``.
* ``compare REF NEW``: every cell whose label differs, whether it sits next to a boundary of
  the reference map (a 4-neighbour with another label), and the DP5-tight label of the cell
  from the reference run's start state (the audit's reference) and from the new run's start
  state: which of the two it agrees with, and whether the start state (not the step) decides.
* ``audit FRAME --config ... --plane wb [--set rtol=...]``: the audit's verdicts (agreement with
  DP5) on a frame, CPU seconds; ``--tight`` settings override the audit's DP5 settings.
* ``settle --config config/quick.yaml --planes wb wxi [--every k] [--sweeps]``: the adaptive
  transient (``integration.settle_check``) against the fixed plan, side by side in one process
  (CPU alternated ``--repeats`` times): periods, steps and CPU per cell, every label, status,
  DC and Kmax compared, and every cell whose label changes simulated ``--long`` periods from
  each run's own start state (its left neighbour's final state): which reading is right.

Usage (one process per core; ``nice -n 5`` while the background fits run):
    python benchmarks/bench_lesswork.py cells --spp 128 160 192 256
    python benchmarks/bench_lesswork.py plane --config config/quick.yaml --plane wb --tag base
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, loadavg, setup_env  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
# the study directory (config/, workflow/schemas/): another checkout's to run its code
CONFIG_ROOT = Path(os.environ.get("LESSWORK_ROOT", ROOT))
SCRATCH = Path(__file__).resolve().parent / ".scratch"


def _value(text: str):
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return {"true": True, "false": False}.get(text.lower(), text)


def _sets(pairs) -> dict:
    out = {}
    for p in pairs or []:
        k, _, v = p.partition("=")
        out[k] = _value(v)
    return out


def _config(configfile: str | None, integration: dict) -> dict:
    from gearsim.study.config import study_config

    over = {"integration": integration} if integration else None
    return study_config([configfile] if configfile else [], over, root=CONFIG_ROOT)


def cmd_cells(args) -> dict:
    import numpy as np

    sys.path.insert(0, str(ROOT / "tests"))
    from test_convergence import CELLS, REFERENCE_SET

    from gearsim.cell.simulate import IntegrationSettings, run_periods, simulate_cell
    from gearsim.dynamics.model import static_state
    from gearsim.dynamics.parameters import ModelParameters

    base = IntegrationSettings(method="rk4", **_sets(args.set))
    tight = IntegrationSettings().tightened()
    out = {"spp": args.spp, "cells": [], "load_before": loadavg()}
    for w, b, label, npq in CELLS:
        p = ModelParameters(w=w, b=b, **REFERENCE_SET)
        y0 = static_state(p.to_array())
        ref = run_periods(p, y0, args.periods, tight)
        sx = ref.summaries.section
        scale = float(ref.summaries.xmax.max() - ref.summaries.xmin.min())
        row = {"w": w, "b": b, "expected": f"{label} {npq}", "labels": {}, "err": {}}
        for n in args.spp:
            st = base.with_(steps_per_period=n)
            c = simulate_cell(p, settings=st).classification
            row["labels"][n] = f"{c.label} {c.label_npq}"
            if label != "chaos":
                r = run_periods(p, y0, args.periods, st)
                e = np.abs(r.summaries.section[-8:, :2] - sx[-8:, :2]).max() / max(scale, 1e-12)
                row["err"][n] = float(e)
        out["cells"].append(row)
        print(w, b, row["expected"], row["labels"],
              {k: f"{v:.1e}" for k, v in row["err"].items()}, flush=True)
    out["load_after"] = loadavg()
    for n in args.spp:
        changed = [c for c in out["cells"] if c["labels"][n] != c["expected"]]
        errs = [c["err"][n] for c in out["cells"] if n in c["err"]]
        print(f"spp {n}: {len(changed)} labels differ from the expected; section error "
              f"max {max(errs):.2e} median {float(np.median(errs)):.2e}")
        out[f"summary_{n}"] = {"changed": len(changed), "err_max": max(errs),
                               "err_median": float(np.median(errs))}
    return out


def cmd_plane(args) -> dict:
    from gearsim.study.config import Study
    from gearsim.study.grid import tile_ids
    from gearsim.study.tiles import records_to_frame, row_specs, simulate_rows_batched

    config = _config(args.config, _sets(args.set))
    if args.n:
        for ax in ("x", "y"):
            config["planes"][args.plane][ax]["n"] = args.n
    study = Study.of(config)
    specs = [s for t in tile_ids(config, args.plane) for s in row_specs(study, args.plane, t)]
    if args.every > 1:  # every k-th row: the plane's w step, fewer rows
        specs = specs[:: args.every]
    l0 = loadavg()
    c0, w0 = time.process_time(), time.perf_counter()
    records = []
    for k in range(0, len(specs), 80):  # the default tile_rows: 80 lanes at once
        records += simulate_rows_batched(specs[k : k + 80])
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    df = records_to_frame(records)
    n = int(config["planes"][args.plane]["x"]["n"])
    SCRATCH.mkdir(exist_ok=True)
    path = SCRATCH / f"{args.plane}_{n}_{args.tag}.parquet"
    df.to_parquet(path)
    out = {"plane": args.plane, "n": n, "tag": args.tag, "set": _sets(args.set), "cells": len(df),
           "cpu_s": cpu, "wall_s": wall, "steps": int(df["steps"].sum()),
           "periods": int(df["periods"].sum()), "load_before": l0, "load_after": loadavg(),
           "frame": str(path)}
    print(json.dumps(out))
    return out


def _dp5_label(config, plane, ref, r):
    """The audit's reference (DP5 at tightened tolerance) for row ``r`` of frame ``ref``."""
    from gearsim.study.audit import audit_frame
    from gearsim.study.config import Study

    config = dict(config, audit={**config["audit"], "fraction": 1.0, "seed": 0})
    sub = ref.iloc[[r]]
    # audit_frame starts from the left neighbour in the frame it is given: pass both rows
    i, j = int(sub["i"].iloc[0]), int(sub["j"].iloc[0])
    pair = ref[(ref["j"] == j) & ref["i"].isin([i - 1, i])]
    df = audit_frame(Study.of(config), plane, pair.reset_index(drop=True))
    hit = df[(df["i"] == i) & (df["j"] == j)].iloc[0]
    return f"{hit['tight_label']} {hit['tight_label_npq']}"


def cmd_compare(args) -> dict:
    import numpy as np
    import pandas as pd

    ref = pd.read_parquet(args.ref)
    new = pd.read_parquet(args.new)
    key = ["j", "i"]
    ref = ref.sort_values(key).reset_index(drop=True)
    new = new.sort_values(key).reset_index(drop=True)
    lab_r = (ref["label"] + " " + ref["label_npq"]).to_numpy()
    lab_n = (new["label"] + " " + new["label_npq"]).to_numpy()
    ny, nx = int(ref["j"].max()) + 1, int(ref["i"].max()) + 1
    grid = lab_r.reshape(ny, nx)
    changed = np.flatnonzero(lab_r != lab_n)
    config = _config(args.config, {})
    rows = []
    for r in changed:
        j, i = divmod(int(r), nx)
        nb = [grid[jj, ii] for jj, ii in ((j, i - 1), (j, i + 1), (j - 1, i), (j + 1, i))
              if 0 <= jj < ny and 0 <= ii < nx]
        boundary = any(v != grid[j, i] for v in nb)
        row = {"i": i, "j": j, "x": float(ref["x"][r]), "y": float(ref["y"][r]),
               "ref": lab_r[r], "new": lab_n[r], "boundary": bool(boundary)}
        if args.dp5 and len(rows) < args.dp5:
            row["dp5"] = _dp5_label(config, args.plane, ref, int(r))
            # and from the new run's own start state (its left neighbour's final state)
            row["dp5_new_start"] = _dp5_label(config, args.plane, new, int(r))
        rows.append(row)
        print(row, flush=True)
    n_b = sum(r["boundary"] for r in rows)
    agree_ref = sum(r.get("dp5") == r["ref"] for r in rows)
    agree_new = sum(r.get("dp5") == r["new"] for r in rows)
    agree_new_start = sum(r.get("dp5_new_start") == r["new"] for r in rows)
    # each run against DP5 from its own start state: the error rate of each step size
    ref_wrong = sum("dp5" in r and r["dp5"] != r["ref"] for r in rows)
    new_wrong = sum("dp5" in r and r["dp5_new_start"] != r["new"] for r in rows)
    summary = {"cells": len(ref), "changed": len(rows), "changed_at_boundary": n_b,
               "changed_interior": len(rows) - n_b, "dp5_checked": sum("dp5" in r for r in rows),
               "dp5_agrees_ref": agree_ref, "dp5_agrees_new": agree_new,
               "dp5_from_new_start_agrees_new": agree_new_start,
               "ref_differs_from_dp5_same_start": ref_wrong,
               "new_differs_from_dp5_same_start": new_wrong,
               "cpu_ref_periods": int(ref["periods"].sum()),
               "cpu_new_periods": int(new["periods"].sum()),
               "steps_ref": int(ref["steps"].sum()), "steps_new": int(new["steps"].sum())}
    print(json.dumps(summary))
    return {"ref": args.ref, "new": args.new, "summary": summary, "rows": rows}


def _rows_records(config, plane, every):
    from gearsim.study.config import Study
    from gearsim.study.grid import tile_ids
    from gearsim.study.tiles import row_specs, simulate_rows_batched

    study = Study.of(config)
    specs = [s for t in tile_ids(config, plane) for s in row_specs(study, plane, t)][::every]
    c0 = time.process_time()
    rec = []
    for k in range(0, len(specs), 80):  # the default tile_rows: 80 lanes at once
        rec += simulate_rows_batched(specs[k : k + 80])
    return rec, time.process_time() - c0, study


def _long_label(study, plane, rec, start, periods):
    """The fixed plan after ``periods`` periods of transient from ``start`` (None: rest)."""
    import numpy as np

    from gearsim.cell.simulate import simulate_cell

    pl = study.config["planes"][plane]
    p = study.parameters(plane=plane).model.with_(**{pl["x"]["name"]: float(rec["x"]),
                                                     pl["y"]["name"]: float(rec["y"])})
    st = study.settings.with_(settle_check=0)
    y = None if start is None else np.asarray(start, dtype=float)
    c = simulate_cell(p, y, settings=st, transient=periods).classification
    return f"{c.label} {c.label_npq} {c.status}"


def cmd_settle(args) -> dict:
    import numpy as np

    out = {"config": args.config, "every": args.every, "load_before": loadavg(), "planes": {}}
    fixed = _config(args.config, {"settle_check": 0})
    adaptive = _config(args.config, {"settle_check": args.check})
    for plane in args.planes:
        cpu = {"fixed": [], "adaptive": []}
        recs = {}
        for _ in range(args.repeats):
            for tag, cfg in (("fixed", fixed), ("adaptive", adaptive)):
                recs[tag], c, study = _rows_records(cfg, plane, args.every)
                cpu[tag].append(c)
        a, b = recs["fixed"], recs["adaptive"]
        key = lambda r: (r["label"], r["label_npq"], r["status"])  # noqa: E731
        st = study.settings
        w = min(st.chunk, st.max_periods)

        def first_test(r, st=st, w=w):  # the fixed plan's first period test (row start: rest)
            return (st.transient if r["i"] == 0 else st.transient_continuation) + w

        changed, ddc, dk, early_dc, early_dk = [], [], [], [], []
        by_cell = {(r["i"], r["j"]): r for r in a}
        by_cell_b = {(r["i"], r["j"]): r for r in b}
        for ra, rb in zip(a, b, strict=True):
            if key(ra) != key(rb):
                changed.append((ra, rb))
            elif ra["n"] > 0:
                ddc.append(abs(ra["dc"] - rb["dc"]))
                if ra["kmax"] == ra["kmax"]:
                    dk.append(abs(ra["kmax"] - rb["kmax"]) / max(abs(ra["kmax"]), 1e-12))
                if rb["periods"] < first_test(ra):  # the cells that stopped early
                    early_dc.append(ddc[-1])
                    early_dk.append(dk[-1] if ra["kmax"] == ra["kmax"] else 0.0)
        table = []
        for ra, rb in changed:
            left_a = by_cell.get((ra["i"] - 1, ra["j"]))
            left_b = by_cell_b.get((rb["i"] - 1, rb["j"]))
            sa = None if left_a is None or left_a["status"] in ("diverged", "budget") \
                else left_a["final_state"]
            sb = None if left_b is None or left_b["status"] in ("diverged", "budget") \
                else left_b["final_state"]
            row = {"i": ra["i"], "j": ra["j"], "x": ra["x"], "y": ra["y"],
                   "fixed": " ".join(map(str, key(ra))), "fixed_periods": ra["periods"],
                   "adaptive": " ".join(map(str, key(rb))), "adaptive_periods": rb["periods"],
                   "long_from_fixed_start": _long_label(study, plane, ra, sa, args.long),
                   "long_from_adaptive_start": _long_label(study, plane, rb, sb, args.long)}
            table.append(row)
            print(row, flush=True)
        per_a = np.array([r["periods"] for r in a])
        per_b = np.array([r["periods"] for r in b])
        res = {"cells": len(a), "cpu_s": cpu,
               "cpu_ratio": min(cpu["adaptive"]) / min(cpu["fixed"]),
               "periods_mean": [float(per_a.mean()), float(per_b.mean())],
               "periods_median": [float(np.median(per_a)), float(np.median(per_b))],
               "steps_mean": [float(np.mean([r["steps"] for r in a])),
                              float(np.mean([r["steps"] for r in b]))],
               "early": int(sum(r["periods"] < first_test(r) for r in b)),
               "changed": len(changed),
               "dc_abs_max": max(ddc, default=0.0),
               "dc_abs_p99": float(np.quantile(ddc, 0.99)) if ddc else 0.0,
               "kmax_rel_max": max(dk, default=0.0),
               "kmax_rel_p99": float(np.quantile(dk, 0.99)) if dk else 0.0,
               "early_dc_abs_max": max(early_dc, default=0.0),
               "early_kmax_rel_max": max(early_dk, default=0.0),
               "table": table}
        out["planes"][plane] = res
        print(plane, json.dumps({k: v for k, v in res.items() if k != "table"}), flush=True)
    out["load_after"] = loadavg()
    return out


def cmd_audit(args) -> dict:
    import pandas as pd

    from gearsim.study.audit import audit_frame
    from gearsim.study.config import Study

    config = _config(args.config, {})
    if args.audit:
        config["audit"] = {**config["audit"], **_sets(args.audit)}
    cells = pd.read_parquet(args.frame)
    l0 = loadavg()
    c0 = time.process_time()
    df = audit_frame(Study.of(config), args.plane, cells)
    cpu = time.process_time() - c0
    if args.save:
        df.to_parquet(SCRATCH / args.save)
    out = {"frame": args.frame, "audit": config["audit"], "cells": len(df),
           "agreement": float(df["agree"].mean()) if len(df) else float("nan"),
           "cpu_s": cpu, "load_before": l0, "load_after": loadavg()}
    print(json.dumps(out))
    return out


def cmd_audit_ab(args) -> dict:
    """CPU of the audit's reference at each ``tighten``, side by side: the same sample, the
    variants alternated ``--repeats`` times in one process (load recorded)."""
    import pandas as pd

    from gearsim.study.audit import audit_frame
    from gearsim.study.config import Study

    config = _config(args.config, {})
    cells = pd.read_parquet(args.frame)
    cpu: dict = {f: [] for f in args.tighten}
    labels: dict = {}
    l0 = loadavg()
    for _ in range(args.repeats):
        for f in args.tighten:
            config["audit"] = {**config["audit"], "fraction": args.fraction, "tighten": f}
            c0 = time.process_time()
            df = audit_frame(Study.of(config), args.plane, cells)
            cpu[f].append(time.process_time() - c0)
            labels[f] = (df["tight_label"] + " " + df["tight_label_npq"]).tolist()
    ref = labels[args.tighten[0]]
    out = {"frame": args.frame, "fraction": args.fraction, "cells": len(ref),
           "cpu_s": {str(f): v for f, v in cpu.items()},
           "ratio_to_first": {str(f): min(cpu[f]) / min(cpu[args.tighten[0]])
                              for f in args.tighten},
           "label_diffs_vs_first": {str(f): sum(a != b for a, b in zip(labels[f], ref,
                                                                       strict=True))
                                    for f in args.tighten},
           "load_before": l0, "load_after": loadavg()}
    print(json.dumps(out))
    return out


def cmd_tile_ab(args) -> dict:
    """Tile CPU per variant, side by side: every ``--every``-th row of the plane (its w step)
    through the tiles' batched path, variants alternated ``--repeats`` times in one process."""
    from gearsim.study.config import Study
    from gearsim.study.grid import tile_ids
    from gearsim.study.tiles import row_specs, simulate_rows_batched

    variants = [_sets(v.split(",")) for v in args.variants]
    specs = {}
    for k, v in enumerate(variants):
        config = _config(args.config, v)
        study = Study.of(config)
        rows = [s for t in tile_ids(config, args.plane) for s in row_specs(study, args.plane, t)]
        specs[k] = rows[:: args.every]
    cpu: dict = {k: [] for k in specs}
    steps: dict = {}
    l0 = loadavg()
    for _ in range(args.repeats):
        for k, rows in specs.items():
            c0 = time.process_time()
            rec = []
            for i in range(0, len(rows), 80):
                rec += simulate_rows_batched(rows[i : i + 80])
            cpu[k].append(time.process_time() - c0)
            steps[k] = sum(r["steps"] for r in rec)
    first = min(cpu[0])
    out = {"plane": args.plane, "every": args.every, "cells": sum(len(r["x_values"])
                                                                  for r in specs[0]),
           "variants": args.variants, "cpu_s": [cpu[k] for k in specs],
           "ratio_to_first": [min(cpu[k]) / first for k in specs],
           "steps": [steps[k] for k in specs], "load_before": l0, "load_after": loadavg()}
    print(json.dumps(out))
    return out


def cmd_landmarks(args) -> dict:
    """The report's numbers with a setting changed: the standard sweep's landmarks matched to
    the paper's (report.py: find_landmarks, match_paper; the default sweep, 1201 points) and the
    thresholds read off plane frames (report.row_threshold)."""
    import pandas as pd

    from gearsim.analysis.landmarks import find_landmarks, match_paper
    from gearsim.analysis.paper import PAPER_B_THRESHOLD, PAPER_XI_THRESHOLD
    from gearsim.presentation.report import double_sided_rows, not_period_one, row_threshold
    from gearsim.study.config import Study, integration_settings
    from gearsim.study.grid import sweep_values
    from gearsim.study.sweeps import sweep_frame

    config = _config(args.config, _sets(args.set))
    sw = config["sweeps"]["standard"]
    base = Study.of(config, CONFIG_ROOT).parameters(sweep="standard").model
    c0 = time.process_time()
    df = sweep_frame(base, sw["name"], sweep_values(sw), sw["direction"],
                     integration_settings(config))
    cpu = time.process_time() - c0
    m = match_paper(find_landmarks(df))
    out = {"set": _sets(args.set), "sweep_cpu_s": cpu, "load": loadavg(),
           "landmarks": m[["key", "paper", "ours", "error", "found"]].to_dict("records")}
    for f in args.frames or []:
        cells = pd.read_parquet(f)
        y = "b" if "b" in cells.columns and cells["b"].nunique() > 1 else "xi"
        fn, paper = (double_sided_rows, PAPER_B_THRESHOLD) if y == "b" else (not_period_one,
                                                                        PAPER_XI_THRESHOLD)
        t = row_threshold(cells, y, fn(cells), name=y, paper=paper)
        out[f"threshold {Path(f).stem}"] = None if t is None else {
            "value": t.value, "last_with": t.last_with, "first_without": t.first_without}
    for r in out["landmarks"]:
        print(r["key"], r["paper"], r["ours"], r["error"])
    print({k: v for k, v in out.items() if k.startswith("threshold")}, f"sweep CPU {cpu:.1f} s")
    return out


def main(argv=None) -> int:
    setup_env()
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("cells")
    a.add_argument("--spp", type=int, nargs="+", default=[128, 160, 192, 256])
    a.add_argument("--periods", type=int, default=200)
    a.add_argument("--set", nargs="*", help="IntegrationSettings overrides key=value")
    b = sub.add_parser("plane")
    b.add_argument("--config", default=None)
    b.add_argument("--plane", default="wb")
    b.add_argument("--n", type=int, default=0, help="override the plane size (n x n)")
    b.add_argument("--every", type=int, default=1, help="only every k-th row")
    b.add_argument("--tag", required=True)
    b.add_argument("--set", nargs="*", help="integration overrides key=value")
    c = sub.add_parser("compare")
    c.add_argument("ref")
    c.add_argument("new")
    c.add_argument("--config", default=None)
    c.add_argument("--plane", default="wb")
    c.add_argument("--dp5", type=int, default=0, help="DP5-tight check of up to this many cells")
    d = sub.add_parser("audit")
    d.add_argument("frame")
    d.add_argument("--config", default=None)
    d.add_argument("--plane", default="wb")
    d.add_argument("--audit", nargs="*", help="audit overrides key=value")
    d.add_argument("--save", default=None)
    e = sub.add_parser("audit-ab")
    e.add_argument("frame")
    e.add_argument("--config", default=None)
    e.add_argument("--plane", default="wb")
    e.add_argument("--fraction", type=float, default=0.001)
    e.add_argument("--tighten", type=float, nargs="+", default=[100.0, 10.0, 1.0])
    e.add_argument("--repeats", type=int, default=2)
    t = sub.add_parser("tile-ab")
    t.add_argument("variants", nargs="+", help="comma-separated key=value integration sets")
    t.add_argument("--config", default=None)
    t.add_argument("--plane", default="wb")
    t.add_argument("--every", type=int, default=10)
    t.add_argument("--repeats", type=int, default=2)
    h = sub.add_parser("settle")
    h.add_argument("--config", default=None)
    h.add_argument("--planes", nargs="+", default=["wb", "wxi"])
    h.add_argument("--every", type=int, default=1, help="only every k-th row")
    h.add_argument("--check", type=int, default=4, help="settle_check of the adaptive run")
    h.add_argument("--long", type=int, default=4000, help="periods of the long reference")
    h.add_argument("--repeats", type=int, default=1)
    g = sub.add_parser("landmarks")
    g.add_argument("--config", default=None)
    g.add_argument("--set", nargs="*", help="integration overrides key=value")
    g.add_argument("--frames", nargs="*", help="plane frames to read the thresholds from")
    ap.add_argument("--name", default=None, help="write benchmarks/results/<name>.json")
    args = ap.parse_args(argv)
    out = {"cells": cmd_cells, "plane": cmd_plane, "compare": cmd_compare,
           "audit": cmd_audit, "audit-ab": cmd_audit_ab,
           "landmarks": cmd_landmarks, "tile-ab": cmd_tile_ab,
           "settle": cmd_settle}[args.cmd](args)
    if args.name:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / f"{args.name}.json").write_text(json.dumps(out, indent=1, default=str))
    return 0


if __name__ == "__main__":
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    raise SystemExit(main())
