"""What the subcommands share: their common options, a command's study
(:func:`study_from_args`), the command line's parameter values (:func:`command_parameters`,
resolved by :mod:`gearsim.study.changes`) and output-path checks."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from gearsim.dynamics.parameters import ParameterError
from gearsim.errors import UsageError
from gearsim.numerics.settings import IntegrationSettings
from gearsim.study.changes import (  # noqa: F401 - parse_assignment: the commands' one parser
    PHYSICAL_OPTIONS,
    CommandParameters,
    parse_assignment,
    resolve,
)
from gearsim.study.config import Study


def add_config_arguments(p: argparse.ArgumentParser) -> None:
    """``--configfile`` and ``--config-json``: the study's configuration, as Snakemake reads it."""
    p.add_argument("--configfile", metavar="YAML", nargs="+", action="extend", default=[],
                   help="study config file(s) (YAML or JSON) merged over config/config.yaml in "
                   "order, like `snakemake --configfile`")
    p.add_argument("--config-json", metavar="JSON", default=None,
                   help="overrides merged last, like `snakemake --config` (a JSON mapping)")


def add_device_argument(p: argparse.ArgumentParser) -> None:
    """``--device``: where a simulating command's lanes run (over ``execution.device``)."""
    from gearsim.numerics.device import DEVICES

    p.add_argument("--device", choices=DEVICES, default=None,
                   help="where the lanes run: cpu (SIMD kernel), cuda (GPU; needs numba-cuda) or "
                   "auto (default: execution.device of the config)")


def select_device(args: argparse.Namespace, study: Study):
    """The lanes backend of the command's device (``--device``, else the study's
    ``execution.device``; :func:`gearsim.numerics.backend.select`: cuda that cannot run is one
    line, exit 2)."""
    from gearsim.numerics.backend import select

    asked = getattr(args, "device", None)
    return select(study.with_device(asked).execution.device,
                  "--device" if asked else "execution.device")


def add_parameter_arguments(p: argparse.ArgumentParser, *, integration: bool = True) -> None:
    """The parameter options of every command that simulates: ``--configfile``,
    ``--config-json``, ``--params``, ``--set``, ``--gear`` with ``--rpm`` / ``--torque`` /
    ``--backlash`` and, with ``integration``, ``--method`` / ``--rtol``. One resolution for all:
    :func:`command_parameters`."""
    add_config_arguments(p)
    p.add_argument("--params", metavar="YAML",
                   help="standard-parameter file replacing the study's (default: "
                   "standard_parameters of config/config.yaml, i.e. "
                   "config/standard_parameters.yaml)")
    p.add_argument("--set", metavar="NAME=VALUE", action="append", default=[],
                   help="override a model parameter (repeatable), e.g. --set xi=0.05; with a "
                   "gear file also speed_rpm, torque_Nm, half_backlash_um, te_amplitude_um")
    p.add_argument("--gear", metavar="YAML",
                   help="gear file in physical units (config/gears/*.yaml, docs/units.md): its "
                   "dimensionless set replaces the standard parameters")
    p.add_argument("--rpm", type=float, default=None,
                   help="speed of the non-circular gear in rpm (needs a gear file; sets w)")
    p.add_argument("--torque", type=float, default=None,
                   help="driving torque on the non-circular gear in N m (needs a gear file; "
                   "sets Fm)")
    p.add_argument("--backlash", type=float, default=None,
                   help="half backlash in um (needs a gear file; sets b)")
    if integration:
        p.add_argument("--method", choices=("dp5", "rk4"), default=None,
                       help="integrator (default: the study's integration.method, rk4)")
        p.add_argument("--rtol", type=float, default=None,
                       help="DP5 relative tolerance (default: the study's)")


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


def check_plane(study: Study, plane: str) -> None:
    """``plane`` is one of the study's planes; else one line naming them (a usage error)."""
    planes = study.config.get("planes") or {}
    if plane not in planes:
        raise UsageError(f"unknown plane '{plane}'; configured: {', '.join(planes) or 'none'}")


def command_parameters(args: argparse.Namespace, *, omega_required: bool = False,
                       **extra: float | None) -> CommandParameters:
    """A simulating command's parameters (:func:`gearsim.study.changes.resolve`): its study
    (:func:`study_from_args`), ``--set``, ``--rpm`` / ``--torque`` / ``--backlash``, then
    ``extra`` (a command's own option such as ``--omega``; ``None`` = not given)."""
    return resolve(study_from_args(args), sets=getattr(args, "set", None) or (),
                   physical={opt: getattr(args, opt, None) for opt in PHYSICAL_OPTIONS},
                   extra=extra, omega_required=omega_required,
                   params_path=getattr(args, "params", None),
                   gear_path=getattr(args, "gear", None),
                   sweep=getattr(args, "of_sweep", None))


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
