"""``gearsim refine-orbits``: Newton refinement and multipliers of a plane's periodic cells (the
job, resumable from its partial table: :mod:`gearsim.study.orbit_refinement`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from gearsim.cli.commands._common import add_config_arguments, check_plane, study_from_args
from gearsim.study.orbit_refinement import EVERY

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
    p.add_argument("--limit", type=int, default=None,
                   help="refine only the first N periodic cells (a whole 400 x 400 plane: "
                   "~150 000 cells, ~50 min on one core)")
    p.add_argument("--every", type=int, default=EVERY,
                   help=f"write the cells refined so far to OUT.partial every N cells (default "
                   f"{EVERY}); a run started again with the same inputs resumes from it")
    p.add_argument("--out", "-o", default=None,
                   help="output Parquet (default: PLANE_orbits.parquet in the working directory; "
                   "the pipeline writes results/PLANE/orbits.parquet)")
    p.add_argument("--replace", action="store_true",
                   help="replace a table that a workflow run made (refused otherwise)")


def _out(args: argparse.Namespace) -> Path:
    return Path(args.out or f"{args.plane}_orbits.parquet")


def kept(args: argparse.Namespace) -> str:
    """What Ctrl-C keeps: the partial table of the last checkpoint (--every)."""
    from gearsim.results.in_place import partial_kept
    from gearsim.study.orbit_refinement import partial_path

    return partial_kept(partial_path(_out(args)), "cells refined")


def run(args: argparse.Namespace) -> int:
    import pandas as pd

    from gearsim.cli.commands._progress import Progress, duration_text
    from gearsim.results import parquet
    from gearsim.results.in_place import check_hand_outputs
    from gearsim.study import orbit_refinement as ref
    from gearsim.study.preflight import check_output

    study = study_from_args(args)
    check_plane(study, args.plane)
    cells = pd.read_parquet(args.cells)
    job = ref.plan(study, args.plane, cells, cells_path=args.cells, rtol=args.rtol,
                   limit=args.limit, every=args.every)
    out = _out(args)
    check_hand_outputs([out], replace=args.replace, elsewhere="--out PATH")  # a run's table
    check_output(out)  # writable, with room, before any Newton solve
    partial = ref.partial_path(out)
    done, why = parquet.read_partial(partial, job.key)
    if why:
        print(f"refine-orbits: {why}", file=sys.stderr)
    if done is not None:
        print(f"refine-orbits {args.plane}: resuming from {partial} ({len(done)} of "
              f"{len(job.todo)} cells refined before)", file=sys.stderr)
    start = 0 if done is None else len(done)
    progress = Progress(f"refine-orbits {args.plane}", max(1, len(job.todo)), start=start)
    print(f"refine-orbits {args.plane}: {len(job.todo)} periodic cells of {len(cells)} to {out} "
          f"(partial table every {args.every} cells: {partial})", file=sys.stderr)
    meta = {parquet.PROVENANCE_KEY: job.partial_metadata}
    df, prov = ref.refine(job, done=done, every=args.every, progress=progress,
                          checkpoint=lambda t: parquet.write_parquet(t, partial, meta))
    progress.close()
    parquet.write_parquet(df, out, {parquet.PROVENANCE_KEY: prov})
    partial.unlink(missing_ok=True)
    flagged = df[df["orbit_flag"] != ""]
    ms = float(df["orbit_ms"].mean()) if len(df) else float("nan")
    sim_ms = float(cells["elapsed_s"].mean() * 1e3) if "elapsed_s" in cells else float("nan")
    print(
        f"refine-orbits {args.plane}: wrote {out}: {len(df)} periodic cells of {len(cells)}, "
        f"{len(flagged)} flagged ({flagged['orbit_flag'].value_counts().to_dict()}), "
        f"{ms:.1f} ms per cell (simulated classification: {sim_ms:.1f} ms per cell), "
        f"{duration_text(prov['wall_s'])}",
        file=sys.stderr,
    )
    return 0
