"""Publishing a built SQLite catalogue to a PostgreSQL server as one study, atomically.

:func:`publish_study` copies every table of the catalogue (the driver's bulk ``COPY``) into a
new schema ``_gearsim_new_<study>``, builds its indexes, foreign keys and views there, and then,
in the same transaction, renames the study's current schema away, renames the new one to
``<study>``, drops the old one and records the study in ``public.studies``. A reader sees the
old study or the new one, never a part of either; a fault anywhere (the server unreachable or
stopped, the catalogue unreadable) rolls the whole transaction back: the database is as it was.

Each table, index and view carries its SQLite definition as its comment, so a reader gets back
the very catalogue that was published (:mod:`gearsim.results.server_read`).
"""

from __future__ import annotations

import hashlib
import json
import re
import sqlite3
from pathlib import Path
from typing import Any

from gearsim.errors import CatalogueError, one_line
from gearsim.results.schema import open_catalogue
from gearsim.results.server import (
    ACROSS,
    LOCK_PUBLISH,
    LOCK_READ,
    LOCK_SWAP,
    STUDIES,
    check_study_name,
    connect,
    ensure_layout,
    fault_line,
    psycopg_module,
    quote,
    safe_url,
    schema_exists,
    study_record,
)

#: The schemas a publish builds in and sets aside (a study's name starts with a letter).
NEW, OLD = "_gearsim_new_{}", "_gearsim_old_{}"


def _source(path: Path) -> tuple[Any, list[tuple[str, str, str, str | None]], int]:
    """The catalogue's reflected tables (SQLAlchemy), its ``sqlite_master`` rows ``(type, name,
    tbl_name, sql)`` and its schema version."""
    import sqlalchemy as sa

    con = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)
    try:
        master = con.execute("SELECT type, name, tbl_name, sql FROM sqlite_master "
                             "WHERE name NOT LIKE 'sqlite_%' ORDER BY rowid").fetchall()
        version = con.execute("PRAGMA user_version").fetchone()[0]
    finally:
        con.close()
    uri = f"{path.resolve().as_uri()}?mode=ro"
    engine = sa.create_engine("sqlite://", creator=lambda: sqlite3.connect(uri, uri=True),
                              poolclass=sa.pool.NullPool)
    md = sa.MetaData()
    try:
        md.reflect(engine, views=False)
    finally:
        engine.dispose()
    return md, master, version


def _ddl(md, schema: str) -> tuple[list[str], list[str], list[Any]]:
    """PostgreSQL DDL of the reflected tables in ``schema``: the tables (primary keys and
    unique constraints inline), then their indexes and foreign keys (built after the copy)."""
    import sqlalchemy as sa
    from sqlalchemy.dialects import postgresql
    from sqlalchemy.schema import AddConstraint, CreateIndex, CreateTable

    dialect = postgresql.dialect()
    out = sa.MetaData(schema=schema)
    tables, after = [], []
    for t in md.sorted_tables:
        t2 = t.to_metadata(out, schema=schema)
        for c in t2.columns:
            c.autoincrement = False  # ids come from the catalogue
            c.server_default = None
            c.type = c.type.as_generic()  # SQLite's DATETIME: TIMESTAMP, FLOAT: double ...
            if isinstance(c.type, sa.String):  # SQLite keeps longer text than VARCHAR(n) says
                c.type = sa.Text()
        tables.append(str(CreateTable(t2, include_foreign_key_constraints=[]).compile(
            dialect=dialect)))
        after += [str(CreateIndex(ix).compile(dialect=dialect)) for ix in
                  sorted(t2.indexes, key=lambda ix: ix.name or "")]
        after += [str(AddConstraint(fk).compile(dialect=dialect)) for fk in
                  sorted(t2.foreign_key_constraints, key=lambda fk: fk.name or "")]
    return tables, after, list(md.sorted_tables)


def _copy_table(cur, src: sqlite3.Connection, schema: str, table) -> int:
    """Every row of ``table`` (rowid order) into ``schema`` through ``COPY ... FROM STDIN``."""
    cols = [c.name for c in table.columns]
    names = ", ".join(quote(c) for c in cols)
    n = 0
    rows = src.execute(f"SELECT {names} FROM {quote(table.name)} ORDER BY rowid")
    from psycopg.copy import QueuedLibpqWriter

    # the queued writer sends from a thread of its own while this one formats the next rows
    with cur.copy(f"COPY {quote(schema)}.{quote(table.name)} ({names}) FROM STDIN",
                  writer=QueuedLibpqWriter(cur)) as cp:
        while batch := rows.fetchmany(20_000):
            for row in batch:
                cp.write_row(row)
            n += len(batch)
    return n


