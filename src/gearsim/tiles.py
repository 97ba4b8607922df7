"""Planes, tiles and the pipeline configuration.

A *plane* spans two :class:`~gearsim.parameters.ModelParameters` names (axes ``x`` and ``y``) at
cell centres ``v_i = min + (i + 0.5) (max - min) / n``. A *tile* is ``tile_rows`` consecutive rows
(``y`` indices) of a plane; a *row* is one forward continuation chain along ``x``
(:func:`gearsim.sweep.continuation_chain`). One Snakemake job simulates one tile; the rows of a
tile are mapped over a dask cluster (:mod:`gearsim.cluster`).

The configuration (``config/config.yaml``, layout in docs/TEAM.md) is checked twice with the same
code: by the workflow before any job (``workflow/rules/common.smk``) and by the ``gearsim`` CLI
(:func:`load_config`), so a bad key fails with one line that names it, never a traceback.

This module holds no file output (Parquet and SQLite live in :mod:`gearsim.catalogue`).
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
import platform
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .parameters import ModelParameters, ParameterError, check_value

#: Modules whose source determines simulation results: with the functions of this module
#: that build cells (:data:`CODE_FUNCTIONS`) their hash is ``code_version``. Figures, CLI,
#: catalogue and config-checking code are left out, so editing them does not re-run the tiles.
CODE_MODULES = (
    "parameters",
    "model",
    "integrate",
    "classify",
    "simulate",
    "sweep",
    "batch",
)
CODE_FUNCTIONS = (
    "axis_values",
    "sweep_values",
    "simulate_row",
    "simulate_rows_batched",
    "cell_records",
    "row_groups",
    "row_specs",
    "records_to_frame",
)

#: Packages whose versions go into the provenance.
PACKAGES = ("gearsim", "numpy", "numba", "scipy", "pandas", "pyarrow", "dask", "distributed")

DEFAULT_CONFIG = "config/config.yaml"
#: Names a plane may not take (they are directories of results/ used by other outputs).
RESERVED_PLANE_NAMES = ("sweeps", "points", "figures", "benchmarks", "logs", "report")
SCHEMA_RELATIVE = Path("workflow/schemas/config.schema.yaml")


class ConfigError(ParameterError):
    """The pipeline configuration is invalid; the message names the offending key."""


# ---------------------------------------------------------------------------------- schema
def _project_root() -> Path:
    # src/gearsim/tiles.py -> project root (editable install / source checkout)
    return Path(__file__).resolve().parents[2]


def schema_path(root: str | Path | None = None) -> Path:
    """Location of ``workflow/schemas/config.schema.yaml`` (``root`` first, then the checkout)."""
    candidates = []
    if root is not None:
        candidates.append(Path(root) / SCHEMA_RELATIVE)
    candidates += [Path.cwd() / SCHEMA_RELATIVE, _project_root() / SCHEMA_RELATIVE]
    for c in candidates:
        if c.is_file():
            return c
    raise ConfigError(f"config schema not found (looked for {SCHEMA_RELATIVE} in the project)")


def load_schema(root: str | Path | None = None) -> dict:
    import yaml

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
    from jsonschema import Draft202012Validator, validators

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
        from .config_io import load_standard_parameters

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
    from .config_io import load_yaml

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


# ------------------------------------------------------------------------------ the grids
def axis_values(axis: Mapping[str, Any]) -> np.ndarray:
    """Cell centres ``min + (i + 0.5) (max - min) / n`` of a plane axis."""
    lo, hi, n = float(axis["min"]), float(axis["max"]), int(axis["n"])
    return lo + (np.arange(n) + 0.5) * (hi - lo) / n


def sweep_values(sweep: Mapping[str, Any]) -> np.ndarray:
    """Sweep values, end points included: ``min + k (max - min) / (n - 1)``."""
    return np.linspace(float(sweep["min"]), float(sweep["max"]), int(sweep["n"]))


def n_tiles(config: Mapping, plane: str) -> int:
    return -(-int(config["planes"][plane]["y"]["n"]) // int(config["tile_rows"]))


def tile_ids(config: Mapping, plane: str) -> list[int]:
    return list(range(n_tiles(config, plane)))


def tile_rows(config: Mapping, plane: str, tile: int) -> range:
    """Row indices ``j`` (y) of ``tile``."""
    if not 0 <= tile < n_tiles(config, plane):
        raise ConfigError(
            f"tile {tile} does not exist for plane '{plane}' (0..{n_tiles(config, plane) - 1})"
        )
    rows = int(config["tile_rows"])
    ny = int(config["planes"][plane]["y"]["n"])
    return range(tile * rows, min((tile + 1) * rows, ny))


# ------------------------------------------------------------------- parameters, settings
def base_parameters(config: Mapping, root: str | Path = ".") -> tuple[dict[str, Any], str]:
    """Standard parameters (file, or built-in defaults when absent) plus ``parameters`` overrides.

    Returns the values and their source: the file path, or ``"builtin-defaults"``.
    """
    values: dict[str, Any] = {}
    source = "builtin-defaults"
    sp = config.get("standard_parameters")
    if sp and (Path(root) / sp).is_file():
        from .config_io import load_standard_parameters

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


def integration_settings(config: Mapping):
    from .simulate import IntegrationSettings

    return IntegrationSettings(**(config.get("integration") or {}))


# ---------------------------------------------------------------------------- provenance
def canonical_json(obj: Any) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=float)


def config_hash(obj: Any) -> str:
    """sha256 (16 hex digits) of the canonical JSON of ``obj``."""
    return hashlib.sha256(canonical_json(obj).encode()).hexdigest()[:16]


def code_version() -> str:
    """Hash of the sources that determine results (:data:`CODE_MODULES`, :data:`CODE_FUNCTIONS`)."""
    import inspect

    h = hashlib.sha256()
    pkg = Path(__file__).resolve().parent
    for name in CODE_MODULES:
        f = pkg / f"{name}.py"
        if f.is_file():
            h.update(name.encode())
            h.update(f.read_bytes())
    for name in CODE_FUNCTIONS:
        h.update(inspect.getsource(globals()[name]).encode())
    return h.hexdigest()[:16]


def package_versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:  # pragma: no cover
            out[name] = "absent"
    return out


def plane_subtree(config: Mapping, plane: str, root: str | Path = ".") -> dict[str, Any]:
    """What a plane's tiles depend on (the Snakemake params and the hashed provenance)."""
    return {
        "plane": copy.deepcopy(dict(config["planes"][plane])),
        "parameters": resolved_parameters(config, root),
        "integration": integration_settings(config).to_dict(),
        "tile_rows": int(config["tile_rows"]),
    }


