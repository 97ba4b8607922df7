"""``gearsim basins``: basins of attraction of one point on a grid of starts (Parquet + PNG)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from gearsim.cli.commands.attractors import add_multistability_arguments, load_point, resolve

__all__ = ["HELP", "NAME", "add_arguments", "resolve", "run"]

NAME = "basins"
HELP = (
    "classify an n x n grid of starting states (x, x') of one point by the attractor reached; "
    "write the grid (Parquet) and its picture (PNG/PDF)"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_multistability_arguments(p)
    p.add_argument("--n", type=int, default=200, help="grid points per axis (default 200)")
    p.add_argument("--box", type=float, nargs=4, metavar=("XMIN", "XMAX", "VMIN", "VMAX"),
                   help="start box in (x, x') (default: the finder's start box of the point)")
    p.add_argument("--out", "-o", required=True, metavar="PARQUET",
                   help="output grid; the picture goes next to it (.png, .pdf)")
    p.add_argument("--title", default=None, help="figure title (default: the point)")


def run(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")
    from gearsim.analysis.attractors import FinderOptions
    from gearsim.analysis.basins import basin_grid, write_basin_grid
    from gearsim.presentation.figures.multistability import figure_basins
    from gearsim.presentation.figures.style import save_figure

    params, source, settings, backend = load_point(args)
    t0 = time.perf_counter()
    grid = basin_grid(params, n=args.n, settings=settings,
                      box=None if args.box is None else tuple(args.box),
                      options=FinderOptions(early=not args.full), backend=backend)  # fmt: skip
    elapsed = time.perf_counter() - t0
    out = write_basin_grid(grid, args.out)
    att = grid.attractor_table()
    title = args.title or (f"Basins of attraction at w = {params.w:g}, b = {params.b:g}, "
                           f"xi = {params.xi:.4g} (transient {settings.transient} periods)")
    fig = figure_basins(grid.frame(), att, title=title)
    pics = save_figure(fig, Path(args.out).with_suffix(".png"))
    n = args.n * args.n
    print(f"{n} starts in {elapsed:.1f} s: {len(att)} attractor(s), "
          f"{int(grid.early.sum())} labelled early, diverged {grid.cell.diverged_fraction:.3f}")
    for _, a in att.iterrows():
        npq = a["label_npq"] or ""
        print(f"  #{a['attractor']} {a['label']} {('(' + npq + ')') if npq else ''} "
              f"basin={a['basin_fraction']:.4f}")
    print(f"wrote {out}, {', '.join(str(p) for p in pics)}")
    return 0