def _settings(src: sqlite3.Connection) -> tuple[str, str, str | None, str | None, int]:
    """``(settings_hash, code_version, git_commit, built, cells)`` of a catalogue: the hash of
    its planes' and sweeps' configuration hashes, its runs' code versions."""
    hashes = sorted({h for (h,) in src.execute(
        "SELECT config_hash FROM planes UNION SELECT config_hash FROM sweeps") if h})
    info = {k: json.loads(v) for k, v in src.execute("SELECT key, value FROM catalogue_info")}
    settings = hashlib.sha256(json.dumps(hashes).encode()).hexdigest()[:16]
    codes = ",".join(info.get("code_versions") or [])
    cells = src.execute("SELECT count(*) FROM cells").fetchone()[0]
    return settings, codes, info.get("git_commit"), info.get("built"), int(cells)


def _across(cur) -> None:
    """``public.study_plane_cells``: the ``plane_cells`` of every study, each row with its
    study's name (the columns every study has: a study of another schema version may lack
    some)."""
    cur.execute(f"DROP VIEW IF EXISTS public.{ACROSS}")
    names = [r[0] for r in cur.execute(
        f"SELECT s.name FROM public.{STUDIES} s JOIN pg_namespace n ON n.nspname = s.name "
        "ORDER BY s.name")]
    if not names:
        return
    cols: dict[str, list[str]] = {n: [] for n in names}
    for schema, col in cur.execute(
            "SELECT table_schema, column_name FROM information_schema.columns WHERE "
            "table_name = 'plane_cells' AND table_schema = ANY(%s) ORDER BY ordinal_position",
            (names,)).fetchall():
        cols[schema].append(col)
    # the columns every study has, in the order of the first (a migrated catalogue adds its new
    # columns last; a study of an older gearsim may lack some)
    common = [c for c in cols[names[0]] if all(c in cols[n] for n in names)]
    select = ", ".join(f"v.{quote(c)}" for c in common)
    parts = [f"SELECT {_lit(n)}::text AS study, {select} FROM {quote(n)}.plane_cells v"
             for n in names]
    cur.execute(f"CREATE VIEW public.{ACROSS} AS " + " UNION ALL ".join(parts))


def _lit(s: str) -> str:
    return "'" + s.replace("'", "''") + "'"


def publish_study(source: str | Path, url: str, study: str, *, check: bool = True,
                  expect_published: Any = None) -> dict[str, int]:
    """Publish the catalogue ``source`` to the server ``url`` as ``study`` (see module doc).
    ``check``: refuse a catalogue readers would refuse (:func:`open_catalogue`).
    ``expect_published``: refuse unless the study's ``published`` stamp is still this (a
    migration's read-modify-write). Returns the row count of each table."""
    psycopg = psycopg_module()
    study = check_study_name(study)
    source = Path(source)
    if check:
        open_catalogue(source).close()
    elif not source.is_file():
        raise CatalogueError(f"catalogue not found: {source}")
    md, master, version = _source(source)
    new, old = NEW.format(study), OLD.format(study)
    tables, after, order = _ddl(md, new)
    src = sqlite3.connect(f"{source.resolve().as_uri()}?mode=ro", uri=True)
    con = connect(url, writing=True)
    counts: dict[str, int] = {}
    try:
        ensure_layout(con)
        settings = _settings(src)
        with con.transaction(), con.cursor() as cur:
            cur.execute("SELECT pg_advisory_xact_lock(%s, hashtext(%s))", (LOCK_PUBLISH, study))
            _check_target(cur, study, expect_published)
            cur.execute(f"DROP SCHEMA IF EXISTS {quote(new)} CASCADE")
            cur.execute(f"CREATE SCHEMA {quote(new)}")
            for ddl in tables:
                cur.execute(ddl)
            for t in order:
                counts[t.name] = _copy_table(cur, src, new, t)
            for ddl in after:
                cur.execute(ddl)
            cur.execute(f"SET LOCAL search_path TO {quote(new)}")
            _definitions(cur, new, master)
            cur.execute("SET LOCAL search_path TO public")
            # the swap: one at a time, and never while a reader holds the study
            cur.execute("SELECT pg_advisory_xact_lock(%s, 0)", (LOCK_SWAP,))
            cur.execute("SELECT pg_advisory_xact_lock(%s, hashtext(%s))", (LOCK_READ, study))
            _take_old_study(cur, study, url)
            if schema_exists(cur, study):
                cur.execute(f"ALTER SCHEMA {quote(study)} RENAME TO {quote(old)}")
            cur.execute(f"ALTER SCHEMA {quote(new)} RENAME TO {quote(study)}")
            cur.execute(f"DROP SCHEMA IF EXISTS {quote(old)} CASCADE")
            cur.execute(
                f"INSERT INTO public.{STUDIES} (name, schema_version, settings_hash, "
                "code_version, git_commit, published, built, source, cells) "
                "VALUES (%s, %s, %s, %s, %s, clock_timestamp(), %s, %s, %s) "
                "ON CONFLICT (name) DO UPDATE SET schema_version = EXCLUDED.schema_version, "
                "settings_hash = EXCLUDED.settings_hash, code_version = EXCLUDED.code_version, "
                "git_commit = EXCLUDED.git_commit, published = EXCLUDED.published, "
                "built = EXCLUDED.built, source = EXCLUDED.source, cells = EXCLUDED.cells",
                (study, version, *settings[:3], settings[3], str(source.resolve()), settings[4]))
            _across(cur)
    except psycopg.Error as exc:
        raise CatalogueError(
            fault_line(exc, url, f"publishing study {study}")
            + f"; study {study} is as it was") from None
    except (sqlite3.Error, OSError) as exc:
        raise CatalogueError(f"catalogue {source}: cannot read it ({one_line(exc)}); study "
                             f"{study} on {safe_url(url)} is as it was") from None
    finally:
        src.close()
        con.close()
    return counts


