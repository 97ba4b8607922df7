"""``gearsim bifurcation-curves``: the plane atlas, the bifurcation curves seeded from every
boundary of a plane's pattern map and their codimension-2 points (docs/orbits.md)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from gearsim.cli.commands._common import add_config_arguments, check_plane, study_from_args
from gearsim.errors import UsageError
from gearsim.study.preflight import check_outputs

NAME = "bifurcation-curves"
#: Wall-clock budget of a job (s): the curves stop there, keep what they have, status 'budget'.
DEFAULT_BUDGET_S = 1800.0
HELP = (
    "the plane atlas: every boundary of a plane's pattern map seeds a bifurcation curve (fold, "
    "period doubling of every period, grazing of both flanks), located by Newton-Floquet and "
    "followed across the plane; codimension-2 points where curves end or meet (Parquet + figure)"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plane", required=True, help="plane name in the config (e.g. wb, wxi)")
    add_config_arguments(p)
    p.add_argument("--cells", required=True,
                   help="the plane's cells.parquet: its boundaries seed the curves, which are "
                   "drawn over its pattern map")
    p.add_argument("--kinds", default="fold,period_doubling,grazing",
                   help="comma-separated kinds to follow (fold, period_doubling, grazing)")
    p.add_argument("--max-period", type=int, default=16,
                   help="the cascade to this period: doublings of orbits of half of it or less, "
                   "grazings and folds of orbits of at most it (default 16)")
    p.add_argument("--workers", type=int, default=1,
                   help="processes, one seed and its curve each (default 1)")
    p.add_argument("--method", choices=("secant", "window"), default="secant",
                   help="re-location of a curve point: direct secant solve (default), or a "
                   "windowed continuation (the slower reference; also the secant's fallback)")
    p.add_argument("--out", "-o", required=True,
                   help="curves Parquet (results/orbits/PLANE_curves.parquet); the seeds go to "
                   "*_points.parquet, the seeding continuations to *_branches.parquet, the "
                   "codimension-2 points to PLANE_codim2.parquet, the figure to *.png")
    p.add_argument("--budget-s", type=float, default=DEFAULT_BUDGET_S,
                   help="wall-clock budget of the job in seconds: the curves stop there, keep "
                   f"what they have and record status 'budget' (default {DEFAULT_BUDGET_S:g})")


def outputs(out: Path) -> dict[str, Path]:
    stem = out.with_suffix("")
    plane_stem = str(stem)[: -len("_curves")] if str(stem).endswith("_curves") else str(stem)
    return {"curves": out, "seeds": Path(f"{stem}_points.parquet"),
            "branches": Path(f"{stem}_branches.parquet"),
            "codim2": Path(f"{plane_stem}_codim2.parquet"), "figure": out.with_suffix(".png")}


def run(args: argparse.Namespace) -> int:
    from gearsim.results import parquet
    from gearsim.study.atlas_job import atlas_provenance, run_atlas

    study = study_from_args(args)
    check_plane(study, args.plane)
    if not 1 <= args.workers <= 64:
        raise UsageError(f"--workers = {args.workers} must be in [1, 64]")
    if not 0 < args.budget_s <= 7 * 86400:
        raise UsageError(f"--budget-s = {args.budget_s:g} must be in (0, 604800]")
    files = outputs(Path(args.out))
    check_outputs(list(files.values()))  # before any computation
    kinds = tuple(k.strip() for k in args.kinds.split(",") if k.strip())
    res = run_atlas(study, args.plane, args.cells, kinds=kinds, max_period=args.max_period,
                    workers=args.workers, method=args.method, budget_s=args.budget_s,
                    started=parquet.now_iso(), progress=_log)
    prov = atlas_provenance(study, args.plane, res, parquet.now_iso(), args.budget_s)
    meta = {parquet.PROVENANCE_KEY: prov}
    for key in ("branches", "seeds", "codim2", "curves"):
        parquet.write_parquet(res[key].assign(plane=args.plane), files[key], meta)
    _figure(args, res, files["figure"])
    _summary(args, res, files)
    return 0


def _figure(args: argparse.Namespace, res: dict, png: Path) -> None:
    import textwrap

    import pandas as pd

    from gearsim.presentation.figures.style import save_figure
    from gearsim.presentation.orbit_plots import figure_curves, param_label

    grid = res["grid"]
    title = (f"plane {args.plane}: {res['reasons'][0]}" if res["status"] == "skipped" else
             f"plane {args.plane}: bifurcation curves seeded from the map's boundaries")
    fig = figure_curves(res["curves"].assign(plane=args.plane), pd.read_parquet(args.cells),
                        title="\n".join(textwrap.wrap(title, 80)))
    fig.axes[0].set_xlabel(param_label(grid.x_name))
    fig.axes[0].set_ylabel(param_label(grid.y_name))
    save_figure(fig, png)


def _summary(args: argparse.Namespace, res: dict, files: dict[str, Path]) -> None:
    """The command's closing lines on stderr: counts, times, stop reasons, the files written."""
    cur = res["curves"]
    print(json.dumps({"plane": args.plane, "curves": int(cur["curve"].nunique()) if len(cur)
                      else 0, "curve_points": len(cur), "codim2": len(res["codim2"]),
                      "wall_s": round(res["wall_s"], 1), "cpu_s": round(res["cpu_s"], 1),
                      **res.get("stats", {})}, default=str), file=sys.stderr)
    for r in res["reasons"]:
        print(f"  {r}", file=sys.stderr)
    if res["status"] == "budget":
        print(f"plane {args.plane}: stopped at the budget of {args.budget_s:g} s "
              "(status budget); the curves are partial", file=sys.stderr)
    print(f"wrote {', '.join(str(f) for f in files.values())}", file=sys.stderr)


def _log(line: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {line}", file=sys.stderr, flush=True)
