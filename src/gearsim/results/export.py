"""A catalogue plane as an :class:`xarray.Dataset` on its grid, written as NetCDF, Zarr, CSV or
Parquet (``gearsim export``).

The Dataset has the plane's two parameters as dimensions and coordinates, named by parameter
(e.g. ``b`` x ``w`` for the wb plane: ``ds.label.sel(w=1.0, b=0.3, method="nearest")``), the
cell centres ``min + (i + 0.5)(max - min)/n`` as coordinate values, and one variable per cell
column of the catalogue (:data:`gearsim.results.columns.RESULT`, plus ``elapsed_s``) with
``units`` and ``long_name`` attributes from :mod:`gearsim.results.columns`. Integer columns that
may be NULL (``p``,
``q``) are float with NaN. Global attributes carry the provenance: plane record, fixed
parameters, integration settings, configuration hash, code version, git commit of the catalogue
build. Nested values are JSON strings (NetCDF attributes are flat).

Every file is written under a temporary name and renamed into place (a Zarr store: the
directory), so a reader never sees a partial export.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from gearsim.cell.record import result_columns
from gearsim.errors import CatalogueError
from gearsim.results.columns import PARAMETERS, RESULT
from gearsim.study.preflight import check_output, os_cause

FORMATS = ("netcdf", "zarr", "csv", "parquet")
#: cell columns exported, in catalogue spelling (``I`` is ``impact``; the order of
#: ``CellResult.row()``), and the wall time per cell
_COLUMNS = {("impact" if n == "I" else n): t for n, t in result_columns().items()}
VARIABLES = (*_COLUMNS, "elapsed_s")
_TEXT = {n for n, (t, _) in _COLUMNS.items() if t is str}
_NULLABLE_INT = {n for n, (t, opt) in _COLUMNS.items() if t is int and opt}
_INT = {n for n, (t, opt) in _COLUMNS.items() if t is int and not opt}


def _plane(con, plane: str) -> dict[str, Any]:
    con.row_factory = None
    cols = [r[1] for r in con.execute("PRAGMA table_info(planes)")]
    row = con.execute("SELECT * FROM planes WHERE name = ?", (plane,)).fetchone()
    if row is None:
        names = [r[0] for r in con.execute("SELECT name FROM planes ORDER BY name")]
        raise CatalogueError(
            f"--plane: no plane {plane!r} in the catalogue; it has: {', '.join(names) or 'none'}"
        )
    rec = dict(zip(cols, row, strict=True))
    for k in ("fixed", "parameters", "integration"):
        rec[k] = json.loads(rec[k]) if rec.get(k) else {}
    return rec


def _axis(lo: float, hi: float, n: int) -> np.ndarray:
    return lo + (np.arange(n) + 0.5) * (hi - lo) / n


def plane_dataset(catalogue: str | Path, plane: str, *, source: str | None = None):
    """The cells of ``plane`` from the catalogue as an :class:`xarray.Dataset` (see module doc).
    ``source``: the catalogue's name in the attributes (default its path; a study read from a
    server: :func:`gearsim.results.server_read.catalogue_name`)."""
    import xarray as xr

    from gearsim import __version__
    from gearsim.results.catalogue import open_catalogue

    con = open_catalogue(catalogue)
    try:
        rec = _plane(con, plane)
        info = {k: json.loads(v) for k, v in con.execute("SELECT key, value FROM catalogue_info")}
        nx, ny = int(rec["x_n"]), int(rec["y_n"])
        data: dict[str, np.ndarray] = {}
        for c in VARIABLES:
            if c in _TEXT:
                data[c] = np.full((ny, nx), "", dtype=object)
            elif c == "converged":
                data[c] = np.zeros((ny, nx), dtype=bool)
            elif c in _INT:
                data[c] = np.zeros((ny, nx), dtype=np.int64)
            else:
                data[c] = np.full((ny, nx), np.nan)
        seen = np.zeros((ny, nx), dtype=bool)
        cur = con.execute(
            f"SELECT i, j, {', '.join(VARIABLES)} FROM cells WHERE plane_id = ?", (rec["id"],)
        )
        while batch := cur.fetchmany(20_000):
            arr = list(zip(*batch, strict=True))
            i = np.asarray(arr[0], dtype=np.int64)
            j = np.asarray(arr[1], dtype=np.int64)
            seen[j, i] = True
            for k, c in enumerate(VARIABLES):
                vals = arr[k + 2]
                if c in _TEXT:
                    data[c][j, i] = np.asarray(vals, dtype=object)
                elif c == "converged":
                    data[c][j, i] = np.asarray(vals, dtype=bool)
                elif c in _INT:
                    data[c][j, i] = np.asarray(vals, dtype=np.int64)
                else:
                    data[c][j, i] = np.asarray([np.nan if v is None else v for v in vals], float)
    finally:
        con.close()
    if not seen.all():
        raise CatalogueError(
            f"plane {plane!r}: {int((~seen).sum())} of {seen.size} cells missing in the catalogue"
        )
    xn, yn = rec["x_name"], rec["y_name"]
    coords = {
        yn: (yn, _axis(rec["y_min"], rec["y_max"], ny), _coord_attrs(yn, rec, "y")),
        xn: (xn, _axis(rec["x_min"], rec["x_max"], nx), _coord_attrs(xn, rec, "x")),
    }
    variables = {}
    for c in VARIABLES:
        unit, meaning = RESULT.get(c, ("s", "wall time of the cell"))
        attrs = {"long_name": meaning, "units": unit or "1"}
        if c in _NULLABLE_INT:
            attrs["comment"] = "NaN where the motion has no period"
        variables[c] = ((yn, xn), data[c], attrs)
    attrs = {
        "title": f"gearsim plane {plane}: {yn} x {xn}",
        "plane": plane,
        "x_name": xn,
        "y_name": yn,
        "cell_centres": "v_i = min + (i + 0.5) (max - min) / n",
        "fixed": json.dumps(rec["fixed"], sort_keys=True),
        "parameters": json.dumps(rec["parameters"], sort_keys=True),
        "integration": json.dumps(rec["integration"], sort_keys=True),
        "config_hash": rec.get("config_hash") or "",
        "code_version": rec.get("code_version") or "",
        "catalogue": source if source is not None else str(catalogue),
        "catalogue_built": str(info.get("built", "")),
        "catalogue_schema_version": int(info.get("schema_version", 0)),
        "git_commit": str(info.get("git_commit") or ""),
        "gearsim_version": __version__,
        "scalings": "dimensionless: lengths / b_c, time tau = w_n t, forces / (Km b_c) "
        "(docs/model.md)",
    }
    return xr.Dataset(variables, coords=coords, attrs=attrs)


def _coord_attrs(name: str, rec: dict, axis: str) -> dict[str, Any]:
    unit, meaning = PARAMETERS.get(name, ("1", name))
    return {
        "long_name": meaning,
        "units": unit or "1",
        "axis": axis.upper(),
        "valid_min": float(rec[f"{axis}_min"]),
        "valid_max": float(rec[f"{axis}_max"]),
        "cells": int(rec[f"{axis}_n"]),
    }


def _tmp(path: Path) -> Path:
    return path.with_name(f".{path.name}.tmp-{os.getpid()}")


def check_out(out: str | Path, fmt: str) -> Path:
    """The output path, refused with one line before any work if it cannot be written."""
    out = Path(out)
    if not out.parent.is_dir():
        raise CatalogueError(f"--out: directory {out.parent} does not exist")
    if fmt != "zarr" and out.is_dir():
        raise CatalogueError(f"--out: {out} is a directory (expected a file name)")
    if fmt == "zarr" and out.exists() and not out.is_dir():
        raise CatalogueError(f"--out: {out} is a file (a Zarr store is a directory)")
    # a probe file and free space (read-only mounts, permissions, a full disk)
    check_output(out.with_name(out.name + ".probe") if fmt == "zarr" else out, what="--out")
    return out


def _table(ds):
    """Long form: one row per cell, ``j``, ``i`` and both parameters as columns."""
    xn, yn = ds.attrs["x_name"], ds.attrs["y_name"]
    df = ds.to_dataframe().reset_index()
    ny, nx = ds.sizes[yn], ds.sizes[xn]
    df.insert(0, "i", np.tile(np.arange(nx), ny))
    df.insert(0, "j", np.repeat(np.arange(ny), nx))
    return df


def write(ds, out: str | Path, fmt: str) -> Path:
    """Write ``ds`` (from :func:`plane_dataset`) as ``fmt`` to ``out`` atomically."""
    out = check_out(out, fmt)
    tmp = _tmp(out)
    try:
        if fmt == "netcdf":
            ds.to_netcdf(tmp, engine="h5netcdf")
        elif fmt == "zarr":
            import warnings

            with warnings.catch_warnings():
                # consolidated metadata is what xr.open_zarr looks for first (no warning on
                # opening); zarr 3 notes that it is not yet in the v3 specification
                warnings.filterwarnings("ignore", message="Consolidated metadata")
                ds.to_zarr(tmp, mode="w", consolidated=True)
        elif fmt == "csv":
            _table(ds).to_csv(tmp, index=False)
            meta = out.with_name(out.name + ".json")
            _write_json(meta, _sidecar(ds))
        elif fmt == "parquet":
            from gearsim.results.catalogue import write_parquet

            write_parquet(_table(ds), tmp, {b"gearsim.results.export": _sidecar(ds)})
        else:
            raise CatalogueError(f"--format: {fmt!r} is not one of {', '.join(FORMATS)}")
        if fmt == "zarr" and out.exists():
            old = out.with_name(f".{out.name}.old-{os.getpid()}")
            os.replace(out, old)
            os.replace(tmp, out)
            shutil.rmtree(old)
        else:
            os.replace(tmp, out)
    except OSError as exc:
        raise CatalogueError(f"--out {out}: {os_cause(exc)}") from None
    finally:
        if tmp.is_dir():
            shutil.rmtree(tmp)
        elif tmp.exists():
            tmp.unlink()
    return out


def _sidecar(ds) -> dict[str, Any]:
    """Units, long names and provenance of a tabular export (CSV sidecar, Parquet metadata)."""
    return {
        "attrs": dict(ds.attrs),
        "columns": {
            name: {
                k: (v if isinstance(v, (str, int, float)) else str(v)) for k, v in var.attrs.items()
            }
            for name, var in {**ds.coords, **ds.data_vars}.items()
        },
    }


def _write_json(path: Path, obj: Any) -> None:
    tmp = _tmp(path)
    try:
        tmp.write_text(json.dumps(obj, indent=1, sort_keys=True))
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
