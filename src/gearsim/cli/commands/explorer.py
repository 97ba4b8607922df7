"""``gearsim explorer``: the study in the browser, one static page (no server, no network).

Example::

    gearsim explorer --configfile config/config.yaml --out results/explorer/index.html

Reads ``results/<plane>/cells.parquet`` of the config's planes, ``results/sweeps/<sweep>.parquet``
of its sweeps and the catalogue's ``attractors`` table when it has one
(:mod:`gearsim.presentation.explorer`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from gearsim.cli.commands._common import add_config_arguments, study_from_args
from gearsim.errors import UsageError

NAME = "explorer"
HELP = ("write the interactive explorer page (one static HTML file: the scorecard, every plane's "
        "layers, cells, Poincare points, attractors, every sweep's diagram)")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--results", default="results",
                   help="results directory (<plane>/cells.parquet, sweeps/<sweep>.parquet; "
                   "default: %(default)s)")
    p.add_argument("--catalogue", default="results/catalogue.sqlite",
                   help="SQLite catalogue (its attractors table is shown when present; "
                   "default: %(default)s), or a database URL with --study")
    p.add_argument("--study", help="with a database URL: the study to read")
    p.add_argument("--out", "-o", default="results/explorer/index.html",
                   help="the page, one HTML file to open in a browser (default: %(default)s, "
                   "unless a workflow run made it: then --out elsewhere or --replace)")
    p.add_argument("--replace", action="store_true",
                   help="replace a page that a workflow run made (refused otherwise)")
    p.add_argument("--plane", nargs="+", default=None, metavar="NAME",
                   help="only these planes of the config (default: every one)")
    p.add_argument("--sweep", nargs="+", default=None, metavar="NAME",
                   help="only these sweeps of the config (default: every one)")
    add_config_arguments(p)


def run(args: argparse.Namespace) -> int:
    from gearsim.presentation.explorer import write_explorer
    from gearsim.presentation.report_inputs import study_from_config
    from gearsim.results.in_place import check_hand_outputs

    study = study_from_args(args)
    config = study.config
    planes, sweeps = study_from_config(config)
    for flag, chosen, known in (("--plane", args.plane, list(planes)),
                                ("--sweep", args.sweep, sweeps)):
        bad = [n for n in chosen or [] if n not in known]
        if bad:
            raise UsageError(f"{flag} {bad[0]}: not in the config; allowed: "
                             f"{', '.join(known) or 'none configured'}")
    if args.plane is not None:
        planes = {n: planes[n] for n in args.plane}
    if args.sweep is not None:
        sweeps = list(args.sweep)
    results = Path(args.results)
    missing = [str(results / p / "cells.parquet") for p in planes
               if not (results / p / "cells.parquet").is_file()]
    missing += [str(results / "sweeps" / f"{s}.parquet") for s in sweeps
                if not (results / "sweeps" / f"{s}.parquet").is_file()]
    if missing:
        raise UsageError(f"--results {results}: missing {', '.join(missing[:3])}"
                         + (f" and {len(missing) - 3} more" if len(missing) > 3 else "")
                         + " (run the pipeline first)")
    check_hand_outputs([args.out], replace=args.replace, elsewhere="--out PATH")
    fixed = {k: dict(v.get("fixed") or {}) for k, v in (config.get("sweeps") or {}).items()}
    from gearsim.physical.units import config_gear
    from gearsim.presentation.report import build_report
    from gearsim.presentation.scorecard import scorecard
    from gearsim.results.server_read import readable_catalogue

    catalogue = readable_catalogue(args.catalogue, args.study)
    rep, _ = build_report(sweeps_dir=results / "sweeps", catalogue=catalogue,
                          results=results, calibration=None, planes=planes, sweeps=sweeps,
                          study=config.get("study"))
    rows = ([{"item": r.item, "paper": r.paper, "ours": r.ours, "located": r.located,
              "difference": r.difference, "ok": r.ok} for r in scorecard(rep)]
            if rep.paper_study else [])
    title = (f"gearsim explorer: study {config['study']}" if config.get("study")
             else "gearsim explorer: reproduction of the paper")
    out = write_explorer(args.out, planes=planes, sweeps=sweeps, results=results,
                         catalogue=catalogue, sweep_fixed=fixed,
                         gear=config_gear(config, study.root), scorecard=rows, title=title)
    size = out.stat().st_size
    print(f"wrote {out} ({size / 1e6:.1f} MB; {len(planes)} planes, {len(sweeps)} sweeps)",
          file=sys.stderr)
    return 0
