"""``gearsim simulate-tile``: simulate one tile of a plane (or the same tile of several planes
in one call) and write its Parquet file (the job: :mod:`gearsim.study.tile_job`)."""

from __future__ import annotations

import argparse
import sys

from gearsim.cli.commands._common import (
    add_config_arguments,
    add_device_argument,
    check_new_file,
    check_plane,
    select_device,
    study_from_args,
)
from gearsim.cli.commands._progress import Progress
from gearsim.results import parquet
from gearsim.results.in_place import check_hand_outputs
from gearsim.study import tile_job
from gearsim.study.cluster import MAX_WORKERS

NAME = "simulate-tile"
HELP = "simulate one tile (tile_rows rows of a plane) on a dask cluster and write its Parquet file"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plane", required=True, action="append",
                   help="plane name (a key of `planes:`); given again, the same tile index of "
                   "each plane in one call of the chain driver (on a GPU, both planes' chains in "
                   "one launch), one file per plane")
    p.add_argument("--tile", type=int, required=True, help="tile index (0-based)")
    add_config_arguments(p)
    add_device_argument(p)
    p.add_argument(
        "--workers",
        type=int,
        default=1,
        help=f"LocalCluster worker processes, 1..{MAX_WORKERS} (one thread each; 1 without a "
        "scheduler address: in this process, no dask)",
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        default=None,
        help="dask scheduler address (default: cluster.scheduler_address of the config)",
    )
    p.add_argument(
        "--no-cluster",
        action="store_true",
        help="run the rows in this process (no dask); the default with --workers 1 and no "
        "scheduler address",
    )
    p.add_argument(
        "--out",
        "-o",
        default=None,
        action="append",
        help="output Parquet file (default <results>/<plane>/tiles/<tile>.parquet, unless a "
        "run's tile is there); one per --plane, in their order",
    )
    p.add_argument("--replace", action="store_true",
                   help="replace a tile that a workflow run made (refused otherwise)")


def kept(args: argparse.Namespace) -> str:
    """What Ctrl-C keeps: a tile is written whole when its last row is done."""
    return "the tile was not written (a tile is written whole, when its last row is done)"


def _say(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def run(args: argparse.Namespace) -> int:
    study = study_from_args(args)
    for plane in args.plane:
        check_plane(study, plane)
    job = tile_job.plan(study, args.plane, args.tile, args.out)
    check_hand_outputs(job.outs, replace=args.replace, elsewhere="--out PATH")  # a run's tile
    for out in job.outs:
        check_new_file(out, need=0)  # not a folder, no file in the way (the folder not yet made)
    backend = select_device(args, study)
    where = tile_job.placement(job, backend, workers=args.workers, scheduler=args.scheduler,
                               no_cluster=args.no_cluster)
    if where.note:
        _say(where.note)
    for k, out in enumerate(job.outs):  # every argument checked; room before any simulation
        check_new_file(out, need=job.space(k))
    progress = Progress(job.label, job.total)
    tiles = tile_job.run(job, where, backend, progress=progress, say=_say)
    progress.close()
    for plane, out, (df, prov) in zip(job.planes, job.outs, tiles, strict=True):
        parquet.write_parquet(df, out, {parquet.PROVENANCE_KEY: prov})
        if len(job.planes) == 1:
            rate = len(df) / prov["wall_s"]
            _say(f"{job.label}: wrote {out} ({len(df)} cells in {prov['wall_s']:.1f} s, "
                 f"{rate:.2f} cells/s)")
        else:
            _say(f"{plane}/tile {args.tile}: wrote {out} ({len(df)} cells)")
    if len(job.planes) > 1:
        wall = tiles[0][1]["wall_s"]
        _say(f"{job.label}: {job.total} cells in {wall:.1f} s, {job.total / wall:.2f} cells/s")
    return 0
