"""Argument helpers shared by subcommands: a command's study (:func:`study_from_args`), the
command line's parameter values (:func:`command_parameters`) and output-path checks."""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.errors import UsageError
from gearsim.numerics.settings import IntegrationSettings
from gearsim.physical.geometry import GearGeometry
from gearsim.physical.units import (
    DEFAULT_GEAR,
    PHYSICAL_AXES,
    config_gear,
    dimensionless_mapping,
)
from gearsim.study.config import Study


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


def add_config_arguments(p: argparse.ArgumentParser) -> None:
    """``--configfile`` and ``--config-json``: the study's configuration, as Snakemake reads it."""
    p.add_argument(
        "--configfile",
        metavar="YAML",
        nargs="+",
        action="extend",
        default=[],
        help="study config file(s) (YAML or JSON) merged over config/config.yaml in order, "
        "like `snakemake --configfile`",
    )
    p.add_argument(
        "--config-json",
        metavar="JSON",
        default=None,
        help="overrides merged last, like `snakemake --config` (a JSON mapping)",
    )


def add_device_argument(p: argparse.ArgumentParser) -> None:
    """``--device``: where a simulating command's lanes run (over ``execution.device``)."""
    from gearsim.numerics.device import DEVICES

    p.add_argument(
        "--device",
        choices=DEVICES,
        default=None,
        help="where the lanes run: cpu (SIMD kernel), cuda (GPU; needs numba-cuda) or auto "
        "(default: execution.device of the config)",
    )


def select_device(args: argparse.Namespace, study: Study):
    """The command's device (``--device``, else ``execution.device``), made the process's
    (:func:`gearsim.numerics.device.select`; cuda that cannot run is one line, exit 2)."""
    from gearsim.numerics.device import select

    if getattr(args, "device", None):
        return select(args.device, "--device")
    return select(study.config.get("execution", {}).get("device", "cpu"), "execution.device")


#: physical options of every simulating command -> the gear-file name they set (docs/units.md)
PHYSICAL_OPTIONS = {"rpm": "speed_rpm", "torque": "torque_Nm", "backlash": "half_backlash_um"}


def add_parameter_arguments(p: argparse.ArgumentParser, *, integration: bool = True) -> None:
    """The parameter options of every command that simulates: ``--configfile``,
    ``--config-json``, ``--params``, ``--set``, ``--gear`` with ``--rpm`` / ``--torque`` /
    ``--backlash`` and, with ``integration``, ``--method`` / ``--rtol``. One resolution for all:
    :func:`command_parameters`."""
    add_config_arguments(p)
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
        help="override a model parameter (repeatable), e.g. --set xi=0.05; with a gear file "
        "also speed_rpm, torque_Nm, half_backlash_um, te_amplitude_um",
    )
    p.add_argument(
        "--gear",
        metavar="YAML",
        help="gear file in physical units (config/gears/*.yaml, docs/units.md): its "
        "dimensionless set replaces the standard parameters",
    )
    p.add_argument("--rpm", type=float, default=None,
                   help="speed of the non-circular gear in rpm (needs a gear file; sets w)")
    p.add_argument("--torque", type=float, default=None,
                   help="driving torque on the non-circular gear in N m (needs a gear file; "
                   "sets Fm)")
    p.add_argument("--backlash", type=float, default=None,
                   help="half backlash in um (needs a gear file; sets b)")
    if integration:
        p.add_argument(
            "--method",
            choices=("dp5", "rk4"),
            default=None,
            help="integrator (default: the study's integration.method, rk4)",
        )
        p.add_argument(
            "--rtol", type=float, default=None,
            help="DP5 relative tolerance (default: the study's)",
        )


def _file_option(flag: str, path: str) -> str:
    f = Path(path)
    if not f.is_file():
        raise UsageError(f"{flag} {path}: no such file")
    return str(f.resolve())


def study_from_args(args: argparse.Namespace) -> Study:
    """The study of a command: config/config.yaml, the ``--configfile`` files, the
    ``--config-json`` overrides (Snakemake's order; :meth:`gearsim.study.config.Study.load`),
    then ``--gear`` / ``--params`` (which file gives the parameter set). A command asks once
    and passes the study on."""
    overrides: dict = {}
    if getattr(args, "config_json", None):
        try:
            overrides = json.loads(args.config_json)
        except (json.JSONDecodeError, RecursionError) as exc:
            raise UsageError(f"--config-json is not valid JSON ({exc})") from None
        if not isinstance(overrides, dict):
            raise UsageError("--config-json must be a JSON mapping of config keys")
    gear, params = getattr(args, "gear", None), getattr(args, "params", None)
    if gear and params:
        raise ParameterError("--gear and --params both give the parameter set; use one")
    if gear:
        overrides["gear"] = _file_option("--gear", gear)
    if params:
        overrides["standard_parameters"] = _file_option("--params", params)
        overrides["gear"] = None
    return Study.load(getattr(args, "configfile", None) or (), overrides or None)


