"""``gearsim attractor-tile``: coexisting attractors of every cell of one plane tile."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from gearsim.cli.commands._common import (
    add_config_arguments,
    add_device_argument,
    check_plane,
    select_device,
    study_from_args,
)
from gearsim.cli.commands._progress import Progress

NAME = "attractor-tile"
HELP = (
    "find the coexisting attractors of every cell of one plane tile (the plane's "
    "`multistability: {starts, seed}`) and write results/<plane>/attractors/<tile>.parquet"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plane", required=True, help="plane name (a key of `planes:`)")
    p.add_argument("--tile", type=int, required=True, help="tile index (0-based)")
    p.add_argument("--tile-file", metavar="PARQUET", default=None,
                   help="the plane's simulated tile (forward-continuation states; default "
                   "results/<plane>/tiles/<tile>.parquet)")  # fmt: skip
    add_config_arguments(p)
    add_device_argument(p)
    p.add_argument("--workers", type=int, default=1,
                   help="LocalCluster worker processes (1 without a scheduler address: in this "
                   "process, no dask)")  # fmt: skip
    p.add_argument("--no-cluster", action="store_true", help="run in this process (no dask)")
    p.add_argument("--out", "-o", default=None,
                   help="output (default results/<plane>/attractors/<tile>.parquet)")


def run(args: argparse.Namespace) -> int:
    import pandas as pd

    from gearsim.results import parquet
    from gearsim.study import attractor_tiles as at
    from gearsim.study.preflight import check_output

    study = study_from_args(args)
    check_plane(study, args.plane)
    at.multistability(study, args.plane)  # one line when the plane has none
    tile_file = Path(args.tile_file or f"results/{args.plane}/tiles/{args.tile}.parquet")
    tile_df = pd.read_parquet(tile_file) if tile_file.exists() else None
    if tile_df is None:
        print(f"note: {tile_file} not found: no forward-continuation states", file=sys.stderr)
    specs = at.task_specs(study, args.plane, args.tile, tile_df)
    total = sum(len(s.cells) for s in specs)
    out = Path(args.out or f"results/{args.plane}/attractors/{args.tile}.parquet")
    check_output(out)  # writable, with room, before any simulation
    label = f"{args.plane}/attractor tile {args.tile}"
    progress = Progress(label, total)
    started, t0 = parquet.now_iso(), time.perf_counter()
    address = study.config["cluster"].get("scheduler_address")
    backend = select_device(args, study)  # a GPU's lane pools run in this process
    df, workers = at.run_tile_job(specs, progress=progress, workers=args.workers,
                                  address=address, backend=backend,
                                  in_process=args.no_cluster or (args.workers == 1
                                                                 and not address))  # fmt: skip
    progress.close()
    wall = time.perf_counter() - t0
    prov = at.tile_provenance(study, args.plane, args.tile, cells=total,
                              forward_states=tile_df is not None, workers=workers,
                              started=started, finished=parquet.now_iso(), wall_s=wall,
                              device=backend.record())
    parquet.write_parquet(df, out, {parquet.PROVENANCE_KEY: prov})
    print(f"{label}: wrote {out} ({total} cells, {len(df)} attractor rows in {wall:.1f} s)",
          file=sys.stderr, flush=True)  # fmt: skip
    return 0
