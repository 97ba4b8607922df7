"""One plane-tile job (``gearsim simulate-tile``): which tiles, where their rows run, and each
tile's cells with their provenance.

A job is one tile of one plane, or the same tile of several planes in one call of the chain
driver (on a GPU, all their chains in one launch). It runs in this process (one worker and no
scheduler address, ``no_cluster``, or a GPU: the GPU takes every row in one lanes object), on a
LocalCluster of ``workers`` processes, or on the scheduler at ``address``. The rows are
:mod:`gearsim.study.tiles`'; the caller writes each frame with its provenance."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gearsim.errors import UsageError
from gearsim.study import provenance
from gearsim.study.config import Study, results_dir
from gearsim.study.grid import tile_rows

Say = Callable[[str], None]


@dataclass(frozen=True)
class TileJob:
    """The tile ``tile`` of each of ``planes``, written to ``outs`` (in the planes' order)."""

    study: Study
    planes: tuple[str, ...]
    tile: int
    outs: tuple[Path, ...]
    rows: tuple[range, ...]

    @property
    def label(self) -> str:
        return f"{'+'.join(self.planes)}/tile {self.tile}"

    def cells(self, k: int) -> int:
        return int(self.study.config["planes"][self.planes[k]]["x"]["n"]) * len(self.rows[k])

    @property
    def total(self) -> int:
        return sum(self.cells(k) for k in range(len(self.planes)))

    def space(self, k: int) -> int:
        """Bytes the tile file of plane ``k`` and its temporary copy need (~350 bytes per
        cell; 1 kB per cell leaves a margin)."""
        return 2 * 1024 * self.cells(k) + (64 << 10)


def plan(study: Study, planes: Sequence[str], tile: int, outs: Sequence[str] | None
         ) -> TileJob:
    """The job of ``tile`` of ``planes`` (each a plane of the study); ``outs``: one file per
    plane, default ``<results>/<plane>/tiles/<tile>.parquet``."""
    planes = tuple(planes)
    if len(set(planes)) != len(planes):
        raise UsageError(f"--plane: {', '.join(planes)} names a plane twice")
    if outs is not None and len(outs) != len(planes):
        if len(planes) == 1:
            raise UsageError("--out: one file per --plane")
        raise UsageError(f"--out: one file per --plane ({len(planes)}), got {len(outs)}")
    paths = tuple(Path(o) for o in outs) if outs else tuple(
        results_dir(study.config) / plane / "tiles" / f"{tile}.parquet" for plane in planes)
    rows = tuple(tile_rows(study.config, plane, tile) for plane in planes)
    return TileJob(study, planes, tile, paths, rows)


@dataclass(frozen=True)
class Placement:
    """Where a job's rows run: in this process, or on a LocalCluster of ``workers`` processes
    or the scheduler at ``address``; ``note``: a line saying why options were not used."""

    in_process: bool
    workers: int = 1
    address: str | None = None
    note: str = ""


def placement(job: TileJob, backend, *, workers: int = 1, scheduler: str | None = None,
              no_cluster: bool = False) -> Placement:
    """Where ``job`` runs with the lanes ``backend`` (:func:`gearsim.numerics.backend.select`);
    the address or worker count checked (one line) when a cluster is used. Several planes, and
    a backend that takes a job's rows in one lanes object (a GPU), run in this process."""
    from gearsim.study.cluster import check_address, check_workers

    address = scheduler or job.study.config["cluster"].get("scheduler_address")
    # one worker and no scheduler: this process is the worker (a LocalCluster would only add
    # its start-up, ~3-7 s per job: two processes importing gearsim and loading the kernels)
    in_process = no_cluster or len(job.planes) > 1 or (workers == 1 and not address)
    if in_process:
        return Placement(True)
    if address:
        check_address(address)
    else:
        check_workers(workers)
    if backend.one_lanes_object:
        return Placement(True, note=f"{job.label}: on the GPU, in this process "
                         "(--workers and the scheduler address are not used)")
    return Placement(False, workers, address)


def run(job: TileJob, where: Placement, backend, *,
        progress: Callable[[int, int, float], None] | None = None, say: Say = print
        ) -> list[tuple[Any, dict]]:
    """Every tile of ``job`` simulated: one ``(frame, provenance)`` per plane, in order (in this
    process the lanes run on ``backend``; a cluster's workers run theirs on their CPUs)."""
    import time

    from gearsim.study import tiles
    from gearsim.study.cluster import describe, open_client

    started, t0 = provenance.now_iso(), time.perf_counter()
    if len(job.planes) > 1:
        say(f"{job.label}: {job.total} cells of {len(job.planes)} planes in one call, "
            f"in-process ({backend.kind})")
        frames = tiles.run_tiles(job.study, [(p, job.tile) for p in job.planes],
                                 progress=progress, backend=backend)
        workers = f"in-process, one call with {job.label}"
    else:
        rows = job.rows[0]
        nx = int(job.study.config["planes"][job.planes[0]]["x"]["n"])
        banner = f"{job.label}: rows {rows.start}..{rows.stop - 1} x {nx} cells"
        if where.in_process:
            workers = "in-process"
            say(f"{banner}, {workers}")
            frames = [tiles.run_tile(job.study, job.planes[0], job.tile, client=None,
                                     progress=progress, backend=backend)]
        else:
            # connect first: a bad scheduler address is then the only line on stderr
            with open_client(where.workers, where.address) as client:
                workers = describe(client)
                say(f"{banner} on {workers}")
                frames = [tiles.run_tile(job.study, job.planes[0], job.tile, client=client,
                                         progress=progress)]
    wall = time.perf_counter() - t0
    finished = provenance.now_iso()
    return [(df, provenance.provenance(
        provenance.plane_subtree(job.study, plane), kind="tile", name=plane, study=job.study,
        tile=job.tile, rows=[rows.start, rows.stop], workers=workers, started=started,
        finished=finished, wall_s=wall, cells=len(df), device=backend.record(),
    )) for plane, rows, df in zip(job.planes, job.rows, frames, strict=True)]
