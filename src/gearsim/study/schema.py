"""The configuration's schema and the checks a schema cannot express.

``workflow/schemas/config.schema.yaml`` gives the layout, types, ranges and defaults;
:func:`check_config` the rest (finite numbers, names, axes, plane sizes, point sets, the
integration budget, physical units). A bad key fails with one line that names it. The study's
parameters are checked where they are resolved (:class:`gearsim.study.config.Study`).
"""

from __future__ import annotations

import copy
import math
import re
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml
from jsonschema import Draft202012Validator, validators

from gearsim.dynamics.parameters import ModelParameters, ParameterError, check_value
from gearsim.errors import ConfigError
from gearsim.numerics.settings import INTEGER_BOUNDS, IntegrationSettings
from gearsim.study.grid import axis_values, sweep_values

#: Names of planes, sweeps, point sets and studies: a letter, then letters, digits or ``_``.
MAX_NAME_LENGTH = 64
NAME_PATTERN = re.compile(rf"[A-Za-z][A-Za-z0-9_]{{0,{MAX_NAME_LENGTH - 1}}}")
#: Largest plane (cells); a 2000 x 2000 plane is the documented scale test (docs/pipeline.md).
MAX_PLANE_CELLS = 4_000_000
#: Smallest positive normal float: smaller non-zero values (subnormals) are refused.
SMALLEST_NORMAL = sys.float_info.min
#: Names a plane may not take (they are directories of results/ used by other outputs).
RESERVED_PLANE_NAMES = ("sweeps", "points", "figures", "benchmarks", "logs", "report")
SCHEMA_RELATIVE = Path("workflow/schemas/config.schema.yaml")


# ---------------------------------------------------------------------------------- schema
def project_root() -> Path:
    """The source checkout holding ``src/gearsim`` (config/, workflow/ live there)."""
    # src/gearsim/config.py -> project root (editable install / source checkout)
    return Path(__file__).resolve().parents[3]


def schema_path(root: str | Path | None = None) -> Path:
    """Location of ``workflow/schemas/config.schema.yaml`` (``root`` first, then the checkout)."""
    candidates = []
    if root is not None:
        candidates.append(Path(root) / SCHEMA_RELATIVE)
    candidates += [Path.cwd() / SCHEMA_RELATIVE, project_root() / SCHEMA_RELATIVE]
    for c in candidates:
        if c.is_file():
            return c
    raise ConfigError(f"config schema not found (looked for {SCHEMA_RELATIVE} in the project)")


def load_schema(root: str | Path | None = None) -> dict:
    return yaml.safe_load(schema_path(root).read_text())


def _key(path: Iterable[Any]) -> str:
    parts = [str(p) for p in path]
    return ".".join(parts) if parts else "<top level>"


def _format_error(err) -> str:
    """One line naming the config key of a jsonschema ValidationError."""
    path = list(err.absolute_path)
    v = err.validator
    if v == "additionalProperties":
        allowed = sorted(err.schema.get("properties", {}))
        extra = sorted(set(err.instance) - set(allowed)) if isinstance(err.instance, dict) else []
        key = _key(path + extra[:1])
        hint = f" (allowed: {', '.join(allowed)})" if allowed else ""
        return f"config key '{key}': unknown key{hint}"
    if v == "required":
        missing = err.message.split("'")[1] if "'" in err.message else err.message
        return f"config key '{_key(path + [missing])}': required key is missing"
    if v == "propertyNames":
        return f"config key '{_key(path)}': name {err.instance!r} must match {err.schema}"
    if v == "type":
        want = err.validator_value
        want = " or ".join(want) if isinstance(want, list) else want
        return f"config key '{_key(path)}': {err.instance!r} is not of type {want}"
    return f"config key '{_key(path)}': {err.message}"


def _validator_with_defaults(schema: dict):
    base = Draft202012Validator

    def set_defaults(validator, properties, instance, schema):
        if isinstance(instance, dict):
            for name, sub in properties.items():
                if "default" in sub and name not in instance:
                    instance[name] = copy.deepcopy(sub["default"])
        yield from base.VALIDATORS["properties"](validator, properties, instance, schema)

    cls = validators.extend(base, {"properties": set_defaults})
    return cls(schema)


