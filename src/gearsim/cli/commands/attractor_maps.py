"""``gearsim attractor-maps``: coexistence and continuation-basin maps of a plane."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from gearsim.cli.commands._common import add_config_arguments, study_from_args
from gearsim.errors import UsageError

NAME = "attractor-maps"
HELP = (
    "draw a plane's coexistence map (attractors per cell, dominant pattern hatched where "
    "another coexists) and the basin-fraction map of its forward-continuation attractor"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plane", required=True, help="plane name (a key of `planes:`)")
    p.add_argument("--attractors", nargs="+", required=True, metavar="PARQUET",
                   help="the plane's attractor tiles (gearsim attractor-tile)")
    add_config_arguments(p)
    p.add_argument("--out-dir", default="results/figures/planes",
                   help="directory of <plane>-coexistence.png and <plane>-forward-basin.png")


def run(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import pandas as pd

    from gearsim.presentation.figures.multistability import figure_coexistence, figure_forward_basin
    from gearsim.presentation.figures.style import save_figure

    study = study_from_args(args)
    config = study.config
    if args.plane not in config["planes"]:
        raise UsageError(f"unknown plane '{args.plane}'")
    pl = config["planes"][args.plane]
    att = pd.concat([pd.read_parquet(f) for f in args.attractors], ignore_index=True)
    if att.empty:
        raise UsageError(f"plane '{args.plane}': the attractor tiles hold no cell")
    ms = pl.get("multistability") or {}
    note = (f"plane {args.plane}: {att.groupby(['i', 'j']).ngroups} cells, "
            f"{ms.get('starts', '?')} starts each (seed {ms.get('seed', 0)}, every "
            f"{ms.get('every', 1)})")  # fmt: skip
    out = Path(args.out_dir)
    xn, yn = pl["x"]["name"], pl["y"]["name"]
    lims = {"xlim": (pl["x"]["min"], pl["x"]["max"]), "ylim": (pl["y"]["min"], pl["y"]["max"])}
    files = save_figure(figure_coexistence(att, xn, yn, title="Coexisting attractors; " + note,
                                           **lims),
                        out / f"{args.plane}-coexistence.png")  # fmt: skip
    files += save_figure(figure_forward_basin(att, xn, yn, title="Basin of the continuation "
                                              "attractor; " + note, **lims),
                         out / f"{args.plane}-forward-basin.png")  # fmt: skip
    print(f"wrote {', '.join(str(f) for f in files)}", file=sys.stderr)
    return 0
