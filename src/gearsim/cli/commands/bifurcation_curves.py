"""``gearsim bifurcation-curves``: fold, period-doubling and grazing curves over a plane."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from gearsim.cli.commands.simulate_tile import add_config_arguments, config_from_args
from gearsim.errors import UsageError

NAME = "bifurcation-curves"
HELP = (
    "locate the bifurcations along a plane's x axis by continuation (Newton-Floquet) and follow "
    "the fold, period-doubling and grazing points across the plane's y range (Parquet + figure)"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plane", required=True, help="plane name in the config (e.g. wb, wxi)")
    add_config_arguments(p)
    p.add_argument("--cells", default=None,
                   help="the plane's cells.parquet: the curves are drawn over its pattern map")
    p.add_argument("--at", type=float, default=None,
                   help="y value of the seeding continuation (default: the base parameter "
                   "value, clipped into the plane's y range)")
    p.add_argument("--from", dest="start", type=float, default=None,
                   help="start of the seeding continuation along x (default: the plane's x min)")
    p.add_argument("--to", dest="stop", type=float, default=None,
                   help="end of the seeding continuation along x (default: the plane's x max)")
    p.add_argument("--period", "-n", type=int, default=1,
                   help="period of the orbit at the start of the x range (default 1)")
    p.add_argument("--step2", type=float, default=None,
                   help="largest step in y between curve points (default: y range / 10)")
    p.add_argument("--max-period", type=int, default=2,
                   help="follow the points of orbits of at most this period (default 2: the "
                   "period-4 points lie in the chaotic band and cost 4x per map; 0: all)")
    p.add_argument("--switch-depth", type=int, default=2,
                   help="period doublings followed onto the doubled branch")
    p.add_argument("--kinds", default="fold,period_doubling,grazing",
                   help="comma-separated kinds to follow")
    p.add_argument("--points", metavar="PARQUET", default=None,
                   help="located points of a continuation along x at the seed parameters "
                   "(e.g. results/orbits/standard_points.parquet from `gearsim continue`): used "
                   "instead of a new seeding continuation when its parameters are the seed's")
    p.add_argument("--workers", type=int, default=1,
                   help="processes for the curves (one curve half each; default 1)")
    p.add_argument("--method", choices=("secant", "window"), default="secant",
                   help="re-location of a curve point: direct secant solve (default), or a "
                   "windowed continuation (the slower reference; also the secant's fallback)")
    p.add_argument("--out", required=True,
                   help="curves Parquet (results/orbits/PLANE_curves.parquet); the located "
                   "points go to *_points.parquet beside it, the figure to *.png")


def run(args: argparse.Namespace) -> int:
    from gearsim.analysis.bifcurves import bifurcation_points, follow_curves
    from gearsim.analysis.continuation import Continuation, continue_orbit, write_branches
    from gearsim.analysis.orbits import SEEDING, find_periodic_orbit
    from gearsim.results import catalogue
    from gearsim.study import config as gcfg
    from gearsim.study import provenance as gprov

    config = config_from_args(args)
    if args.plane not in config["planes"]:
        raise UsageError(f"unknown plane '{args.plane}'; allowed: {', '.join(config['planes'])}")
    kinds = [k.strip() for k in args.kinds.split(",") if k.strip()]
    allowed = ("fold", "period_doubling", "grazing", "neimark_sacker")
    for k in kinds:
        if k not in allowed:
            raise UsageError(f"--kinds: {k!r} is not one of {', '.join(allowed)}")
    pl = config["planes"][args.plane]
    xn, yn = pl["x"]["name"], pl["y"]["name"]
    x0, x1 = float(pl["x"]["min"]), float(pl["x"]["max"])
    if args.start is not None:
        x0 = args.start
    if args.stop is not None:
        x1 = args.stop
    if x0 == x1:
        raise UsageError(f"--from and --to are equal ({x0}): empty range")
    y0, y1 = float(pl["y"]["min"]), float(pl["y"]["max"])
    base = gcfg.plane_base(config, args.plane)
    at = float(getattr(base, yn)) if args.at is None else args.at
    at = min(max(at, y0), y1)
    step2 = args.step2 if args.step2 is not None else (y1 - y0) / 10
    if args.max_period < 0:
        raise UsageError(f"--max-period = {args.max_period} must be >= 0 (0: all)")
    if not 0 < step2 <= (y1 - y0):
        raise UsageError(f"--step2 = {step2} must be in (0, {y1 - y0}]")
    if not 1 <= args.workers <= 64:
        raise UsageError(f"--workers = {args.workers} must be in [1, 64]")
    params = base.with_(**{yn: at, xn: x0})
    started = catalogue.now_iso()
    t0 = time.perf_counter()
    given = _given_points(args.points, params, xn, x0, x1) if args.points else None
    if given is not None:
        points, branches = given
        _log(f"seed: {len(points)} located points from {args.points} (same parameters)")
    else:
        from gearsim.cell.simulate import simulate_cell

        seed = simulate_cell(params, settings=SEEDING).final_state
        orbit = find_periodic_orbit(params, args.period, seed, grazing=False)
        cfg = Continuation(ds=0.02, ds_max=0.05, switch_depth=args.switch_depth,
                           max_points=600, progress=_log)
        branches = continue_orbit(params, xn, x0, x1, orbit, config=cfg)
        points = bifurcation_points(branches)
    t_branch = time.perf_counter() - t0
    curves = follow_curves(params, points, yn, (y0, y1), step2=step2, kinds=kinds,
                           config=Continuation(progress=_log), workers=args.workers,
                           method=args.method, range1=(x0, x1),
                           max_period=args.max_period or None)
    wall = time.perf_counter() - t0
    out = Path(args.out)
    stem = out.with_suffix("")
    prov = gprov.provenance(
        gprov.plane_subtree(config, args.plane), kind="curves", name=args.plane, config=config,
        scope="analysis",
        started=started, finished=catalogue.now_iso(), wall_s=wall, seed_value=at,
        branch_wall_s=t_branch, curve_wall_s=wall - t_branch, reasons=curves.attrs["reasons"],
        workers="in-process",
    )
    branches.attrs["provenance"] = prov
    write_branches(branches, Path(f"{stem}_branches.parquet"))
    points = points.assign(plane=args.plane, name2=yn, value2=at)
    catalogue.write_parquet(points, Path(f"{stem}_points.parquet"),
                            {catalogue.PROVENANCE_KEY: prov})
    curves = curves.assign(plane=args.plane)
    catalogue.write_parquet(curves, out, {catalogue.PROVENANCE_KEY: prov})
    import pandas as pd

    from gearsim.presentation.figures.style import save_figure
    from gearsim.presentation.orbit_plots import figure_curves

    cells = pd.read_parquet(args.cells) if args.cells else None
    fig = figure_curves(curves, cells, title=f"plane {args.plane}: bifurcation curves "
                        f"(continued from {yn} = {at:g})")
    save_figure(fig, out.with_suffix(".png"))
    print(json.dumps({"plane": args.plane, "points": len(points), "curves":
                      int(curves["curve"].nunique()) if len(curves) else 0,
                      "curve_points": len(curves), "branch_wall_s": t_branch,
                      "curve_wall_s": wall - t_branch}), file=sys.stderr)
    for r in curves.attrs["reasons"]:
        print(f"  {r}", file=sys.stderr)
    print(f"wrote {out}, {stem}_points.parquet, {stem}_branches.parquet and "
          f"{out.with_suffix('.png')}", file=sys.stderr)
    return 0


def _given_points(path: str, params, xn: str, x0: float, x1: float):
    """``(points, branches)`` of a continuation file whose parameters are ``params`` (all but
    ``xn``), restricted to ``[x0, x1]``; None (with a note) when the parameters differ."""
    import pandas as pd

    from gearsim.analysis.continuation import COLUMNS
    from gearsim.results import catalogue

    p = Path(path)
    if not p.is_file():
        raise UsageError(f"--points: file not found: {path}")
    meta = catalogue.read_metadata(p, b"gearsim.analysis.continuation") or {}
    theirs = dict(meta.get("params") or {})
    ours = params.to_dict()
    diff = [k for k in ours if k != xn and theirs.get(k) != ours[k]]
    if meta.get("name") != xn or diff:
        _log(f"--points {path}: not the seed's parameters ({', '.join(diff[:4]) or xn}); "
             "running the seeding continuation")
        return None
    lo, hi = min(x0, x1), max(x0, x1)
    lo_c, hi_c = sorted((float(meta.get("start", lo)), float(meta.get("stop", hi))))
    if lo_c > lo + 1e-12 or hi_c < hi - 1e-12:
        _log(f"--points {path}: covers {xn} in [{lo_c}, {hi_c}], not [{lo}, {hi}]; "
             "running the seeding continuation")
        return None
    pts = pd.read_parquet(p)
    pts = pts[(pts["value"] >= lo) & (pts["value"] <= hi)].reset_index(drop=True)
    pts = pts.drop(columns=[c for c in ("name2", "value2") if c in pts.columns])
    pts.attrs.update(meta)
    branch_path = p.with_name(p.name.replace("_points.parquet", ".parquet"))
    branches = (pd.read_parquet(branch_path) if branch_path.is_file() and branch_path != p
                else pd.DataFrame(columns=list(COLUMNS)))
    branches.attrs.update(meta)
    return pts, branches


def _log(line: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {line}", file=sys.stderr, flush=True)
