"""``gearsim refine-orbits``: Newton refinement and multipliers of a plane's periodic cells."""

from __future__ import annotations

import argparse
import sys
import time

from gearsim.cli.commands._common import add_config_arguments, check_plane, study_from_args
from gearsim.errors import UsageError

NAME = "refine-orbits"
HELP = (
    "refine every periodic cell of a plane by Newton shooting: largest Floquet multiplier, its "
    "kind, grazing margin, and a flag where the refinement disagrees with the simulation"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plane", required=True, help="plane name in the config")
    p.add_argument("--cells", required=True, help="the plane's cells.parquet")
    add_config_arguments(p)
    p.add_argument("--rtol", type=float, default=None,
                   help="DP5 relative tolerance of the shooting integrator (default 1e-12)")
    p.add_argument("--limit", type=int, default=None, help="refine only the first N cells")
    p.add_argument("--out", "-o", required=True,
                   help="output Parquet (results/PLANE/orbits.parquet)")


def run(args: argparse.Namespace) -> int:
    import pandas as pd

    from gearsim.analysis.orbit_cells import refine_cells
    from gearsim.analysis.orbits import shooting_settings
    from gearsim.cli.commands._progress import Progress
    from gearsim.results import parquet
    from gearsim.study import provenance as gprov

    study = study_from_args(args)
    config = study.config
    check_plane(study, args.plane)
    if args.limit is not None and args.limit < 1:
        raise UsageError(f"--limit = {args.limit} must be >= 1")
    if args.rtol is not None and not 0 < args.rtol < 1e-3:
        raise UsageError(f"--rtol = {args.rtol} must be in (0, 1e-3)")
    cells = pd.read_parquet(args.cells)
    for col in ("i", "j", "x", "y", "n", "status", "label", "final_state"):
        if col not in cells.columns:
            raise UsageError(f"{args.cells}: column '{col}' missing (not a plane's cells.parquet)")
    base = study.parameters(plane=args.plane).model
    pl = config["planes"][args.plane]
    st = shooting_settings(args.rtol)
    from gearsim.study.preflight import check_output

    check_output(args.out)  # writable, with room, before any Newton solve
    started = parquet.now_iso()
    t0 = time.perf_counter()
    todo = int(((cells["n"] >= 1) & (cells["status"] != "diverged")).sum())
    progress = Progress(f"refine-orbits {args.plane}", max(1, min(todo, args.limit or todo)))
    df = refine_cells(cells, base, pl["x"]["name"], pl["y"]["name"], st, progress=progress,
                      limit=args.limit)
    progress.close()
    wall = time.perf_counter() - t0
    prov = gprov.provenance(
        gprov.plane_subtree(study, args.plane), kind="orbits", name=args.plane, study=study,
        scope="analysis",
        started=started, finished=parquet.now_iso(), wall_s=wall, cells=len(df),
        settings=st.to_dict(), workers="in-process",
    )
    parquet.write_parquet(df, args.out, {parquet.PROVENANCE_KEY: prov})
    flagged = df[df["orbit_flag"] != ""]
    ms = float(df["orbit_ms"].mean()) if len(df) else float("nan")
    sim_ms = float(cells["elapsed_s"].mean() * 1e3) if "elapsed_s" in cells else float("nan")
    print(
        f"refine-orbits {args.plane}: {len(df)} periodic cells of {len(cells)}, "
        f"{len(flagged)} flagged ({flagged['orbit_flag'].value_counts().to_dict()}), "
        f"{ms:.1f} ms per cell (simulated classification: {sim_ms:.1f} ms per cell), "
        f"{wall:.1f} s",
        file=sys.stderr,
    )
    return 0
