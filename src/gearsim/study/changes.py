"""A simulating command's parameters: its study's, changed by ``name=value`` assignments, the
physical options (speed, torque, backlash, converted with the gear file) and a command's own
values, resolved once by :meth:`gearsim.study.config.Study.parameters`. A value given twice is
an error, never a silent choice."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path

from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.physical.geometry import GearGeometry
from gearsim.physical.units import (
    DEFAULT_GEAR,
    PHYSICAL_AXES,
    config_gear,
    dimensionless_mapping,
)
from gearsim.study.config import Study

#: physical options of every simulating command -> the gear-file name they set (docs/units.md)
PHYSICAL_OPTIONS = {"rpm": "speed_rpm", "torque": "torque_Nm", "backlash": "half_backlash_um"}


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


def assignments(items: Iterable[str]) -> dict:
    """``--set`` items as ``{name: value}``; a name given twice with two values is an error."""
    out: dict = {}
    for item in items:
        name, value = parse_assignment(item)
        if name in out and out[name] != value:
            raise ParameterError(f"--set {name} is given twice with different values")
        out[name] = value
    return out


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


def _values(sets: Mapping, physical: Mapping[str, float | None]
            ) -> tuple[dict, dict, list[str]]:
    """(numeric values, text values, source words) of ``--set`` and the physical options."""
    numbers: dict = {}
    words: list[str] = []
    text = {}
    for name, value in sets.items():
        (text if isinstance(value, str) else numbers)[name] = value
    if sets:
        words.append("--set " + ", ".join(f"{k}={v}" for k, v in sets.items()))
    for opt, name in PHYSICAL_OPTIONS.items():
        value = physical.get(opt)
        if value is None:
            continue
        if name in numbers:
            raise ParameterError(f"--set {name} and --{opt} both set {name}; give one")
        numbers[name] = value
        words.append(f"--{opt} {value:g}")
    return numbers, text, words


def resolve(study: Study, *, sets: Iterable[str] = (),
            physical: Mapping[str, float | None] | None = None,
            extra: Mapping[str, float | None] | None = None, omega_required: bool = False,
            params_path: str | None = None, gear_path: str | None = None,
            sweep: str | None = None) -> CommandParameters:
    """``study``'s parameters with ``sets`` (``name=value``), then ``physical``
    (``{rpm, torque, backlash}``, converted with the gear file), then ``extra`` (a command's own
    option such as ``--omega``; ``None`` = not given). ``omega_required``: a one-point command,
    whose mesh frequency must be given (``--omega``, ``--set w=...``, ``--rpm`` with a gear
    file, or the study's ``parameters``). ``params_path`` / ``gear_path``: the files as the user
    named them, for the source text. ``sweep``: start from that configured sweep's parameter set
    (its ``fixed`` values on top of the study's), as the sweep itself runs."""
    physical = dict(physical or {})
    extra = dict(extra or {})
    sweeps = study.config.get("sweeps") or {}
    if sweep is not None and sweep not in sweeps:
        raise ParameterError(f"--of-sweep {sweep}: not a sweep of the study; configured: "
                             f"{', '.join(sweeps) or 'none'}")
    given_sets = assignments(sets)
    if omega_required and (extra.get("w") is None and "w" not in given_sets
                           and "speed_rpm" not in given_sets
                           and "mesh_frequency_Hz" not in given_sets
                           and physical.get("rpm") is None
                           and "w" not in (study.config.get("parameters") or {})):
        raise ParameterError("give --omega W (dimensionless mesh frequency), --set w=W, or "
                             "--gear FILE with --rpm N")
    numbers, text, words = _values(given_sets, physical)
    gear = config_gear(study.config, study.root)
    if any(name in PHYSICAL_AXES for name in numbers) and gear is None:
        raise ParameterError("--rpm, --torque, --backlash and physical --set names need a gear "
                             f"file: add --gear {DEFAULT_GEAR} (or your own, docs/units.md)")
    for opt, name in PHYSICAL_OPTIONS.items():  # the gear file's own range check, by option
        if physical.get(opt) is not None:
            try:
                replace(gear, **{name: physical[opt]})
            except ParameterError as exc:
                raise ParameterError(f"--{opt}: {exc}") from None
    numbers = dimensionless_mapping(numbers, gear, "--set")
    given = {k: v for k, v in extra.items() if v is not None}
    for name in given:
        if name in numbers or name in text:
            flag = "--omega" if name == "w" else f"--{name}"
            raise ParameterError(f"{name} is set twice (--set or a physical option, and {flag});"
                                 " give one")
    resolved = study.parameters(sweep=sweep, changes={**numbers, **text, **given},
                                words=" + ".join(words))
    source = resolved.source
    if params_path:
        source = source.replace(str(Path(params_path).resolve()), params_path, 1)
    if gear_path:
        source = source.replace(str(Path(gear_path).resolve()), gear_path, 1)
    return CommandParameters(resolved.model, source, study.with_parameters(numbers), gear,
                             study.config.get("gear"))