def validate_schema(config: dict, schema: dict | None = None) -> dict:
    """Fill schema defaults into ``config`` (in place) and raise :class:`ConfigError` if invalid."""
    if not isinstance(config, dict):
        raise ConfigError("the configuration must be a mapping")
    schema = load_schema() if schema is None else schema
    validator = _validator_with_defaults(schema)
    errors = list(validator.iter_errors(config))
    if errors:
        errors.sort(key=lambda e: (len(list(e.absolute_path)), [str(p) for p in e.absolute_path]))
        # prefer the deepest error on the first offending path (most specific message)
        first = errors[0]
        raise ConfigError(_format_error(first))
    return config


# ------------------------------------------------------------------------- semantic checks
def _check_names(mapping: Mapping[str, Any], where: str) -> None:
    names = set(ModelParameters.names()) | {"model"}
    for name, value in mapping.items():
        if name not in names:
            raise ConfigError(
                f"config key '{where}.{name}': unknown parameter '{name}'; "
                f"allowed: {', '.join(ModelParameters.names())}"
            )
        if name == "model":
            continue
        try:
            check_value(name, value)
        except ParameterError as exc:
            text = str(exc).replace(f"= {value!r}", f"= {as_written(value)}")
            raise ConfigError(f"config key '{where}.{name}': {text}") from None


def as_written(v: Any) -> str:
    """A config value as a user would write it in YAML: ``1.0e8``, ``0.25``, ``400``."""
    if isinstance(v, bool) or not isinstance(v, float) or not math.isfinite(v):
        return repr(v)
    if v != 0 and not 1e-4 <= abs(v) < 1e6:
        mant, exp = f"{v:.15e}".split("e")
        mant = mant.rstrip("0")
        mant = mant + "0" if mant.endswith(".") else mant
        return f"{mant}e{int(exp)}"
    return repr(v)


def _check_axis(axis: Mapping[str, Any], where: str, *, centres: bool) -> None:
    name = axis["name"]
    if name not in ModelParameters.names():
        raise ConfigError(
            f"config key '{where}.name': unknown parameter '{name}'; "
            f"allowed: {', '.join(ModelParameters.names())}"
        )
    lo, hi = float(axis["min"]), float(axis["max"])
    if not (math.isfinite(lo) and math.isfinite(hi)) or not lo < hi:
        raise ConfigError(
            f"config key '{where}': empty or reversed range min={axis['min']!r} "
            f"max={axis['max']!r} (need min < max)"
        )
    if int(axis["n"]) < 1:
        raise ConfigError(f"config key '{where}.n': resolution must be positive, got {axis['n']}")
    vals = axis_values(axis) if centres else sweep_values(axis)
    # the ends as the user wrote them first: a message names the key and value in the file
    # (a plane's cells lie inside [min, max], so an end outside the range but with its cells
    # inside, e.g. b: min 0 of an open range, is allowed)
    bad_ends = {}
    for key in ("min", "max"):
        try:
            check_value(name, float(axis[key]))
        except ParameterError as exc:
            bad_ends[key] = exc
    for v, key in ((vals[0], "min"), (vals[-1], "max")):
        try:
            check_value(name, float(v))
        except ParameterError as exc:
            end = key if key in bad_ends else next(iter(bad_ends), None)
            if end is None:  # both ends allowed, a cell centre not (cannot happen for a range)
                raise ConfigError(f"config key '{where}': {exc}") from None
            text = str(bad_ends[end]).replace(f"= {float(axis[end])!r}",
                                              f"= {as_written(axis[end])}")
            raise ConfigError(f"config key '{where}.{end}': {as_written(axis[end])}: {text}"
                              ) from None


def _physical_units(config: dict, root: Path) -> None:
    """Names in rpm / N m / um (``gear`` file) -> w / Fm / Fe / b, in place (docs/units.md)."""
    from gearsim.physical.units import dimensionless_config

    try:
        dimensionless_config(config, root)
    except ParameterError as exc:
        raise ConfigError(str(exc)) from None


