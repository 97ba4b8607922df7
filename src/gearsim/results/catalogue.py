"""Storage: Parquet files with provenance, and the SQLite catalogue (SQLAlchemy 2).

Files (see docs/pipeline.md)
----------------------------
``results/<plane>/tiles/<tile>.parquet``
    One row per cell of a tile; provenance under the key ``gearsim.study.provenance`` of the Parquet
    key-value metadata.
``results/<plane>/cells.parquet``
    All tiles of a plane (list columns ``poincare_x``, ``poincare_v``); metadata holds the plane
    record and the provenance of every tile.
``results/sweeps/<name>.parquet``
    One row per sweep value (the columns of :func:`gearsim.cell.sweep.orbit_diagram`).
``results/catalogue.sqlite``
    Tables ``runs``, ``planes``, ``cells``, ``sweeps``, ``sweep_points``, ``audits``; written by one
    rule, in one transaction, to a temporary file renamed into place.

Every writer here writes to a temporary name in the target directory and renames it, so a reader
never sees a half-written file.
"""

from __future__ import annotations

import json
import os
import sqlite3
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
    Text,
    UniqueConstraint,
    create_engine,
    event,
    insert,
)
from sqlalchemy.exc import DBAPIError as SQLAlchemyDBAPIError
from sqlalchemy.orm import DeclarativeBase, Mapped, Session, mapped_column

from gearsim.errors import UsageError
from gearsim.study.integrity import CatalogueError, _one_line
from gearsim.cell.simulate import result_columns
from gearsim.results.views import create_views

__all__ = [
    "CatalogueError",
    "build_catalogue",
    "combine_tiles",
    "migrate_catalogue",
    "open_catalogue",
    "publish",
]

PROVENANCE_KEY = b"gearsim.study.provenance"
PLANE_KEY = b"gearsim.plane"
TILES_KEY = b"gearsim.study.tiles"
#: ``PRAGMA user_version`` of the catalogue this code writes and reads. It rises with every
#: change of the schema, and :data:`MIGRATIONS` brings an older catalogue up to it.
#: 1: runs, planes, cells, sweeps, sweep_points, audits;
#: 2: column dictionary, catalogue_info, integration settings of planes and sweeps;
#: 3: attractors, bifurcation_points, bifurcation_curves, cell_orbits, cells.n_attractors (some
#:    catalogues of version 2 already have them) and runs.status (ok, budget, skipped).
SCHEMA_VERSION = 3
#: The oldest version :func:`migrate_catalogue` brings up to date (older: rebuild).
OLDEST_MIGRATABLE = 2
#: ``PRAGMA application_id``: "GEAR"; tells a gearsim catalogue from any other SQLite file.
APPLICATION_ID = 0x47454152
#: Tables and views a reader may rely on (version 2; :data:`REQUIRED`: this version).
REQUIRED_2 = frozenset(
    {
        "runs",
        "planes",
        "cells",
        "sweeps",
        "sweep_points",
        "audits",
        "catalogue_info",
        "column_dictionary",
        "plane_cells",
    }
)
REQUIRED = REQUIRED_2 | frozenset(
    {
        "attractors",
        "bifurcation_points",
        "bifurcation_curves",
        "cell_orbits",
    }
)
#: How to rebuild a catalogue, for messages.
REBUILD = "rebuild it: snakemake --cores 2 --forcerun catalogue"


# ------------------------------------------------------------------------------ Parquet
def _tmp_name(path: Path) -> Path:
    return path.with_name(f".{path.name}.tmp-{os.getpid()}")


def _prepare_dir(out: Path, need: int = 0) -> None:
    """Create ``out``'s directory, clear dead writers' temporary files and check that a file
    can be written there with ``need`` bytes free (:func:`gearsim.study.preflight.check_output`),
    or one line."""
    from gearsim.study.preflight import check_output

    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        _remove_stale_tmp(out)
    except OSError as exc:
        raise CatalogueError(f"cannot write {out} ({_fault(exc)})") from None
    try:
        check_output(out, need=need, what="output")
    except UsageError as exc:
        raise CatalogueError(str(exc)) from None


