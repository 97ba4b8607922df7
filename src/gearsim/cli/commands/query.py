"""``gearsim query "SELECT ..."``: read-only SQL on the catalogue, printed as a table, CSV or JSON.

Guards (docs/pipeline.md, "Querying the catalogue" and "Guarantees"):

* the catalogue is opened through :func:`gearsim.results.catalogue.open_catalogue` (``mode=ro``, our
  schema version), so a file that is not a catalogue is refused with one line;
* an authorizer allows reading only: ``SELECT`` / ``WITH`` (recursive included) and the SQL
  functions of :data:`ALLOWED_FUNCTIONS`; any write, ``PRAGMA``, ``ATTACH`` or other function
  (``load_extension``, ``fts3_tokenizer``, ``randomblob``, ...) is refused;
* ``--timeout`` seconds of work at most (SQLite progress handler), and a value of at most
  100 MB (``SQLITE_LIMIT_LENGTH``);
* ``--max-rows`` bounds the fetch itself (an endless recursive CTE stops there) and a cut is
  announced on stderr. The table format shows 1000 rows unless told otherwise; CSV and JSON
  stream every row unless ``--max-rows`` is given. ``--max-rows -1`` means all rows.
"""

from __future__ import annotations

import argparse
import base64
import csv
import json
import math
import os
import sqlite3
import sys
import time
from collections.abc import Iterator
from pathlib import Path

from gearsim.errors import UsageError

NAME = "query"
HELP = "run a read-only SELECT on results/catalogue.sqlite and print the result"

#: README-ready examples (docs/pipeline.md shows the same text; they run in plain sqlite3).
EXAMPLES = {
    "patterns": """\
SELECT p.name AS plane, c.label, COUNT(*) AS cells
FROM cells c JOIN planes p ON p.id = c.plane_id
GROUP BY p.name, c.label
ORDER BY p.name, cells DESC, c.label;""",
    "b-threshold": """\
SELECT MAX(c.y) AS last_b_with_I2,
       MAX(c.y) + (MAX(p.y_max) - MAX(p.y_min)) / (2.0 * MAX(p.y_n)) AS b_threshold
FROM cells c JOIN planes p ON p.id = c.plane_id
WHERE p.name = 'wb' AND p.y_name = 'b' AND c.impact = 2;""",
    "chaos": """\
SELECT p.name AS plane, c.i, c.j, c.x, c.y, c.label, c.lyapunov
FROM cells c JOIN planes p ON p.id = c.plane_id
WHERE c.lyapunov > 0
ORDER BY c.lyapunov DESC
LIMIT 20;""",
    "plane-view": """\
SELECT w, b, label, dc, kmax
FROM wb
WHERE b > 0.9
ORDER BY w, b
LIMIT 10;""",
    "sweep-view": """\
SELECT w, label, label_npq, dc, kmax
FROM standard
ORDER BY k;""",
}

#: SQL functions a query may call (core scalar, aggregate, window, math, date and JSON
#: functions). Anything else is refused, e.g. ``load_extension``, ``fts3_tokenizer`` (returns a
#: raw pointer), ``randomblob`` / ``zeroblob`` (allocate at will).
ALLOWED_FUNCTIONS = frozenset(
    """
    abs avg count max min sum total group_concat string_agg
    round length octet_length lower upper substr substring instr replace trim ltrim rtrim
    coalesce ifnull nullif iif if typeof printf format like glob char unicode hex unhex quote
    concat concat_ws sign random likelihood likely unlikely
    exp ln log log10 log2 pow power sqrt floor ceil ceiling trunc mod pi
    sin cos tan asin acos atan atan2 sinh cosh tanh asinh acosh atanh degrees radians
    date time datetime julianday unixepoch strftime timediff current_date current_time
    current_timestamp
    row_number rank dense_rank percent_rank cume_dist ntile lag lead first_value last_value
    nth_value
    json json_extract json_array_length json_type json_valid json_quote json_array
    json_object json_group_array json_group_object json_each json_tree
    sqlite_version
    """.split()
)

