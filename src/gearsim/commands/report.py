"""``gearsim report``: the reproduction report (paper landmarks and thresholds beside ours)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..report import build_report

NAME = "report"
HELP = "write the reproduction report (Markdown) from the sweeps, planes and calibration"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--sweeps", default="results/sweeps", help="directory of <sweep>.parquet")
    p.add_argument("--catalogue", default="results/catalogue.sqlite", help="SQLite catalogue")
    p.add_argument("--results", default="results",
                   help="results directory (fallback <plane>/cells.parquet)")
    p.add_argument("--calibration", default="docs/calibration.json", help="calibration record")
    p.add_argument("--out", default="results/report.md")


def run(args: argparse.Namespace) -> int:
    rep, text = build_report(sweeps_dir=args.sweeps, catalogue=args.catalogue,
                             results=args.results, calibration=args.calibration)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".tmp")
    tmp.write_text(text)
    tmp.replace(out)
    print(f"wrote {out} ({len(rep.misses)} mismatches listed)")
    return 0