def _size(paths: Iterable[str | Path]) -> int:
    """Bytes of the files ``paths`` (missing ones count 0): the estimate of an output's size."""
    return sum(Path(p).stat().st_size for p in paths if Path(p).is_file())


def _remove_stale_tmp(path: Path) -> None:
    """Delete temporary files of ``path`` left by writers that were killed (their pid is gone)."""
    for f in path.parent.glob(f".{path.name}.tmp-*"):
        # .NAME.tmp-PID, and SQLite's .NAME.tmp-PID-journal / -wal / -shm beside it
        pid = f.name[len(path.name) + 6 :].split("-", 1)[0]
        if not pid.isdigit() or int(pid) == os.getpid():
            continue
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            f.unlink(missing_ok=True)
        except PermissionError:  # alive, another user's
            pass


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
    """Check a plane's tile files and stream them into ``cells.parquet`` (sorted by j, i).

    Every tile must carry the plane's configuration hash and code version and as many cells as
    its provenance recorded; together the tiles must cover each cell ``(i, j)`` of the grid
    exactly once (:mod:`gearsim.study.integrity`). Otherwise :class:`CatalogueError` names the tile
    and nothing is written. One tile is in memory at a time.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    from gearsim.study.integrity import Coverage, tile_info

    infos = [tile_info(p, plane_record, PROVENANCE_KEY) for p in paths]
    if not infos:
        raise CatalogueError(f"plane {plane_record['name']!r}: no tiles given")
    infos.sort(key=lambda t: (t.first_row, str(t.path)))
    try:
        schema = pa.unify_schemas([t.schema for t in infos], promote_options="permissive")
    except (pa.ArrowInvalid, pa.ArrowTypeError) as exc:
        raise CatalogueError(
            f"plane {plane_record['name']!r}: tiles with incompatible columns ({_one_line(exc)})"
        ) from None
    provs = [{**t.provenance, "file": str(t.path)} for t in infos]
    meta = {k: v for k, v in (schema.metadata or {}).items() if k == b"pandas"}
    meta[PLANE_KEY] = json.dumps(dict(plane_record), default=_json_default).encode()
    meta[TILES_KEY] = json.dumps(provs, default=_json_default).encode()
    schema = schema.with_metadata(meta)
    coverage = Coverage(plane_record)
    out = Path(out)
    _prepare_dir(out, need=_size(t.path for t in infos))
    tmp = _tmp_name(out)
    try:
        with pq.ParquetWriter(tmp, schema) as writer:
            for t in infos:
                try:
                    table = pq.read_table(t.path)
                except Exception as exc:  # damaged pages behind a valid footer
                    raise CatalogueError(
                        f"tile {t.path}: not a readable Parquet file ({_one_line(exc)})"
                    ) from None
                missing = [c for c in ("i", "j", "x", "y") if c not in table.column_names]
                if missing:
                    raise CatalogueError(f"tile {t.path}: no column {missing[0]!r}")
                table = table.sort_by([("j", "ascending"), ("i", "ascending")])
                coverage.add(
                    table["i"].to_numpy(),
                    table["j"].to_numpy(),
                    table["x"].to_numpy(),
                    table["y"].to_numpy(),
                    f"tile {t.path}",
                )
                cols = []
                for field in schema:
                    if field.name in table.column_names:
                        cols.append(table[field.name].cast(field.type))
                    else:
                        cols.append(pa.nulls(len(table), field.type))
                writer.write_table(pa.Table.from_arrays(cols, schema=schema))
        coverage.finish(f"plane {plane_record['name']!r}")
        os.replace(tmp, out)
    except OSError as exc:  # full disk, vanished directory: one line, the old file stays
        raise CatalogueError(f"cannot write {out} ({_fault(exc)})") from None
    finally:
        if tmp.exists():
            tmp.unlink()
    return out


def _fault(exc: BaseException) -> str:
    """The cause of a write fault in a few words: SQLite's own message without SQLAlchemy's
    statement and link, an OSError's cause without its errno."""
    orig = getattr(exc, "orig", None)
    if isinstance(orig, BaseException):
        exc = orig
    if isinstance(exc, OSError):
        from gearsim.study.preflight import os_cause

        return os_cause(exc)
    return _one_line(exc)


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
    # ok | budget (a job stopped at its budget: its results are partial) | skipped
    status: Mapped[str | None] = mapped_column(String(16))


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
    code_version: Mapped[str] = mapped_column(String(64))
    integration: Mapped[dict] = mapped_column(JSON)  # IntegrationSettings fields


