"""``gearsim query "SELECT ..."``: read-only SQL on the catalogue, printed as a table, CSV or JSON.

The engine and its guards (authorizer, one read-only statement, time and size limits) are
:mod:`gearsim.results.query`. The table format shows 1000 rows unless told otherwise; CSV and
JSON stream every row unless ``--max-rows`` is given; a cut is announced on stderr.
"""

from __future__ import annotations

import argparse
import os
import sys

from gearsim.errors import UsageError
from gearsim.results import query

NAME = "query"
HELP = "run a read-only SELECT on results/catalogue.sqlite and print the result"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("sql", nargs="?", help="one SELECT (or WITH ... SELECT) statement")
    p.add_argument("--example", choices=sorted(query.EXAMPLES), help="run a documented example")
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
        help=f"fetch at most this many rows, -1 = all (default: {query.TABLE_ROWS} for the "
        "table, all for csv/json); a cut is reported on stderr",
    )
    p.add_argument(
        "--timeout",
        type=float,
        default=60.0,
        help=f"stop the query after this many seconds (0 < s <= {query.MAX_TIMEOUT:.0f}; "
        "default 60)",
    )


def run(args: argparse.Namespace) -> int:
    if (args.sql is None) == (args.example is None):
        raise UsageError("give one SQL statement or --example NAME")
    timeout = query.check_timeout(args.timeout)
    limit = query.row_limit(args.max_rows, args.format)
    sql = query.EXAMPLES[args.example] if args.example else args.sql
    res = query.open_query(args.db, sql, limit=limit, timeout=timeout)
    try:
        if args.example:
            sys.stdout.write(sql + "\n\n")
        query.write_result(res, args.format, sys.stdout)
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
