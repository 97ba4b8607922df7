"""``gearsim bifurcation-curves``: fold, period-doubling and grazing curves over a plane."""

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
#: Wall-clock budget of a job (s). The paper's (w, xi) plane took 686 s on a loaded machine
#: (benchmarks/README.md, section (g)): twice that, so a normal job is never cut.
DEFAULT_BUDGET_S = 1800.0
#: A plane whose cells are more than this fraction diverged or out of their step budget (stiff)
#: has no periodic orbits to follow: its curves are skipped (status 'skipped').
MAX_UNUSABLE = 0.5
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
    p.add_argument("--out", "-o", required=True,
                   help="curves Parquet (results/orbits/PLANE_curves.parquet); the located "
                   "points go to *_points.parquet beside it, the figure to *.png")
    p.add_argument("--budget-s", type=float, default=DEFAULT_BUDGET_S,
                   help="wall-clock budget of the job in seconds: the continuation and the "
                   "curves stop there, keep what they have and record status 'budget' "
                   f"(default {DEFAULT_BUDGET_S:g})")


def run(args: argparse.Namespace) -> int:
    from gearsim.analysis.bifcurves import follow_curves
    from gearsim.analysis.continuation import continue_orbit, write_branches
    from gearsim.analysis.continuation_options import Continuation
    from gearsim.analysis.exact_landmarks import bifurcation_points
    from gearsim.analysis.orbits import SEEDING, find_periodic_orbit
    from gearsim.results import parquet
    from gearsim.study import provenance as gprov

    study = study_from_args(args)
    kinds, xn, yn, x0, x1, y0, y1, at, step2, base = _plane_ranges(args, study)
    out = Path(args.out)
    stem = out.with_suffix("")
    outputs = [out, Path(f"{stem}_points.parquet"), Path(f"{stem}_branches.parquet"),
               out.with_suffix(".png")]
    check_outputs(outputs)  # before any computation
    deadline = time.monotonic() + args.budget_s
    params = base.with_(**{yn: at, xn: x0})
    started = parquet.now_iso()
    t0 = time.perf_counter()
    skip = _unusable_plane(args.cells) if args.cells else None
    if skip is not None:
        return _write_skipped(args, study, outputs, skip, started, at, yn)
    given = _given_points(args.points, params, xn, x0, x1) if args.points else None
    if given is not None:
        points, branches = given
        _log(f"seed: {len(points)} located points from {args.points} (same parameters)")
    else:
        from gearsim.cell.simulate import simulate_cell

        seed = simulate_cell(params, settings=SEEDING).final_state
        orbit = find_periodic_orbit(params, args.period, seed, grazing=False)
        cfg = Continuation(ds=0.02, ds_max=0.05, switch_depth=args.switch_depth,
                           max_points=600, progress=_log, deadline=deadline)
        branches = continue_orbit(params, xn, x0, x1, orbit, config=cfg)
        points = bifurcation_points(branches)
    t_branch = time.perf_counter() - t0
    curves = follow_curves(params, points, yn, (y0, y1), step2=step2, kinds=kinds,
                           config=Continuation(progress=_log, deadline=deadline),
                           workers=args.workers,
                           method=args.method, range1=(x0, x1),
                           max_period=args.max_period or None)
    wall = time.perf_counter() - t0
    status = ("budget" if "budget" in (branches.attrs.get("status"), curves.attrs.get("status"))
              else "ok")
    prov = gprov.provenance(
        gprov.plane_subtree(study, args.plane), kind="curves", name=args.plane, study=study,
        scope="analysis",
        started=started, finished=parquet.now_iso(), wall_s=wall, seed_value=at,
        branch_wall_s=t_branch, curve_wall_s=wall - t_branch, reasons=curves.attrs["reasons"],
        workers="in-process", status=status, budget_s=args.budget_s,
    )
    branches.attrs["provenance"] = prov
    write_branches(branches, Path(f"{stem}_branches.parquet"))
    points = points.assign(plane=args.plane, name2=yn, value2=at)
    parquet.write_parquet(points, Path(f"{stem}_points.parquet"),
                          {parquet.PROVENANCE_KEY: prov})
    curves = curves.assign(plane=args.plane)
    parquet.write_parquet(curves, out, {parquet.PROVENANCE_KEY: prov})
    import pandas as pd

    from gearsim.presentation.figures.style import save_figure
    from gearsim.presentation.orbit_plots import figure_curves

    cells = pd.read_parquet(args.cells) if args.cells else None
    fig = figure_curves(curves, cells, title=f"plane {args.plane}: bifurcation curves "
                        f"(continued from {yn} = {at:g})")
    save_figure(fig, out.with_suffix(".png"))
    _summary(args, out, points, branches, curves, t_branch, wall, status)
    return 0


def _plane_ranges(args: argparse.Namespace, study):
    """The checked ranges of the command: ``(kinds, xn, yn, x0, x1, y0, y1, at, step2, base)``
    (the plane's axes, its continuation range, the seed value of the second parameter, the
    curve step and the plane's base parameters)."""
    config = study.config
    check_plane(study, args.plane)
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
    base = study.parameters(plane=args.plane).model
    at = float(getattr(base, yn)) if args.at is None else args.at
    at = min(max(at, y0), y1)
    step2 = args.step2 if args.step2 is not None else (y1 - y0) / 10
    if args.max_period < 0:
        raise UsageError(f"--max-period = {args.max_period} must be >= 0 (0: all)")
    if not 0 < step2 <= (y1 - y0):
        raise UsageError(f"--step2 = {step2} must be in (0, {y1 - y0}]")
    if not 1 <= args.workers <= 64:
        raise UsageError(f"--workers = {args.workers} must be in [1, 64]")
    if not 0 < args.budget_s <= 7 * 86400:
        raise UsageError(f"--budget-s = {args.budget_s:g} must be in (0, 604800]")
    return kinds, xn, yn, x0, x1, y0, y1, at, step2, base


