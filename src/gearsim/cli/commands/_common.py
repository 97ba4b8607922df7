"""Argument helpers shared by subcommands."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from gearsim.cell.simulate import IntegrationSettings
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.errors import UsageError
from gearsim.study.config import base_parameters, integration_settings, study_config
from gearsim.study.config_io import load_standard_parameters


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
    """``--configfile``, ``--params``, ``--set``, ``--method``, ``--rtol``: the study's
    parameters and settings (config/config.yaml) unless these say otherwise."""
    p.add_argument(
        "--configfile",
        metavar="YAML",
        nargs="+",
        action="extend",
        default=[],
        help="study config file(s) merged over config/config.yaml in order, like "
        "`snakemake --configfile` (their standard_parameters, parameters and integration apply)",
    )
    p.add_argument(
        "--params",
        metavar="YAML",
        help="standard-parameter file replacing the study's (default: standard_parameters of "
        "config/config.yaml, i.e. config/standard_parameters.yaml)",
    )
    p.add_argument(
        "--set",
        metavar="NAME=VALUE",
        action="append",
        default=[],
        help="override a model parameter (repeatable), e.g. --set xi=0.05",
    )
    p.add_argument(
        "--method",
        choices=("dp5", "rk4"),
        default=None,
        help="integrator (default: the study's integration.method, rk4)",
    )
    p.add_argument(
        "--rtol", type=float, default=None, help="DP5 relative tolerance (default: the study's)"
    )


def study_from_args(args: argparse.Namespace) -> dict:
    """The study configuration of a point-like command (config/config.yaml + --configfile)."""
    return study_config(getattr(args, "configfile", None) or ())


def _assignments(args: argparse.Namespace) -> dict:
    out: dict = {}
    for item in getattr(args, "set", []) or []:
        name, value = parse_assignment(item)
        if name in out and out[name] != value:
            raise ParameterError(f"--set {name} is given twice with different values")
        out[name] = value
    return out


def parameters_and_source(args: argparse.Namespace, **extra: float) -> tuple[ModelParameters, str]:
    """The study's parameters with ``--params`` / ``--set`` / ``extra`` applied, and a text
    naming where they came from (printed and saved beside the result)."""
    sets = _assignments(args)
    for name in extra:
        if name in sets:
            flag = "--omega" if name == "w" else f"--{name}"
            raise ParameterError(
                f"--set {name}={sets[name]:g} and {flag} both set {name}; give one"
            )
    if args.params:
        base = load_standard_parameters(args.params)
        source = str(args.params)
    else:
        config = study_from_args(args)
        base, source = base_parameters(config)
    base.update(sets)
    base.update(extra)
    if sets:
        source += " + --set " + ", ".join(f"{k}={v}" for k, v in sets.items())
    return ModelParameters.from_mapping(base), source


def parameters_from_args(args: argparse.Namespace, **extra: float) -> ModelParameters:
    """:func:`parameters_and_source` without the source."""
    return parameters_and_source(args, **extra)[0]


def settings_from_args(args: argparse.Namespace) -> IntegrationSettings:
    """The study's integration settings with ``--method`` / ``--rtol`` applied."""
    settings = integration_settings(study_from_args(args))
    kw: dict = {}
    if args.method is not None:
        kw["method"] = args.method
    if args.rtol is not None:
        kw["rtol"] = args.rtol
    return settings.with_(**kw) if kw else settings


def check_new_file(path: str | Path, *, create_parent: bool = True, need: int | None = None
                   ) -> Path:
    """An output file path that can be written, checked before any computation (one line,
    exit 2): not a directory; its directory exists (or, with ``create_parent``, can be made:
    no file stands in the way); a file can be created there and ``need`` bytes are free
    (:func:`gearsim.study.preflight.check_output`)."""
    from gearsim.study.preflight import DEFAULT_NEED, check_output

    out = Path(path)
    if out.is_dir():
        raise UsageError(f"{out}: is a directory, expected a file name")
    parent = out.parent
    if not create_parent and not parent.is_dir():
        raise UsageError(f"{out}: directory {parent} does not exist")
    for anc in (parent, *parent.parents):
        if anc.exists():
            if not anc.is_dir():
                raise UsageError(f"{out}: {anc} is a file, not a directory")
            break
    if need == 0 and not parent.exists():
        return out  # shape only: the folder is made (and probed) by a later call
    return check_output(out, need=DEFAULT_NEED if need is None else need)


def check_output_path(path: str | Path) -> Path:
    """:func:`check_new_file` for a file in an existing directory (``--out`` of a point)."""
    return check_new_file(path, create_parent=False)


def json_safe(row: dict) -> dict:
    """NaN and infinities -> null, numpy scalars -> Python numbers (strict JSON)."""
    out = {}
    for k, v in row.items():
        if isinstance(v, (np.floating, float)):
            v = float(v)
            out[k] = v if math.isfinite(v) else None
        elif isinstance(v, np.integer):
            out[k] = int(v)
        elif isinstance(v, np.bool_):
            out[k] = bool(v)
        elif isinstance(v, dict):
            out[k] = json_safe(v)
        else:
            out[k] = v
    return out


def default_parameters_file():
    """The repository's ``config/standard_parameters.yaml`` (None if absent)."""
    path = Path(__file__).resolve().parents[4] / "config" / "standard_parameters.yaml"
    return path if path.is_file() else None


def orbit_parameters(
    path: str | None, assignments: list[str], **extra: float
) -> tuple[ModelParameters, str]:
    """Parameters for the orbit commands: the standard set (or ``path``) plus ``--set`` values.

    Returns the parameters and a one-line description of their source.
    """
    base: dict[str, Any] = {}
    src = "built-in defaults (no standard parameter file found)"
    file = path if path else default_parameters_file()
    if file is not None:
        base = load_standard_parameters(file)
        src = f"standard parameters {file}"
    sets = []
    for item in assignments:
        name, value = parse_assignment(item)
        base[name] = value
        sets.append(f"{name}={value}")
    base.update(extra)
    if sets:
        src += " with " + ", ".join(sets)
    return ModelParameters.from_mapping(base), src