#: How long a swap waits for the study's statements to let go (then: one line, as it was).
SWAP_PATIENCE_S = 600.0


def _take_old_study(cur, study: str, url: str) -> None:
    """Hold every relation of the study's current schema and the cross-study view exclusively,
    all or none: a reader's statement that has begun on them ends first, one that begins later
    waits and then reads the new study (it never holds an old table and a new one). Never
    waiting while holding part of them, the swap cannot deadlock with a reader; it tries again
    every 50-100 ms while statements hold them."""
    import random
    import time

    psycopg = psycopg_module()
    con = cur.connection
    rels = [f"{quote(study)}.{quote(n)}" for (n,) in cur.execute(
        "SELECT c.relname FROM pg_class c JOIN pg_namespace n ON n.oid = c.relnamespace "
        "WHERE n.nspname = %s AND c.relkind IN ('r', 'v') ORDER BY c.relname",
        (study,)).fetchall()]
    t0 = time.monotonic()
    while True:
        try:
            with con.transaction():  # a savepoint: a failed try lets go of what it took
                cur.execute("SET LOCAL lock_timeout = '100ms'")
                # the view alone (LOCK TABLE on a view would lock every study's tables)
                cur.execute(f"DROP VIEW IF EXISTS public.{ACROSS}")
                if rels:
                    cur.execute(f"LOCK TABLE {', '.join(rels)} IN ACCESS EXCLUSIVE MODE NOWAIT")
                cur.execute("SET LOCAL lock_timeout = 0")
            return
        except psycopg.errors.LockNotAvailable:
            if time.monotonic() - t0 > SWAP_PATIENCE_S:
                raise CatalogueError(
                    f"{safe_url(url)}: readers kept study {study} busy for "
                    f"{SWAP_PATIENCE_S:.0f} s; study {study} is as it was (publish again)"
                ) from None
            time.sleep(0.05 + 0.05 * random.random())


def _check_target(cur, study: str, expect_published: Any) -> None:
    """Refuse to replace a schema that is not a gearsim study, or a study published again since
    it was read (``expect_published``)."""
    rec = study_record(cur, study)
    if rec is None and schema_exists(cur, study):
        raise CatalogueError(
            f"schema {study} exists and is not a gearsim study (not in public.{STUDIES}); "
            "nothing was changed: choose another --study")
    if expect_published is not None and (rec or {}).get("published") != expect_published:
        raise CatalogueError(f"study {study} was published again meanwhile; nothing was "
                             "changed: run the migration again")


def _definitions(cur, schema: str, master) -> None:
    """The views (SQLite's SQL runs as it is, ``IF NOT EXISTS`` aside), and the SQLite
    definition of every table, index and view as its comment."""
    for kind, _name, _tbl, sql in master:
        if kind == "view":
            cur.execute(re.sub(r"^\s*CREATE\s+VIEW\s+IF\s+NOT\s+EXISTS\s", "CREATE VIEW ", sql,
                               flags=re.I))
    for kind, name, _tbl, sql in master:
        if sql is None or kind not in ("table", "index", "view"):
            continue
        what = {"table": "TABLE", "index": "INDEX", "view": "VIEW"}[kind]
        cur.execute(f"COMMENT ON {what} {quote(schema)}.{quote(name)} IS {_lit('sqlite: ' + sql)}")
