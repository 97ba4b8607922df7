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
import os
import re
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml
from jsonschema import Draft202012Validator, validators

from gearsim.cell.simulate import IntegrationSettings
from gearsim.dynamics.parameters import ModelParameters, ParameterError, check_value
from gearsim.errors import ConfigError
from gearsim.numerics.integrate import INTEGER_BOUNDS
from gearsim.safe_yaml import load_mapping
from gearsim.study.config_io import load_standard_parameters
from gearsim.study.grid import axis_values, sweep_values

__all__ = ["ConfigError"]

DEFAULT_CONFIG = "config/config.yaml"
DEFAULT_STANDARD_PARAMETERS = "config/standard_parameters.yaml"
#: Names of planes, sweeps, point sets and studies: a letter, then letters, digits or ``_``.
MAX_NAME_LENGTH = 64
NAME_PATTERN = re.compile(rf"[A-Za-z][A-Za-z0-9_]{{0,{MAX_NAME_LENGTH - 1}}}")
#: Largest plane (cells); a 2000 x 2000 plane is the documented scale test (docs/pipeline.md).
MAX_PLANE_CELLS = 4_000_000
#: Smallest positive normal float: smaller non-zero values (subnormals) are refused.
SMALLEST_NORMAL = sys.float_info.min
#: Environment variable naming the study directory of workflow jobs (see :func:`study_root`).
STUDY_ROOT_ENV = "GEARSIM_STUDY_ROOT"
#: What a study file replaces instead of merging (:func:`merge_study`).
STUDY_KEYS = ("planes", "sweeps", "points")
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


def _physical_units(config: dict, root: str | Path | None) -> None:
    """Names in rpm / N m / um (``gear`` file) -> w / Fm / Fe / b, in place (docs/units.md)."""
    from gearsim.physical.units import dimensionless_config

    try:
        dimensionless_config(config, study_root(root))
    except ParameterError as exc:
        raise ConfigError(str(exc)) from None


