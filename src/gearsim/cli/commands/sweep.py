"""``gearsim sweep``: a one-parameter sweep (bifurcation data) or a figure's named points (the
job: :mod:`gearsim.study.sweep_job`)."""

from __future__ import annotations

import argparse
import sys

from gearsim.cli.commands._common import (
    add_device_argument,
    add_parameter_arguments,
    check_new_file,
    command_parameters,
    select_device,
)
from gearsim.cli.commands._progress import Progress
from gearsim.results import parquet
from gearsim.study import sweep_job

NAME = "sweep"
HELP = "run a configured sweep (--name) or figure point set (--points) and write its Parquet file"


def add_arguments(p: argparse.ArgumentParser) -> None:
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--name", help="sweep name (a key of `sweeps:`)")
    what.add_argument("--points", metavar="FIG", help="point set name (a key of `points:`)")
    add_parameter_arguments(p, integration=False)
    add_device_argument(p)
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


def resolve(args: argparse.Namespace):
    """The sweep's study with the command line's values folded into its parameters (the swept
    value and the sweep's ``fixed`` values are set per point); it carries them into the
    provenance."""
    return command_parameters(args)


def run(args: argparse.Namespace) -> int:
    recording = sweep_job.Recording(args.ramp_from, args.ramp_step, args.periods,
                                    args.samples_per_period).check()
    study = resolve(args).study
    out = check_new_file(args.out or sweep_job.default_out(study, args.name, args.points))
    n = sweep_job.size(study, args.name, args.points)
    progress = Progress(f"sweep {args.name}" if args.name else f"points {args.points}", n)
    backend = select_device(args, study)
    df, prov = sweep_job.run(study, args.name, args.points, recording, progress, backend)
    progress.close()
    parquet.write_parquet(df, out, {parquet.PROVENANCE_KEY: prov})
    print(f"{prov['kind']} {prov['name']}: wrote {out} ({len(df)} rows in {prov['wall_s']:.1f} s)",
          file=sys.stderr)
    return 0