_ALLOWED_ACTIONS = {
    sqlite3.SQLITE_SELECT,
    sqlite3.SQLITE_READ,
    getattr(sqlite3, "SQLITE_RECURSIVE", 33),
}
MAX_TIMEOUT = 24 * 3600.0
MAX_VALUE_BYTES = 100_000_000
#: rows the table format shows when --max-rows is not given
TABLE_ROWS = 1000


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("sql", nargs="?", help="one SELECT (or WITH ... SELECT) statement")
    p.add_argument("--example", choices=sorted(EXAMPLES), help="run a documented example")
    p.add_argument(
        "--catalogue",
        "--db",
        dest="db",
        default="results/catalogue.sqlite",
        help="catalogue file (default results/catalogue.sqlite)",
    )
    p.add_argument(
        "--format",
        choices=("table", "csv", "json"),
        default="table",
        help="output format (BLOB values as base64 text in CSV and JSON)",
    )
    p.add_argument(
        "--max-rows",
        type=int,
        default=None,
        help=f"fetch at most this many rows, -1 = all (default: {TABLE_ROWS} for the table, "
        "all for csv/json); a cut is reported on stderr",
    )
    p.add_argument(
        "--timeout",
        type=float,
        default=60.0,
        help=f"stop the query after this many seconds (0 < s <= {MAX_TIMEOUT:.0f}; default 60)",
    )


def _authorizer(action, arg1, arg2, _db, _trigger):
    if action in _ALLOWED_ACTIONS:
        return sqlite3.SQLITE_OK
    if action == sqlite3.SQLITE_FUNCTION and str(arg2).lower() in ALLOWED_FUNCTIONS:
        return sqlite3.SQLITE_OK
    return sqlite3.SQLITE_DENY


def connect_readonly(db: str | Path, timeout: float = 60.0) -> sqlite3.Connection:
    """A checked, read-only connection with the authorizer, time and size limits installed."""
    from gearsim.results.catalogue import open_catalogue

    con = open_catalogue(db)
    con.setlimit(sqlite3.SQLITE_LIMIT_LENGTH, MAX_VALUE_BYTES)
    con.set_authorizer(_authorizer)
    deadline = time.monotonic() + timeout
    con.set_progress_handler(lambda: int(time.monotonic() > deadline), 10_000)
    return con


def _strip_comments(text: str) -> str:
    """``text`` without leading whitespace and SQL comments (``-- ...`` and ``/* ... */``)."""
    k = 0
    while k < len(text):
        if text[k].isspace():
            k += 1
        elif text.startswith("--", k):
            nl = text.find("\n", k)
            k = len(text) if nl < 0 else nl + 1
        elif text.startswith("/*", k):
            end = text.find("*/", k + 2)
            k = len(text) if end < 0 else end + 2
        else:
            break
    return text[k:]


def check_select(sql: str) -> str:
    text = sql.strip().rstrip(";").strip()
    body = _strip_comments(text)
    first = body.split(None, 1)[0].upper() if body else ""
    first = first.split("(", 1)[0]
    if first not in ("SELECT", "WITH", "VALUES"):
        raise UsageError("only SELECT statements are allowed (read-only catalogue)")
    if not sqlite3.complete_statement(text + "\n;"):
        raise UsageError("incomplete SQL statement")
    return text


def _sql_error(exc: sqlite3.Error, timeout: float) -> UsageError:
    msg = " ".join(str(exc).split())
    if "not authorized" in msg:
        msg = (
            "only reading is allowed (read-only catalogue; functions: see "
            "gearsim.cli.commands.query.ALLOWED_FUNCTIONS)"
        )
    elif "one statement at a time" in msg:
        msg = "exactly one SELECT statement is allowed"
    elif "interrupted" in msg:
        msg = f"query stopped after {timeout:g} s (--timeout); narrow it or raise --timeout"
    elif "too big" in msg:
        msg = f"a value exceeds {MAX_VALUE_BYTES} bytes"
    return UsageError(f"SQL error: {msg}")


class Result:
    """Columns and a bounded row stream of one query (``cut`` is set once a row was left out)."""

    def __init__(
        self, con: sqlite3.Connection, cur: sqlite3.Cursor, limit: int | None, timeout: float
    ):
        self.con, self.cur, self.limit, self.timeout = con, cur, limit, timeout
        self.columns = [d[0] for d in cur.description or []]
        self.cut = False
        self.count = 0

    def __iter__(self) -> Iterator[tuple]:
        try:
            while True:
                want = 1000 if self.limit is None else min(1000, self.limit - self.count)
                if want <= 0:
                    # one more row decides whether the limit cut anything
                    self.cut = self.cur.fetchone() is not None
                    return
                batch = self.cur.fetchmany(want)
                if not batch:
                    return
                self.count += len(batch)
                yield from batch
        except sqlite3.Error as exc:
            raise _sql_error(exc, self.timeout) from None

    def close(self) -> None:
        self.con.close()