def check_config(config: dict, root: str | Path | None = None) -> dict:
    """Checks beyond the schema; call after :func:`validate_schema`. Returns ``config``.

    ``root`` is the study directory that relative paths are resolved against
    (default :func:`study_root`).
    """
    _check_finite(config, [])
    _check_limits(config)
    study = config.get("study")
    if study is not None:
        _check_name(study, "study")
    _physical_units(config, root)
    _check_names(config.get("parameters", {}), "parameters")
    base_parameters(config, root)  # the standard-parameter file exists and is valid
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
                f"({plane['y']['n']} rows)"
            )
        cells = int(plane["x"]["n"]) * int(plane["y"]["n"])
        if cells > MAX_PLANE_CELLS:
            raise ConfigError(
                f"config key '{where}': {plane['x']['n']} x {plane['y']['n']} = {cells} cells is "
                f"more than the limit of {MAX_PLANE_CELLS} cells per plane (docs/pipeline.md)"
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
        integration_settings(config)
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


def merge(base: dict, update: Mapping) -> dict:
    """Recursive update (Snakemake's semantics for config files given with --configfile)."""
    for key, value in update.items():
        if isinstance(value, Mapping) and isinstance(base.get(key), dict):
            merge(base[key], value)
        else:
            base[key] = copy.deepcopy(value)
    return base


def merge_study(config: dict, doc: Mapping) -> dict:
    """Merge one config file (or ``--config`` overrides) over ``config``.

    Snakemake's rule (recursive update), with one addition: a document that names a ``study``
    starts its own ``planes``, ``sweeps`` and ``points`` (those merged before it are dropped), so
    a study file runs only what it lists. Snakemake's own merge is redone this way in
    ``workflow/rules/common.smk``.
    """
    if doc.get("study") is not None:
        for key in STUDY_KEYS:
            config[key] = {}
    return merge(config, doc)


def load_config(
    paths: str | Path | Iterable[str | Path],
    overrides: Mapping | None = None,
    root: str | Path | None = None,
) -> dict:
    """Merge config files in order (later wins, recursively; :func:`merge_study`), validate and
    fill defaults. Relative paths inside are resolved against ``root`` (:func:`study_root`)."""
    if isinstance(paths, (str, Path)):
        paths = [paths]
    config: dict = {}
    for p in paths:
        try:
            doc = load_mapping(p, "config file")
        except ParameterError as exc:
            raise ConfigError(str(exc)) from None
        merge_study(config, doc)
    if overrides:
        if not isinstance(overrides, Mapping):
            raise ConfigError("config overrides must be a mapping of keys")
        merge_study(config, overrides)
    validate_schema(config)
    return check_config(config, root=root)


def study_root(root: str | Path | None = None) -> Path:
    """The directory a study runs in: ``root``; else ``$GEARSIM_STUDY_ROOT`` (set by the
    workflow for its jobs); else the working directory when it holds ``config/config.yaml``
    (Snakemake's working directory); else the source checkout."""
    if root is not None:
        return Path(root)
    env = os.environ.get(STUDY_ROOT_ENV)
    if env:
        return Path(env)
    cwd = Path.cwd()
    if (cwd / DEFAULT_CONFIG).is_file():
        return cwd
    return project_root()


def study_config(
    configfiles: Iterable[str | Path] = (),
    overrides: Mapping | None = None,
    root: str | Path | None = None,
) -> dict:
    """The study's configuration as the pipeline sees it: ``config/config.yaml`` of
    :func:`study_root`, then ``configfiles`` merged over it in order (as ``snakemake
    --configfile``), then ``overrides`` (as ``snakemake --config``).

    This is the one resolution of "the study's defaults": the CLI, the Python API
    (:func:`standard_parameters`, :func:`study_settings`) and the workflow use it.
    """
    base = study_root(root) / DEFAULT_CONFIG
    if not base.is_file():
        raise ConfigError(f"{base}: the study's configuration is missing")
    paths = [base]
    for p in configfiles:
        if Path(p).resolve() != base.resolve():
            paths.append(Path(p))
    return load_config(paths, overrides, root=study_root(root))


# ------------------------------------------------------------------- parameters, settings
def standard_parameters_path(config: Mapping, root: str | Path | None = None) -> Path | None:
    """The standard-parameter file of ``config`` (relative to :func:`study_root`), or ``None``
    for an explicit ``standard_parameters: null`` (the built-in ModelParameters defaults)."""
    sp = config.get("standard_parameters", DEFAULT_STANDARD_PARAMETERS)
    if sp is None:
        return None
    path = Path(sp)
    return path if path.is_absolute() else study_root(root) / path


def base_parameters(
    config: Mapping, root: str | Path | None = None
) -> tuple[dict[str, Any], str]:
    """Standard parameters (the file, or the built-in defaults for ``standard_parameters: null``)
    plus the ``parameters`` overrides.

    Returns the values and their source: ``"<file>"``, ``"builtin-defaults"``, with
    ``" + parameters {...}"`` when the config overrides some. A missing or invalid file is a
    :class:`ConfigError` (never a silent fallback).
    """
    values: dict[str, Any] = {}
    source = "builtin-defaults"
    path = standard_parameters_path(config, root)
    if config.get("gear"):  # a gear file replaces the standard parameters (docs/units.md)
        from gearsim.physical.units import config_gear

        try:
            values = config_gear(config, study_root(root)).to_model_parameters().to_dict()
        except ParameterError as exc:
            raise ConfigError(str(exc)) from None
        source = f"gear file {config['gear']}"
    elif path is not None:
        try:
            values = dict(load_standard_parameters(path))
        except ParameterError as exc:
            raise ConfigError(
                f"config key 'standard_parameters': {exc} (standard_parameters: null means the "
                "built-in defaults)"
            ) from None
        source = str(config.get("standard_parameters", DEFAULT_STANDARD_PARAMETERS))
    extra = dict(config.get("parameters", {}) or {})
    values.update(extra)
    if extra:
        source += " + parameters " + ", ".join(f"{k}={v}" for k, v in sorted(extra.items()))
    return values, source


def resolved_parameters(config: Mapping, root: str | Path | None = None) -> dict[str, Any]:
    """The full parameter set (every ModelParameters field) the pipeline simulates from."""
    values, _ = base_parameters(config, root)
    return ModelParameters.from_mapping(values).to_dict()


def study_parameters(
    config: Mapping | None = None, root: str | Path | None = None
) -> ModelParameters:
    """The study's standard parameters (``config`` default: :func:`study_config`)."""
    config = study_config(root=root) if config is None else config
    return ModelParameters.from_mapping(resolved_parameters(config, root))


def standard_parameters(config: Mapping | None = None, **changes: Any) -> ModelParameters:
    """The study's standard parameters as the pipeline simulates them, ``changes`` on top
    (``standard_parameters(w=0.48)``); ``config`` default: :func:`study_config`."""
    base = study_parameters(config)
    return base.with_(**changes) if changes else base


def study_settings(config: Mapping | None = None) -> IntegrationSettings:
    """The study's integration settings (``config['integration']``; default :func:`study_config`:
    RK4, 192 steps per period, a 40-period continuation transient)."""
    return integration_settings(study_config() if config is None else config)


def plane_base(config: Mapping, plane: str, root: str | Path | None = None) -> ModelParameters:
    """The parameters of a plane's cells before its axes are set (the plane's ``fixed`` on top)."""
    values, _ = base_parameters(config, root)
    values.update(config["planes"][plane].get("fixed", {}) or {})
    return ModelParameters.from_mapping(values)


def settings_text(settings: IntegrationSettings) -> str:
    """One line describing integration settings (printed and saved beside every result)."""
    if settings.method == "rk4":
        how = f"rk4 {settings.steps_per_period} steps/period"
    else:
        how = f"dp5 rtol={settings.rtol:g} atol={settings.atol:g}"
    return (
        f"{how}, hmax={settings.hmax:g}, transient {settings.transient} periods "
        f"({settings.transient_continuation} on continuation), up to {settings.max_periods} "
        f"measured, n_max={settings.n_max}"
    )


def results_dir(config: Mapping) -> Path:
    """Where a study's results go: ``results`` for the default study, else
    ``studies/<study>/results`` (logs beside it in ``studies/<study>/logs``)."""
    study = config.get("study")
    return Path("results") if study is None else Path("studies", study, "results")


def logs_dir(config: Mapping) -> Path:
    """Where a study's logs go (``logs`` or ``studies/<study>/logs``)."""
    study = config.get("study")
    return Path("logs") if study is None else Path("studies", study, "logs")


def integration_settings(config: Mapping) -> IntegrationSettings:
    """The :class:`~gearsim.cell.simulate.IntegrationSettings` of ``config['integration']``."""
    return IntegrationSettings(**(config.get("integration") or {}))


def sweep_set_arguments(config, sweep: str) -> str:
    """``--set name=value ...`` of a configured sweep's parameter set (the study's resolved
    parameters and the sweep's ``fixed``, less the swept parameter, which the continuation's
    ``--name/--from`` sets): the continuation of workflow/rules/orbits.smk runs on exactly the
    sweep's parameters."""
    spec = config["sweeps"][sweep]
    values = {**resolved_parameters(config), **(spec.get("fixed") or {})}
    values.pop(spec["name"], None)
    return " ".join(f"--set {k}={v!r}" if k != "model" else f"--set model={v}"
                    for k, v in values.items())
