"""Reading a study back from a PostgreSQL server.

:func:`reading` is one consistent read of a study: a read-only ``REPEATABLE READ`` transaction
taken under the study's shared read lock, so a publish's swap
(:mod:`gearsim.results.server_publish`) waits for it and it never sees half of two studies.
:func:`pull_study` copies the study, in one such read, into a SQLite catalogue file identical to
the one that was published (the tables, indexes and views from the SQLite definitions they
carry as comments, the rows in their order). The report, the explorer and the export read that
file through :func:`readable_catalogue`, so what they write from the server is what they write from
the file.
"""

from __future__ import annotations

import sqlite3
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from gearsim.errors import CatalogueError
from gearsim.results.schema import APPLICATION_ID, SCHEMA_VERSION, open_catalogue
from gearsim.results.server import (
    LOCK_READ,
    check_study_name,
    connect,
    fault_line,
    is_server_url,
    list_studies,
    psycopg_module,
    quote,
    safe_url,
    study_record,
)


def study_problem(url: str, study: str, rec: dict[str, Any] | None, studies: list[str]
                  ) -> str | None:
    """Why the study ``rec`` of ``url`` cannot be read by this gearsim, or ``None``."""
    where = safe_url(url)
    if rec is None:
        return (f"{where}: no study {study!r}; it has: {', '.join(studies) or 'none'} "
                f"(publish one: gearsim catalogue publish --from results/catalogue.sqlite "
                f"--to URL --study NAME)")
    have = int(rec["schema_version"])
    if have < SCHEMA_VERSION:
        return (f"{where}: study {study} has catalogue schema version {have}, this gearsim "
                f"reads version {SCHEMA_VERSION} (migrate it: gearsim catalogue migrate "
                f"{where} --study {study}, or publish it again)")
    if have > SCHEMA_VERSION:
        return (f"{where}: study {study} has catalogue schema version {have}, written by a "
                f"newer gearsim; this one reads version {SCHEMA_VERSION} (update gearsim)")
    return None


@contextmanager
def reading(url: str, study: str, *, any_version: bool = False) -> Iterator[tuple[Any, dict]]:
    """``(connection, studies row)`` inside one consistent, read-only read of ``study`` (its
    schema first on the search path). A study this gearsim cannot read is one line."""
    psycopg = psycopg_module()
    study = check_study_name(study)
    con = connect(url, autocommit=True)
    try:
        con.execute("SELECT pg_advisory_lock_shared(%s, hashtext(%s))", (LOCK_READ, study))
        con.isolation_level = psycopg.IsolationLevel.REPEATABLE_READ
        con.read_only = True
        with con.transaction():
            rec = study_record(con, study)
            problem = study_problem(url, study, rec, list_studies(con))
            if problem and not (any_version and rec is not None):
                raise CatalogueError(problem)
            con.execute(f"SET LOCAL search_path TO {quote(study)}, public")
            con.execute("SET LOCAL DateStyle TO ISO")
            yield con, rec
    except psycopg.Error as exc:
        raise CatalogueError(fault_line(exc, url, f"reading study {study}")) from None
    finally:
        con.close()


def _loaders(con) -> None:
    """JSON as the text that was published; a timestamp as SQLite's catalogue stores it."""
    psycopg = psycopg_module()
    from psycopg.types.string import TextLoader

    class SqliteTimestamp(psycopg.adapt.Loader):
        def load(self, data):
            head, _, frac = bytes(data).decode().partition(".")
            return f"{head}.{frac.ljust(6, '0')}"

    con.adapters.register_loader("json", TextLoader)
    con.adapters.register_loader("timestamp", SqliteTimestamp)


