"""The SQLite catalogue's schema (SQLAlchemy 2), its version, its checks on open and migrations.

Tables ``runs``, ``planes``, ``cells``, ``sweeps``, ``sweep_points``, ``audits``, ``attractors``,
``bifurcation_points``, ``bifurcation_curves``, ``codim2_points``, ``cell_orbits``,
``catalogue_info`` and
``column_dictionary``; ``PRAGMA user_version`` is :data:`SCHEMA_VERSION`. Every reader opens a
catalogue through :func:`open_catalogue`; :func:`migrate_catalogue` brings an older one up to date.
"""

from __future__ import annotations

import json
import os
import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import datetime
from pathlib import Path
from typing import Any

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

from gearsim.cell.record import result_columns
from gearsim.errors import CatalogueError, one_line
from gearsim.results.parquet import _fault, _prepare_dir, _tmp_name
from gearsim.results.views import create_views

#: What the catalogue facade (:mod:`gearsim.results.catalogue`) passes on.
__all__ = [
    "APPLICATION_ID", "MIGRATIONS", "OLDEST_MIGRATABLE", "REBUILD", "REQUIRED", "REQUIRED_2",
    "ROW_COLUMNS", "SCHEMA_VERSION", "Audit", "Base", "BifurcationCurve", "BifurcationPoint",
    "Codim2Point",
    "CatalogueInfo", "Cell", "CellAttractor", "CellOrbit", "ColumnDoc", "Plane", "Run", "Sweep",
    "SweepPoint", "catalogue_problem", "make_engine", "migrate_catalogue", "open_catalogue",
]

#: ``PRAGMA user_version`` of the catalogue this code writes and reads. It rises with every
#: change of the schema, and :data:`MIGRATIONS` brings an older catalogue up to it.
#: 1: runs, planes, cells, sweeps, sweep_points, audits;
#: 2: column dictionary, catalogue_info, integration settings of planes and sweeps;
#: 3: attractors, bifurcation_points, bifurcation_curves, cell_orbits, cells.n_attractors (some
#:    catalogues of version 2 already have them) and runs.status (ok, budget, skipped);
#: 4: codim2_points, and the plane atlas's columns of bifurcation_curves (flank, seq, source,
#:    seed cells and labels, how each end ends) and bifurcation_points (curve, source, seed).
SCHEMA_VERSION = 4
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
        "codim2_points",
    }
)
#: How to rebuild a catalogue, for messages.
REBUILD = "rebuild it: snakemake --cores 2 --forcerun catalogue"



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


class _StudyInputs:
    """What a plane or a sweep was computed from (meanings: results/columns.py). Mixin columns
    follow a table's own; ``sort_order`` puts ``integration`` after ``planes.code_version``."""

    fixed: Mapped[dict] = mapped_column(JSON)
    parameters: Mapped[dict] = mapped_column(JSON)
    config_hash: Mapped[str] = mapped_column(String(64))
    integration: Mapped[dict] = mapped_column(JSON, sort_order=2)


class Plane(_StudyInputs, Base):
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
    code_version: Mapped[str] = mapped_column(String(64), sort_order=1)


_SQL_TYPES = {str: lambda: String(32), int: Integer, float: Float, bool: Boolean}


