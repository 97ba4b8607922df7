"""``gearsim figures``: draw figures of the study from the pipeline's tables.

Examples::

    gearsim figures --fig 4 --sweep standard=results/sweeps/standard.parquet
    gearsim figures --fig 7 12 13 --plane wb=results/wb/cells.parquet
    gearsim figures --fig 9 10 11 --sweep b015=results/sweeps/b015.parquet
    gearsim figures --index

Each figure is written as ``<outdir>/figNN.png`` (200 dpi) and ``.pdf`` plus ``figNN.json``
(captions and differences from the paper) that ``--index`` collects into ``README.md``.
Parameters and integration settings come from the pipeline config (``--configfile``), exactly
as the simulation rules see them.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..errors import UsageError
from .simulate_tile import add_config_arguments, config_from_args

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


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--fig", type=int, nargs="+", action="extend", default=[], metavar="N",
                   help="figure number(s), 1-17 (9, 10, 11 are built together)")
    p.add_argument("--all", action="store_true", help="every figure whose inputs are given")
    p.add_argument("--sweep", action="append", default=[], metavar="NAME=PATH",
                   help="a sweep table (results/sweeps/NAME.parquet), repeatable")
    p.add_argument("--plane", action="append", default=[], metavar="NAME=PATH",
                   help="a plane cells table (results/NAME/cells.parquet), repeatable")
    p.add_argument("--points", action="append", default=[], metavar="NAME=PATH",
                   help="a recorded point set (results/points/NAME.parquet), repeatable")
    p.add_argument("--outdir", default="results/figures", help="output directory")
    p.add_argument("--index", action="store_true",
                   help="write OUTDIR/README.md from the figure records present")
    add_config_arguments(p)


def _context(args, config):
    from ..config import base_parameters, integration_settings
    from ..figures.data import read_table
    from ..figures.registry import Context
    from ..parameters import ModelParameters

    values, _source = base_parameters(config)
    ctx = Context(
        params=ModelParameters.from_mapping(values),
        settings=integration_settings(config),
        point_specs=dict(config.get("points") or {}),
        sweep_fixed={k: dict(v.get("fixed") or {}) for k, v in
                     (config.get("sweeps") or {}).items()},
    )
    for name, path in _pairs(args.sweep, "--sweep").items():
        ctx.sweeps[name] = read_table(path)
    for name, path in _pairs(args.plane, "--plane").items():
        ctx.planes[name] = read_table(path)
    for name, path in _pairs(args.points, "--points").items():
        ctx.points[name] = read_table(path)
    return ctx


def run(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..figures import registry
    from ..figures.index import write_index
    from ..figures.style import save_figure

    outdir = Path(args.outdir)
    numbers = list(dict.fromkeys(args.fig))
    if args.all:
        numbers = list(registry.ALL)
    if not numbers and not args.index:
        raise UsageError("nothing to do: give --fig N, --all or --index")
    if numbers:
        config = config_from_args(args)
        ctx = _context(args, config)
        if args.all:  # keep the figures whose inputs are present
            numbers = [n for n in numbers if all(
                name in getattr(ctx, kind) for kind, names in registry.INPUTS[n].items()
                if kind != "points" and n not in (2, 5, 6, 9, 10, 11) for name in names)]
        for b in registry.build(numbers, ctx):
            files = [str(f) for f in save_figure(b.figure, outdir / f"fig{b.number:02d}")]
            plt.close(b.figure)
            rec = registry.record(b, files, ctx)
            (outdir / f"fig{b.number:02d}.json").write_text(
                json.dumps(rec, indent=1, ensure_ascii=False) + "\n")
            print(f"figure {b.number}: wrote {', '.join(files)}", file=sys.stderr)
    if args.index:
        path = write_index(outdir)
        print(f"wrote {path}", file=sys.stderr)
    return 0
