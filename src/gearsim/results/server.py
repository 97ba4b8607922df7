"""A lab's results database: the connection to a PostgreSQL server, its layout and its faults.

Each study's catalogue lives in a schema named after the study (``paper``, ``quick``, ...) with
the tables, views and column dictionary of the SQLite catalogue (:mod:`gearsim.results.schema`);
``public.studies`` lists the studies (name, schema version, settings hash, code version, when
published) and ``public.study_plane_cells`` puts every study's ``plane_cells`` side by side with
a ``study`` column. docs/pipeline.md describes the layout and the swap
(:mod:`gearsim.results.server_publish`); readers read through
:mod:`gearsim.results.server_read`.

Every fault is one :class:`CatalogueError` line naming the server by its URL with the password
hidden (``postgresql://user:***@host/db``); the password is never written anywhere.
"""

from __future__ import annotations

import re
from typing import Any

from gearsim.errors import CatalogueError, one_line

#: Advisory lock classes (the first key of ``pg_advisory_*lock(int, int)``; the second is
#: ``hashtext(study)``): a publish of a study holds PUBLISH for its whole transaction (two
#: publishers of one study run one after the other); the swap holds SWAP (one swap at a time,
#: the cross-study view is rebuilt by each) and READ exclusively; a reader holds READ shared
#: for its one snapshot, so it reads the whole old study or the whole new one.
LOCK_PUBLISH, LOCK_SWAP, LOCK_READ = 0x47530001, 0x47530002, 0x47530003
#: The study registry and the cross-study view, in schema ``public``.
STUDIES, ACROSS = "studies", "study_plane_cells"
#: A study's name: a PostgreSQL schema name of our own (lower case, digits, underscores).
STUDY_NAME = re.compile(r"^[a-z][a-z0-9_]{0,39}$")
_RESERVED = ("public", "information_schema", "gearsim")

STUDIES_DDL = f"""
CREATE TABLE IF NOT EXISTS public.{STUDIES} (
    name text PRIMARY KEY,
    schema_version integer NOT NULL,
    settings_hash text NOT NULL,
    code_version text NOT NULL,
    git_commit text,
    published timestamptz NOT NULL,
    built text,
    source text,
    cells bigint
)"""


def is_server_url(target: Any) -> bool:
    """Whether ``target`` names a database server (``dialect[+driver]://...``) rather than a
    file."""
    return isinstance(target, str) and re.match(r"^[a-z][a-z0-9+]*://", target) is not None


def safe_url(url: str) -> str:
    """``url`` with its password hidden (``***``), for every line, log and record."""
    from sqlalchemy.engine import make_url

    try:
        return make_url(url).render_as_string(hide_password=True)
    except Exception:  # an unparsable URL: show its scheme only
        return url.split("://", 1)[0] + "://..."


def _scrub(text: str, url: str) -> str:
    """``text`` with the password of ``url`` (and the URL itself) replaced: a driver's message
    never carries it out."""
    from sqlalchemy.engine import make_url

    try:
        password = make_url(url).password
    except Exception:
        password = None
    text = text.replace(url, safe_url(url))
    if password:
        text = text.replace(str(password), "***")
    return text


def check_study_name(study: str | None) -> str:
    """``study`` if it can name a study's schema, else one line with the rule."""
    if not study or not STUDY_NAME.match(study) or study in _RESERVED or study.startswith("pg_"):
        raise CatalogueError(
            f"--study {study!r}: a study's name is its schema's: a lower-case letter, then up to "
            "39 lower-case letters, digits or underscores (not public, gearsim or pg_...)"
        )
    return study


def conninfo(url: str) -> dict[str, Any]:
    """psycopg's connection keywords from a SQLAlchemy URL (``postgresql://``,
    ``postgresql+psycopg://``; the query string's keys, e.g. ``host=/run/postgresql``, pass
    through). Another dialect is one line."""
    from sqlalchemy.engine import make_url

    try:
        u = make_url(url)
    except Exception as exc:
        raise CatalogueError(f"--to {safe_url(url)}: not a database URL ({one_line(exc)})"
                             ) from None
    if u.get_backend_name() != "postgresql" or u.get_driver_name() not in ("psycopg", "psycopg2"):
        raise CatalogueError(
            f"{safe_url(url)}: publishing to a server supports PostgreSQL "
            "(postgresql://user@host/db, through psycopg 3)"
        )
    kw: dict[str, Any] = {k: v for k, v in u.query.items() if isinstance(v, str)}
    for key, value in (("host", u.host), ("port", u.port), ("user", u.username),
                       ("password", u.password), ("dbname", u.database)):
        if value is not None:
            kw[key] = str(value)
    kw.setdefault("application_name", "gearsim")
    kw.setdefault("connect_timeout", "10")
    return kw