def _summary(args: argparse.Namespace, out: Path, points, branches, curves, t_branch: float,
             wall: float, status: str) -> None:
    """The command's closing lines on stderr: counts, times, stop reasons, the files written."""
    stem = out.with_suffix("")
    print(json.dumps({"plane": args.plane, "points": len(points), "curves":
                      int(curves["curve"].nunique()) if len(curves) else 0,
                      "curve_points": len(curves), "branch_wall_s": t_branch,
                      "curve_wall_s": wall - t_branch}), file=sys.stderr)
    for r in [*branches.attrs.get("reasons", []), *curves.attrs["reasons"]]:
        print(f"  {r}", file=sys.stderr)
    if status == "budget":
        print(f"plane {args.plane}: stopped at the budget of {args.budget_s:g} s "
              "(status budget); the curves are partial", file=sys.stderr)
    print(f"wrote {out}, {stem}_points.parquet, {stem}_branches.parquet and "
          f"{out.with_suffix('.png')}", file=sys.stderr)


def _unusable_plane(cells: str) -> str | None:
    """Why a plane's curves are not worth following (most cells diverged or stiff), or None."""
    import pandas as pd

    p = Path(cells)
    if not p.is_file():
        raise UsageError(f"--cells: file not found: {cells}")
    try:
        df = pd.read_parquet(p, columns=["status"])
    except Exception as exc:  # pyarrow: a foreign or damaged file
        cause = " ".join(str(exc).split()) or type(exc).__name__
        raise UsageError(f"--cells: {cells} is not a readable cells table ({cause})") from None
    if not len(df):
        return f"plane has no cells in {cells}"
    bad = df["status"].isin(["diverged", "budget"])
    frac = float(bad.mean())
    if frac > MAX_UNUSABLE:
        return (f"{int(bad.sum())} of {len(df)} cells diverged or out of their step budget "
                f"(more than {MAX_UNUSABLE:.0%}): no periodic orbits to follow")
    return None


def _write_skipped(args, study, outputs, why: str, started: str, at: float, yn: str) -> int:
    """Empty curve tables (status 'skipped', the reason in their provenance) and a figure
    saying why: the catalogue and the report then state it, the workflow goes on."""
    import pandas as pd

    from gearsim.analysis.bifcurves import CURVE_COLUMNS
    from gearsim.analysis.continuation import COLUMNS, write_branches
    from gearsim.analysis.exact_landmarks import POINT_COLUMNS
    from gearsim.presentation.figures.style import save_figure
    from gearsim.presentation.orbit_plots import figure_curves
    from gearsim.results import parquet
    from gearsim.study import provenance as gprov

    out, points_path, branches_path, png = outputs
    reason = f"curves skipped: {why}"
    prov = gprov.provenance(
        gprov.plane_subtree(study, args.plane), kind="curves", name=args.plane, study=study,
        scope="analysis", started=started, finished=parquet.now_iso(), wall_s=0.0,
        seed_value=at, reasons=[reason], workers="in-process", status="skipped",
        budget_s=args.budget_s,
    )
    branches = pd.DataFrame(columns=list(COLUMNS))
    branches.attrs.update(provenance=prov, reasons=[reason], status="skipped")
    write_branches(branches, branches_path)
    points = pd.DataFrame(columns=list(POINT_COLUMNS)).assign(plane=args.plane, name2=yn, value2=at)
    parquet.write_parquet(points, points_path, {parquet.PROVENANCE_KEY: prov})
    curves = pd.DataFrame(columns=list(CURVE_COLUMNS)).assign(plane=args.plane)
    parquet.write_parquet(curves, out, {parquet.PROVENANCE_KEY: prov})
    import textwrap

    from gearsim.presentation.orbit_plots import param_label

    fig = figure_curves(curves, pd.read_parquet(args.cells),
                        title="\n".join(textwrap.wrap(f"plane {args.plane}: {reason}", 80)))
    pl = study.config["planes"][args.plane]
    fig.axes[0].set_xlabel(param_label(pl["x"]["name"]))
    fig.axes[0].set_ylabel(param_label(pl["y"]["name"]))
    save_figure(fig, png)
    print(f"plane {args.plane}: {reason}", file=sys.stderr)
    print(f"wrote {out}, {points_path}, {branches_path} and {png}", file=sys.stderr)
    return 0


def _given_points(path: str, params, xn: str, x0: float, x1: float):
    """``(points, branches)`` of a continuation file whose parameters are ``params`` (all but
    ``xn``), restricted to ``[x0, x1]``; None (with a note) when the parameters differ."""
    import pandas as pd

    from gearsim.analysis.continuation import COLUMNS
    from gearsim.results import parquet

    p = Path(path)
    if not p.is_file():
        raise UsageError(f"--points: file not found: {path}")
    meta = parquet.read_metadata(p, b"gearsim.analysis.continuation") or {}
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
