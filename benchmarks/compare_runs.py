"""Two default runs' catalogues side by side: what a whole-run comparison reports besides time.

Not a timing (the times come from ``/usr/bin/time -v make reproduce`` and
``bench_workflow.py rules``). For two ``results`` folders of the same configuration (e.g. fresh
clones of an old revision and of this code, each after ``make reproduce``):

* per plane: cells whose label or status differ, by kind of change; for the cells with the same
  periodic label, the largest DC and relative Kmax differences (and how many exceed 1e-6);
* cells and attractors labelled chaos or quasi-periodic with Kmax above 1 000 (a growing motion
  before the divergence bound, not an attractor);
* pairs of one orbit in a cell's attractor list: two periodic attractors whose periods divide
  one another with DC and Kmax equal to 1e-4 (relative above 1);
* the DP5 audit's agreement.

Usage: python benchmarks/compare_runs.py OLD/results NEW/results
"""

from __future__ import annotations

import argparse
import sqlite3
import sys
from pathlib import Path

import numpy as np
import pandas as pd

CLOUDS = ("chaos", "quasi-periodic")
CELLS = ("select p.name plane, c.i, c.j, c.x, c.y, c.label, c.status, c.motion, c.dc, c.kmax "
         "from cells c join planes p on p.id = c.plane_id")
ATTRACTORS = ("select p.name plane, c.i, c.j, a.label, a.motion, a.n, a.dc, a.kmax "
              "from attractors a join cells c on c.id = a.cell_id "
              "join planes p on p.id = c.plane_id")


def _read(results: Path, query: str) -> pd.DataFrame:
    with sqlite3.connect(results / "catalogue.sqlite") as con:
        return pd.read_sql(query, con)


def _close(a: float, b: float) -> bool:
    return abs(a - b) < 1e-4 * max(1.0, abs(a))


def orbit_copies(att: pd.DataFrame) -> list[tuple]:
    """Pairs of periodic attractors of one cell that are one orbit (periods n | m, DC and Kmax
    equal to 1e-4)."""
    out = []
    per = att[att.motion == "periodic"]
    for key, g in per.groupby(["plane", "i", "j"]):
        rows = g.to_dict("records")
        for k, a in enumerate(rows):
            for b in rows[k + 1:]:
                n1, n2 = sorted((int(a["n"]), int(b["n"])))
                if (n1 > 0 and n2 % n1 == 0 and _close(a["dc"], b["dc"])
                        and _close(a["kmax"], b["kmax"])):
                    out.append((key, a["label"], b["label"]))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old", type=Path)
    ap.add_argument("new", type=Path)
    args = ap.parse_args(argv)
    for d in (args.old, args.new):
        if not (d / "catalogue.sqlite").exists():
            print(f"{d}: no catalogue.sqlite", file=sys.stderr)
            return 2
    old, new = _read(args.old, CELLS), _read(args.new, CELLS)
    m = old.merge(new, on=["plane", "i", "j"], suffixes=("_o", "_n"))
    for plane, g in m.groupby("plane"):
        diff = g[(g.label_o != g.label_n) | (g.status_o != g.status_n)]
        print(f"{plane}: {len(diff)} of {len(g)} cells differ in label or status")
        kinds = (diff.label_o + " -> " + diff.label_n).value_counts()
        for kind, k in kinds.head(10).items():
            print(f"    {k:6d}  {kind}")
        same = g[(g.label_o == g.label_n) & (g.status_o == g.status_n)
                 & (g.motion_n == "periodic")]
        dd = (same.dc_o - same.dc_n).abs()
        dk = (same.kmax_o - same.kmax_n).abs() / same.kmax_o.abs().clip(lower=1e-12)
        print(f"  same periodic label: {len(same)} cells; |dDC| max {dd.max():.3g} "
              f"(p99 {dd.quantile(0.99):.3g}, {int((dd > 1e-6).sum())} above 1e-6); relative "
              f"dKmax max {dk.max():.3g} ({int((dk > 1e-6).sum())} above 1e-6)")
        for side in ("o", "n"):
            big = g[g[f"motion_{side}"].isin(CLOUDS) & (g[f"kmax_{side}"] > 1000)]
            print(f"  {'old' if side == 'o' else 'new'}: {len(big)} chaos / quasi-periodic "
                  "cells with Kmax > 1 000")
    for name, d in (("old", args.old), ("new", args.new)):
        att = _read(d, ATTRACTORS)
        per_cell = att.groupby(["plane", "i", "j"]).size()
        big = att[att.motion.isin(CLOUDS) & (att.kmax > 1000)]
        copies = orbit_copies(att)
        with sqlite3.connect(d / "catalogue.sqlite") as con:
            agree = pd.read_sql("select agree from audits", con).agree
        print(f"{name}: {len(att)} attractors in {len(per_cell)} cells "
              f"({int((per_cell > 1).sum())} multistable); {len(big)} chaos / quasi-periodic "
              f"attractors with Kmax > 1 000; {len(copies)} pairs of one orbit "
              f"{copies[:3]}; DP5 audit {np.mean(agree):.3f} of {len(agree)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
