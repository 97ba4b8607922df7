"""``gearsim attractor-tile``: coexisting attractors of every cell of one plane tile."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from gearsim.cli.commands._common import add_config_arguments, study_from_args
from gearsim.cli.commands._progress import Progress
from gearsim.errors import UsageError

NAME = "attractor-tile"
HELP = (
    "find the coexisting attractors of every cell of one plane tile (the plane's "
    "`multistability: {starts, seed}`) and write results/<plane>/attractors/<tile>.parquet"
)

#: cells per task (their starts share one lane pool: large enough that lanes stay busy)
CELLS_PER_TASK = 640


def _plain(v):
    """A tile value as plain data (lists for arrays, None for missing)."""
    import numpy as np
    import pandas as pd

    if isinstance(v, np.ndarray):
        return v.tolist()
    if v is None or v is pd.NA:
        return None
    return v.item() if isinstance(v, np.generic) else v


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plane", required=True, help="plane name (a key of `planes:`)")
    p.add_argument("--tile", type=int, required=True, help="tile index (0-based)")
    p.add_argument("--tile-file", metavar="PARQUET", default=None,
                   help="the plane's simulated tile (forward-continuation states; default "
                   "results/<plane>/tiles/<tile>.parquet)")  # fmt: skip
    add_config_arguments(p)
    p.add_argument("--workers", type=int, default=1,
                   help="LocalCluster worker processes (1 without a scheduler address: in this "
                   "process, no dask)")  # fmt: skip
    p.add_argument("--no-cluster", action="store_true", help="run in this process (no dask)")
    p.add_argument("--out", "-o", default=None,
                   help="output (default results/<plane>/attractors/<tile>.parquet)")


def task_specs(study, plane: str, tile: int, tile_df) -> list[dict]:
    """Plain-data tasks of :func:`gearsim.analysis.attractors.cell_group_records` for one tile
    (each cell with its forward-continuation state and the tile's row of it: a known motion)."""
    from gearsim.study import tiles

    ms = study.config["planes"][plane]["multistability"]
    rows = tiles.row_specs(study, plane, tile)
    fwd: dict = {}
    known: dict = {}
    if tile_df is not None:
        for rec in tile_df.to_dict("records"):
            s = rec.get("final_state")
            key = (int(rec["i"]), int(rec["j"]))
            fwd[key] = None if s is None else [float(v) for v in s]
            if "poincare_x" in rec:
                known[key] = {k: _plain(v) for k, v in rec.items()}
    every = int(ms.get("every", 1))
    cells = [
        (i, r["j"], float(x), float(r["y_value"]), fwd.get((i, r["j"])))
        for r in rows
        if r["j"] % every == 0
        for i, x in enumerate(r["x_values"])
        if i % every == 0
    ]
    base = rows[0] if rows else {}
    return [
        {
            "plane": plane, "tile": tile, "params": base["params"],
            "settings": base["settings"], "x_name": base["x_name"], "y_name": base["y_name"],
            "cells": cells[k : k + CELLS_PER_TASK], "starts": int(ms["starts"]),
            "forward_rows": [known.get((c[0], c[1])) for c in cells[k : k + CELLS_PER_TASK]],
            "seed": int(ms.get("seed", 0)),
        }  # fmt: skip
        for k in range(0, len(cells), CELLS_PER_TASK)
    ]


def run(args: argparse.Namespace) -> int:
    import pandas as pd

    from gearsim.analysis.attractors import TILE_COLUMNS, cell_group_records
    from gearsim.results import parquet
    from gearsim.study import grid as ggrid
    from gearsim.study import provenance as gprov
    from gearsim.study.cluster import describe, map_unordered, open_client

    study = study_from_args(args)
    config = study.config
    if args.plane not in config["planes"]:
        raise UsageError(
            f"unknown plane '{args.plane}'; configured: {', '.join(config['planes']) or 'none'}"
        )
    if not config["planes"][args.plane].get("multistability"):
        raise UsageError(f"plane '{args.plane}' has no 'multistability' (starts, seed) set")
    rows = ggrid.tile_rows(config, args.plane, args.tile)
    tile_file = Path(args.tile_file or f"results/{args.plane}/tiles/{args.tile}.parquet")
    tile_df = None
    if tile_file.exists():
        tile_df = pd.read_parquet(tile_file)  # the forward motion of every cell: known
    else:
        print(f"note: {tile_file} not found: no forward-continuation states", file=sys.stderr)
    specs = task_specs(study, args.plane, args.tile, tile_df)
    total = sum(len(s["cells"]) for s in specs)
    out = Path(args.out or f"results/{args.plane}/attractors/{args.tile}.parquet")
    from gearsim.study.preflight import check_output

    check_output(out)  # writable, with room, before any simulation
    label = f"{args.plane}/attractor tile {args.tile}"
    progress = Progress(label, total)
    started = parquet.now_iso()
    t0 = time.perf_counter()
    records: list[dict] = []
    done = 0

    def collect(results):
        nonlocal done
        for recs in results:
            records.extend(recs)
            done += len({(r["i"], r["j"]) for r in recs})
            progress(done, total, time.perf_counter() - t0)

    address = config["cluster"].get("scheduler_address")
    if args.no_cluster or (args.workers == 1 and not address):
        workers = "in-process"
        collect(map(cell_group_records, specs))
    else:
        with open_client(args.workers, address) as client:
            workers = describe(client)
            collect(map_unordered(client, cell_group_records, specs))
    progress.close()
    wall = time.perf_counter() - t0
    df = pd.DataFrame.from_records(records, columns=list(TILE_COLUMNS))
    for c in ("p", "q"):
        df[c] = pd.array([None if v is None or v != v else int(v) for v in df[c]], dtype="Int64")
    df = df.sort_values(["j", "i", "attractor"], kind="stable").reset_index(drop=True)
    ms = config["planes"][args.plane]["multistability"]
    prov = gprov.provenance(
        gprov.plane_subtree(study, args.plane), kind="attractors", name=args.plane,
        scope="analysis",
        study=study, tile=args.tile, rows=[rows.start, rows.stop], workers=workers,
        started=started, finished=parquet.now_iso(), wall_s=wall, cells=total,
        starts=int(ms["starts"]), seed=int(ms.get("seed", 0)), every=int(ms.get("every", 1)),
        forward_states=tile_df is not None,
    )  # fmt: skip
    parquet.write_parquet(df, out, {parquet.PROVENANCE_KEY: prov})
    print(f"{label}: wrote {out} ({total} cells, {len(df)} attractor rows in {wall:.1f} s)",
          file=sys.stderr, flush=True)  # fmt: skip
    return 0
