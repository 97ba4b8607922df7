"""Storage: Parquet files with provenance, and the SQLite catalogue (SQLAlchemy 2).

Files (see docs/pipeline.md)
----------------------------
``results/<plane>/tiles/<tile>.parquet``
    One row per cell of a tile; provenance under the key ``gearsim.provenance`` of the Parquet
    key-value metadata.
``results/<plane>/cells.parquet``
    All tiles of a plane (list columns ``poincare_x``, ``poincare_v``); metadata holds the plane
    record and the provenance of every tile.
``results/sweeps/<name>.parquet``
    One row per sweep value (the columns of :func:`gearsim.sweep.orbit_diagram`).
``results/catalogue.sqlite``
    Tables ``runs``, ``planes``, ``cells``, ``sweeps``, ``sweep_points``, ``audits``; written by one
    rule, in one transaction, to a temporary file renamed into place.

Every writer here writes to a temporary name in the target directory and renames it, so a reader
never sees a half-written file.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Mapping
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pandas as pd
from sqlalchemy import (
    JSON,
    Boolean,
    DateTime,
    Float,
    ForeignKey,
    Index,
    Integer,
    MetaData,
    String,
    UniqueConstraint,
    create_engine,
    event,
    insert,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, Session, mapped_column

PROVENANCE_KEY = b"gearsim.provenance"
PLANE_KEY = b"gearsim.plane"
TILES_KEY = b"gearsim.tiles"
SCHEMA_VERSION = 1


# ------------------------------------------------------------------------------ Parquet
def _tmp_name(path: Path) -> Path:
    return path.with_name(f".{path.name}.tmp-{os.getpid()}")


def write_parquet(df: pd.DataFrame, path: str | Path, metadata: Mapping[bytes, Any]) -> Path:
    """Write ``df`` with JSON-encoded key-value ``metadata`` atomically (temp name + rename)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    table = pa.Table.from_pandas(df, preserve_index=False)
    meta = dict(table.schema.metadata or {})
    for k, v in metadata.items():
        meta[k] = v if isinstance(v, bytes) else json.dumps(v, default=_json_default).encode()
    table = table.replace_schema_metadata(meta)
    tmp = _tmp_name(path)
    try:
        pq.write_table(table, tmp)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


def read_metadata(path: str | Path, key: bytes = PROVENANCE_KEY) -> Any:
    """A JSON value from the Parquet key-value metadata (``None`` when absent)."""
    import pyarrow.parquet as pq

    meta = pq.read_schema(path).metadata or {}
    raw = meta.get(key)
    return None if raw is None else json.loads(raw)


def _json_default(o: Any) -> Any:
    try:
        return float(o)
    except (TypeError, ValueError):
        return str(o)


