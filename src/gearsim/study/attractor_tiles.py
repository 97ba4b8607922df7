"""Running an attractor tile: the coexisting attractors of every cell of one plane tile
(the plane's ``multistability: {starts, seed, every}``), in-process or on dask, and its records.

The plane tile's simulated rows (:mod:`gearsim.study.tiles`) give every cell its forward
continuation state and its classified motion (a known attractor at no cost); the cells are
cut into tasks of :data:`CELLS_PER_TASK` whose starts share one lane pool
(:func:`gearsim.analysis.attractors.find_attractors`). One record per attractor of a cell
(:data:`TILE_COLUMNS`); a cell whose starts all diverged gets one record, ``attractor = -1``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from gearsim.analysis.attractors.api import find_attractors, grid_neighbours
from gearsim.analysis.attractors.gear import plain_value, steady_from_row
from gearsim.analysis.attractors.options import FinderOptions
from gearsim.analysis.attractors.results import CellAttractors, n_real
from gearsim.cell.simulate import IntegrationSettings
from gearsim.dynamics.parameters import ModelParameters
from gearsim.errors import UsageError
from gearsim.study.cluster import describe, map_unordered, open_client
from gearsim.study.config import Study
from gearsim.study.grid import tile_rows
from gearsim.study.provenance import plane_subtree, provenance
from gearsim.study.tiles import row_specs

#: Columns of a plane's attractor tile (results/<plane>/attractors/<tile>.parquet).
TILE_COLUMNS = ("plane", "tile", "i", "j", "x", "y", "attractor", "n_attractors", "motion",
                "status", "label", "label_npq", "I", "n", "p", "q", "dc", "kmax", "lyapunov",
                "basin_fraction", "n_starts", "n_early", "found_by", "starts",
                "diverged_fraction", "periods_run", "poincare_x", "poincare_v", "mu_max",
                "critical", "refined")  # fmt: skip

#: cells per task (their starts share one lane pool: large enough that lanes stay busy)
CELLS_PER_TASK = 640


def multistability(study: Study, plane: str) -> Mapping[str, Any]:
    """The plane's ``multistability`` settings; one line when the plane has none."""
    ms = study.config["planes"][plane].get("multistability")
    if not ms:
        raise UsageError(f"plane '{plane}' has no 'multistability' (starts, seed) set")
    return ms


#: a task's cell: ``(i, j, x, y, forward-continuation state or None)``
Cell = tuple[int, int, float, float, list[float] | None]


@dataclass(frozen=True)
class AttractorTask:
    """The cells of one attractor-search task (a dask task of :func:`cell_group_records`), the
    plane's parameters and the study's settings as the frozen objects they are, the finder's
    starts and seed, and per cell the tile's row of it (a known forward motion) or None.
    ``stats``: a :class:`gearsim.cell.pool.PoolStats` collecting the lane use, or None."""

    plane: str
    tile: int
    params: ModelParameters
    settings: IntegrationSettings
    x_name: str
    y_name: str
    cells: tuple[Cell, ...]
    starts: int
    seed: int
    forward_rows: tuple[Mapping[str, Any] | None, ...] | None = None
    stats: Any = None


def task_specs(study: Study, plane: str, tile: int, tile_df: pd.DataFrame | None
               ) -> list[AttractorTask]:
    """The tasks of :func:`cell_group_records` for one tile (each cell with its
    forward-continuation state and the tile's row of it: a known motion)."""
    ms = multistability(study, plane)
    rows = row_specs(study, plane, tile)
    fwd: dict = {}
    known: dict = {}
    if tile_df is not None:
        for rec in tile_df.to_dict("records"):
            s = rec.get("final_state")
            key = (int(rec["i"]), int(rec["j"]))
            fwd[key] = None if s is None else [float(v) for v in s]
            if "poincare_x" in rec:
                known[key] = {k: plain_value(v) for k, v in rec.items()}
    every = int(ms.get("every", 1))
    cells = [
        (i, r.j, float(x), float(r.y_value), fwd.get((i, r.j)))
        for r in rows
        if r.j % every == 0
        for i, x in enumerate(r.x_values)
        if i % every == 0
    ]
    return [
        AttractorTask(plane, tile, rows[0].params, rows[0].settings, rows[0].x_name,
                      rows[0].y_name, tuple(cells[k : k + CELLS_PER_TASK]), int(ms["starts"]),
                      int(ms.get("seed", 0)),
                      tuple(known.get((c[0], c[1])) for c in cells[k : k + CELLS_PER_TASK]))
        for k in range(0, len(cells), CELLS_PER_TASK)
    ]


