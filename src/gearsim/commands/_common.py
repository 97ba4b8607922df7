"""Argument helpers shared by subcommands."""

from __future__ import annotations

import argparse
import math

from ..parameters import ModelParameters, ParameterError
from ..simulate import IntegrationSettings


def parse_assignment(text: str) -> tuple[str, float | str]:
    """Parse ``name=value`` from ``--set``; the value is a float except for ``model``."""
    if "=" not in text:
        raise ParameterError(f"--set expects name=value, got {text!r}")
    name, _, raw = text.partition("=")
    name = name.strip()
    if name == "model":
        return name, raw.strip()
    try:
        value = float(raw)
    except ValueError:
        raise ParameterError(f"--set {name}: {raw!r} is not a number") from None
    if not math.isfinite(value):
        raise ParameterError(f"--set {name}: value must be finite, got {raw!r}")
    return name, value


def add_parameter_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--params",
        metavar="YAML",
        help="standard parameters file (default: built-in defaults, see docs/model.md)",
    )
    p.add_argument(
        "--set",
        metavar="NAME=VALUE",
        action="append",
        default=[],
        help="override a model parameter (repeatable), e.g. --set xi=0.05",
    )
    p.add_argument("--method", choices=("dp5", "rk4"), default="dp5", help="integrator")
    p.add_argument("--rtol", type=float, default=None, help="DP5 relative tolerance")


def parameters_from_args(args: argparse.Namespace, **extra: float) -> ModelParameters:
    base: dict = {}
    if args.params:
        from ..config_io import load_standard_parameters

        base = load_standard_parameters(args.params)
    for item in args.set:
        name, value = parse_assignment(item)
        base[name] = value
    base.update(extra)
    return ModelParameters.from_mapping(base)


def settings_from_args(args: argparse.Namespace) -> IntegrationSettings:
    kw: dict = {"method": args.method}
    if args.rtol is not None:
        kw["rtol"] = args.rtol
    return IntegrationSettings(**kw)
