"""``gearsim continue``: pseudo-arclength continuation of a periodic orbit in one parameter."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from gearsim.analysis.continuation import write_branches
from gearsim.cli.commands._common import command_parameters
from gearsim.cli.commands.orbit import add_orbit_parameter_arguments
from gearsim.study import continuation_job
from gearsim.study.continuation_job import DEFAULT_BUDGET_S, ContinuationJob
from gearsim.study.preflight import check_outputs

NAME = "continue"
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
    p.add_argument("--of-sweep", metavar="SWEEP", default=None,
                   help="start from a configured sweep's parameter set (its fixed values on "
                   "the study's), as `gearsim sweep SWEEP` runs; the continued parameter is "
                   "--name")
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
    """The start point's parameters: the shared resolution (with ``--of-sweep``, the sweep's
    set) with the continued parameter at ``--from``."""
    return command_parameters(args, **{args.name: args.start})


def run(args: argparse.Namespace) -> int:
    job = ContinuationJob(args.name, args.start, args.stop, args.period, args.ds, args.ds_max,
                          args.max_points, args.switch_depth, args.budget_s, args.rtol)
    job.check()
    r = resolve(args)
    out = Path(args.out) if args.out else job.default_out(
        args.period if args.period is not None else "N")
    fig_path = Path(args.figure) if args.figure else out.with_suffix(".png")
    check_outputs([out, fig_path])  # before any computation
    period, sim = continuation_job.start_period(job, r.params)
    if args.out is None:
        out = job.default_out(period)
        fig_path = Path(args.figure) if args.figure else out.with_suffix(".png")
    # where the tables go, before the minutes of continuation (the default is beside the
    # pipeline's orbit tables, under a name of its own)
    _log(f"continue {args.name}: writing {out} (+ its _points table) and "
         f"{fig_path}" + ("" if args.out else "; --out to choose"))
    result = continuation_job.run(job, r.params, r.source, sweep=args.sweep, period=period,
                                  sim=sim, log=_log)
    from gearsim.presentation.figures.style import save_figure
    from gearsim.presentation.orbit_plots import figure_branches
    from gearsim.results import parquet

    df = result.branches
    write_branches(df, out)
    points_path = out.with_name(out.stem + "_points.parquet")
    parquet.write_parquet(result.points, points_path,
                          {b"gearsim.analysis.continuation": dict(df.attrs)})
    save_figure(figure_branches(df, title=f"continuation in {args.name}, start period "
                                f"{period}; {r.source}"), fig_path)
    landmarks_path = None
    if result.landmarks is not None:
        landmarks_path = out.with_name(out.stem + "_landmarks.parquet")
        parquet.write_parquet(result.landmarks, landmarks_path,
                              {b"gearsim.cell.sweep": str(args.sweep)})
    if args.json:
        paths = {"parquet": out, "figure": fig_path, "landmarks": landmarks_path}
        print(json.dumps(continuation_job.as_json(job, result, r.source, paths), default=float))
        return 0
    print("\n".join(continuation_job.summary(job, result, r.params, r.source)))
    print(f"wrote {out}, {points_path} and {fig_path}"
          + (f" and {landmarks_path}" if landmarks_path else ""))
    return 0


def _log(line: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {line}", file=sys.stderr, flush=True)
