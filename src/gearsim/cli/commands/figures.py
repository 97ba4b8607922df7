"""``gearsim figures``: draw figures of the study from the pipeline's tables.

Examples::

    gearsim figures --fig 4 --sweep standard=results/sweeps/standard.parquet
    gearsim figures --fig 7 12 13 --plane wb=results/wb/cells.parquet
    gearsim figures --fig 9 10 11 --sweep b015=results/sweeps/b015.parquet
    gearsim figures --maps --plane weps=results/weps/cells.parquet   # any axes
    gearsim figures --sweep-diagrams --sweep torque=results/sweeps/torque.parquet
    gearsim figures --index

Each figure is written as ``<outdir>/figNN.png`` (200 dpi) and ``.pdf`` plus ``figNN.json``
(captions and differences from the paper) that ``--index`` collects into ``README.md``. The
figures and what they read: :data:`gearsim.presentation.figures.registry.FIGURES`. ``--maps`` draws
every
registered plane map (pattern, DC, Kmax, ...) of each ``--plane``, whatever its two axes, as
``<outdir>/planes/<plane>-<kind>.{png,pdf,json}``. A paper figure of one plane (e.g. Fig 7)
given one ``--plane`` of another name draws that plane (the paper comparison then says "not
applicable" when the paper has no plane of those axes).
Parameters and integration settings come from the pipeline config (``--configfile``), exactly
as the simulation rules see them.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from gearsim.cli.commands._common import add_config_arguments, study_from_args
from gearsim.errors import UsageError

NAME = "figures"
HELP = "draw figures of the study (PNG + PDF + caption record) or the figure index"


def _pairs(items: list[str], flag: str) -> dict[str, str]:
    out = {}
    for item in items:
        name, sep, path = item.partition("=")
        if not sep or not name or not path:
            raise UsageError(f"{flag} expects NAME=PATH, got {item!r}")
        if not Path(path).is_file():
            raise UsageError(f"{flag} {name}: file not found: {path}")
        out[name] = path
    return out

def kept(args: argparse.Namespace) -> str:
    """What Ctrl-C keeps: every file is written whole (a temporary name renamed into place)."""
    return "the figures written before are kept, each file whole"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--fig", type=int, nargs="+", action="extend", default=[], metavar="N",
                   help="figure number(s): 1-17 of the paper, higher for later analyses "
                   "(9, 10, 11 are built together)")
    p.add_argument("--all", action="store_true", help="every figure whose inputs are given")
    p.add_argument("--sweep", action="append", default=[], metavar="NAME=PATH",
                   help="a sweep table (results/sweeps/NAME.parquet), repeatable")
    p.add_argument("--plane", action="append", default=[], metavar="NAME=PATH",
                   help="a plane cells table (results/NAME/cells.parquet), repeatable")
    p.add_argument("--points", action="append", default=[], metavar="NAME=PATH",
                   help="a recorded point set (results/points/NAME.parquet), repeatable")
    p.add_argument("--figure-data", action="append", default=[], metavar="NAME=PATH",
                   help="a figure-data table (results/figure_data/NAME.parquet: the simulated "
                   "motions, attractor search or basins a figure draws), repeatable")
    p.add_argument("--outdir", default="results/figures",
                   help="output directory (default: %(default)s; a figure a workflow run made "
                   "there is not replaced unless --replace)")
    p.add_argument("--replace", action="store_true",
                   help="replace figures that a workflow run made (refused otherwise)")
    p.add_argument("--orbits", action="append", default=[], metavar="NAME=PATH",
                   help="a continuation table (results/orbits/standard.parquet, "
                   "results/orbits/wb_curves.parquet), repeatable; for 'standard' the located "
                   "points are read from *_points.parquet beside it")
    p.add_argument("--maps", action="store_true",
                   help="draw the maps of every --plane (any two axes) into OUTDIR/planes/")
    p.add_argument("--map", nargs="+", default=None, metavar="KIND",
                   help="with --maps: only these maps (default every registered one: "
                   "pattern, dc, kmax, ...)")
    p.add_argument("--sweep-diagrams", action="store_true",
                   help="draw the bifurcation diagram (section points, DC, Kmax) of every "
                   "--sweep, in the sweep's own units, into OUTDIR/sweeps/")
    p.add_argument("--index", action="store_true",
                   help="write OUTDIR/README.md from the figure records present")
    add_config_arguments(p)


def run(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")
    from gearsim.presentation.figures import outputs
    from gearsim.results.in_place import check_hand_outputs

    req = outputs.Request(outdir=Path(args.outdir), numbers=args.fig, every=args.all,
                          maps=args.maps, map_kinds=args.map,
                          sweep_diagrams=args.sweep_diagrams, index=args.index)
    tables = outputs.Tables(
        sweeps=_pairs(args.sweep, "--sweep"), planes=_pairs(args.plane, "--plane"),
        points=_pairs(args.points, "--points"),
        figure_data=_pairs(args.figure_data, "--figure-data"),
        orbits=_pairs(args.orbits, "--orbits"))
    outputs.check_request(req, tables)
    check_hand_outputs(outputs.planned(req, tables), replace=args.replace,
                       elsewhere="--outdir DIR")  # nothing of a run's results/ replaced unasked
    study = study_from_args(args) if (req.numbers or req.every or req.maps
                                      or req.sweep_diagrams) else None
    outputs.draw(study, tables, req, lambda line: print(line, file=sys.stderr))
    return 0