def pull_study(url: str, study: str, dest: str | Path, *, any_version: bool = False
               ) -> tuple[Path, dict[str, Any]]:
    """Copy ``study`` into the SQLite file ``dest`` (replaced), in one consistent read. Returns
    ``(dest, studies row)``. ``any_version``: a study of an older schema version too (for a
    migration)."""
    dest = Path(dest)
    if dest.exists():
        dest.unlink()
    out = sqlite3.connect(dest)
    try:
        out.execute("PRAGMA journal_mode=OFF")
        out.execute("PRAGMA synchronous=OFF")
        with reading(url, study, any_version=any_version) as (con, rec):
            _loaders(con)
            defs = con.execute(
                "SELECT c.relkind, c.relname, obj_description(c.oid, 'pg_class') "
                "FROM pg_class c JOIN pg_namespace n ON n.oid = c.relnamespace "
                "WHERE n.nspname = %s AND c.relkind IN ('r', 'i', 'v') ORDER BY c.oid",
                (study,)).fetchall()
            # a constraint's own index has no comment: the table's definition makes it
            sql = {k: [(n, c[len("sqlite: "):]) for kind, n, c in defs
                       if kind == k and (c or "").startswith("sqlite: ")] for k in "riv"}
            if "cells" not in dict(sql["r"]):
                raise CatalogueError(f"{safe_url(url)}: study {study} is not a gearsim "
                                     "catalogue (its tables carry no definitions)")
            for name, ddl in sql["r"]:  # the tables, their rows, then indexes and views
                out.execute(ddl)
                _pull_table(con, out, name)
            for _name, ddl in sql["i"] + sql["v"]:
                out.execute(ddl)
            version = int(rec["schema_version"])
        out.execute(f"PRAGMA application_id = {APPLICATION_ID}")
        out.execute(f"PRAGMA user_version = {version}")
        out.commit()
    except BaseException:
        out.close()
        dest.unlink(missing_ok=True)
        raise
    out.close()
    return dest, rec


def _pull_table(con, out: sqlite3.Connection, table: str) -> None:
    cols = [r[0] for r in con.execute(
        "SELECT attname FROM pg_attribute WHERE attrelid = to_regclass(%s) AND attnum > 0 "
        "AND NOT attisdropped ORDER BY attnum", (quote(table),))]
    names = ", ".join(quote(c) for c in cols)
    sql = f"INSERT INTO {quote(table)} ({names}) VALUES ({', '.join('?' * len(cols))})"
    with con.cursor(name=f"pull_{table}") as cur:  # a server-side cursor: bounded memory
        cur.itersize = 20_000
        cur.execute(f"SELECT {names} FROM {quote(table)} ORDER BY ctid")
        while batch := cur.fetchmany(20_000):
            out.executemany(sql, batch)


def readable_catalogue(catalogue: str | Path, study: str | None) -> Path:
    """The SQLite catalogue a command reads: ``catalogue`` itself when it is a file, or, when it
    is a server URL, ``study`` pulled from it into a temporary file (checked like every
    catalogue, removed when the process ends)."""
    if not is_server_url(str(catalogue)):
        if study is not None:
            raise CatalogueError(f"--study {study}: a study is read from a database URL "
                                 f"(--catalogue postgresql://...), not from {catalogue}")
        return Path(catalogue)
    if study is None:
        raise CatalogueError(f"--catalogue {safe_url(str(catalogue))}: name the study to read "
                             "(--study NAME)")
    import atexit
    import shutil

    tmp = Path(tempfile.mkdtemp(prefix="gearsim-study-"))
    atexit.register(shutil.rmtree, tmp, True)
    path, _ = pull_study(str(catalogue), study, tmp / f"{study}.sqlite")
    open_catalogue(path).close()
    return path


def catalogue_name(catalogue: str | Path, study: str | None) -> str:
    """How outputs name the catalogue they were read from: its path, or the server's URL
    (password hidden) and the study."""
    if is_server_url(str(catalogue)):
        return f"{safe_url(str(catalogue))} study {study}"
    return str(catalogue)


def migrate_study(url: str, study: str) -> tuple[int, int]:
    """Bring ``study`` on ``url`` up to this gearsim's schema version as a SQLite catalogue is
    (:func:`gearsim.results.schema.migrate_catalogue`): pulled into a temporary file, migrated
    there and published back atomically (refused when it was published again meanwhile).
    Returns ``(old, new)`` versions."""
    from gearsim.results.schema import migrate_catalogue
    from gearsim.results.server_publish import publish_study

    with tempfile.TemporaryDirectory(prefix="gearsim-migrate-") as tmp:
        path, rec = pull_study(url, study, Path(tmp) / f"{study}.sqlite", any_version=True)
        old, new = migrate_catalogue(path)
        if old == new:
            return old, new
        publish_study(path, url, study, expect_published=rec["published"])
    return old, new