_SQL_TYPES = {str: lambda: String(32), int: Integer, float: Float, bool: Boolean}


def _cell_columns() -> dict[str, Any]:
    """SQL columns of ``CellResult.row()`` (:func:`gearsim.cell.simulate.result_columns`).

    ``I`` is stored as ``impact`` (SQL names are case-insensitive and ``i`` is the grid index).
    """
    return {
        ("impact" if name == "I" else name): mapped_column(_SQL_TYPES[typ](), nullable=optional)
        for name, (typ, optional) in result_columns().items()
    }


#: Every column of ``CellResult.row()``, derived from the fields of ``Classification``: a new
#: field there is a new column of ``cells`` and ``sweep_points`` with no edit here.
_CellColumns = type("_CellColumns", (), {"__doc__": _cell_columns.__doc__, **_cell_columns()})

ROW_COLUMNS = tuple(result_columns())


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
    # coexisting attractors found from many starts (NULL: multistability off for the plane)
    n_attractors: Mapped[int | None] = mapped_column(Integer)
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
    parameters: Mapped[dict] = mapped_column(JSON)  # values held fixed (swept one omitted)
    config_hash: Mapped[str] = mapped_column(String(64))
    integration: Mapped[dict] = mapped_column(JSON)


class SweepPoint(_CellColumns, Base):
    __tablename__ = "sweep_points"
    id: Mapped[int] = mapped_column(primary_key=True)
    sweep_id: Mapped[int] = mapped_column(ForeignKey("sweeps.id"))
    k: Mapped[int] = mapped_column(Integer)  # position in the sweep order
    value: Mapped[float] = mapped_column(Float)
    poincare_x: Mapped[list] = mapped_column(JSON)
    poincare_v: Mapped[list] = mapped_column(JSON)
    # forward | backward (a `direction: both` sweep holds both, forward first)
    direction: Mapped[str | None] = mapped_column(String(16))
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


class CellAttractor(Base):
    """One of the coexisting attractors of a plane cell (gearsim.analysis.attractors, many starts)."""

    __tablename__ = "attractors"
    id: Mapped[int] = mapped_column(primary_key=True)
    cell_id: Mapped[int] = mapped_column(ForeignKey("cells.id"), index=True)
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id"))
    attractor: Mapped[int] = mapped_column(Integer)  # index in the cell, most starts first
    motion: Mapped[str] = mapped_column(String(16))
    label: Mapped[str] = mapped_column(String(32))
    label_npq: Mapped[str] = mapped_column(String(32))
    impact: Mapped[int] = mapped_column(Integer)
    n: Mapped[int] = mapped_column(Integer)
    p: Mapped[int | None] = mapped_column(Integer)
    q: Mapped[int | None] = mapped_column(Integer)
    dc: Mapped[float | None] = mapped_column(Float)
    kmax: Mapped[float | None] = mapped_column(Float)
    lyapunov: Mapped[float | None] = mapped_column(Float)
    basin_fraction: Mapped[float] = mapped_column(Float)
    n_starts: Mapped[int] = mapped_column(Integer)
    n_early: Mapped[int] = mapped_column(Integer)
    found_by: Mapped[str] = mapped_column(String(32))  # forward,backward,start (subset)
    __table_args__ = (UniqueConstraint("cell_id", "attractor"), Index(None, "label"))


