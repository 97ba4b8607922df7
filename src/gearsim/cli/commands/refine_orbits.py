"""``gearsim refine-orbits``: Newton refinement and multipliers of a plane's periodic cells."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from gearsim.cli.commands._common import add_config_arguments, check_plane, study_from_args
from gearsim.errors import UsageError

NAME = "refine-orbits"
HELP = (
    "refine every periodic cell of a plane by Newton shooting: largest Floquet multiplier, its "
    "kind, grazing margin, and a flag where the refinement disagrees with the simulation"
)


#: Refined cells between two writes of the partial table (~10 s on one core at ~50 cells/s).
EVERY = 500


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


def partial_path(out: Path) -> Path:
    """Where a run keeps the cells refined so far (removed when the table is written)."""
    return out.with_name(out.name + ".partial")


def _inputs_key(cells, plane_subtree: dict, settings: dict, limit: int | None) -> str:
    """What a partial table must have been computed from to be resumed: the plane's
    configuration, the shooting settings, the limit, the cells' states and the code."""
    import hashlib

    import numpy as np

    from gearsim.study.provenance import code_version, config_hash

    h = hashlib.sha256()
    for col in ("i", "j", "n"):
        h.update(np.ascontiguousarray(cells[col].to_numpy(dtype=np.int64)).tobytes())
    h.update(np.ascontiguousarray(np.stack([np.asarray(v, dtype=float)
                                            for v in cells["final_state"]])).tobytes()
             if len(cells) else b"")
    return config_hash({"plane": plane_subtree, "settings": settings, "limit": limit,
                        "cells": h.hexdigest(), "code": code_version("analysis")})


def run(args: argparse.Namespace) -> int:
    import pandas as pd

    from gearsim.analysis.orbit_cells import periodic_cells, refine_cells
    from gearsim.analysis.orbits import shooting_settings
    from gearsim.cli.commands._progress import Progress, duration_text
    from gearsim.results import parquet
    from gearsim.study import provenance as gprov
    from gearsim.study.preflight import check_output

    study = study_from_args(args)
    config = study.config
    check_plane(study, args.plane)
    if args.limit is not None and args.limit < 1:
        raise UsageError(f"--limit = {args.limit} must be >= 1")
    if args.every < 0:
        raise UsageError(f"--every = {args.every} must be >= 0 (0: no partial table)")
    if args.rtol is not None and not 0 < args.rtol < 1e-3:
        raise UsageError(f"--rtol = {args.rtol} must be in (0, 1e-3)")
    cells = pd.read_parquet(args.cells)
    for col in ("i", "j", "x", "y", "n", "status", "label", "final_state"):
        if col not in cells.columns:
            raise UsageError(f"{args.cells}: column '{col}' missing (not a plane's cells.parquet)")
    out = Path(args.out or f"{args.plane}_orbits.parquet")
    base = study.parameters(plane=args.plane).model
    pl = config["planes"][args.plane]
    st = shooting_settings(args.rtol)
    check_output(out)  # writable, with room, before any Newton solve
    subtree = gprov.plane_subtree(study, args.plane)
    todo = periodic_cells(cells, args.limit)
    key = _inputs_key(todo, subtree, st.to_dict(), args.limit)
    partial = partial_path(out)
    done = _resumable(partial, key)
    if done is not None:
        print(f"refine-orbits {args.plane}: resuming from {partial} ({len(done)} of {len(todo)} "
              "cells refined before)", file=sys.stderr)
    meta = {parquet.PROVENANCE_KEY: {"kind": "orbits-partial", "inputs": key}}
    started = parquet.now_iso()
    t0 = time.perf_counter()
    start = 0 if done is None else len(done)
    progress = Progress(f"refine-orbits {args.plane}", max(1, len(todo)), start=start)
    print(f"refine-orbits {args.plane}: {len(todo)} periodic cells of {len(cells)} to {out} "
          f"(partial table every {args.every} cells: {partial})", file=sys.stderr)
    df = refine_cells(cells, base, pl["x"]["name"], pl["y"]["name"], st, progress=progress,
                      limit=args.limit, done=done, every=args.every,
                      checkpoint=lambda t: parquet.write_parquet(t, partial, meta))
    progress.close()
    wall = time.perf_counter() - t0
    prov = gprov.provenance(
        subtree, kind="orbits", name=args.plane, study=study, scope="analysis",
        started=started, finished=parquet.now_iso(), wall_s=wall, cells=len(df),
        settings=st.to_dict(), workers="in-process", resumed=start,
    )
    parquet.write_parquet(df, out, {parquet.PROVENANCE_KEY: prov})
    partial.unlink(missing_ok=True)
    flagged = df[df["orbit_flag"] != ""]
    ms = float(df["orbit_ms"].mean()) if len(df) else float("nan")
    sim_ms = float(cells["elapsed_s"].mean() * 1e3) if "elapsed_s" in cells else float("nan")
    print(
        f"refine-orbits {args.plane}: wrote {out}: {len(df)} periodic cells of {len(cells)}, "
        f"{len(flagged)} flagged ({flagged['orbit_flag'].value_counts().to_dict()}), "
        f"{ms:.1f} ms per cell (simulated classification: {sim_ms:.1f} ms per cell), "
        f"{duration_text(wall)}",
        file=sys.stderr,
    )
    return 0


def _resumable(partial: Path, key: str):
    """The rows of ``partial`` when it was computed from the same inputs (``key``), else None
    (a partial table of other inputs is replaced, and the run says so)."""
    if not partial.is_file():
        return None
    from gearsim.results import parquet

    try:
        meta = parquet.read_metadata(partial) or {}
        if meta.get("inputs") == key:
            import pandas as pd

            return pd.read_parquet(partial)
    except Exception as exc:  # noqa: BLE001 - a damaged partial table is recomputed
        print(f"refine-orbits: {partial} unreadable ({type(exc).__name__}): starting afresh",
              file=sys.stderr)
        return None
    print(f"refine-orbits: {partial} holds cells of other inputs: starting afresh",
          file=sys.stderr)
    return None