def check_config(config: dict, root: str | Path) -> dict:
    """Checks beyond the schema; call after :func:`validate_schema`. Returns ``config``.

    ``root`` is the study directory that relative paths are resolved against
    (:func:`gearsim.study.config.study_root`). The parameters are checked by
    :class:`gearsim.study.config.Study`.
    """
    _check_finite(config, [])
    _check_limits(config)
    study = config.get("study")
    if study is not None:
        _check_name(study, "study")
    folder = config.get("folder")
    if folder is not None:
        _check_name(folder, "folder")
        if study is not None and folder != study:
            raise ConfigError(f"config key 'folder': {folder!r} differs from study {study!r} "
                              "(a study runs in studies/<study>/; leave folder out)")
    _physical_units(config, Path(root))
    _check_names(config.get("parameters", {}), "parameters")
    rows = int(config["tile_rows"])
    for kind in ("planes", "sweeps", "points"):
        for name in config.get(kind, {}):
            _check_name(name, f"{kind}.{name!r}")
    for pname, plane in config.get("planes", {}).items():
        where = f"planes.{pname}"
        if pname in RESERVED_PLANE_NAMES:
            raise ConfigError(f"config key '{where}': reserved name (used by other results)")
        _check_axis(plane["x"], f"{where}.x", centres=True)
        _check_axis(plane["y"], f"{where}.y", centres=True)
        if plane["x"]["name"] == plane["y"]["name"]:
            raise ConfigError(f"config key '{where}': axes x and y name the same parameter")
        fixed = plane.get("fixed", {})
        _check_names(fixed, f"{where}.fixed")
        for ax in ("x", "y"):
            if plane[ax]["name"] in fixed:
                raise ConfigError(
                    f"config key '{where}.fixed.{plane[ax]['name']}': is also axis {ax}"
                )
        if rows > int(plane["y"]["n"]):
            raise ConfigError(
                f"config key 'tile_rows': {rows} is larger than the grid of plane '{pname}' "
                f"({plane['y']['n']} rows): set tile_rows (plane rows per job) to 1.."
                f"{plane['y']['n']}"
            )
        cells = int(plane["x"]["n"]) * int(plane["y"]["n"])
        if cells > MAX_PLANE_CELLS:
            raise ConfigError(
                f"config key '{where}': {plane['x']['n']} x {plane['y']['n']} = {cells} cells is "
                f"more than the limit of {MAX_PLANE_CELLS} cells per plane (docs/pipeline.md)"
            )
    for sname, sweep in config.get("sweeps", {}).items():
        where = f"sweeps.{sname}"
        _check_axis(sweep, where, centres=False)
        _check_names(sweep.get("fixed", {}), f"{where}.fixed")
        if sweep["name"] in sweep.get("fixed", {}):
            raise ConfigError(f"config key '{where}.fixed.{sweep['name']}': is the swept name")
    for fig, spec in config.get("points", {}).items():
        if isinstance(spec, dict):
            if "w" not in spec:
                raise ConfigError(
                    f"config key 'points.{fig}.w': required key is missing (every point needs "
                    "a mesh frequency w)"
                )
            _check_names(
                {k: (v[0] if isinstance(v, list) else v) for k, v in spec.items()}, f"points.{fig}"
            )
            for k, v in spec.items():
                for item in v if isinstance(v, list) else [v]:
                    try:
                        check_value(k, item)
                    except ParameterError as exc:
                        raise ConfigError(f"config key 'points.{fig}.{k}': {exc}") from None
        else:
            for item in spec:
                try:
                    check_value("w", item)
                except ParameterError as exc:
                    raise ConfigError(f"config key 'points.{fig}': {exc}") from None
    try:
        IntegrationSettings(**(config.get("integration") or {}))
    except ParameterError as exc:
        raise ConfigError(f"config key 'integration': {exc}") from None
    return config


def _check_name(name: Any, where: str) -> None:
    if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name):
        shown = repr(name)[:40] if isinstance(name, str) else type(name).__name__
        raise ConfigError(
            f"config key '{where}': name {shown} must be a letter then letters, digits or _ "
            f"(at most {MAX_NAME_LENGTH} characters)"
        )


def _check_finite(node: Any, path: list) -> None:
    """Every number of the configuration is finite and not subnormal (no NaN, inf, 1e-320)."""
    if isinstance(node, Mapping):
        for k, v in node.items():
            _check_finite(v, [*path, k])
    elif isinstance(node, list):
        for k, v in enumerate(node):
            _check_finite(v, [*path, k])
    elif isinstance(node, float) and not isinstance(node, bool):
        if not math.isfinite(node):
            raise ConfigError(f"config key '{_key(path)}': {node!r} is not a finite number")
        if node != 0.0 and abs(node) < SMALLEST_NORMAL:
            raise ConfigError(
                f"config key '{_key(path)}': {node!r} is subnormal (|value| < {SMALLEST_NORMAL:g})"
            )


def _check_limits(config: Mapping) -> None:
    """Documented upper bounds of the integration budget (beyond them a cell never ends)."""
    for name, (_, limit) in INTEGER_BOUNDS.items():
        v = (config.get("integration") or {}).get(name)
        if isinstance(v, (int, float)) and not isinstance(v, bool) and v > limit:
            raise ConfigError(
                f"config key 'integration.{name}': {v!r} is more than the limit of {limit}"
            )


