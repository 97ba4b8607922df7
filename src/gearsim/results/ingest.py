"""Building the catalogue: checked Parquet files streamed into SQLite in one transaction.

:func:`build_catalogue` writes a temporary file renamed into place, then publishes it
(:func:`gearsim.results.publish.publish`).
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pandas as pd
from sqlalchemy import insert
from sqlalchemy.orm import Session

from gearsim.cell.record import result_columns
from gearsim.errors import CatalogueError, one_line
from gearsim.results.parquet import (
    PLANE_KEY,
    PROVENANCE_KEY,
    TILES_KEY,
    _prepare_dir,
    _size,
    now_iso,
    read_metadata,
)
from gearsim.results.publish import publish
from gearsim.results.schema import (
    APPLICATION_ID,
    ROW_COLUMNS,
    SCHEMA_VERSION,
    Audit,
    Base,
    BifurcationCurve,
    BifurcationPoint,
    CatalogueInfo,
    Cell,
    CellAttractor,
    CellOrbit,
    Codim2Point,
    ColumnDoc,
    Plane,
    Run,
    Sweep,
    SweepPoint,
    _column_rows,
    replacing,
)
from gearsim.results.views import create_views
from gearsim.study.provenance import git_commit


# ------------------------------------------------------------------------------ builders
def _nan_to_none(v: Any) -> Any:
    if v is None:
        return None
    if isinstance(v, float) and v != v:
        return None
    try:
        import pandas as _pd

        if v is _pd.NA:
            return None
    except ImportError:  # pragma: no cover
        pass
    return v


def _row_values(rec: Mapping[str, Any]) -> dict[str, Any]:
    out = {}
    for c in ROW_COLUMNS:
        v = _nan_to_none(rec.get(c))
        out["impact" if c == "I" else c] = v
    for c in ("impact", "n", "p", "q", "window_periods", "periods", "steps"):
        if out.get(c) is not None:
            out[c] = int(out[c])
    out["converged"] = bool(out["converged"])
    return out


def _when(s: Any) -> datetime | None:
    if not s:
        return None
    return datetime.fromisoformat(s).astimezone(UTC).replace(tzinfo=None)


def _run_row(prov: Mapping[str, Any]) -> dict[str, Any]:
    return {
        "kind": prov.get("kind", "?"),
        "name": prov.get("name", "?"),
        "tile": prov.get("tile"),
        "file": prov.get("file"),
        "config_hash": prov.get("config_hash", ""),
        "code_version": prov.get("code_version", ""),
        "package_versions": prov.get("package_versions", {}),
        "parameters_source": prov.get("parameters_source"),
        "tangent_seed": prov.get("tangent_seed"),
        "audit_seed": prov.get("audit_seed"),
        "host": prov.get("host"),
        "workers": prov.get("workers"),
        "started": _when(prov.get("started")),
        "finished": _when(prov.get("finished")),
        "wall_s": prov.get("wall_s"),
        "cells": prov.get("cells"),
        "status": prov.get("status", "ok"),
    }


def _plane_row(rec: Mapping[str, Any]) -> dict[str, Any]:
    axes = {rec["x"]["name"], rec["y"]["name"]}
    return dict(
        name=rec["name"],
        x_name=rec["x"]["name"],
        x_min=rec["x"]["min"],
        x_max=rec["x"]["max"],
        x_n=rec["x"]["n"],
        y_name=rec["y"]["name"],
        y_min=rec["y"]["min"],
        y_max=rec["y"]["max"],
        y_n=rec["y"]["n"],
        fixed=rec.get("fixed", {}),
        parameters={k: v for k, v in rec.get("parameters", {}).items() if k not in axes},
        config_hash=rec.get("config_hash", ""),
        code_version=rec.get("code_version", ""),
        integration=rec.get("integration", {}),
    )


_CELL_INSERT_COLUMNS = (
    "plane_id",
    "run_id",
    "i",
    "j",
    "x",
    "y",
    "elapsed_s",
    *("impact" if c == "I" else c for c in ROW_COLUMNS),
)
_FLOAT_COLUMNS = {"x", "y", "elapsed_s"} | {
    name for name, (typ, _) in result_columns().items() if typ is float
}


def _column_values(batch, name: str, n: int) -> list:
    """A batch column as Python values: NaN -> None (SQL NULL), booleans as 0/1."""
    if name not in batch.schema.names:
        return [None] * n
    vals = batch.column(name).to_pylist()
    if name in _FLOAT_COLUMNS:
        return [None if v is None or v != v else float(v) for v in vals]
    if name == "converged":
        return [bool(v) for v in vals]
    return vals


def _insert_plane(session: Session, f: Path, names: set[str], counts: dict, chunk: int) -> None:
    """Check one ``cells.parquet`` (plane record, tiles' hashes, cell counts, coverage) and insert
    it batch by batch (bounded memory)."""
    import pyarrow.parquet as pq

    from gearsim.study.integrity import Coverage, check_run, read_footer

    meta, kv = read_footer(f, "plane file")
    if PLANE_KEY not in kv:
        raise CatalogueError(
            f"plane file {f}: no plane record (not written by 'gearsim catalogue cells')"
        )
    rec = json.loads(kv[PLANE_KEY])
    tiles = json.loads(kv.get(TILES_KEY, b"[]"))
    if rec["name"] in names:
        raise CatalogueError(f"plane file {f}: plane {rec['name']!r} is given twice")
    names.add(rec["name"])
    for prov in tiles:
        check_run(prov, rec, f"plane file {f}: tile {prov.get('file', prov.get('tile'))}")
    recorded = sum(int(p.get("cells") or 0) for p in tiles)
    if recorded != meta.num_rows:
        raise CatalogueError(
            f"plane file {f}: {meta.num_rows} cells stored but its tiles recorded {recorded} "
            "(truncated or altered; re-run its plane_cells job)"
        )
    plane = Plane(**_plane_row(rec))
    session.add(plane)
    run_of_tile: dict[int, int] = {}
    for prov in tiles:
        run = Run(**_run_row(prov))
        session.add(run)
        session.flush()
        if int(prov["tile"]) in run_of_tile:
            raise CatalogueError(f"plane file {f}: tile {prov['tile']} recorded twice")
        run_of_tile[int(prov["tile"])] = run.id
        counts["runs"] += 1
    session.flush()
    counts["planes"] += 1
    coverage = Coverage(rec)
    cols = ["tile", "i", "j", "x", "y", "elapsed_s", *ROW_COLUMNS]
    dbapi = session.connection().connection.dbapi_connection
    sql = (
        f"INSERT INTO cells ({', '.join(_CELL_INSERT_COLUMNS)}) "
        f"VALUES ({', '.join('?' * len(_CELL_INSERT_COLUMNS))})"
    )
    try:
        pf = pq.ParquetFile(f)
        present = [c for c in cols if c in pf.schema_arrow.names]
        for batch in pf.iter_batches(batch_size=chunk, columns=present):
            n = batch.num_rows
            i = batch.column("i").to_numpy()
            j = batch.column("j").to_numpy()
            coverage.add(
                i, j, batch.column("x").to_numpy(), batch.column("y").to_numpy(), f"plane file {f}"
            )
            tile = batch.column("tile").to_pylist()
            unknown = set(tile) - set(run_of_tile)
            if unknown:
                raise CatalogueError(
                    f"plane file {f}: cells of tile {min(unknown)} that has no provenance"
                )
            values = [[plane.id] * n, [run_of_tile[t] for t in tile]]
            values += [
                _column_values(batch, "I" if c == "impact" else c, n)
                for c in _CELL_INSERT_COLUMNS[2:]
            ]
            dbapi.executemany(sql, zip(*values, strict=True))
            counts["cells"] += n
    except CatalogueError:
        raise
    except (OSError, ValueError, KeyError) as exc:
        raise CatalogueError(f"plane file {f}: unreadable cells ({one_line(exc)})") from None
    coverage.finish(f"plane file {f}")


def _insert_sweep(session: Session, f: Path, counts: dict) -> None:
    from gearsim.study.integrity import read_footer

    _, kv = read_footer(f, "sweep file")
    prov = json.loads(kv.get(PROVENANCE_KEY, b"{}"))
    if prov.get("kind") != "sweep":
        raise CatalogueError(f"sweep file {f}: no sweep provenance (not written by gearsim sweep)")
    prov = {**prov, "file": str(f)}
    df = pd.read_parquet(f)
    if prov.get("cells") is not None and int(prov["cells"]) != len(df):
        raise CatalogueError(
            f"sweep file {f}: {len(df)} points stored but {prov['cells']} recorded "
            "(truncated or altered)"
        )
    run = Run(**_run_row(prov))
    session.add(run)
    session.flush()
    counts["runs"] += 1
    subtree = prov.get("subtree", {})
    spec = subtree.get("sweep", {})
    swept = spec.get("name", df["parameter"].iloc[0] if len(df) else "?")
    # the values actually used: the resolved parameters with the sweep's own overrides on top
    used = {**subtree.get("parameters", {}), **spec.get("fixed", {})}
    used.pop(swept, None)
    sweep = Sweep(
        name=prov.get("name", Path(f).stem),
        run_id=run.id,
        parameter=swept,
        min=float(spec.get("min", df["value"].min())),
        max=float(spec.get("max", df["value"].max())),
        n=int(spec.get("n", len(df))),
        direction=spec.get("direction", "forward"),
        fixed=spec.get("fixed", {}),
        parameters=used,
        config_hash=prov.get("config_hash", ""),
        integration=subtree.get("integration", {}),
    )
    session.add(sweep)
    session.flush()
    counts["sweeps"] += 1
    rows = []
    for k, rec_ in enumerate(df.to_dict("records")):
        r = _row_values(rec_)
        r.update(
            sweep_id=sweep.id,
            k=k,
            value=float(rec_["value"]),
            poincare_x=[float(v) for v in rec_["poincare_x"]],
            poincare_v=[float(v) for v in rec_["poincare_v"]],
            direction=rec_.get("direction"),
        )
        rows.append(r)
    if rows:
        session.execute(insert(SweepPoint), rows)
    counts["sweep_points"] += len(rows)


def _file_run(session: Session, f: Path, what: str, counts: dict):
    """The provenance of a result file, its ``runs`` row (added and flushed) and its table."""
    from gearsim.study.integrity import read_footer

    _, kv = read_footer(f, what)
    prov = {**json.loads(kv.get(PROVENANCE_KEY, b"{}")), "file": str(f)}
    run = Run(**_run_row(prov))
    session.add(run)
    session.flush()
    counts["runs"] += 1
    return prov, run, pd.read_parquet(f)


def _cell_ids(session: Session, planes) -> dict[tuple[str, int, int], int]:
    """The catalogue's cell ids of ``planes`` by ``(plane, i, j)``."""
    from sqlalchemy import select

    cell_ids = {}
    for name in planes:
        q = select(Cell.id, Cell.i, Cell.j).join(Plane).where(Plane.name == name)
        cell_ids.update({(name, i, j): cid for cid, i, j in session.execute(q)})
    return cell_ids


def _insert_audit(session: Session, f: Path, counts: dict) -> None:

    prov, run, df = _file_run(session, f, "audit file", counts)
    cell_ids = _cell_ids(session, set(df["plane"]) if len(df) else set())
    rows = []
    for rec_ in df.to_dict("records"):
        key = (rec_["plane"], int(rec_["i"]), int(rec_["j"]))
        if key not in cell_ids:
            raise CatalogueError(
                f"audit file {f}: cell {key} is not in the catalogue (audit of another plane run)"
            )
        rows.append(
            {
                "cell_id": cell_ids[key],
                "run_id": run.id,
                "label": rec_["tight_label"],
                "label_npq": rec_["tight_label_npq"],
                "impact": int(rec_["tight_I"]),
                "dc": _nan_to_none(rec_["tight_dc"]),
                "kmax": _nan_to_none(rec_["tight_kmax"]),
                "lyapunov": _nan_to_none(rec_["tight_lyapunov"]),
                "agree": bool(rec_["agree"]),
            }
        )
    if rows:
        session.execute(insert(Audit), rows)
    counts["audits"] += len(rows)


def _insert_attractors(session: Session, f: Path, counts: dict) -> None:
    """Insert one attractor tile (``gearsim attractor-tile``) and set ``cells.n_attractors``."""
    from sqlalchemy import select, update

    from gearsim.study.integrity import read_footer

    _, kv = read_footer(f, "attractor file")
    prov = json.loads(kv.get(PROVENANCE_KEY, b"{}"))
    if prov.get("kind") != "attractors":
        raise CatalogueError(
            f"attractor file {f}: no attractor provenance (not written by gearsim attractor-tile)"
        )
    plane = session.execute(select(Plane).where(Plane.name == prov.get("name"))).scalar()
    if plane is None:
        raise CatalogueError(f"attractor file {f}: plane {prov.get('name')!r} is not catalogued")
    if prov.get("config_hash") != plane.config_hash:
        raise CatalogueError(
            f"attractor file {f}: made for another configuration of plane {plane.name!r} "
            "(re-run its attractor_tile job)"
        )
    run = Run(**_run_row({**prov, "file": str(f)}))
    session.add(run)
    session.flush()
    counts["runs"] += 1
    q = select(Cell.id, Cell.i, Cell.j).where(Cell.plane_id == plane.id)
    cell_ids = {(i, j): cid for cid, i, j in session.execute(q)}
    df = pd.read_parquet(f)
    rows, n_of = [], {}
    for r in df.to_dict("records"):
        key = (int(r["i"]), int(r["j"]))
        if key not in cell_ids:
            raise CatalogueError(f"attractor file {f}: cell {key} is not in plane {plane.name!r}")
        cid = cell_ids[key]
        n_of[cid] = int(r["n_attractors"])
        if int(r["attractor"]) < 0:
            continue  # every start diverged: no attractor, n_attractors = 0
        rows.append(
            {
                "cell_id": cid, "run_id": run.id, "attractor": int(r["attractor"]),
                "motion": r["motion"], "label": r["label"], "label_npq": r["label_npq"] or "",
                "impact": int(r["I"]), "n": int(r["n"]),
                "p": None if _nan_to_none(r["p"]) is None else int(r["p"]),
                "q": None if _nan_to_none(r["q"]) is None else int(r["q"]),
                "dc": _nan_to_none(r["dc"]), "kmax": _nan_to_none(r["kmax"]),
                "lyapunov": _nan_to_none(r["lyapunov"]),
                "status": r.get("status"), "mu_max": _nan_to_none(r.get("mu_max")),
                "critical": r.get("critical") or None,
                "basin_fraction": float(r["basin_fraction"]), "n_starts": int(r["n_starts"]),
                "n_early": int(r["n_early"]), "found_by": r["found_by"],
            }  # fmt: skip
        )
    if rows:
        session.execute(insert(CellAttractor), rows)
    for cid, n in n_of.items():
        session.execute(update(Cell).where(Cell.id == cid).values(n_attractors=n))
    counts["attractors"] = counts.get("attractors", 0) + len(rows)


#: the plane atlas's columns of the seed and curve tables (docs/orbits.md): integers, the rest
#: text; absent from older files (NULL)
_SEED_INTS = ("seed_i", "seed_j", "seed_i2", "seed_j2")
_POINT_ATLAS = ("curve", "source", *_SEED_INTS, "label_a", "label_b")
_CURVE_ATLAS = ("flank", "seq", "source", *_SEED_INTS, "label_a", "label_b", "end_first",
                "end_last", "end_first_detail", "end_last_detail", "codim2_first",
                "codim2_last")
_ATLAS_INTS = {"curve", "seq", "codim2_first", "codim2_last", *_SEED_INTS}


def _atlas_values(r: Mapping[str, Any], names: tuple[str, ...]) -> dict[str, Any]:
    out = {}
    for n in names:
        v = _nan_to_none(r.get(n))
        out[n] = None if v is None else int(v) if n in _ATLAS_INTS else str(v)
    return out


def _codim2_row(r: Mapping[str, Any], run_id: int) -> dict[str, Any]:
    """A row of ``codim2_points`` from a row of a plane's ``*_codim2.parquet``."""
    def f(name):
        v = _nan_to_none(r.get(name))
        return None if v is None else float(v)

    mu = None
    if r.get("mu_re") is not None and r.get("mu_im") is not None:
        mu = [[float(a), float(b)] for a, b in zip(r["mu_re"], r["mu_im"], strict=True)]
    it = _nan_to_none(r.get("iterations"))
    return {
        "run_id": run_id, "plane": r.get("plane", ""), "point": int(r["point"]),
        "kind": str(r["kind"]), "conditions": str(r["conditions"]),
        "period": int(r["period"]), "boundary": str(r.get("boundary") or ""),
        "name": str(r["name"]), "value": float(r["value"]), "name2": str(r["name2"]),
        "value2": float(r["value2"]),
        "curves": [int(c) for c in (r.get("curves") if r.get("curves") is not None else [])],
        "curve_kinds": [str(c) for c in (r.get("curve_kinds")
                                         if r.get("curve_kinds") is not None else [])],
        "residual_1": f("residual_1"), "residual_2": f("residual_2"),
        "residual": f("residual"), "step": f("step"),
        "iterations": None if it is None else int(it), "converged": bool(r["converged"]),
        "gap_cells": f("gap_cells"), "x": f("x"), "v": f("v"), "mu_max": f("mu_max"),
        "multipliers": mu,
    }


def _insert_orbit_file(session: Session, f: Path, counts: dict) -> None:
    """Insert a bifurcation points / curves / codimension-2 file or a refine-orbits file (by
    its columns)."""

    prov, run, df = _file_run(session, f, "orbit file", counts)
    if "orbit_flag" in df.columns:
        cell_ids = _cell_ids(session, set(df["plane"]))
        rows = []
        for r in df.to_dict("records"):
            key = (r["plane"], int(r["i"]), int(r["j"]))
            if key not in cell_ids:
                raise CatalogueError(f"orbit file {f}: cell {key} is not in the catalogue")
            rows.append({
                "cell_id": cell_ids[key], "run_id": run.id,
                "converged": bool(r["orbit_converged"]),
                "residual": _nan_to_none(r["orbit_residual"]),
                "mu_max": _nan_to_none(r["orbit_mu_max"]), "kind": r["orbit_kind"],
                "grazing_margin": _nan_to_none(r["orbit_grazing_margin"]),
                "shift": _nan_to_none(r["orbit_shift"]),
                "minimal_period": int(r["orbit_minimal_period"]), "flag": r["orbit_flag"],
                "ms": _nan_to_none(r["orbit_ms"]),
            })
        table, key = CellOrbit, "cell_orbits"
    elif "conditions" in df.columns:  # a plane's codimension-2 points (docs/orbits.md)
        rows = [_codim2_row(r, run.id) for r in df.to_dict("records")]
        table, key = Codim2Point, "codim2_points"
    else:
        # curve points have no 'point' column; a seed table (bifurcation points) has one,
        # and since the plane atlas also the 'curve' it seeded
        is_curve = "curve" in df.columns and "point" not in df.columns
        rows = []
        for r in df.to_dict("records"):
            row = {
                "run_id": run.id, "plane": r.get("plane", ""), "kind": r["kind"],
                "period": int(r["period"]), "boundary": r["boundary"] or "", "name": r["name"],
                "value": float(r["value"]), "name2": r.get("name2", ""),
                "value2": float(r.get("value2", float("nan"))), "x": float(r["x"]),
                "v": float(r["v"]), "mu_max": float(r["mu_max"]),
                "multipliers": [[float(a), float(b)]
                                for a, b in zip(r["mu_re"], r["mu_im"], strict=True)],
                "stable": bool(r["stable"]),
            }
            row.update(_atlas_values(r, _CURVE_ATLAS if is_curve else _POINT_ATLAS))
            if is_curve:
                row["curve"] = int(r["curve"])
            rows.append(row)
        table, key = ((BifurcationCurve, "bifurcation_curves") if is_curve
                      else (BifurcationPoint, "bifurcation_points"))
    if rows:
        session.execute(insert(table), rows)
    counts[key] = counts.get(key, 0) + len(rows)


def _info_rows(session: Session, counts: Mapping[str, int]) -> list[dict[str, Any]]:
    from sqlalchemy import select

    from gearsim import __version__

    commit, dirty = git_commit()
    settings = [
        json.dumps(s, sort_keys=True)
        for col in (Plane.integration, Sweep.integration)
        for (s,) in session.execute(select(col))
    ]
    codes = sorted({c for (c,) in session.execute(select(Run.code_version)) if c})
    info = {
        "schema_version": SCHEMA_VERSION,
        "built": now_iso(),
        "git_commit": commit,
        "git_dirty": dirty,
        "gearsim_version": __version__,
        "code_versions": codes,
        "integration": json.loads(settings[0]) if len(set(settings)) == 1 else None,
        "counts": dict(counts),
    }
    return [{"key": k, "value": json.dumps(v, sort_keys=True)} for k, v in info.items()]


def build_catalogue(
    out: str | Path,
    plane_files: Iterable[str | Path] = (),
    sweep_files: Iterable[str | Path] = (),
    audit_files: Iterable[str | Path] = (),
    *,
    attractor_files: Iterable[str | Path] = (),
    orbit_files: Iterable[str | Path] = (),
    chunk: int = 20_000,
    publish_to: str | Path | None = None,
) -> dict[str, int]:
    """Build the SQLite catalogue in one transaction into a temp file renamed to ``out``.

    ``plane_files`` are ``cells.parquet`` files (each checked: plane record, every tile of the
    plane's configuration hash and code version, cell counts, each ``(i, j)`` exactly once),
    ``sweep_files`` sweep Parquet files and ``audit_files`` audit Parquet files;
    ``attractor_files`` per-tile attractor files of planes with multistability (the
    ``attractors`` table and ``cells.n_attractors``). Cells stream in
    batches of ``chunk`` rows (bounded memory). A bad input raises :class:`CatalogueError` and
    leaves ``out`` (and ``publish_to``) as they were. With ``publish_to``, the finished catalogue
    is then published there atomically (:func:`publish`). Returns row counts.
    """
    out = Path(out)
    plane_files, sweep_files, audit_files, attractor_files, orbit_files = (
        list(f) for f in (plane_files, sweep_files, audit_files, attractor_files, orbit_files)
    )
    # a lower bound (cells are stored once more, with their indexes): catches a folder that
    # cannot hold the catalogue at all before the build
    _prepare_dir(out, need=_size([*plane_files, *sweep_files, *audit_files, *attractor_files,
                                  *orbit_files]))
    counts = {"runs": 0, "planes": 0, "cells": 0, "sweeps": 0, "sweep_points": 0, "audits": 0}
    with replacing(out, "write", bulk=True) as (_tmp, engine):
        Base.metadata.create_all(engine)
        # the cells' lookup indexes are built once after the bulk insert (much faster than
        # maintaining them row by row); the unique (plane_id, i, j) constraint stays on
        cell_indexes = sorted(Cell.__table__.indexes, key=lambda ix: ix.name)
        with engine.begin() as con:
            for ix in cell_indexes:
                ix.drop(con)
        with Session(engine) as session, session.begin():
            names: set[str] = set()
            for f in plane_files:
                _insert_plane(session, Path(f), names, counts, chunk)
            for f in sweep_files:
                _insert_sweep(session, Path(f), counts)
            for f in audit_files:
                _insert_audit(session, Path(f), counts)
            for f in attractor_files:
                _insert_attractors(session, Path(f), counts)
            for f in orbit_files:  # docs/orbits.md: bifurcation points, curves, cell orbits
                _insert_orbit_file(session, Path(f), counts)
            session.execute(insert(ColumnDoc), _column_rows())
            session.execute(insert(CatalogueInfo), _info_rows(session, counts))
        with engine.begin() as con:
            for ix in cell_indexes:
                ix.create(con)
            create_views(con, [read_metadata(f, PLANE_KEY) for f in plane_files],
                         [read_metadata(f) for f in sweep_files])  # one per plane and sweep
            con.exec_driver_sql(f"PRAGMA application_id = {APPLICATION_ID}")
            con.exec_driver_sql(f"PRAGMA user_version = {SCHEMA_VERSION}")
    if publish_to is not None:
        publish(out, publish_to)
    return counts