def configured_target(publish: dict[str, Any], study: str | None) -> tuple[str, str]:
    """``(url, study)`` of the config's ``publish`` section: a URL without a password (the
    config is recorded and logged; the password belongs in ~/.pgpass or PGPASSWORD) and a study
    name (default: the config's ``study``, else ``paper``)."""
    from sqlalchemy.engine import make_url

    from gearsim.errors import ConfigError

    url = str(publish.get("url") or "")
    try:
        u = make_url(url)
    except Exception:
        raise ConfigError(f"config key 'publish.url': {safe_url(url)} is not a database URL "
                          "(postgresql://user@host/db)") from None
    if u.password is not None:
        raise ConfigError(f"config key 'publish.url': {safe_url(url)} carries a password; give "
                          "it in ~/.pgpass or PGPASSWORD, never in the config")
    conninfo(url)  # a dialect we publish to
    name = publish.get("study") or study or "paper"
    try:
        return url, check_study_name(name)
    except CatalogueError as exc:
        raise ConfigError(f"config key 'publish.study': {exc}".replace("--study ", "")) from None


def psycopg_module():
    try:
        import psycopg
    except ImportError:
        raise CatalogueError(
            "a database server needs psycopg 3: pip install 'gearsim[postgres]'"
        ) from None
    import logging

    # the driver's own warnings (a COPY cut off by a stopped server) are said once, in our line;
    # Python's last-resort handler would print them beside it (an application's handlers still
    # get them)
    log = logging.getLogger("psycopg")
    if not any(isinstance(h, logging.NullHandler) for h in log.handlers):
        log.addHandler(logging.NullHandler())
    return psycopg


def connect(url: str, *, autocommit: bool = False, writing: bool = False):
    """A psycopg connection to ``url``; unreachable or refused is one line (``writing``: saying
    that nothing was changed)."""
    psycopg = psycopg_module()
    try:
        return psycopg.connect(autocommit=autocommit, **conninfo(url))
    except psycopg.Error as exc:
        tail = "; nothing was changed" if writing else ""
        raise CatalogueError(
            f"{safe_url(url)}: cannot connect ({_scrub(one_line(exc), url)}){tail}") from None


def fault_line(exc: BaseException, url: str, what: str) -> str:
    """One line for a fault of the server while doing ``what``, the password scrubbed."""
    return f"{safe_url(url)}: {what} failed ({_scrub(one_line(exc), url)})"


def quote(name: str) -> str:
    return '"' + name.replace('"', '""') + '"'


def ensure_layout(con) -> None:
    """``public.studies``, created once (under the swap lock: two first publishers at once)."""
    with con.transaction():
        con.execute("SELECT pg_advisory_xact_lock(%s, 0)", (LOCK_SWAP,))
        con.execute(STUDIES_DDL)


def study_record(con, study: str) -> dict[str, Any] | None:
    """The ``studies`` row of ``study``, or ``None`` (no such study, or no ``studies`` table)."""
    has = con.execute("SELECT to_regclass(%s)", (f"public.{STUDIES}",)).fetchone()[0]
    if has is None:
        return None
    cur = con.execute(f"SELECT * FROM public.{STUDIES} WHERE name = %s", (study,))
    row = cur.fetchone()
    if row is None:
        return None
    return dict(zip([d.name for d in cur.description], row, strict=True))


def schema_exists(con, name: str) -> bool:
    return con.execute("SELECT 1 FROM pg_namespace WHERE nspname = %s", (name,)
                       ).fetchone() is not None


def list_studies(con) -> list[str]:
    has = con.execute("SELECT to_regclass(%s)", (f"public.{STUDIES}",)).fetchone()[0]
    if has is None:
        return []
    return [r[0] for r in con.execute(f"SELECT name FROM public.{STUDIES} ORDER BY name")]