def sweep_subtree(config: Mapping, sweep: str, root: str | Path = ".") -> dict[str, Any]:
    return {
        "sweep": copy.deepcopy(dict(config["sweeps"][sweep])),
        "parameters": resolved_parameters(config, root),
        "integration": integration_settings(config).to_dict(),
    }


def provenance(
    subtree: Mapping, *, kind: str, name: str, root: str | Path = ".", config=None, **extra: Any
) -> dict[str, Any]:
    """Provenance record (goes into Parquet key-value metadata and the catalogue's runs)."""
    from .simulate import TANGENT_SEED

    _, source = base_parameters(config, root) if config is not None else ({}, "unknown")
    rec = {
        "kind": kind,
        "name": name,
        "config_hash": config_hash(subtree),
        "code_version": code_version(),
        "package_versions": package_versions(),
        "tangent_seed": TANGENT_SEED,
        "parameters_source": source,
        "subtree": subtree,
        "host": platform.node(),
    }
    rec.update(extra)
    return rec


# --------------------------------------------------------------------------- simulation
#: Integer columns that may be missing (None) in CellResult.row().
NULLABLE_INT = ("p", "q")


def simulate_row(spec: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Simulate one plane row: a forward continuation chain along ``x`` at fixed ``y``.

    ``spec`` (plain data, so it pickles cheaply to dask workers): ``plane``, ``tile``, ``j``,
    ``params`` (dict), ``settings`` (dict), ``x_name``, ``x_values``, ``y_name``, ``y_value``.
    Returns one record per cell in increasing ``x``.
    """
    from .simulate import IntegrationSettings
    from .sweep import continuation_chain

    base = ModelParameters.from_mapping(dict(spec["params"]))
    settings = IntegrationSettings(**spec["settings"])
    xs = [float(v) for v in spec["x_values"]]
    yname, yval = spec["y_name"], float(spec["y_value"])
    plist = [base.with_(**{spec["x_name"]: x, yname: yval}) for x in xs]
    stamps: list[float] = []
    t0 = time.perf_counter()
    results = continuation_chain(
        plist, settings=settings, on_cell=lambda i, r: stamps.append(time.perf_counter())
    )
    return cell_records(spec, xs, results, stamps, t0)


def cell_records(spec: Mapping[str, Any], xs, results, stamps, t0: float) -> list[dict[str, Any]]:
    """The tile records of one plane row: grid indices, both parameter values, the cell's
    classification row, Poincare samples, the continuation seed and the wall time per cell."""
    yname, yval = spec["y_name"], float(spec["y_value"])
    rows = []
    prev = t0
    for i, (x, res, t) in enumerate(zip(xs, results, stamps, strict=True)):
        x = float(x)
        row = {
            "plane": spec["plane"],
            "tile": int(spec["tile"]),
            "i": i,
            "j": int(spec["j"]),
            "x": x,
            "y": yval,
            spec["x_name"]: x,
            yname: yval,
        }
        row.update(res.row())
        row["poincare_x"] = res.poincare[:, 0].tolist()
        row["poincare_v"] = res.poincare[:, 1].tolist()
        row["final_state"] = res.final_state.tolist()
        row["final_period"] = int(res.final_period)
        row["elapsed_s"] = t - prev
        prev = t
        rows.append(row)
    return rows


def simulate_rows_batched(specs: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Simulate several plane rows at once with the batched RK4 kernel (gearsim.batch).

    Same records as :func:`simulate_row` for every spec (one lane per row; the rows advance
    together, 8 per SIMD block). The integration is fixed-step RK4 at ``steps_per_period``.
    """
    from .batch import simulate_rows
    from .simulate import IntegrationSettings

    settings = IntegrationSettings(**specs[0]["settings"])
    chains = []
    for spec in specs:
        base = ModelParameters.from_mapping(dict(spec["params"]))
        yname, yval = spec["y_name"], float(spec["y_value"])
        chains.append(
            [base.with_(**{spec["x_name"]: float(x), yname: yval}) for x in spec["x_values"]]
        )
    stamps: list[list[float]] = [[] for _ in specs]
    t0 = time.perf_counter()
    results = simulate_rows(
        chains, settings=settings, on_cell=lambda r, i, res: stamps[r].append(time.perf_counter())
    )
    rows = []
    for spec, res_row, st_row in zip(specs, results, stamps, strict=True):
        rows += cell_records(spec, spec["x_values"], res_row, st_row, t0)
    return rows


def row_groups(specs: list[dict], workers: int) -> list[list[dict]]:
    """Split a tile's rows into one group per worker, in multiples of the SIMD block (8 rows)."""
    from .batch import LANES

    n_groups = max(1, min(workers, -(-len(specs) // LANES)))
    size = -(-len(specs) // n_groups)
    return [specs[k : k + size] for k in range(0, len(specs), size)]


def row_specs(config: Mapping, plane: str, tile: int, root: str | Path = ".") -> list[dict]:
    """The dask tasks of a tile: one spec per row."""
    pl = config["planes"][plane]
    base = plane_base(config, plane, root).to_dict()
    settings = integration_settings(config).to_dict()
    xs = axis_values(pl["x"]).tolist()
    ys = axis_values(pl["y"])
    return [
        {
            "plane": plane,
            "tile": tile,
            "j": j,
            "params": base,
            "settings": settings,
            "x_name": pl["x"]["name"],
            "x_values": xs,
            "y_name": pl["y"]["name"],
            "y_value": float(ys[j]),
        }
        for j in tile_rows(config, plane, tile)
    ]


def records_to_frame(records: list[dict[str, Any]]) -> pd.DataFrame:
    """Cell records -> DataFrame with stable dtypes (same schema for every tile)."""
    df = pd.DataFrame.from_records(records)
    for c in NULLABLE_INT:
        if c in df:
            df[c] = pd.array(
                [
                    None if v is None or (isinstance(v, float) and math.isnan(v)) else int(v)
                    for v in df[c]
                ],
                dtype="Int64",
            )
    for c in ("I", "n", "window_periods", "periods", "steps", "final_period", "i", "j", "tile"):
        if c in df:
            df[c] = df[c].astype("int64")
    if "converged" in df:
        df["converged"] = df["converged"].astype(bool)
    return df


def run_tile(
    config: Mapping,
    plane: str,
    tile: int,
    *,
    client=None,
    root: str | Path = ".",
    progress: Callable[[int, int, float], None] | None = None,
) -> pd.DataFrame:
    """Simulate all cells of a tile (rows mapped over ``client``, or in-process when None).

    ``progress(done_cells, total_cells, elapsed_s)`` is called after each finished row.
    """
    specs = row_specs(config, plane, tile, root)
    nx = int(config["planes"][plane]["x"]["n"])
    total = nx * len(specs)
    t0 = time.perf_counter()
    records: list[dict] = []
    done = 0
    if specs and specs[0]["settings"].get("method") == "rk4":
        # fixed-step RK4: the batched kernel, rows advanced together (8 per SIMD block)
        workers = 1 if client is None else max(1, len(client.nthreads()))
        groups = row_groups(specs, workers)
        if client is None:
            results = map(simulate_rows_batched, groups)
        else:
            from .cluster import map_unordered

            results = map_unordered(client, simulate_rows_batched, groups)
        for recs in results:
            records += recs
            done += len(recs)
            if progress:
                progress(done, total, time.perf_counter() - t0)
    elif client is None:
        for spec in specs:
            records += simulate_row(spec)
            done += nx
            if progress:
                progress(done, total, time.perf_counter() - t0)
    else:
        from .cluster import map_unordered

        for rows in map_unordered(client, simulate_row, specs):
            records += rows
            done += nx
            if progress:
                progress(done, total, time.perf_counter() - t0)
    df = records_to_frame(records)
    return df.sort_values(["j", "i"], kind="stable").reset_index(drop=True)
