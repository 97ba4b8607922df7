"""``gearsim figure-data``: simulate what a figure draws (its steady motions, attractor search
or basins) and write the table its figure job reads."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from gearsim.cli.commands._common import add_config_arguments, check_new_file, study_from_args
from gearsim.errors import UsageError
from gearsim.study.figure_tables import FIGURE_DATA, FIGURE_DATA_KEY

NAME = "figure-data"
HELP = ("simulate the motions, attractor search or basins a figure draws and write "
        "results/figure_data/<name>.parquet")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--name", required=True, choices=list(FIGURE_DATA),
                   help="the figure-data table")
    p.add_argument("--sweep", action="append", default=[], metavar="NAME=PATH",
                   help="a sweep table the figure's simulations start from, repeatable")
    add_config_arguments(p)
    p.add_argument("--out", "-o", default=None,
                   help="output (default <results>/figure_data/<name>.parquet)")


def run(args: argparse.Namespace) -> int:
    import pandas as pd

    from gearsim.results import parquet
    from gearsim.study import provenance as gprov
    from gearsim.study.config import results_dir
    from gearsim.study.figure_data import figure_table

    sweeps = {}
    for item in args.sweep:
        name, sep, path = item.partition("=")
        if not sep or not name or not path:
            raise UsageError(f"--sweep expects NAME=PATH, got {item!r}")
        if not Path(path).is_file():
            raise UsageError(f"--sweep {name}: file not found: {path}")
        sweeps[name] = pd.read_parquet(path)
    study = study_from_args(args)
    out = check_new_file(args.out or results_dir(study.config) / "figure_data"
                         / f"{args.name}.parquet")  # fmt: skip
    started, t0 = parquet.now_iso(), time.perf_counter()
    print(f"figure data {args.name}: simulating", file=sys.stderr, flush=True)
    df, stated = figure_table(args.name, study, sweeps)
    wall = time.perf_counter() - t0
    subtree = {"figure_data": args.name, "sweeps": sorted(sweeps),
               "points": study.config.get("points") or {},
               "parameters": study.parameters().model.to_dict(),
               "integration": study.settings.to_dict()}  # fmt: skip
    prov = gprov.provenance(subtree, kind="figure_data", name=args.name, study=study,
                            scope="analysis",
                            started=started, finished=parquet.now_iso(), wall_s=wall)
    parquet.write_parquet(df, out, {parquet.PROVENANCE_KEY: prov, FIGURE_DATA_KEY: stated})
    print(f"figure data {args.name}: wrote {out} ({len(df)} rows in {wall:.1f} s)",
          file=sys.stderr, flush=True)  # fmt: skip
    return 0