@dataclass(frozen=True)
class CommandParameters:
    """The parameters a command simulates, where they came from, and the study behind them.

    ``study`` is the command's study with the command line's values folded into its
    ``parameters`` (what a sweep records in its provenance); ``gear`` the gear file's geometry
    (``None`` without one)."""

    params: ModelParameters
    source: str
    study: Study
    gear: GearGeometry | None
    gear_path: str | None


def check_plane(study: Study, plane: str) -> None:
    """``plane`` is one of the study's planes; else one line naming them (a usage error)."""
    planes = study.config.get("planes") or {}
    if plane not in planes:
        raise UsageError(f"unknown plane '{plane}'; configured: {', '.join(planes) or 'none'}")


def _cli_values(args: argparse.Namespace) -> tuple[dict, dict, list[str]]:
    """(numeric values, text values, source words) of ``--set`` and the physical options."""
    numbers: dict = {}
    words: list[str] = []
    text = {}
    sets = _assignments(args)
    for name, value in sets.items():
        (text if isinstance(value, str) else numbers)[name] = value
    if sets:
        words.append("--set " + ", ".join(f"{k}={v}" for k, v in sets.items()))
    for opt, name in PHYSICAL_OPTIONS.items():
        value = getattr(args, opt, None)
        if value is None:
            continue
        if name in numbers:
            raise ParameterError(f"--set {name} and --{opt} both set {name}; give one")
        numbers[name] = value
        words.append(f"--{opt} {value:g}")
    return numbers, text, words


def command_parameters(args: argparse.Namespace, *, omega_required: bool = False,
                       **extra: float | None) -> CommandParameters:
    """A simulating command's parameters: its study's (:func:`study_from_args`), then
    ``--set`` values and ``--rpm`` / ``--torque`` / ``--backlash`` (physical names converted
    with the gear file), then ``extra`` (a command's own option such as ``--omega``; ``None`` =
    not given), resolved by :meth:`gearsim.study.config.Study.parameters`. A value given twice
    is an error, never a silent choice. ``omega_required``: a one-point command, whose mesh
    frequency must be given (``--omega``, ``--set w=...``, ``--rpm`` with a gear file, or the
    study's ``parameters``)."""
    study = study_from_args(args)
    sets = _assignments(args)
    if omega_required and (extra.get("w") is None and "w" not in sets
                           and "speed_rpm" not in sets and "mesh_frequency_Hz" not in sets
                           and getattr(args, "rpm", None) is None
                           and "w" not in (study.config.get("parameters") or {})):
        raise ParameterError("give --omega W (dimensionless mesh frequency), --set w=W, or "
                             "--gear FILE with --rpm N")
    numbers, text, words = _cli_values(args)
    gear = config_gear(study.config, study.root)
    if any(name in PHYSICAL_AXES for name in numbers) and gear is None:
        raise ParameterError("--rpm, --torque, --backlash and physical --set names need a gear "
                             f"file: add --gear {DEFAULT_GEAR} (or your own, docs/units.md)")
    for opt, name in PHYSICAL_OPTIONS.items():  # the gear file's own range check, by option
        if getattr(args, opt, None) is not None:
            try:
                replace(gear, **{name: getattr(args, opt)})
            except ParameterError as exc:
                raise ParameterError(f"--{opt}: {exc}") from None
    numbers = dimensionless_mapping(numbers, gear, "--set")
    given = {k: v for k, v in extra.items() if v is not None}
    for name in given:
        if name in numbers or name in text:
            flag = "--omega" if name == "w" else f"--{name}"
            raise ParameterError(f"{name} is set twice (--set or a physical option, and {flag});"
                                 " give one")
    resolved = study.parameters(changes={**numbers, **text, **given},
                                words=" + ".join(words))
    source = resolved.source
    if getattr(args, "params", None):
        source = source.replace(str(Path(args.params).resolve()), args.params, 1)
    if getattr(args, "gear", None):
        source = source.replace(str(Path(args.gear).resolve()), args.gear, 1)
    return CommandParameters(resolved.model, source, study.with_parameters(numbers), gear,
                             study.config.get("gear"))


def _assignments(args: argparse.Namespace) -> dict:
    out: dict = {}
    for item in getattr(args, "set", []) or []:
        name, value = parse_assignment(item)
        if name in out and out[name] != value:
            raise ParameterError(f"--set {name} is given twice with different values")
        out[name] = value
    return out


def settings_from_args(args: argparse.Namespace, study: Study) -> IntegrationSettings:
    """The study's integration settings with ``--method`` / ``--rtol`` applied."""
    kw: dict = {}
    if getattr(args, "method", None) is not None:
        kw["method"] = args.method
    if getattr(args, "rtol", None) is not None:
        kw["rtol"] = args.rtol
    return study.settings.with_(**kw) if kw else study.settings


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
