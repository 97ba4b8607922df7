"""``gearsim report``: the study's report (a scorecard against the paper first, when the study
holds the paper's material; else a report about the study's own planes, sweeps and points).

The study's planes (with their axes) and sweeps come from the pipeline config (``--configfile``,
merged like Snakemake's); without one, the paper's planes ``wb`` and ``wxi`` and every sweep in
``--sweeps`` are reported. A plane whose axes the paper does not map, and a paper sweep the study
does not configure, are reported as "not applicable".
"""

from __future__ import annotations

import argparse
from pathlib import Path

from gearsim.cli.commands._common import add_config_arguments, study_from_args
from gearsim.presentation.report import build_report
from gearsim.presentation.report_inputs import study_from_config

NAME = "report"
HELP = ("write the study's report (Markdown): the scorecard against the paper, or the study's "
        "own planes, sweeps and points")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--sweeps", default="results/sweeps", help="directory of <sweep>.parquet")
    p.add_argument("--catalogue", default="results/catalogue.sqlite",
                   help="SQLite catalogue, or a database URL with --study")
    p.add_argument("--study", help="with a database URL: the study to read")
    p.add_argument("--results", default="results",
                   help="results directory (<plane>/audit.parquet, fallback <plane>/cells.parquet)")
    p.add_argument("--calibration", default="docs/calibration.json",
                   help="calibration record (read when the file exists; '' for none)")
    p.add_argument("--out", "-o", default="results/report.md", help="the report (Markdown)")
    add_config_arguments(p)


def run(args: argparse.Namespace) -> int:
    planes: dict[str, tuple[str, str]] | tuple[str, ...] = ("wb", "wxi")
    sweeps = specs = points = study = None
    if args.configfile or args.config_json:
        config = study_from_args(args).config
        planes, sweeps = study_from_config(config)
        specs = dict(config.get("sweeps") or {})
        points = list(config.get("points") or {})
        study = config.get("study")
    from gearsim.results.server_read import readable_catalogue

    catalogue = readable_catalogue(args.catalogue, args.study)
    rep, text = build_report(sweeps_dir=args.sweeps, catalogue=catalogue,
                             results=args.results, calibration=args.calibration or None,
                             planes=planes, sweeps=sweeps, study=study, sweep_specs=specs,
                             point_sets=points)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".tmp")
    tmp.write_text(text)
    tmp.replace(out)
    print(f"wrote {out} ({len(rep.misses)} mismatches listed, {rep.compared} comparisons "
          "with the paper)")
    return 0
