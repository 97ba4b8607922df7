"""``gearsim continue``: pseudo-arclength continuation of a periodic orbit in one parameter."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from gearsim.analysis.continuation import continue_orbit, write_branches
from gearsim.analysis.continuation_options import Continuation
from gearsim.analysis.orbits import SEEDING, find_periodic_orbit, shooting_settings
from gearsim.cell.simulate import simulate_cell
from gearsim.cli.commands._common import command_parameters
from gearsim.cli.commands.orbit import add_orbit_parameter_arguments
from gearsim.errors import UsageError
from gearsim.study.preflight import check_outputs

NAME = "continue"
#: Wall-clock budget of a continuation (s): the standard one takes ~1 CPU-minute, 4 minutes
#: of wall on a loaded machine (benchmarks/README.md); a normal run is never cut.
DEFAULT_BUDGET_S = 1800.0
HELP = (
    "continue a periodic orbit in one parameter: stable and unstable branches, located folds, "
    "period doublings (with branch switching), Neimark-Sacker points and grazings"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--name", default="w", help="continuation parameter (default w)")
    p.add_argument("--from", dest="start", type=float, required=True, help="start value")
    p.add_argument("--to", dest="stop", type=float, required=True, help="end value")
    p.add_argument("--period", "-n", type=int, default=None,
                   help="period of the start orbit (default: the period simulated from rest)")
    add_orbit_parameter_arguments(p)
    p.add_argument("--ds", type=float, default=0.01, help="initial arclength step")
    p.add_argument("--ds-max", type=float, default=0.05, help="largest arclength step")
    p.add_argument("--max-points", type=int, default=400, help="points per branch")
    p.add_argument("--switch-depth", type=int, default=2,
                   help="period doublings followed onto the doubled branch (0: none)")
    p.add_argument("--out", "-o", metavar="PARQUET", default=None,
                   help="branch table (default results/orbits/continue_NAME_FROM_TO_pN.parquet)")
    p.add_argument("--figure", metavar="PNG", default=None,
                   help="branch figure (default: the Parquet path with .png)")
    p.add_argument("--sweep", metavar="PARQUET", default=None,
                   help="a simulated sweep of the same parameter set (results/sweeps/*.parquet): "
                   "write the exact landmarks (paper, grid-read, continuation) beside the branches")
    p.add_argument("--json", action="store_true", help="print the events as JSON")
    p.add_argument("--budget-s", type=float, default=DEFAULT_BUDGET_S,
                   help="wall-clock budget in seconds: the continuation stops there, keeps "
                   f"its branches and records status 'budget' (default {DEFAULT_BUDGET_S:g})")


def resolve(args: argparse.Namespace):
    """The start point's parameters: the shared resolution with the continued parameter at
    ``--from``."""
    return command_parameters(args, **{args.name: args.start})


def run(args: argparse.Namespace) -> int:
    for key in ("ds", "ds_max"):
        v = getattr(args, key)
        if not (0 < v <= 1):
            raise UsageError(f"--{key.replace('_', '-')} = {v} must be in (0, 1]")
    if args.max_points < 2:
        raise UsageError(f"--max-points = {args.max_points} must be >= 2")
    if not 0 <= args.switch_depth <= 6:
        raise UsageError(f"--switch-depth = {args.switch_depth} must be in [0, 6]")
    if args.start == args.stop:
        raise UsageError(f"--from and --to are equal ({args.start}): empty range")
    if not 0 < args.budget_s <= 7 * 86400:
        raise UsageError(f"--budget-s = {args.budget_s:g} must be in (0, 604800]")
    r = resolve(args)
    params, source = r.params, r.source
    st = shooting_settings(args.rtol)
    out = Path(args.out or
               f"results/orbits/continue_{args.name}_{args.start:g}_{args.stop:g}_p"
               f"{args.period if args.period is not None else 'N'}.parquet")
    fig_path = Path(args.figure) if args.figure else out.with_suffix(".png")
    check_outputs([out, fig_path])  # before any computation
    deadline = time.monotonic() + args.budget_s
    t0 = time.perf_counter()
    sim = simulate_cell(params, settings=SEEDING)
    n = args.period if args.period is not None else max(sim.classification.n, 1)
    if args.out is None:
        out = Path(f"results/orbits/continue_{args.name}_{args.start:g}_{args.stop:g}_p{n}"
                   ".parquet")
        fig_path = Path(args.figure) if args.figure else out.with_suffix(".png")
    # where the tables go, before the minutes of continuation (the default is beside the
    # pipeline's orbit tables, under a name of its own)
    _log(f"continue {args.name}: writing {out} (+ its _points table) and "
         f"{fig_path}" + ("" if args.out else "; --out to choose"))
    orbit = find_periodic_orbit(params, n, sim.final_state, st, grazing=False)
    cfg = Continuation(ds=args.ds, ds_max=args.ds_max, max_points=args.max_points,
                       switch_depth=args.switch_depth, settings=st, progress=_log,
                       deadline=deadline)
    df = continue_orbit(params, args.name, args.start, args.stop, orbit, config=cfg)
    elapsed = time.perf_counter() - t0
    df.attrs["parameters_source"] = source
    write_branches(df, out)
    from gearsim.analysis.exact_landmarks import bifurcation_points
    from gearsim.results import parquet

    points_path = out.with_name(out.stem + "_points.parquet")
    parquet.write_parquet(bifurcation_points(df).assign(name2="", value2=float("nan")),
                          points_path, {b"gearsim.analysis.continuation": dict(df.attrs)})
    from gearsim.presentation.figures.style import save_figure
    from gearsim.presentation.orbit_plots import figure_branches

    fig = figure_branches(df, title=f"continuation in {args.name}, start period {n}; {source}")
    save_figure(fig, fig_path)
    ev = df[df["event"] != ""]
    landmarks_path = None
    if args.sweep:
        import pandas as pd

        from gearsim.analysis.exact_landmarks import exact_landmarks, report_lines

        if not Path(args.sweep).is_file():
            raise UsageError(f"--sweep: file not found: {args.sweep}")
        table = exact_landmarks(bifurcation_points(df), pd.read_parquet(args.sweep))
        landmarks_path = out.with_name(out.stem + "_landmarks.parquet")
        parquet.write_parquet(table, landmarks_path, {b"gearsim.cell.sweep": str(args.sweep)})
        if not args.json:
            print("\n".join(report_lines(table)))
    if args.json:
        print(json.dumps({
            "parameters_source": source, "name": args.name, "period": n,
            "points": int(len(df)), "elapsed_s": elapsed, "parquet": str(out),
            "figure": str(fig_path),
            "events": [
                {"event": r.event, "value": r.value, "period": int(r.period),
                 "branch": int(r.branch), "boundary": r.boundary, "x": r.x}
                for r in ev.itertuples()
            ],
            "reasons": df.attrs["reasons"], "status": df.attrs.get("status", "ok"),
            "landmarks": None if landmarks_path is None else str(landmarks_path),
        }, default=float))
        return 0
    print(f"parameters: {source} (model {params.model})")
    print(f"{len(df)} branch points on {df['branch'].nunique()} branches in {elapsed:.1f} s")
    for r in ev.itertuples():
        extra = f" ({r.boundary})" if r.boundary else ""
        print(f"  {r.event:16s}{extra:10s} {args.name} = {r.value:.10f}  period {r.period}  "
              f"x = {r.x:.6f}")
    for reason in df.attrs["reasons"]:
        print(f"  {reason}")
    if df.attrs.get("status") == "budget":
        print(f"stopped at the budget of {args.budget_s:g} s (status budget): the branches "
              "are partial")
    print(f"wrote {out}, {points_path} and {fig_path}"
          + (f" and {landmarks_path}" if landmarks_path else ""))
    return 0


def _log(line: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {line}", file=sys.stderr, flush=True)