class _LocatedBifurcation:
    """Columns of a located bifurcation: its kind, the orbit's period, the parameter value(s),
    the section point and the Floquet multipliers there."""

    kind: Mapped[str] = mapped_column(String(32))
    period: Mapped[int] = mapped_column(Integer)
    boundary: Mapped[str] = mapped_column(String(32))
    name: Mapped[str] = mapped_column(String(32))
    value: Mapped[float] = mapped_column(Float)
    name2: Mapped[str] = mapped_column(String(32))
    value2: Mapped[float] = mapped_column(Float)
    x: Mapped[float] = mapped_column(Float)
    v: Mapped[float] = mapped_column(Float)
    mu_max: Mapped[float] = mapped_column(Float)
    multipliers: Mapped[list] = mapped_column(JSON)
    stable: Mapped[bool] = mapped_column(Boolean)


class BifurcationPoint(_LocatedBifurcation, Base):
    """A bifurcation located by continuation (gearsim.analysis.continuation; docs/orbits.md)."""

    __tablename__ = "bifurcation_points"
    id: Mapped[int] = mapped_column(primary_key=True)
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id"))
    plane: Mapped[str] = mapped_column(String(64), index=True)


class BifurcationCurve(_LocatedBifurcation, Base):
    """A point of a two-parameter bifurcation curve (gearsim.analysis.bifcurves; docs/orbits.md)."""

    __tablename__ = "bifurcation_curves"
    id: Mapped[int] = mapped_column(primary_key=True)
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id"))
    plane: Mapped[str] = mapped_column(String(64), index=True)
    curve: Mapped[int] = mapped_column(Integer)


class CellOrbit(Base):
    """Newton refinement of a periodic cell (gearsim refine-orbits; docs/orbits.md)."""

    __tablename__ = "cell_orbits"
    id: Mapped[int] = mapped_column(primary_key=True)
    cell_id: Mapped[int] = mapped_column(ForeignKey("cells.id"), index=True)
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id"))
    converged: Mapped[bool] = mapped_column(Boolean)
    residual: Mapped[float | None] = mapped_column(Float)
    mu_max: Mapped[float | None] = mapped_column(Float)
    kind: Mapped[str] = mapped_column(String(32))
    grazing_margin: Mapped[float | None] = mapped_column(Float)
    shift: Mapped[float | None] = mapped_column(Float)
    minimal_period: Mapped[int] = mapped_column(Integer)
    flag: Mapped[str] = mapped_column(String(32))
    ms: Mapped[float | None] = mapped_column(Float)


class CatalogueInfo(Base):
    """Facts about the build: schema version, git commit, code versions, integration settings."""

    __tablename__ = "catalogue_info"
    key: Mapped[str] = mapped_column(String(64), primary_key=True)
    value: Mapped[str] = mapped_column(Text)  # JSON text (TEXT affinity keeps '2' a string)


class ColumnDoc(Base):
    """Unit and meaning of every column (:data:`gearsim.results.columns.CATALOGUE`)."""

    __tablename__ = "column_dictionary"
    table_name: Mapped[str] = mapped_column(String(64), primary_key=True)
    column_name: Mapped[str] = mapped_column(String(64), primary_key=True)
    unit: Mapped[str] = mapped_column(String(64))
    meaning: Mapped[str] = mapped_column(String(256))


@event.listens_for(Base.metadata, "after_create")
def _views(target, connection, **kw):  # pragma: no cover - exercised via build_catalogue
    connection.exec_driver_sql(
        "CREATE VIEW IF NOT EXISTS plane_cells AS "
        "SELECT p.name AS plane, p.x_name, p.y_name, c.* "
        "FROM cells c JOIN planes p ON p.id = c.plane_id"
    )


