"""``gearsim gear``: a gear file's dimensionless set, or a dimensionless set's physical meaning.

Also the ``--gear / --rpm / --torque`` options of ``gearsim point`` (docs/units.md).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

from gearsim.cli.commands._common import parse_assignment
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.physical.geometry import GearGeometry

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


# ----------------------------------------------------------------------------- gearsim point
def add_gear_arguments(p: argparse.ArgumentParser) -> None:
    """``--gear FILE``, ``--rpm N``, ``--torque T`` (used by ``gearsim point``)."""
    p.add_argument("--gear", metavar="YAML",
                   help="gear file in physical units (config/gears/*.yaml, docs/units.md): its "
                        "dimensionless set replaces the standard parameters, and the result is "
                        "printed in physical units too")
    p.add_argument("--rpm", type=float, default=None,
                   help="speed of the non-circular gear, rpm (needs --gear; sets w)")
    p.add_argument("--torque", type=float, default=None,
                   help="driving torque on the non-circular gear, N m (needs --gear; sets Fm)")


def gear_from_args(args: argparse.Namespace) -> GearGeometry | None:
    """The gear of ``--gear`` with ``--rpm`` / ``--torque`` applied, or ``None``."""
    from gearsim.physical.units import DEFAULT_GEAR, load_gear

    rpm, torque = getattr(args, "rpm", None), getattr(args, "torque", None)
    if not getattr(args, "gear", None):
        if rpm is not None or torque is not None:
            raise ParameterError(f"--rpm and --torque need a gear file: add --gear {DEFAULT_GEAR}"
                                 " (or your own, docs/units.md)")
        return None
    gear = load_gear(args.gear)
    for opt, field, value in (("--rpm", "speed_rpm", rpm), ("--torque", "torque_Nm", torque)):
        if value is not None:
            try:
                gear = replace(gear, **{field: value})
            except ParameterError as exc:
                raise ParameterError(f"{opt}: {exc}") from None
    return gear


def point_parameters(args: argparse.Namespace, parameters_from_args
                     ) -> tuple[ModelParameters, GearGeometry | None]:
    """The dimensionless set of ``gearsim point`` and its gear (``None`` without ``--gear``).

    With ``--gear``: the gear's set (``--rpm``, ``--torque`` applied), ``--set`` on top, then
    ``--omega`` if given. Without: ``parameters_from_args(args, w=omega)``.
    """
    gear = gear_from_args(args)
    omega = getattr(args, "omega", None)
    if gear is None:
        if omega is None:
            raise ParameterError("give --omega W (dimensionless mesh frequency), or --gear FILE "
                                 "with --rpm N")
        return parameters_from_args(args, w=omega), None
    if getattr(args, "params", None):
        raise ParameterError("--gear and --params both give the parameter set; use one")
    if omega is not None and getattr(args, "rpm", None) is not None:
        raise ParameterError("--omega and --rpm both set the mesh frequency; use one")
    values = gear.to_model_parameters().to_dict()
    for item in getattr(args, "set", []) or []:
        name, value = parse_assignment(item)
        values[name] = value
    if omega is not None:
        values["w"] = omega
    return ModelParameters.from_mapping(values), gear