def _cell_columns() -> dict[str, Any]:
    """SQL columns of ``CellResult.row()`` (:func:`gearsim.cell.record.result_columns`).

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


class Sweep(_StudyInputs, Base):
    __tablename__ = "sweeps"
    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(64), unique=True)
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id"))
    parameter: Mapped[str] = mapped_column(String(32))
    min: Mapped[float] = mapped_column(Float)
    max: Mapped[float] = mapped_column(Float)
    n: Mapped[int] = mapped_column(Integer)
    direction: Mapped[str] = mapped_column(String(16))


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
    """One of the coexisting attractors of a plane cell (gearsim.analysis.attractors, many
    starts)."""

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
    # how the motion was settled and the Floquet margin of its refined orbit (NULL: not
    # refined, or a tile written before these columns)
    status: Mapped[str | None] = mapped_column(String(16))
    mu_max: Mapped[float | None] = mapped_column(Float)
    critical: Mapped[str | None] = mapped_column(String(16))
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


class _Seeded:
    """Where a curve was seeded (the plane atlas, docs/orbits.md): from a boundary of the map
    (its two cells and their labels) or from the standard sweep; NULL in older catalogues."""

    source: Mapped[str | None] = mapped_column(String(16))
    seed_i: Mapped[int | None] = mapped_column(Integer)
    seed_j: Mapped[int | None] = mapped_column(Integer)
    seed_i2: Mapped[int | None] = mapped_column(Integer)
    seed_j2: Mapped[int | None] = mapped_column(Integer)
    label_a: Mapped[str | None] = mapped_column(String(32))
    label_b: Mapped[str | None] = mapped_column(String(32))


class BifurcationPoint(_LocatedBifurcation, _Seeded, Base):
    """A bifurcation located by continuation (gearsim.analysis.continuation; docs/orbits.md)."""

    __tablename__ = "bifurcation_points"
    id: Mapped[int] = mapped_column(primary_key=True)
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id"))
    plane: Mapped[str] = mapped_column(String(64), index=True)
    curve: Mapped[int | None] = mapped_column(Integer)  # the curve it seeded (-1: none)


class BifurcationCurve(_LocatedBifurcation, _Seeded, Base):
    """A point of a two-parameter bifurcation curve (gearsim.analysis.bifcurves; docs/orbits.md)."""

    __tablename__ = "bifurcation_curves"
    id: Mapped[int] = mapped_column(primary_key=True)
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id"))
    plane: Mapped[str] = mapped_column(String(64), index=True)
    curve: Mapped[int] = mapped_column(Integer)
    flank: Mapped[str | None] = mapped_column(String(16))
    seq: Mapped[int | None] = mapped_column(Integer)
    end_first: Mapped[str | None] = mapped_column(String(16))
    end_last: Mapped[str | None] = mapped_column(String(16))
    end_first_detail: Mapped[str | None] = mapped_column(Text)
    end_last_detail: Mapped[str | None] = mapped_column(Text)
    codim2_first: Mapped[int | None] = mapped_column(Integer)
    codim2_last: Mapped[int | None] = mapped_column(Integer)


class Codim2Point(Base):
    """A codimension-2 point of a plane: where two curves meet or a curve ends inside the
    plane, located by Newton on its two defining conditions (docs/orbits.md)."""

    __tablename__ = "codim2_points"
    id: Mapped[int] = mapped_column(primary_key=True)
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id"))
    plane: Mapped[str] = mapped_column(String(64), index=True)
    point: Mapped[int] = mapped_column(Integer)
    kind: Mapped[str] = mapped_column(String(32))
    conditions: Mapped[str] = mapped_column(Text)
    period: Mapped[int] = mapped_column(Integer)
    boundary: Mapped[str] = mapped_column(String(32))
    name: Mapped[str] = mapped_column(String(32))
    value: Mapped[float] = mapped_column(Float)
    name2: Mapped[str] = mapped_column(String(32))
    value2: Mapped[float] = mapped_column(Float)
    curves: Mapped[list] = mapped_column(JSON)
    curve_kinds: Mapped[list] = mapped_column(JSON)
    residual_1: Mapped[float | None] = mapped_column(Float)
    residual_2: Mapped[float | None] = mapped_column(Float)
    residual: Mapped[float | None] = mapped_column(Float)
    step: Mapped[float | None] = mapped_column(Float)
    iterations: Mapped[int | None] = mapped_column(Integer)
    converged: Mapped[bool] = mapped_column(Boolean)
    gap_cells: Mapped[float | None] = mapped_column(Float)
    x: Mapped[float | None] = mapped_column(Float)
    v: Mapped[float | None] = mapped_column(Float)
    mu_max: Mapped[float | None] = mapped_column(Float)
    multipliers: Mapped[list | None] = mapped_column(JSON)


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


@contextmanager
def replacing(path: Path, verb: str, *, bulk: bool = False) -> Iterator[tuple[Path, Any]]:
    """A temporary SQLite file beside ``path`` and its engine, for a build or a migration: on a
    clean exit the file is synced and replaces ``path`` atomically; a full disk, a read-only or
    vanished folder or an SQLite fault is one :class:`CatalogueError` line (``cannot <verb>
    it``); the temporary file never stays and ``path`` stays as it was on any failure."""
    tmp = _tmp_name(path)
    if tmp.exists():
        tmp.unlink()
    engine = make_engine(f"sqlite:///{tmp}", bulk=bulk)
    try:
        yield tmp, engine
        engine.dispose()
        _fsync(tmp)
        os.replace(tmp, path)
    except (OSError, sqlite3.Error, SQLAlchemyDBAPIError) as exc:
        raise CatalogueError(f"catalogue {path}: cannot {verb} it ({_fault(exc)})") from None
    finally:
        engine.dispose()
        if tmp.exists():
            tmp.unlink()


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


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
        raise CatalogueError(f"{p}: cannot open the catalogue ({one_line(exc)})") from None
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
        return f"not a gearsim catalogue, or damaged ({one_line(exc)}; {REBUILD})"
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
            return f"damaged ({one_line(exc)}; {REBUILD})"
        if [r[0] for r in rows] != ["ok"]:
            return f"damaged (SQLite quick_check: {one_line(rows[0][0])}; {REBUILD})"
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


# ---------------------------------------------------------------------------- migrations
def _migrate_2_to_3(op, con) -> None:
    """Version 3: the attractor and orbit tables, ``cells.n_attractors``, ``runs.status``."""
    import sqlalchemy as sa

    have = set(sa.inspect(con).get_table_names())
    for name in ("attractors", "bifurcation_points", "bifurcation_curves", "cell_orbits"):
        if name not in have:  # this version's table (step 4 then finds its columns there)
            Base.metadata.tables[name].create(con)  # with its indexes
    cols = {c["name"] for c in sa.inspect(con).get_columns("cells")}
    if "n_attractors" not in cols:
        op.add_column("cells", sa.Column("n_attractors", sa.Integer(), nullable=True))
    cols = {c["name"] for c in sa.inspect(con).get_columns("runs")}
    if "status" not in cols:
        op.add_column("runs", sa.Column("status", sa.String(16), nullable=True))
    con.exec_driver_sql("UPDATE runs SET status = 'ok' WHERE status IS NULL")


#: the columns version 4 adds to older tables (the plane atlas's), by table
_ATLAS_COLUMNS = {
    "bifurcation_points": ("curve", "source", "seed_i", "seed_j", "seed_i2", "seed_j2",
                           "label_a", "label_b"),
    "bifurcation_curves": ("flank", "seq", "source", "seed_i", "seed_j", "seed_i2", "seed_j2",
                           "label_a", "label_b", "end_first", "end_last", "end_first_detail",
                           "end_last_detail", "codim2_first", "codim2_last"),
}


def _migrate_3_to_4(op, con) -> None:
    """Version 4: ``codim2_points`` and the plane atlas's columns of the curve tables (NULL in
    the rows already there)."""
    import sqlalchemy as sa

    if "codim2_points" not in set(sa.inspect(con).get_table_names()):
        Base.metadata.tables["codim2_points"].create(con)
    for table, names in _ATLAS_COLUMNS.items():
        have = {c["name"] for c in sa.inspect(con).get_columns(table)}
        for name in names:
            if name not in have:
                col = Base.metadata.tables[table].c[name]
                op.add_column(table, sa.Column(name, col.type, nullable=True))


#: ``{version: step}``: the step takes a catalogue of ``version`` to ``version + 1``
#: (Alembic operations on one connection, inside one transaction).
MIGRATIONS = {2: _migrate_2_to_3, 3: _migrate_3_to_4}


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
        raise CatalogueError(f"{p}: cannot open the catalogue ({one_line(exc)})") from None
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
    with replacing(p, "migrate") as (tmp, engine):
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
            # the views of the planes and sweeps, as a build makes them (axes in physical units
            # are known only to the Parquet files: a rebuild adds those columns)
            create_views(conn)
            conn.exec_driver_sql(f"PRAGMA user_version = {SCHEMA_VERSION}")
        engine.dispose()
        open_catalogue(tmp).close()
    return old, SCHEMA_VERSION