def make_engine(url: str, *, bulk: bool = False):
    """A SQLAlchemy engine with foreign keys enforced. ``bulk``: for a build into a temporary
    file that is renamed only when complete (no rollback journal, no syncs until the final
    fsync, a 64 MB page cache): a crash mid-build loses only the temporary file."""
    engine = create_engine(url)

    @event.listens_for(engine, "connect")
    def _fk_on(dbapi_connection, _record):
        cur = dbapi_connection.cursor()
        cur.execute("PRAGMA foreign_keys=ON")
        if bulk:
            cur.execute("PRAGMA journal_mode=OFF")
            cur.execute("PRAGMA synchronous=OFF")
            cur.execute("PRAGMA cache_size=-65536")
        cur.close()

    return engine


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


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
        raise CatalogueError(f"plane file {f}: unreadable cells ({_one_line(exc)})") from None
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


def _insert_audit(session: Session, f: Path, counts: dict) -> None:
    from sqlalchemy import select

    prov, run, df = _file_run(session, f, "audit file", counts)
    q = select(Cell.id, Cell.i, Cell.j).join(Plane).where(Plane.name == prov.get("name"))
    planes = set(df["plane"]) if len(df) else set()
    cell_ids = {}
    for name in planes:
        q = select(Cell.id, Cell.i, Cell.j).join(Plane).where(Plane.name == name)
        cell_ids.update({(name, i, j): cid for cid, i, j in session.execute(q)})
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
                "basin_fraction": float(r["basin_fraction"]), "n_starts": int(r["n_starts"]),
                "n_early": int(r["n_early"]), "found_by": r["found_by"],
            }  # fmt: skip
        )
    if rows:
        session.execute(insert(CellAttractor), rows)
    for cid, n in n_of.items():
        session.execute(update(Cell).where(Cell.id == cid).values(n_attractors=n))
    counts["attractors"] = counts.get("attractors", 0) + len(rows)


def _insert_orbit_file(session: Session, f: Path, counts: dict) -> None:
    """Insert a bifurcation points / curves file or a refine-orbits file (by its columns)."""
    from sqlalchemy import select

    prov, run, df = _file_run(session, f, "orbit file", counts)
    if "orbit_flag" in df.columns:
        cell_ids = {}
        for name in set(df["plane"]):
            q = select(Cell.id, Cell.i, Cell.j).join(Plane).where(Plane.name == name)
            cell_ids.update({(name, i, j): cid for cid, i, j in session.execute(q)})
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
    else:
        is_curve = "curve" in df.columns
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
            if is_curve:
                row["curve"] = int(r["curve"])
            rows.append(row)
        table, key = ((BifurcationCurve, "bifurcation_curves") if is_curve
                      else (BifurcationPoint, "bifurcation_points"))
    if rows:
        session.execute(insert(table), rows)
    counts[key] = counts.get(key, 0) + len(rows)


def git_commit(root: str | Path | None = None) -> tuple[str | None, bool | None]:
    """``(commit, dirty)`` of the source checkout, or ``(None, None)`` outside a git checkout."""
    import subprocess

    root = Path(root) if root is not None else Path(__file__).resolve().parents[3]
    if not (root / ".git").exists():
        return None, None
    try:
        head = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            timeout=10,
        )
        if head.returncode != 0:
            return None, None
        st = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no", "--", "src"],
            capture_output=True,
            text=True,
            timeout=10,
        )
    except (OSError, subprocess.SubprocessError):
        return None, None
    return head.stdout.strip(), bool(st.stdout.strip()) if st.returncode == 0 else None


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


