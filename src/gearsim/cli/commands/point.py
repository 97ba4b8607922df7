"""``gearsim point``: simulate and classify one parameter point."""

from __future__ import annotations

import argparse
import json

from gearsim.cli.commands._common import (
    add_device_argument,
    add_parameter_arguments,
    check_output_path,
    command_parameters,
    select_device,
    settings_from_args,
)
from gearsim.study import point_job

NAME = "point"
HELP = "simulate one point and print its pattern, DC, Kmax, Lyapunov exponent and convergence"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--omega", "-w", type=float, default=None,
        help="dimensionless mesh frequency w (default with --gear: the gear file's speed_rpm; "
        "otherwise required unless --set w=... or the study's parameters give it)",
    )
    add_parameter_arguments(p)
    add_device_argument(p)
    p.add_argument(
        "--out",
        "-o",
        "--save",
        dest="out",
        metavar="PARQUET",
        help="write time series, Poincare points and spectrum to this Parquet file "
        "(--save is the old spelling)",
    )
    p.add_argument(
        "--json", action="store_true", help="print the result as one JSON object (no NaN)"
    )
    p.add_argument(
        "--check", action="store_true", help="re-run at tightened tolerance and compare"
    )
    p.add_argument(
        "--spectrum", nargs="?", type=int, const=0, default=None, metavar="PERIODS",
        help="also compute all Lyapunov exponents (QR of a tangent basis) over PERIODS mesh "
        "periods (default: max(200, analysed window)); the sum is checked against the trace",
    )


def resolve(args: argparse.Namespace):
    """The point's parameters (:func:`gearsim.cli.commands._common.command_parameters`): a gear
    file gives its own speed and torque (``speed_rpm``, ``torque_Nm``) unless an option sets
    them, so ``--omega`` is required only without one."""
    return command_parameters(args, omega_required=not args.gear, w=args.omega)


def run(args: argparse.Namespace) -> int:
    out = check_output_path(args.out) if args.out else None
    r = resolve(args)
    select_device(args, r.study)  # a device that cannot run is one line; one cell runs here
    settings = settings_from_args(args, r.study)
    spectrum = False if args.spectrum is None else (args.spectrum or True)
    res, row, elapsed = point_job.simulate_point(r.params, settings, source=r.source,
                                                 spectrum=spectrum, check=args.check,
                                                 gear=r.gear)
    if args.json:
        print(json.dumps(point_job.strict_json(row), allow_nan=False))
    else:
        for line in point_job.summary_lines(r.params, res, row, source=r.source,
                                            settings=settings, elapsed=elapsed, gear=r.gear,
                                            gear_path=r.gear_path or ""):
            print(line)
    if out is not None:
        print(f"saved {point_job.save(out, r.params, res, settings, r.source)}")
    return 0
