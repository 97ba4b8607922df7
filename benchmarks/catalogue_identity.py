"""Two runs' results, table by table: the identity check of a move-and-merge change.

Not a timing. Run the same configuration (e.g. ``snakemake --cores 1 --configfile
config/quick.yaml``) in two clones, one before the change and one after, then compare their
``results`` folders: every table and view of ``catalogue.sqlite`` (row by row, column by column,
and the views' definitions), every Parquet file below ``results`` and every PNG figure and its
JSON record byte for byte. Provenance and time columns are set aside: a job's code version,
host, workers, start, finish and wall time, a cell's elapsed time, the run's input paths (its
file and its parameters' source), the package versions, and the catalogue's build time, git
commit and code versions.

Usage: python benchmarks/catalogue_identity.py BEFORE/results AFTER/results
Prints one line per table, file group and figure set, then IDENTICAL (exit 0) or NOT IDENTICAL
(exit 1); a folder without a catalogue is one line and exit 2.
"""

from __future__ import annotations

import argparse
import sqlite3
import sys
from pathlib import Path

import numpy as np
import pandas as pd

#: provenance and time columns (every table and Parquet file)
ASIDE = {"started", "finished", "wall_s", "elapsed_s", "host", "code_version", "workers",
         "package_versions", "file", "parameters_source"}
#: catalogue_info keys that are provenance
INFO_ASIDE = {"built", "git_commit", "git_dirty", "code_versions"}


def _equal(u, v) -> bool:
    """One cell: arrays and lists element by element (NaN equal to NaN), else ``==``."""
    if isinstance(u, (list, tuple, np.ndarray)) or isinstance(v, (list, tuple, np.ndarray)):
        ua, va = np.asarray(u), np.asarray(v)
        if ua.shape != va.shape:
            return False
        if ua.dtype.kind in "fc" and va.dtype.kind in "fc":
            return bool(np.array_equal(ua, va, equal_nan=True))
        return all(_equal(x, y) for x, y in zip(ua.tolist(), va.tolist(), strict=True))
    if isinstance(u, float) and isinstance(v, float) and u != u and v != v:
        return True
    return bool(u == v)


def _same(x: pd.Series, y: pd.Series) -> pd.Series:
    if x.dtype == object or y.dtype == object:
        return pd.Series([_equal(u, v) for u, v in zip(x, y, strict=True)], index=x.index)
    return (x.isna() & y.isna()) | (x == y)


def compare_frames(a: pd.DataFrame, b: pd.DataFrame) -> tuple[list[str], list[tuple[str, int]]]:
    """The compared columns and the ``(column, rows that differ)`` of two tables; a different
    column list or row count is reported as ``("<shape>", -1)``."""
    cols_a = [c for c in a.columns if c not in ASIDE]
    cols_b = [c for c in b.columns if c not in ASIDE]
    if cols_a != cols_b or len(a) != len(b):
        return cols_a, [("<shape>", -1)]
    a, b = a.reset_index(drop=True), b.reset_index(drop=True)
    bad = [(c, int((~_same(a[c], b[c])).sum())) for c in cols_a]
    return cols_a, [(c, n) for c, n in bad if n]


def compare_catalogues(pa: Path, pb: Path, out: list[str]) -> bool:
    ca, cb = sqlite3.connect(f"file:{pa}?mode=ro", uri=True), sqlite3.connect(
        f"file:{pb}?mode=ro", uri=True)
    q = ("SELECT name FROM sqlite_master WHERE type IN ('table', 'view') "
         "AND name NOT LIKE 'sqlite_%' ORDER BY type, name")
    names_a = [r[0] for r in ca.execute(q)]
    names_b = [r[0] for r in cb.execute(q)]
    ok = names_a == names_b
    if not ok:
        out.append(f"catalogue: tables and views differ: {sorted(set(names_a) ^ set(names_b))}")
    for t in (n for n in names_a if n in names_b):
        da = pd.read_sql_query(f'SELECT * FROM "{t}"', ca)
        db = pd.read_sql_query(f'SELECT * FROM "{t}"', cb)
        if t == "catalogue_info":
            da, db = (d[~d["key"].isin(INFO_ASIDE)] for d in (da, db))
        cols, bad = compare_frames(da, db)
        ok &= not bad
        state = "identical" if not bad else f"DIFFERENT {bad}"
        out.append(f"catalogue {t}: {len(da)} rows x {len(cols)} columns {state}")
    q = "SELECT name, sql FROM sqlite_master WHERE type = 'view'"
    same_views = dict(ca.execute(q).fetchall()) == dict(cb.execute(q).fetchall())
    out.append(f"catalogue views: definitions {'identical' if same_views else 'DIFFERENT'}")
    return ok and same_views


def compare_files(ra: Path, rb: Path, out: list[str]) -> bool:
    ok = True
    pq_a = sorted(p.relative_to(ra) for p in ra.rglob("*.parquet"))
    pq_b = sorted(p.relative_to(rb) for p in rb.rglob("*.parquet"))
    if pq_a != pq_b:
        ok = False
        out.append(f"Parquet files differ: {sorted(map(str, set(pq_a) ^ set(pq_b)))}")
    same = 0
    for rel in (p for p in pq_a if p in pq_b):
        _, bad = compare_frames(pd.read_parquet(ra / rel), pd.read_parquet(rb / rel))
        if bad:
            ok = False
            out.append(f"{rel}: DIFFERENT {bad}")
        else:
            same += 1
    out.append(f"Parquet: {same} of {len(pq_a)} files identical")
    for ext in ("png", "json"):
        files = sorted(p.relative_to(ra) for p in (ra / "figures").glob(f"*.{ext}"))
        differ = [str(f) for f in files
                  if not (rb / f).is_file() or (ra / f).read_bytes() != (rb / f).read_bytes()]
        ok &= not differ
        out.append(f"figures *.{ext}: {len(files) - len(differ)} of {len(files)} byte-identical"
                   + (f"; differ: {differ}" if differ else ""))
    return ok


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", type=Path, help="the results folder of the run before the change")
    ap.add_argument("after", type=Path, help="the results folder of the run after the change")
    args = ap.parse_args(argv)
    for r in (args.before, args.after):
        if not (r / "catalogue.sqlite").is_file():
            print(f"catalogue_identity: {r} has no catalogue.sqlite (not a results folder of a "
                  "finished run)", file=sys.stderr)
            return 2
    out: list[str] = []
    ok = compare_catalogues(args.before / "catalogue.sqlite", args.after / "catalogue.sqlite",
                            out)
    ok &= compare_files(args.before, args.after, out)
    print("\n".join(out))
    print("IDENTICAL" if ok else "NOT IDENTICAL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