def _column_rows() -> list[dict[str, str]]:
    from gearsim.results.columns import CATALOGUE

    rows = []
    for table in Base.metadata.sorted_tables:
        for col in table.columns:
            doc = CATALOGUE.get((table.name, col.name))
            if doc is None:
                raise RuntimeError(f"column {table.name}.{col.name} has no dictionary entry")
            rows.append(
                {
                    "table_name": table.name,
                    "column_name": col.name,
                    "unit": doc[0],
                    "meaning": doc[1],
                }
            )
    unit, meaning = CATALOGUE[("plane_cells", "*")]
    rows.append({"table_name": "plane_cells", "column_name": "*", "unit": unit, "meaning": meaning})
    return rows


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
    tmp = _tmp_name(out)
    if tmp.exists():
        tmp.unlink()
    engine = make_engine(f"sqlite:///{tmp}", bulk=True)
    counts = {"runs": 0, "planes": 0, "cells": 0, "sweeps": 0, "sweep_points": 0, "audits": 0}
    try:
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
        engine.dispose()
        _fsync(tmp)
        os.replace(tmp, out)
    except (OSError, sqlite3.Error, SQLAlchemyDBAPIError) as exc:
        # full disk, read-only or vanished directory: one line; the previous files stay
        raise CatalogueError(f"catalogue {out}: cannot write it ({_fault(exc)})") from None
    finally:
        engine.dispose()
        if tmp.exists():
            tmp.unlink()
    if publish_to is not None:
        publish(out, publish_to)
    return counts


def publish(built: str | Path, target: str | Path) -> Path:
    """Make ``target`` the catalogue ``built``, atomically: a hard link (or copy) of ``built`` under
    a temporary name in ``target``'s directory, renamed over ``target``.

    At every instant ``target`` is either the previous catalogue or the new one, whole. Readers
    holding the previous file open keep reading it (the rename does not change its inode), and a
    workflow that deletes ``built`` before rebuilding it leaves ``target`` untouched.
    """
    import shutil

    built, target = Path(built), Path(target)
    open_catalogue(built).close()  # never publish a file that readers would refuse
    _prepare_dir(target, need=0)  # a hard link needs no room (a copy: checked as it goes)
    tmp = _tmp_name(target)
    try:
        if tmp.exists():
            tmp.unlink()
        try:
            os.link(built, tmp)
        except OSError:  # no hard links here (another file system, FAT, ...): copy
            shutil.copyfile(built, tmp)
        os.replace(tmp, target)
    except OSError as exc:
        raise CatalogueError(
            f"cannot publish {built} as {target} ({_one_line(exc)}); {target} is unchanged"
        ) from None
    finally:
        if tmp.exists():
            tmp.unlink()
    return target


def open_catalogue(path: str | Path, *, check: bool = True) -> sqlite3.Connection:
    """Open a catalogue read-only (``sqlite3``), refusing anything that is not one of our schema.

    Checks SQLite's own ``PRAGMA quick_check`` (with ``check``: a damaged page or index),
    ``PRAGMA application_id`` (gearsim), ``PRAGMA user_version`` (= :data:`SCHEMA_VERSION`;
    an older one names ``gearsim catalogue migrate``) and the tables readers rely on; raises
    :class:`CatalogueError` with one line otherwise. Every reader (query, export, report,
    figures, explorer) and the workflow open the catalogue through this function.
    """
    p = Path(path)
    if not p.is_file():
        raise CatalogueError(f"catalogue not found: {p} (build it with snakemake)")
    try:
        with open(p, "rb"):  # SQLite would say only "unable to open database file"
            pass
    except OSError as exc:
        raise CatalogueError(f"{p}: cannot read the catalogue ({_fault(exc)})") from None
    try:
        con = sqlite3.connect(f"{p.resolve().as_uri()}?mode=ro", uri=True)
    except sqlite3.Error as exc:
        raise CatalogueError(f"{p}: cannot open the catalogue ({_one_line(exc)})") from None
    problem = _catalogue_problem(con, check=check)
    if problem:
        con.close()
        raise CatalogueError(f"{p}: {problem}".replace("{path}", str(p)))
    return con


