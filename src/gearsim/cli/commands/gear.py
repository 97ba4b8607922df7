"""``gearsim gear``: a gear file's dimensionless set, or a dimensionless set's physical meaning.

The ``--gear / --rpm / --torque / --backlash`` options of the simulating commands are in
:mod:`gearsim.cli.commands._common` (docs/units.md).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from gearsim.dynamics.parameters import ModelParameters
from gearsim.physical.geometry import GearGeometry
from gearsim.study.changes import parse_assignment

NAME = "gear"
HELP = ("print a gear file's dimensionless parameter set, or what a dimensionless set means in "
        "physical units on that gear (rpm, N m, um)")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--gear", metavar="YAML", default=None,
                   help="gear file (default config/gears/standard.yaml, the study's standard "
                        "gear); keys and units in docs/units.md")
    p.add_argument("--params", metavar="YAML", default=None,
                   help="a standard-parameter file (config/standard_parameters.yaml format): "
                        "print its physical meaning on the gear's geometry instead")
    p.add_argument("--set", metavar="NAME=VALUE", action="append", default=[],
                   help="override a dimensionless parameter (repeatable), e.g. --set w=0.48: "
                        "prints the speed, torque, ... it means")
    p.add_argument("--yaml", action="store_true",
                   help="print the (back-computed) gear as a gear file instead of the report")


def _gear(path: str | None) -> tuple[GearGeometry, str]:
    from gearsim.physical.units import DEFAULT_GEAR, load_gear

    if path:
        return load_gear(path), path
    if Path(DEFAULT_GEAR).is_file():
        return load_gear(DEFAULT_GEAR), DEFAULT_GEAR
    return GearGeometry(), "the standard gear (GearGeometry defaults)"


def run(args: argparse.Namespace) -> int:
    from gearsim.physical.units import describe, gear_yaml

    gear, source = _gear(args.gear)
    params = None
    if args.params or args.set:
        if args.params:
            from gearsim.study.config_io import load_standard_parameters

            values = load_standard_parameters(args.params)
        else:
            values = gear.to_model_parameters().to_dict()
        for item in args.set:
            name, value = parse_assignment(item)
            values[name] = value
        params = ModelParameters.from_mapping(values)
    if args.yaml:
        shown = gear if params is None else GearGeometry.from_dimensionless(params, gear)
        sets = f" with {' '.join(args.set)}" if args.set else ""
        what = (f"back-computed from {args.params or 'the gear set'}{sets} on {source}"
                if params is not None else source)
        print(gear_yaml(shown, description=f"gearsim gear: {what}".strip()), end="")
        return 0
    head = f"gear: {source}"
    if params is not None:
        head += (f"; physical meaning of the dimensionless set of "
                 f"{args.params or 'the gear'}{' with ' + ' '.join(args.set) if args.set else ''}")
    print(head)
    print(describe(gear, params))
    return 0
