"""Read-only SQL on a catalogue: the engine behind ``gearsim query`` and every reader of the
catalogue through SQL.

Guards (docs/pipeline.md, "Querying the catalogue" and "Guarantees"):

* the catalogue is opened through :func:`gearsim.results.catalogue.open_catalogue` (``mode=ro``, our
  schema version), so a file that is not a catalogue is refused with one line;
* an authorizer allows reading only: ``SELECT`` / ``WITH`` (recursive included) and the SQL
  functions of :data:`ALLOWED_FUNCTIONS`; any write, ``PRAGMA``, ``ATTACH`` or other function
  (``load_extension``, ``fts3_tokenizer``, ``randomblob``, ...) is refused;
* ``timeout`` seconds of work at most (SQLite progress handler), and a value of at most
  100 MB (``SQLITE_LIMIT_LENGTH``);
* ``limit`` bounds the fetch itself (an endless recursive CTE stops there); :attr:`Result.cut`
  says whether a row was left out.
"""

from __future__ import annotations

import base64
import csv
import json
import math
import sqlite3
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TextIO

from gearsim.errors import UsageError

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
            "gearsim.results.query.ALLOWED_FUNCTIONS)"
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


def row_limit(max_rows: int | None, fmt: str) -> int | None:
    """The fetch bound of ``--max-rows`` for output format ``fmt``: None = all rows."""
    if max_rows is None:
        return TABLE_ROWS if fmt == "table" else None
    if max_rows == -1:
        return None
    if max_rows < 0:
        raise UsageError(f"--max-rows: {max_rows} is not allowed (-1 = all rows, or 0 and above)")
    return max_rows


def check_timeout(timeout: float) -> float:
    if not (0 < timeout <= MAX_TIMEOUT):
        raise UsageError(f"--timeout: {timeout!r} is outside 0 < s <= {MAX_TIMEOUT:.0f}")
    return timeout


def write_result(res: Result, fmt: str, out: TextIO) -> None:
    """Stream ``res`` to ``out`` as ``table``, ``csv`` or ``json`` (BLOB as base64 text)."""
    if fmt == "csv":
        w = csv.writer(out)
        w.writerow(res.columns)
        for r in res:
            w.writerow([_plain(v) for v in r])
    elif fmt == "json":
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