def _catalogue_problem(con: sqlite3.Connection, *, check: bool = True,
                       version: int = SCHEMA_VERSION, required=REQUIRED) -> str | None:
    """What makes the open database ``con`` not a sound gearsim catalogue of ``version``
    (with the tables and views ``required``); ``{path}`` in the line stands for its file."""
    try:
        app = con.execute("PRAGMA application_id").fetchone()[0]
        have = con.execute("PRAGMA user_version").fetchone()[0]
        names = {
            r[0]
            for r in con.execute("SELECT name FROM sqlite_master WHERE type IN ('table', 'view')")
        }
    except sqlite3.DatabaseError as exc:
        return f"not a gearsim catalogue, or damaged ({_one_line(exc)}; {REBUILD})"
    if app != APPLICATION_ID:
        return f"not a gearsim catalogue (application_id {app:#x}, expected {APPLICATION_ID:#x})"
    if have < version:
        how = (f"migrate it: gearsim catalogue migrate {{path}}, or {REBUILD}"
               if have >= OLDEST_MIGRATABLE else REBUILD)
        return (f"catalogue schema version {have}, this gearsim reads version {version} "
                f"({how})")
    if have > version:
        return (f"catalogue schema version {have} was written by a newer gearsim, this one "
                f"reads version {version} (update gearsim, or {REBUILD})")
    if check:
        try:
            rows = con.execute("PRAGMA quick_check").fetchall()
        except sqlite3.DatabaseError as exc:
            return f"damaged ({_one_line(exc)}; {REBUILD})"
        if [r[0] for r in rows] != ["ok"]:
            return f"damaged (SQLite quick_check: {_one_line(rows[0][0])}; {REBUILD})"
    missing = sorted(required - names)
    if missing:
        return f"catalogue lacks table {missing[0]!r} (damaged; {REBUILD})"
    return None


def catalogue_problem(path: str | Path) -> str | None:
    """One line saying why ``path`` is not a sound catalogue of this schema, or ``None``
    (a missing file is ``None``: there is nothing to refuse)."""
    p = Path(path)
    if not p.exists():
        return None
    try:
        open_catalogue(p).close()
    except CatalogueError as exc:
        return str(exc)
    return None


def set_aside_damaged(published: str | Path, built: str | Path, *,
                      dry_run: bool = False) -> list[str]:
    """Make the workflow rebuild a catalogue that readers would refuse. Returns a line for each.

    ``published`` is what readers open (``results/catalogue.sqlite``), ``built`` the catalogue
    rule's output it is published from. When either is damaged, foreign or of another schema
    version (:func:`catalogue_problem`), ``built`` is moved into ``damaged/`` beside it (kept
    for inspection, never deleted): its rule then rebuilds it from the verified Parquet files
    and publishes it over ``published``. ``dry_run``: only say so.
    """
    published, built = Path(published), Path(built)
    lines, seen = [], []
    for p in (published, built):
        if not p.exists() or any(os.path.samefile(p, q) for q in seen):
            continue  # the built file is mostly the published one (a hard link)
        seen.append(p)
        why = catalogue_problem(p)
        if why:
            for tail, keep in ((f"; {REBUILD})", ")"), (f", or {REBUILD})", ")"),
                               (f" ({REBUILD})", "")):
                why = why.replace(tail, keep)
            lines.append(why)
    if not lines:
        return []
    what = "the next run rebuilds it" if dry_run else "rebuilding it from the Parquet files"
    lines = [f"{line}: {what}" for line in lines]
    if not dry_run and built.exists():
        stamp = now_iso().replace(":", "")
        aside = built.parent / "damaged" / f"{built.stem}-{stamp}.sqlite"
        k = 0
        while aside.exists():
            k += 1
            aside = built.parent / "damaged" / f"{built.stem}-{stamp}-{k}.sqlite"
        try:
            aside.parent.mkdir(parents=True, exist_ok=True)
            os.replace(built, aside)
        except OSError as exc:
            raise CatalogueError(f"cannot move {built} aside ({_one_line(exc)})") from None
        lines.append(f"{built} kept as {aside}")
    return lines


