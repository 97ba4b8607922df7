"""``gearsim query "SELECT ..."``: read-only SQL on the catalogue, printed as a table.

The database is opened with the SQLite URI ``mode=ro`` and an authorizer that allows reading
only, so a query can never change the catalogue. Examples: docs/pipeline.md.
"""

from __future__ import annotations

import argparse
import csv
import json
import sqlite3
import sys
from pathlib import Path

from ..errors import UsageError

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
}

_ALLOWED = {
    sqlite3.SQLITE_SELECT,
    sqlite3.SQLITE_READ,
    sqlite3.SQLITE_FUNCTION,
    getattr(sqlite3, "SQLITE_RECURSIVE", 33),
}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("sql", nargs="?", help="one SELECT (or WITH ... SELECT) statement")
    p.add_argument("--example", choices=sorted(EXAMPLES), help="run a documented example")
    p.add_argument("--db", default="results/catalogue.sqlite", help="catalogue file")
    p.add_argument("--format", choices=("table", "csv", "json"), default="table")
    p.add_argument("--max-rows", type=int, default=1000, help="print at most this many rows")


def _authorizer(action, *_args):
    return sqlite3.SQLITE_OK if action in _ALLOWED else sqlite3.SQLITE_DENY


def connect_readonly(db: str | Path) -> sqlite3.Connection:
    path = Path(db)
    if not path.is_file():
        raise UsageError(f"catalogue not found: {db} (build it with snakemake)")
    con = sqlite3.connect(f"file:{path.resolve()}?mode=ro", uri=True)
    con.set_authorizer(_authorizer)
    return con


def check_select(sql: str) -> str:
    text = sql.strip().rstrip(";").strip()
    first = text.split(None, 1)[0].upper() if text else ""
    if first not in ("SELECT", "WITH"):
        raise UsageError("only SELECT statements are allowed (read-only catalogue)")
    if not sqlite3.complete_statement(text + ";"):
        raise UsageError("incomplete SQL statement")
    return text


def execute(db: str | Path, sql: str) -> tuple[list[str], list[tuple]]:
    """Run one read-only SELECT; returns column names and rows."""
    text = check_select(sql)
    con = connect_readonly(db)
    try:
        cur = con.execute(text)
        cols = [d[0] for d in cur.description or []]
        return cols, cur.fetchall()
    except sqlite3.DatabaseError as exc:
        msg = str(exc)
        if "not authorized" in msg:
            msg = "only reading is allowed (read-only catalogue)"
        elif "one statement at a time" in msg:
            msg = "exactly one SELECT statement is allowed"
        raise UsageError(f"SQL error: {msg}") from None
    finally:
        con.close()


def _fmt(v) -> str:
    if v is None:
        return "NULL"
    if isinstance(v, float):
        return f"{v:.6g}"
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


def run(args: argparse.Namespace) -> int:
    if (args.sql is None) == (args.example is None):
        raise UsageError("give one SQL statement or --example NAME")
    sql = EXAMPLES[args.example] if args.example else args.sql
    if args.example:
        print(sql + "\n")
    cols, rows = execute(args.db, sql)
    shown = rows[: args.max_rows]
    if args.format == "csv":
        w = csv.writer(sys.stdout)
        w.writerow(cols)
        w.writerows(shown)
    elif args.format == "json":
        print(json.dumps([dict(zip(cols, r, strict=True)) for r in shown]))
    else:
        print(format_table(cols, shown))
        note = f" (first {args.max_rows} shown)" if len(rows) > args.max_rows else ""
        print(f"({len(rows)} rows){note}")
    return 0