def tile_records(spec: AttractorTask, cells, found: Sequence[CellAttractors]
                 ) -> list[dict[str, Any]]:
    """The attractor-tile records (:data:`TILE_COLUMNS`) of ``cells`` and their attractors."""
    out: list[dict[str, Any]] = []
    for (i, j, x, y, _), ca in zip(cells, found, strict=True):
        common = {
            "plane": spec.plane, "tile": int(spec.tile), "i": int(i), "j": int(j),
            "x": float(x), "y": float(y), "n_attractors": n_real(ca),
            "starts": int(ca.n_starts), "diverged_fraction": ca.diverged_fraction,
            "periods_run": int(ca.start_periods_run.sum()),
        }  # fmt: skip
        if not ca.attractors:
            out.append({**common, "attractor": -1, "motion": "diverged", "status": "diverged",
                        "label": "diverged", "label_npq": "", "I": 0, "n": 0, "p": None,
                        "q": None, "dc": float("nan"), "kmax": float("nan"),
                        "lyapunov": float("nan"), "basin_fraction": 0.0, "n_starts": 0,
                        "n_early": 0, "found_by": "", "poincare_x": [],
                        "poincare_v": [], "mu_max": float("nan"), "critical": "",
                        "refined": False})  # fmt: skip
            continue
        for a in ca.attractors:
            r = a.record()
            out.append({**common, **{k: r.get(k) for k in TILE_COLUMNS if k in r}})
    return out




def cell_group_records(spec: AttractorTask, backend=None) -> list[dict[str, Any]]:
    """Attractor records of a group of plane cells (one task of ``gearsim attractor-tile``):
    one record per attractor of each cell; a cell whose starts all diverged gets one record
    with ``attractor = -1`` and label ``diverged``. A cell with its tile row (``forward_rows``)
    has its forward motion known without a run. ``backend``: where the starts' lanes run
    (None: the CPU).
    """
    base, settings = spec.params, spec.settings
    xn, yn = spec.x_name, spec.y_name
    cells = spec.cells
    plist = [base.with_(**{xn: float(c[2]), yn: float(c[3])}) for c in cells]
    fwd = [None if c[4] is None else np.asarray(c[4], dtype=float) for c in cells]
    rows = spec.forward_rows
    known = None if rows is None else [None if r is None else steady_from_row(r, p.w)
                                       for r, p in zip(rows, plist, strict=True)]
    options = FinderOptions(starts=int(spec.starts), seed=int(spec.seed))
    found = find_attractors(plist, options, settings=settings, forward=fwd,
                            forward_results=known, stats=spec.stats,
                            neighbours=grid_neighbours([(c[0], c[1]) for c in cells]),
                            backend=backend)  # fmt: skip
    return tile_records(spec, cells, found)


def records_to_frame(records: list[dict[str, Any]]) -> pd.DataFrame:
    """Attractor records -> DataFrame with stable dtypes (same schema for every tile), sorted
    by row, cell and attractor."""
    df = pd.DataFrame.from_records(records, columns=list(TILE_COLUMNS))
    for c in ("p", "q"):
        df[c] = pd.array([None if v is None or v != v else int(v) for v in df[c]], dtype="Int64")
    return df.sort_values(["j", "i", "attractor"], kind="stable").reset_index(drop=True)


def run_attractor_tile(
    specs: Sequence[AttractorTask],
    *,
    client=None,
    progress: Callable[[int, int, float], None] | None = None,
    backend=None,
) -> pd.DataFrame:
    """The attractor records of the tasks ``specs`` (:func:`task_specs`), mapped over
    ``client`` or in-process when None (the lanes on ``backend``); ``progress(done_cells,
    total_cells, elapsed_s)`` after each finished task."""
    total = sum(len(s.cells) for s in specs)
    t0 = time.perf_counter()
    records: list[dict] = []
    done = 0
    results = ((cell_group_records(s, backend) for s in specs) if client is None
               else map_unordered(client, cell_group_records, specs))  # fmt: skip
    for recs in results:
        records.extend(recs)
        done += len({(r["i"], r["j"]) for r in recs})
        if progress:
            progress(done, total, time.perf_counter() - t0)
    return records_to_frame(records)


def run_tile_job(specs: Sequence[AttractorTask], *, in_process: bool, workers: int = 1,
                 address: str | None = None,
                 progress: Callable[[int, int, float], None] | None = None, backend=None
                 ) -> tuple[pd.DataFrame, str]:
    """:func:`run_attractor_tile` in this process (its lanes on ``backend``, None: the CPU; a
    backend that takes a job in one lanes object always runs here) or on a dask cluster
    (``workers`` local processes, or the scheduler at ``address``); also where it ran, in
    words."""
    if in_process or (backend is not None and backend.one_lanes_object):
        return run_attractor_tile(specs, progress=progress, backend=backend), "in-process"
    with open_client(workers, address) as client:
        return run_attractor_tile(specs, client=client, progress=progress), describe(client)


def tile_provenance(study: Study, plane: str, tile: int, *, cells: int, forward_states: bool,
                    **run: Any) -> dict[str, Any]:
    """The provenance of an attractor tile: the plane's subtree, the tile's rows, the plane's
    ``multistability`` settings, and ``run`` (workers, start, end, wall)."""
    ms = multistability(study, plane)
    rows = tile_rows(study.config, plane, tile)
    return provenance(plane_subtree(study, plane), kind="attractors", name=plane,
                      scope="analysis", study=study, tile=tile, rows=[rows.start, rows.stop],
                      cells=cells, starts=int(ms["starts"]), seed=int(ms.get("seed", 0)),
                      every=int(ms.get("every", 1)), forward_states=forward_states, **run)
