"""The report's inputs: the sweeps, the planes' cells (from the catalogue, else their Parquet
files), the audits and the bifurcation-curve records of a finished run, and the planes and
sweeps a configuration names. Reading only; the comparison is :mod:`gearsim.presentation.report`,
the text :mod:`gearsim.presentation.report_markdown`."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pandas as pd


def load_sweeps(directory: str | Path, names: Sequence[str] | None = None
                ) -> dict[str, pd.DataFrame]:
    """The orbit diagrams ``<name>.parquet`` in ``directory`` of the sweeps ``names`` (default:
    every one there), keyed by name; a missing file is left out."""
    d = Path(directory)
    if not d.is_dir():
        return {}
    paths = (sorted(d.glob("*.parquet")) if names is None else
             [d / f"{n}.parquet" for n in names if (d / f"{n}.parquet").is_file()])
    return {p.stem: pd.read_parquet(p) for p in paths}


def _cells_from_catalogue(path: Path, plane: str) -> pd.DataFrame | None:
    """Cells of ``plane`` from the pipeline's catalogue (``cells`` joined to ``planes`` by
    ``plane_id``; the impact state is stored as ``impact``, the axes as ``x`` / ``y``), opened
    through :func:`gearsim.results.catalogue.open_catalogue` (a file that is not a catalogue of our
    schema is an error). ``None`` when there is no catalogue or the plane is not in it."""
    if not path.is_file():
        return None
    from gearsim.results.catalogue import open_catalogue

    con = open_catalogue(path)
    try:
        df = pd.read_sql_query(
            "select c.* from cells c join planes p on c.plane_id = p.id where p.name = ?",
            con, params=(plane,))
    finally:
        con.close()
    if not len(df):
        return None
    if "I" not in df.columns and "impact" in df.columns:
        df = df.rename(columns={"impact": "I"})
    return df


def fallback_notes(catalogue: str | Path | None, results: str | Path,
                    planes: Sequence[str]) -> list[str]:
    """A note for each plane whose cells came from its Parquet file although a catalogue was
    given (:func:`load_plane`): the report says where its numbers come from."""
    if catalogue is None or not planes:
        return []
    path = Path(catalogue)
    if not path.is_file():
        return [f"catalogue {path} not found: the cells of {', '.join(planes)} were read from "
                f"{Path(results)}/<plane>/cells.parquet"]
    from gearsim.results.catalogue import open_catalogue

    con = open_catalogue(path, check=False)  # checked when the cells were read
    try:
        have = {name for (name,) in con.execute("SELECT name FROM planes")}
    finally:
        con.close()
    return [f"plane {p} is not in the catalogue {path}: its cells were read from "
            f"{Path(results) / p / 'cells.parquet'}" for p in planes if p not in have]


def load_plane(plane: str, *, catalogue: str | Path | None = None,
               results: str | Path = "results") -> pd.DataFrame | None:
    """Cells of ``plane`` from the catalogue, else from ``results/<plane>/cells.parquet``."""
    if catalogue is not None:
        df = _cells_from_catalogue(Path(catalogue), plane)
        if df is not None:
            return df
    p = Path(results) / plane / "cells.parquet"
    if p.is_file():
        return pd.read_parquet(p)
    return None


def load_curve_status(results: str | Path, planes: Sequence[str]) -> list[str]:
    """A line for each plane whose bifurcation curves (``results/orbits/<plane>_curves.parquet``)
    were skipped or stopped at the job's budget, from the file's provenance."""
    from gearsim.results.catalogue import read_metadata

    out = []
    for plane in planes:
        f = Path(results) / "orbits" / f"{plane}_curves.parquet"
        if not f.is_file():
            continue
        meta = read_metadata(f) or {}
        status = meta.get("status", "ok")
        if status == "skipped":
            why = "; ".join(meta.get("reasons") or []) or "curves skipped"
            out.append(f"plane {plane}: {why}")
        elif status == "budget":
            out.append(f"plane {plane}: the bifurcation curves stopped at the job's budget "
                       f"({meta.get('budget_s', '?')} s); they are partial")
    return out


def load_atlas(results: str | Path, planes: Sequence[str]) -> list[dict[str, Any]]:
    """The plane atlas of each plane that has one (``results/atlas/<plane>.json``, written by
    ``gearsim atlas``), with ``unexplained_file``: the linked list of unexplained edges,
    relative to ``results``."""
    import json

    out = []
    for plane in planes:
        f = Path(results) / "atlas" / f"{plane}.json"
        if f.is_file():
            a = json.loads(f.read_text())
            csv = f.with_name(f"{plane}_unexplained.csv")
            a["unexplained_file"] = f"atlas/{csv.name}" if csv.is_file() else None
            out.append(a)
    return out


def load_audits(results: str | Path, planes: Sequence[str]) -> list[dict[str, Any]]:
    """The numerical audit of each plane (``results/<plane>/audit.parquet`` provenance)."""
    from gearsim.results.catalogue import read_metadata

    out = []
    for plane in planes:
        f = Path(results) / plane / "audit.parquet"
        if f.is_file():
            meta = read_metadata(f) or {}
            out.append({"plane": plane, "cells": meta.get("cells"),
                        "agreement": meta.get("agreement"), "threshold": meta.get("threshold")})
    return out


def study_from_config(config: dict[str, Any]) -> tuple[dict[str, tuple[str, str]], list[str]]:
    """The planes ``{name: (x, y)}`` and sweep names of a pipeline config."""
    planes = {name: (str(spec["x"]["name"]), str(spec["y"]["name"]))
              for name, spec in (config.get("planes") or {}).items()}
    return planes, list(config.get("sweeps") or {})
