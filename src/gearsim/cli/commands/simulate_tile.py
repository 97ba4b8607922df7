"""``gearsim simulate-tile``: simulate one tile of a plane and write its Parquet file."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from gearsim.cli.commands._common import (
    add_config_arguments,
    add_device_argument,
    check_new_file,
    check_plane,
    select_device,
    study_from_args,
)
from gearsim.cli.commands._progress import Progress
from gearsim.errors import UsageError
from gearsim.results import parquet
from gearsim.study import provenance, tiles
from gearsim.study.cluster import MAX_WORKERS, check_address, check_workers, describe, open_client
from gearsim.study.config import results_dir
from gearsim.study.grid import tile_rows

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
        help="output Parquet file (default <results>/<plane>/tiles/<tile>.parquet); one per "
        "--plane, in their order",
    )


def run(args: argparse.Namespace) -> int:
    if len(args.plane) > 1:
        return _run_planes(args)
    args.plane = args.plane[0]
    if args.out is not None and len(args.out) != 1:
        raise UsageError("--out: one file per --plane")
    args.out = args.out[0] if args.out else None
    study = study_from_args(args)
    config = study.config
    check_plane(study, args.plane)
    rows = tile_rows(config, args.plane, args.tile)
    out = Path(args.out or results_dir(config) / args.plane / "tiles" / f"{args.tile}.parquet")
    check_new_file(out, need=0)  # not a folder, no file in the way (the folder not yet made)
    nx = int(config["planes"][args.plane]["x"]["n"])
    label = f"{args.plane}/tile {args.tile}"
    progress = Progress(label, nx * len(rows))
    address = args.scheduler or config["cluster"].get("scheduler_address")
    # one worker and no scheduler: this process is the worker (a LocalCluster would only add
    # its start-up, ~3-7 s per job: two processes importing gearsim and loading the kernels)
    in_process = args.no_cluster or (args.workers == 1 and not address)
    if not in_process:
        if address:
            check_address(address)
        else:
            check_workers(args.workers)
    if select_device(args, study).kind == "cuda" and not in_process:
        # the GPU takes every row of the tile in one lanes object: no dask workers
        print(f"{args.plane}/tile {args.tile}: on the GPU, in this process (--workers and the "
              "scheduler address are not used)", file=sys.stderr, flush=True)
        in_process = True
    # every argument checked; before any simulation: the folder is writable and has room for
    # the tile and its temporary copy (~350 bytes per cell; 1 kB per cell leaves a margin)
    check_new_file(out, need=2 * 1024 * nx * len(rows) + (64 << 10))
    started = parquet.now_iso()
    t0 = time.perf_counter()
    banner = f"{label}: rows {rows.start}..{rows.stop - 1} x {nx} cells"
    if in_process:
        workers = "in-process"
        print(f"{banner}, {workers}", file=sys.stderr, flush=True)
        df = tiles.run_tile(study, args.plane, args.tile, client=None, progress=progress)
    else:
        # connect first: a bad scheduler address is then the only line on stderr
        with open_client(args.workers, address) as client:
            workers = describe(client)
            print(f"{banner} on {workers}", file=sys.stderr, flush=True)
            df = tiles.run_tile(study, args.plane, args.tile, client=client, progress=progress)
    progress.close()
    wall = time.perf_counter() - t0
    prov = provenance.provenance(
        provenance.plane_subtree(study, args.plane),
        kind="tile",
        name=args.plane,
        study=study,
        tile=args.tile,
        rows=[rows.start, rows.stop],
        workers=workers,
        started=started,
        finished=parquet.now_iso(),
        wall_s=wall,
        cells=len(df),
    )
    parquet.write_parquet(df, out, {parquet.PROVENANCE_KEY: prov})
    print(
        f"{label}: wrote {out} ({len(df)} cells in {wall:.1f} s, {len(df) / wall:.2f} cells/s)",
        file=sys.stderr,
        flush=True,
    )
    return 0


def _run_planes(args: argparse.Namespace) -> int:
    """Tile ``--tile`` of every ``--plane`` in one call of the chain driver, in this process;
    the files are written once every cell is done (one per plane, each with its provenance)."""
    study = study_from_args(args)
    config = study.config
    planes = list(args.plane)
    if len(set(planes)) != len(planes):
        raise UsageError(f"--plane: {', '.join(planes)} names a plane twice")
    for plane in planes:
        check_plane(study, plane)
    if args.out is not None and len(args.out) != len(planes):
        raise UsageError(f"--out: one file per --plane ({len(planes)}), got {len(args.out)}")
    outs = [Path(o) for o in args.out] if args.out else [
        results_dir(config) / plane / "tiles" / f"{args.tile}.parquet" for plane in planes]
    rows = {}
    for plane, out in zip(planes, outs, strict=True):
        rows[plane] = tile_rows(config, plane, args.tile)
        nx = int(config["planes"][plane]["x"]["n"])
        check_new_file(out, need=2 * 1024 * nx * len(rows[plane]) + (64 << 10))
    dev = select_device(args, study)
    label = f"{'+'.join(planes)}/tile {args.tile}"
    total = sum(int(config["planes"][p]["x"]["n"]) * len(rows[p]) for p in planes)
    progress = Progress(label, total)
    print(f"{label}: {total} cells of {len(planes)} planes in one call, in-process "
          f"({dev.kind})", file=sys.stderr, flush=True)
    started = parquet.now_iso()
    t0 = time.perf_counter()
    frames = tiles.run_tiles(study, [(p, args.tile) for p in planes], progress=progress)
    progress.close()
    wall = time.perf_counter() - t0
    finished = parquet.now_iso()
    for plane, out, df in zip(planes, outs, frames, strict=True):
        prov = provenance.provenance(
            provenance.plane_subtree(study, plane), kind="tile", name=plane, study=study,
            tile=args.tile, rows=[rows[plane].start, rows[plane].stop],
            workers=f"in-process, one call with {label}", started=started, finished=finished,
            wall_s=wall, cells=len(df),
        )
        parquet.write_parquet(df, out, {parquet.PROVENANCE_KEY: prov})
        print(f"{plane}/tile {args.tile}: wrote {out} ({len(df)} cells)", file=sys.stderr,
              flush=True)
    print(f"{label}: {total} cells in {wall:.1f} s, {total / wall:.2f} cells/s",
          file=sys.stderr, flush=True)
    return 0
