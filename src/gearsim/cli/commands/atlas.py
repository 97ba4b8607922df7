"""``gearsim atlas``: a plane's boundaries accounted for, its chaotic band and the paper's
mechanisms measured over the whole plane (docs/atlas.md)."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

from gearsim.cli.commands._common import add_config_arguments, check_plane, study_from_args
from gearsim.errors import UsageError
from gearsim.study.preflight import check_outputs, write_text_atomic

NAME = "atlas"
HELP = ("classify every boundary edge of a plane's pattern map by the located curve, fold band "
        "or chaotic band that explains it; measure the cascade's doubling ratios along one line")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plane", required=True, help="plane name in the config (e.g. wb, wxi)")
    add_config_arguments(p)
    p.add_argument("--cells", required=True, help="the plane's cells.parquet")
    p.add_argument("--curves", default=None,
                   help="the plane's curves (results/orbits/PLANE_curves.parquet)")
    p.add_argument("--line", type=float, default=None,
                   help="value of the plane's y parameter of the cascade's line (default: the "
                   "paper's sweep of it that runs into chaos, else the base value; the grid "
                   "is read on the nearest row with a cascade into chaos)")
    p.add_argument("--depth", type=int, default=4,
                   help="period doublings followed along the line (4: periods up to 16; 0: no "
                   "cascade)")
    p.add_argument("--no-newton", dest="newton", action="store_false",
                   help="do not read the unexplained periodic edges' cells by Newton (their "
                   "coexisting motions and refuted labels; docs/atlas.md)")
    p.add_argument("--out", "-o", required=True,
                   help="summary JSON (results/atlas/PLANE.json); the edges go to "
                   "*_edges.parquet beside it, the unexplained edges to *_unexplained.csv")


def _log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def run(args: argparse.Namespace) -> int:
    import pandas as pd

    from gearsim.analysis.atlas_summary import chaotic_band, default_line, plane_atlas
    from gearsim.analysis.boundaries import unexplained
    from gearsim.analysis.coexistence import NEWTON_RTOL, newton_edges
    from gearsim.analysis.orbits import shooting_settings
    from gearsim.results import parquet
    from gearsim.study import provenance as gprov

    study = study_from_args(args)
    check_plane(study, args.plane)
    if not 0 <= args.depth <= 6:
        raise UsageError(f"--depth = {args.depth} must be in [0, 6]")
    pl = study.config["planes"][args.plane]
    xn, yn = pl["x"]["name"], pl["y"]["name"]
    out = Path(args.out)
    stem = out.with_suffix("")
    outputs = [out, Path(f"{stem}_edges.parquet"), Path(f"{stem}_unexplained.csv")]
    check_outputs(outputs)
    for f in (args.cells, args.curves):
        if f and not Path(f).is_file():
            raise UsageError(f"{f}: no such file")
    started, t0 = parquet.now_iso(), time.perf_counter()
    cells = pd.read_parquet(args.cells)
    curves = pd.read_parquet(args.curves) if args.curves else None
    _log(f"plane {args.plane}: {len(cells)} cells, "
         f"{0 if curves is None else curves['curve'].nunique()} curves")
    base = study.parameters(plane=args.plane).model
    newton = None
    if args.newton and not {"final_state", xn, yn} <= set(cells.columns):
        _log(f"{args.cells}: no final_state, {xn} and {yn} columns: the unexplained edges "
             "are not read by Newton")
    elif args.newton:
        def newton(sub):
            return newton_edges(base, cells, sub, x_name=xn, y_name=yn,
                                settings=shooting_settings(NEWTON_RTOL), progress=_log)
    edges, summary = plane_atlas(cells, curves, plane=args.plane, x_name=xn, y_name=yn,
                                 newton=newton)
    _log(f"{len(edges)} boundary edges classified in {time.perf_counter() - t0:.1f} s")
    if args.depth:
        at = default_line(yn, getattr(base, yn)) if args.line is None else args.line
        summary["cascade"] = chaotic_band(cells, base, x_name=xn, y_name=yn, y_value=at,
                                          depth=args.depth, progress=_log)
    summary["wall_s"] = time.perf_counter() - t0
    prov = gprov.provenance(gprov.plane_subtree(study, args.plane), kind="atlas",
                            name=args.plane, study=study, scope="analysis", started=started,
                            finished=parquet.now_iso(), wall_s=summary["wall_s"])
    summary["provenance"] = prov
    parquet.write_parquet(edges, Path(f"{stem}_edges.parquet"), {parquet.PROVENANCE_KEY: prov})
    u = unexplained(edges, cells)
    write_text_atomic(Path(f"{stem}_unexplained.csv"), u.to_csv(index=False))
    write_text_atomic(out, json.dumps(_clean(summary), indent=1) + "\n")
    for k, (ok, n) in summary["explained"].items():
        _log(f"{k}: {ok} of {n} edges explained"
             + (f" ({100 * ok / n:.1f} %)" if n else ""))
    _log(f"wrote {out}, {stem}_edges.parquet, {stem}_unexplained.csv ({len(u)} unexplained)")
    return 0


def _clean(v):
    """JSON-ready: numpy scalars as Python's, NaN and infinities as null."""
    if isinstance(v, dict):
        return {str(k): _clean(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_clean(x) for x in v]
    if hasattr(v, "item"):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v
