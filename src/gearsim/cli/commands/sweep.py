"""``gearsim sweep``: a one-parameter sweep (bifurcation data) or a figure's named points."""

from __future__ import annotations

import argparse
import math
import sys
import time

from gearsim.cli.commands._common import (
    add_parameter_arguments,
    check_new_file,
    command_parameters,
)
from gearsim.cli.commands._progress import Progress
from gearsim.errors import UsageError
from gearsim.results import parquet
from gearsim.study.config import results_dir
from gearsim.study.grid import sweep_values
from gearsim.study.provenance import point_subtree, provenance, sweep_subtree
from gearsim.study.sweeps import point_list, points_frame, sweep_frame

NAME = "sweep"
HELP = "run a configured sweep (--name) or figure point set (--points) and write its Parquet file"


def add_arguments(p: argparse.ArgumentParser) -> None:
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--name", help="sweep name (a key of `sweeps:`)")
    what.add_argument("--points", metavar="FIG", help="point set name (a key of `points:`)")
    add_parameter_arguments(p, integration=False)
    p.add_argument(
        "--out",
        "-o",
        default=None,
        help="output Parquet file (default <results>/sweeps/<name>.parquet or "
        "<results>/points/<set>.parquet)",
    )
    p.add_argument(
        "--ramp-from",
        type=float,
        default=0.1,
        help="points: start of the forward continuation ramp in w",
    )
    p.add_argument("--ramp-step", type=float, default=0.02, help="points: ramp step in w")
    p.add_argument("--periods", type=int, default=64, help="points: recorded mesh periods")
    p.add_argument(
        "--samples-per-period",
        type=int,
        default=128,
        help="points: recorded samples per mesh period",
    )


def _check_recording(args: argparse.Namespace) -> None:
    checks = (
        ("--ramp-from", args.ramp_from, 0.0, 100.0, False),
        ("--ramp-step", args.ramp_step, 0.0, 10.0, False),
        ("--periods", args.periods, 1, 100_000, True),
        ("--samples-per-period", args.samples_per_period, 4, 100_000, True),
    )
    for flag, v, lo, hi, closed in checks:
        ok = math.isfinite(v) and (lo <= v if closed else lo < v) and v <= hi
        if not ok:
            rng = f"[{lo}, {hi}]" if closed else f"({lo}, {hi}]"
            raise UsageError(f"{flag}: {v!r} is outside {rng}")


def resolve(args: argparse.Namespace):
    """The sweep's study with the command line's values folded into its parameters (the swept
    value and the sweep's ``fixed`` values are set per point); it carries them into the
    provenance."""
    return command_parameters(args)


def run(args: argparse.Namespace) -> int:
    _check_recording(args)
    study = resolve(args).study
    config = study.config
    res = results_dir(config)
    default = (
        res / "sweeps" / f"{args.name}.parquet"
        if args.name
        else res / "points" / f"{args.points}.parquet"
    )
    out = check_new_file(args.out or default)
    started = parquet.now_iso()
    t0 = time.perf_counter()
    if args.name:
        if args.name not in config["sweeps"]:
            raise UsageError(
                f"unknown sweep '{args.name}'; configured: {', '.join(config['sweeps']) or 'none'}"
            )
        spec = config["sweeps"][args.name]
        base = study.parameters(sweep=args.name).model
        vals = sweep_values(spec)
        progress = Progress(f"sweep {args.name}", len(vals))
        df = sweep_frame(
            base,
            spec["name"],
            vals,
            spec.get("direction", "forward"),
            study.settings,
            progress,
            spec.get("start", "continuation"),
        )
        subtree = sweep_subtree(study, args.name)
        kind, name = "sweep", args.name
    else:
        if args.points not in config["points"]:
            raise UsageError(
                f"unknown point set '{args.points}'; configured: "
                f"{', '.join(config['points']) or 'none'}"
            )
        progress = Progress(
            f"points {args.points}", len(point_list(config["points"][args.points]))
        )
        df = points_frame(study, args.points, ramp_from=args.ramp_from,
                          ramp_step=args.ramp_step, periods=args.periods,
                          samples_per_period=args.samples_per_period, progress=progress)
        subtree = {
            **point_subtree(study, args.points),
            "recording": {
                "ramp_from": args.ramp_from,
                "ramp_step": args.ramp_step,
                "periods": args.periods,
                "samples_per_period": args.samples_per_period,
            },
        }
        kind, name = "points", args.points
    progress.close()
    wall = time.perf_counter() - t0
    prov = provenance(
        subtree,
        kind=kind,
        name=name,
        study=study,
        started=started,
        finished=parquet.now_iso(),
        wall_s=wall,
        cells=len(df),
        workers="in-process",
    )
    parquet.write_parquet(df, out, {parquet.PROVENANCE_KEY: prov})
    print(f"{kind} {name}: wrote {out} ({len(df)} rows in {wall:.1f} s)", file=sys.stderr)
    return 0
