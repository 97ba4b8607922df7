"""The pipeline configuration: schema, checks, loading and merging, resolved parameters.

``config/config.yaml`` and the files merged over it (layout and defaults in
``workflow/schemas/config.schema.yaml``, described in docs/pipeline.md) are checked twice with
the same code: by the workflow before any job (``workflow/rules/common.smk``) and by the
``gearsim`` CLI (:func:`load_config`), so a bad key fails with one line that names it, never a
traceback. The model parameters a configuration simulates (standard-parameter file, then
``parameters``, then a plane's ``fixed``) and its integration settings are resolved here only.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml
from jsonschema import Draft202012Validator, validators

from .config_io import load_standard_parameters, load_yaml
from .errors import ConfigError
from .grid import axis_values, sweep_values
from .parameters import ModelParameters, ParameterError, check_value
from .simulate import IntegrationSettings

__all__ = ["ConfigError"]

DEFAULT_CONFIG = "config/config.yaml"
#: Names a plane may not take (they are directories of results/ used by other outputs).
RESERVED_PLANE_NAMES = ("sweeps", "points", "figures", "benchmarks", "logs", "report")
SCHEMA_RELATIVE = Path("workflow/schemas/config.schema.yaml")


# ---------------------------------------------------------------------------------- schema
def project_root() -> Path:
    """The source checkout holding ``src/gearsim`` (config/, workflow/ live there)."""
    # src/gearsim/config.py -> project root (editable install / source checkout)
    return Path(__file__).resolve().parents[2]


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
            raise ConfigError(f"config key '{where}.{name}': {exc}") from None


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
    for v in (vals[0], vals[-1]):
        try:
            check_value(name, float(v))
        except ParameterError as exc:
            raise ConfigError(f"config key '{where}': {exc}") from None


def check_config(config: dict, root: str | Path = ".") -> dict:
    """Checks beyond the schema; call after :func:`validate_schema`. Returns ``config``."""
    _check_names(config.get("parameters", {}), "parameters")
    sp = config.get("standard_parameters")
    if sp and (Path(root) / sp).is_file():
        try:
            load_standard_parameters(Path(root) / sp)
        except ParameterError as exc:
            raise ConfigError(f"config key 'standard_parameters': {exc}") from None
    rows = int(config["tile_rows"])
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
                f"({plane['y']['n']} rows)"
            )
        try:
            plane_base(config, pname, root=root)
        except ParameterError as exc:
            raise ConfigError(f"config key '{where}': {exc}") from None
    for sname, sweep in config.get("sweeps", {}).items():
        where = f"sweeps.{sname}"
        _check_axis(sweep, where, centres=False)
        _check_names(sweep.get("fixed", {}), f"{where}.fixed")
        if sweep["name"] in sweep.get("fixed", {}):
            raise ConfigError(f"config key '{where}.fixed.{sweep['name']}': is the swept name")
    for fig, spec in config.get("points", {}).items():
        if isinstance(spec, dict):
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
        integration_settings(config)
    except ParameterError as exc:
        raise ConfigError(f"config key 'integration': {exc}") from None
    return config


def merge(base: dict, update: Mapping) -> dict:
    """Recursive update (Snakemake's semantics for config files given with --configfile)."""
    for key, value in update.items():
        if isinstance(value, Mapping) and isinstance(base.get(key), dict):
            merge(base[key], value)
        else:
            base[key] = copy.deepcopy(value)
    return base


def load_config(
    paths: str | Path | Iterable[str | Path],
    overrides: Mapping | None = None,
    root: str | Path = ".",
) -> dict:
    """Merge config files in order (later wins, recursively), validate and fill defaults."""
    if isinstance(paths, (str, Path)):
        paths = [paths]
    config: dict = {}
    for p in paths:
        try:
            doc = load_yaml(p)
        except ParameterError as exc:
            raise ConfigError(str(exc)) from None
        if doc is None:
            doc = {}
        if not isinstance(doc, dict):
            raise ConfigError(f"{p}: a config file must be a mapping of keys")
        merge(config, doc)
    if overrides:
        merge(config, overrides)
    validate_schema(config)
    return check_config(config, root=root)


# ------------------------------------------------------------------- parameters, settings
def base_parameters(config: Mapping, root: str | Path = ".") -> tuple[dict[str, Any], str]:
    """Standard parameters (file, or built-in defaults when absent) plus ``parameters`` overrides.

    Returns the values and their source: the file path, or ``"builtin-defaults"``.
    """
    values: dict[str, Any] = {}
    source = "builtin-defaults"
    sp = config.get("standard_parameters")
    if sp and (Path(root) / sp).is_file():
        values = dict(load_standard_parameters(Path(root) / sp))
        source = str(sp)
    values.update(config.get("parameters", {}) or {})
    return values, source


def resolved_parameters(config: Mapping, root: str | Path = ".") -> dict[str, Any]:
    """The full parameter set (every ModelParameters field) the pipeline simulates from."""
    values, _ = base_parameters(config, root)
    return ModelParameters.from_mapping(values).to_dict()


def plane_base(config: Mapping, plane: str, root: str | Path = ".") -> ModelParameters:
    values, _ = base_parameters(config, root)
    values.update(config["planes"][plane].get("fixed", {}) or {})
    return ModelParameters.from_mapping(values)


def integration_settings(config: Mapping) -> IntegrationSettings:
    """The :class:`~gearsim.simulate.IntegrationSettings` of ``config['integration']``."""
    return IntegrationSettings(**(config.get("integration") or {}))