# ---------------------------------------------------------------------------- migrations
def _migrate_2_to_3(op, con) -> None:
    """Version 3: the attractor and orbit tables, ``cells.n_attractors``, ``runs.status``."""
    import sqlalchemy as sa

    have = set(sa.inspect(con).get_table_names())
    for name in ("attractors", "bifurcation_points", "bifurcation_curves", "cell_orbits"):
        if name not in have:
            Base.metadata.tables[name].create(con)  # with its indexes
    cols = {c["name"] for c in sa.inspect(con).get_columns("cells")}
    if "n_attractors" not in cols:
        op.add_column("cells", sa.Column("n_attractors", sa.Integer(), nullable=True))
    cols = {c["name"] for c in sa.inspect(con).get_columns("runs")}
    if "status" not in cols:
        op.add_column("runs", sa.Column("status", sa.String(16), nullable=True))
    con.exec_driver_sql("UPDATE runs SET status = 'ok' WHERE status IS NULL")


#: ``{version: step}``: the step takes a catalogue of ``version`` to ``version + 1``
#: (Alembic operations on one connection, inside one transaction).
MIGRATIONS = {2: _migrate_2_to_3}


def migrate_catalogue(path: str | Path) -> tuple[int, int]:
    """Bring the catalogue ``path`` up to :data:`SCHEMA_VERSION`, atomically.

    The steps of :data:`MIGRATIONS` (Alembic operations) run on a copy in ``path``'s folder, in
    one transaction; the column dictionary and ``catalogue_info`` are rewritten for the new
    schema, the copy is checked like every catalogue (:func:`open_catalogue`) and only then
    renamed over ``path``. A failure leaves ``path`` as it was. Returns ``(old, new)`` versions.
    """
    import shutil

    from alembic.migration import MigrationContext
    from alembic.operations import Operations
    from sqlalchemy import delete

    p = Path(path)
    if not p.is_file():
        raise CatalogueError(f"catalogue not found: {p}")
    try:
        con = sqlite3.connect(f"{p.resolve().as_uri()}?mode=ro", uri=True)
    except sqlite3.Error as exc:
        raise CatalogueError(f"{p}: cannot open the catalogue ({_one_line(exc)})") from None
    try:
        old = con.execute("PRAGMA user_version").fetchone()[0]
    except sqlite3.DatabaseError:
        old = 0
    if OLDEST_MIGRATABLE <= old < SCHEMA_VERSION:  # sound as a catalogue of its own version
        problem = _catalogue_problem(con, version=old, required=REQUIRED_2)
    else:
        problem = _catalogue_problem(con)
    con.close()
    if problem is None and old == SCHEMA_VERSION:
        return old, old
    if problem is not None and not (0 < old < OLDEST_MIGRATABLE):
        raise CatalogueError(f"{p}: {problem}".replace("{path}", str(p)))
    if old < OLDEST_MIGRATABLE:
        raise CatalogueError(
            f"{p}: catalogue schema version {old} is too old to migrate (oldest "
            f"{OLDEST_MIGRATABLE}); {REBUILD}"
        )
    _prepare_dir(p, need=2 * p.stat().st_size)
    tmp = _tmp_name(p)
    engine = make_engine(f"sqlite:///{tmp}")
    try:
        shutil.copyfile(p, tmp)
        with engine.begin() as conn:
            op = Operations(MigrationContext.configure(conn))
            for v in range(old, SCHEMA_VERSION):
                MIGRATIONS[v](op, conn)
            with Session(bind=conn) as session:
                session.execute(delete(ColumnDoc))
                session.execute(insert(ColumnDoc), _column_rows())
                session.execute(
                    CatalogueInfo.__table__.update()
                    .where(CatalogueInfo.key == "schema_version")
                    .values(value=json.dumps(SCHEMA_VERSION))
                )
                session.flush()
            conn.exec_driver_sql(f"PRAGMA user_version = {SCHEMA_VERSION}")
        engine.dispose()
        open_catalogue(tmp).close()
        _fsync(tmp)
        os.replace(tmp, p)
    except (OSError, sqlite3.Error, SQLAlchemyDBAPIError) as exc:
        raise CatalogueError(f"catalogue {p}: cannot migrate it ({_fault(exc)})") from None
    finally:
        engine.dispose()
        if tmp.exists():
            tmp.unlink()
    return old, SCHEMA_VERSION


def now_iso() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")