def open_query(
    db: str | Path, sql: str, *, limit: int | None = None, timeout: float = 60.0
) -> Result:
    """Start one read-only SELECT; rows are fetched lazily, at most ``limit`` (None = all)."""
    text = check_select(sql)
    con = connect_readonly(db, timeout)
    try:
        cur = con.execute(text)
    except sqlite3.Error as exc:
        con.close()
        raise _sql_error(exc, timeout) from None
    return Result(con, cur, limit, timeout)


def execute(
    db: str | Path, sql: str, *, limit: int | None = None, timeout: float = 60.0
) -> tuple[list[str], list[tuple]]:
    """Run one read-only SELECT; returns column names and (at most ``limit``) rows."""
    res = open_query(db, sql, limit=limit, timeout=timeout)
    try:
        return res.columns, list(res)
    finally:
        res.close()


def _fmt(v) -> str:
    if v is None:
        return "NULL"
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, bytes):
        return f"<{len(v)} bytes>"
    return str(v)


def format_table(cols: list[str], rows: list[tuple]) -> str:
    cells = [[_fmt(v) for v in r] for r in rows]
    widths = [max([len(c)] + [len(r[k]) for r in cells]) for k, c in enumerate(cols)]
    line = "  ".join(c.ljust(w) for c, w in zip(cols, widths, strict=True))
    out = [line, "  ".join("-" * w for w in widths)]
    for r in cells:
        out.append(
            "  ".join(
                v.rjust(w) if _numeric(v) else v.ljust(w) for v, w in zip(r, widths, strict=True)
            )
        )
    return "\n".join(out)


def _numeric(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def _plain(v):
    """A value JSON and CSV can carry: BLOB -> base64 text, NaN/inf -> null."""
    if isinstance(v, bytes):
        return base64.b64encode(v).decode("ascii")
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def _limit(args: argparse.Namespace) -> int | None:
    m = args.max_rows
    if m is None:
        return TABLE_ROWS if args.format == "table" else None
    if m == -1:
        return None
    if m < 0:
        raise UsageError(f"--max-rows: {m} is not allowed (-1 = all rows, or 0 and above)")
    return m


def _write(args, res: Result, out) -> None:
    if args.format == "csv":
        w = csv.writer(out)
        w.writerow(res.columns)
        for r in res:
            w.writerow([_plain(v) for v in r])
    elif args.format == "json":
        out.write("[")
        sep = "\n"
        for r in res:
            rec = {c: _plain(v) for c, v in zip(res.columns, r, strict=True)}
            out.write(sep + json.dumps(rec, allow_nan=False))
            sep = ",\n"
        out.write("\n]\n")
    else:
        rows = list(res)
        out.write(format_table(res.columns, rows) + "\n")
        out.write(f"({len(rows)} rows{', more not shown' if res.cut else ''})\n")


def run(args: argparse.Namespace) -> int:
    if (args.sql is None) == (args.example is None):
        raise UsageError("give one SQL statement or --example NAME")
    if not (0 < args.timeout <= MAX_TIMEOUT):
        raise UsageError(f"--timeout: {args.timeout!r} is outside 0 < s <= {MAX_TIMEOUT:.0f}")
    limit = _limit(args)
    sql = EXAMPLES[args.example] if args.example else args.sql
    res = open_query(args.db, sql, limit=limit, timeout=args.timeout)
    try:
        if args.example:
            sys.stdout.write(sql + "\n\n")
        _write(args, res, sys.stdout)
        sys.stdout.flush()
    except BrokenPipeError:
        # the reader went away (`gearsim query ... | head`): stop quietly, as a filter does
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    finally:
        res.close()
    if res.cut:
        sys.stderr.write(
            f"gearsim query: output cut at {res.count} rows (--max-rows); more rows exist, "
            "use --max-rows -1 for all\n"
        )
    return 0