def combine_tiles(paths: Iterable[str | Path], out: str | Path, plane_record: Mapping) -> Path:
    """Concatenate a plane's tile files into ``cells.parquet`` (sorted by j, i)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    tables, provs = [], []
    for p in paths:
        t = pq.read_table(p)
        tables.append(t.replace_schema_metadata(None))
        prov = read_metadata(p)
        prov["file"] = str(p)
        provs.append(prov)
    table = pa.concat_tables(tables, promote_options="permissive")
    df = table.to_pandas().sort_values(["j", "i"], kind="stable").reset_index(drop=True)
    return write_parquet(df, out, {PLANE_KEY: dict(plane_record), TILES_KEY: provs})


# ---------------------------------------------------------------------- SQLite catalogue
NAMING_CONVENTION = {
    "ix": "ix_%(table_name)s_%(column_0_N_name)s",
    "uq": "uq_%(table_name)s_%(column_0_N_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}


class Base(DeclarativeBase):
    metadata = MetaData(naming_convention=NAMING_CONVENTION)


class Run(Base):
    """A job that produced data (a tile, a sweep, an audit): its provenance."""

    __tablename__ = "runs"
    id: Mapped[int] = mapped_column(primary_key=True)
    kind: Mapped[str] = mapped_column(String(16))  # tile | sweep | audit
    name: Mapped[str] = mapped_column(String(64))  # plane or sweep name
    tile: Mapped[int | None] = mapped_column(Integer)
    file: Mapped[str | None] = mapped_column(String(512))
    config_hash: Mapped[str] = mapped_column(String(64), index=True)
    code_version: Mapped[str] = mapped_column(String(64), index=True)
    package_versions: Mapped[dict] = mapped_column(JSON)
    parameters_source: Mapped[str | None] = mapped_column(String(512))
    tangent_seed: Mapped[int | None] = mapped_column(Integer)
    audit_seed: Mapped[int | None] = mapped_column(Integer)
    host: Mapped[str | None] = mapped_column(String(128))
    workers: Mapped[str | None] = mapped_column(String(256))
    started: Mapped[datetime | None] = mapped_column(DateTime)
    finished: Mapped[datetime | None] = mapped_column(DateTime)
    wall_s: Mapped[float | None] = mapped_column(Float)
    cells: Mapped[int | None] = mapped_column(Integer)


class Plane(Base):
    __tablename__ = "planes"
    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(64), unique=True)
    x_name: Mapped[str] = mapped_column(String(32))
    x_min: Mapped[float] = mapped_column(Float)
    x_max: Mapped[float] = mapped_column(Float)
    x_n: Mapped[int] = mapped_column(Integer)
    y_name: Mapped[str] = mapped_column(String(32))
    y_min: Mapped[float] = mapped_column(Float)
    y_max: Mapped[float] = mapped_column(Float)
    y_n: Mapped[int] = mapped_column(Integer)
    fixed: Mapped[dict] = mapped_column(JSON)  # the plane's `fixed` overrides
    parameters: Mapped[dict] = mapped_column(JSON)  # every fixed parameter value of the plane
    config_hash: Mapped[str] = mapped_column(String(64))


class _CellColumns:
    """Every column of ``CellResult.row()``; ``I`` is stored as ``impact`` (SQL names are
    case-insensitive and ``i`` is the grid index)."""

    motion: Mapped[str] = mapped_column(String(16))
    status: Mapped[str] = mapped_column(String(16))
    impact: Mapped[int] = mapped_column(Integer)  # I: 0, 1, -1, 2, -2
    n: Mapped[int] = mapped_column(Integer)
    p: Mapped[int | None] = mapped_column(Integer)
    q: Mapped[int | None] = mapped_column(Integer)
    label: Mapped[str] = mapped_column(String(32))
    label_npq: Mapped[str] = mapped_column(String(32))
    dc: Mapped[float | None] = mapped_column(Float)
    kmax: Mapped[float | None] = mapped_column(Float)
    kmax_peak_mean: Mapped[float | None] = mapped_column(Float)
    kmax_peak_static: Mapped[float | None] = mapped_column(Float)
    kmax_section_mean: Mapped[float | None] = mapped_column(Float)
    kmax_section_static: Mapped[float | None] = mapped_column(Float)
    kmin_peak_mean: Mapped[float | None] = mapped_column(Float)
    lyapunov: Mapped[float | None] = mapped_column(Float)
    x_min: Mapped[float | None] = mapped_column(Float)
    x_max: Mapped[float | None] = mapped_column(Float)
    converged: Mapped[bool] = mapped_column(Boolean)
    window_periods: Mapped[int] = mapped_column(Integer)
    periods: Mapped[int] = mapped_column(Integer)
    steps: Mapped[int] = mapped_column(Integer)


ROW_COLUMNS = (
    "motion",
    "status",
    "I",
    "n",
    "p",
    "q",
    "label",
    "label_npq",
    "dc",
    "kmax",
    "kmax_peak_mean",
    "kmax_peak_static",
    "kmax_section_mean",
    "kmax_section_static",
    "kmin_peak_mean",
    "lyapunov",
    "x_min",
    "x_max",
    "converged",
    "window_periods",
    "periods",
    "steps",
)


class Cell(_CellColumns, Base):
    __tablename__ = "cells"
    id: Mapped[int] = mapped_column(primary_key=True)
    plane_id: Mapped[int] = mapped_column(ForeignKey("planes.id"))
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id"))
    i: Mapped[int] = mapped_column(Integer)  # x index
    j: Mapped[int] = mapped_column(Integer)  # y index
    x: Mapped[float] = mapped_column(Float)  # value of planes.x_name
    y: Mapped[float] = mapped_column(Float)  # value of planes.y_name
    elapsed_s: Mapped[float | None] = mapped_column(Float)
    __table_args__ = (
        UniqueConstraint("plane_id", "i", "j"),
        Index(None, "plane_id", "label"),
        Index(None, "plane_id", "impact"),
        Index(None, "plane_id", "x", "y"),
        Index(None, "plane_id", "y", "x"),
        Index(None, "label"),
        Index(None, "lyapunov"),
    )


class Sweep(Base):
    __tablename__ = "sweeps"
    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(64), unique=True)
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id"))
    parameter: Mapped[str] = mapped_column(String(32))
    min: Mapped[float] = mapped_column(Float)
    max: Mapped[float] = mapped_column(Float)
    n: Mapped[int] = mapped_column(Integer)
    direction: Mapped[str] = mapped_column(String(16))
    fixed: Mapped[dict] = mapped_column(JSON)
    parameters: Mapped[dict] = mapped_column(JSON)


class SweepPoint(_CellColumns, Base):
    __tablename__ = "sweep_points"
    id: Mapped[int] = mapped_column(primary_key=True)
    sweep_id: Mapped[int] = mapped_column(ForeignKey("sweeps.id"))
    k: Mapped[int] = mapped_column(Integer)  # position in the sweep order
    value: Mapped[float] = mapped_column(Float)
    poincare_x: Mapped[list] = mapped_column(JSON)
    poincare_v: Mapped[list] = mapped_column(JSON)
    __table_args__ = (
        UniqueConstraint("sweep_id", "k"),
        Index(None, "sweep_id", "value"),
        Index(None, "label"),
    )


class Audit(Base):
    """Numerical audit: a cell re-simulated at tightened tolerance from the same start state."""

    __tablename__ = "audits"
    id: Mapped[int] = mapped_column(primary_key=True)
    cell_id: Mapped[int] = mapped_column(ForeignKey("cells.id"), index=True)
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id"))
    label: Mapped[str] = mapped_column(String(32))
    label_npq: Mapped[str] = mapped_column(String(32))
    impact: Mapped[int] = mapped_column(Integer)
    dc: Mapped[float | None] = mapped_column(Float)
    kmax: Mapped[float | None] = mapped_column(Float)
    lyapunov: Mapped[float | None] = mapped_column(Float)
    agree: Mapped[bool] = mapped_column(Boolean)  # same label and n-p-q as the catalogue cell


@event.listens_for(Base.metadata, "after_create")
def _views(target, connection, **kw):  # pragma: no cover - exercised via build_catalogue
    connection.exec_driver_sql(
        "CREATE VIEW IF NOT EXISTS plane_cells AS "
        "SELECT p.name AS plane, p.x_name, p.y_name, c.* "
        "FROM cells c JOIN planes p ON p.id = c.plane_id"
    )


def make_engine(url: str):
    engine = create_engine(url)

    @event.listens_for(engine, "connect")
    def _fk_on(dbapi_connection, _record):
        cur = dbapi_connection.cursor()
        cur.execute("PRAGMA foreign_keys=ON")
        cur.close()

    return engine


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
    }


def build_catalogue(
    out: str | Path,
    plane_files: Iterable[str | Path] = (),
    sweep_files: Iterable[str | Path] = (),
    audit_files: Iterable[str | Path] = (),
    *,
    chunk: int = 20_000,
) -> dict[str, int]:
    """Build the SQLite catalogue in one transaction into a temp file renamed to ``out``.

    ``plane_files`` are ``cells.parquet`` files, ``sweep_files`` sweep Parquet files and
    ``audit_files`` audit Parquet files (the hook of the numerical audit). Returns row counts.
    """
    import pyarrow.parquet as pq

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = _tmp_name(out)
    if tmp.exists():
        tmp.unlink()
    engine = make_engine(f"sqlite:///{tmp}")
    counts = {"runs": 0, "planes": 0, "cells": 0, "sweeps": 0, "sweep_points": 0, "audits": 0}
    try:
        Base.metadata.create_all(engine)
        with Session(engine) as session, session.begin():
            cell_ids: dict[tuple[str, int, int], int] = {}
            for f in plane_files:
                rec = read_metadata(f, PLANE_KEY)
                tiles = read_metadata(f, TILES_KEY) or []
                plane = Plane(
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
                    parameters=rec.get("parameters", {}),
                    config_hash=rec.get("config_hash", ""),
                )
                session.add(plane)
                run_of_tile: dict[int, int] = {}
                for prov in tiles:
                    run = Run(**_run_row(prov))
                    session.add(run)
                    session.flush()
                    run_of_tile[int(prov["tile"])] = run.id
                    counts["runs"] += 1
                session.flush()
                counts["planes"] += 1
                cols = ["tile", "i", "j", "x", "y", "elapsed_s", *ROW_COLUMNS]
                pf = pq.ParquetFile(f)
                for batch in pf.iter_batches(batch_size=chunk, columns=cols):
                    df = batch.to_pandas()
                    rows = []
                    for rec_ in df.to_dict("records"):
                        r = _row_values(rec_)
                        r.update(
                            plane_id=plane.id,
                            run_id=run_of_tile[int(rec_["tile"])],
                            i=int(rec_["i"]),
                            j=int(rec_["j"]),
                            x=float(rec_["x"]),
                            y=float(rec_["y"]),
                            elapsed_s=_nan_to_none(rec_["elapsed_s"]),
                        )
                        rows.append(r)
                    session.execute(insert(Cell), rows)
                    counts["cells"] += len(rows)
            # cell ids for the audit hook
            if audit_files:
                from sqlalchemy import select

                q = select(Cell.id, Plane.name, Cell.i, Cell.j).join(Plane)
                cell_ids = {(p, i, j): cid for cid, p, i, j in session.execute(q)}
            for f in sweep_files:
                prov = read_metadata(f) or {}
                prov = {**prov, "file": str(f)}
                run = Run(**_run_row(prov))
                session.add(run)
                session.flush()
                counts["runs"] += 1
                spec = prov.get("subtree", {}).get("sweep", {})
                df = pd.read_parquet(f)
                sweep = Sweep(
                    name=prov.get("name", Path(f).stem),
                    run_id=run.id,
                    parameter=spec.get("name", df["parameter"].iloc[0] if len(df) else "?"),
                    min=float(spec.get("min", df["value"].min())),
                    max=float(spec.get("max", df["value"].max())),
                    n=int(spec.get("n", len(df))),
                    direction=spec.get("direction", "forward"),
                    fixed=spec.get("fixed", {}),
                    parameters=prov.get("subtree", {}).get("parameters", {}),
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
                    )
                    rows.append(r)
                if rows:
                    session.execute(insert(SweepPoint), rows)
                counts["sweep_points"] += len(rows)
            for f in audit_files:
                prov = read_metadata(f) or {}
                prov = {**prov, "file": str(f)}
                run = Run(**_run_row(prov))
                session.add(run)
                session.flush()
                counts["runs"] += 1
                rows = []
                for rec_ in pd.read_parquet(f).to_dict("records"):
                    key = (rec_["plane"], int(rec_["i"]), int(rec_["j"]))
                    if key not in cell_ids:
                        continue
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
        engine.dispose()
        os.replace(tmp, out)
    finally:
        engine.dispose()
        if tmp.exists():
            tmp.unlink()
    return counts


def now_iso() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")
