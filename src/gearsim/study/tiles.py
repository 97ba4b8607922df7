"""Running a tile: the rows of a plane simulated as continuation chains, in-process or on dask.

A *row* is one forward continuation chain along ``x`` at fixed ``y``
(:func:`gearsim.cell.sweep.continuation_chain`, or the batched RK4 kernel
:mod:`gearsim.numerics.batch` that
advances 8 rows per SIMD block). One Snakemake job simulates one tile; its rows are mapped over a
dask cluster (:mod:`gearsim.study.cluster`). The grids are :mod:`gearsim.study.grid`'s, the
parameters and
settings :mod:`gearsim.study.config`'s. This module holds no file output (Parquet and SQLite live in
:mod:`gearsim.results.catalogue`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import pandas as pd

from gearsim.cell.chains import simulate_rows
from gearsim.cell.simulate import IntegrationSettings
from gearsim.cell.sweep import continuation_chain
from gearsim.cell.verify import fill_margins
from gearsim.dynamics.parameters import ModelParameters
from gearsim.numerics.batch import LANES
from gearsim.study.cluster import map_unordered
from gearsim.study.config import Study
from gearsim.study.grid import axis_values, tile_rows

#: Integer columns that may be missing (None) in CellResult.row().
NULLABLE_INT = ("p", "q")


@dataclass(frozen=True)
class RowSpec:
    """One plane row of a tile (a dask task): the plane's parameters and the study's settings
    as the frozen objects they are (they pickle to the workers as they are), the ``x`` axis's
    values and the row's ``y``."""

    plane: str
    tile: int
    j: int
    params: ModelParameters
    settings: IntegrationSettings
    x_name: str
    x_values: tuple[float, ...]
    y_name: str
    y_value: float

    def cells(self) -> list[ModelParameters]:
        """The row's cells in increasing ``x``."""
        return [self.params.with_(**{self.x_name: x, self.y_name: self.y_value})
                for x in self.x_values]


def simulate_row(spec: RowSpec) -> list[dict[str, Any]]:
    """Simulate one plane row: a forward continuation chain along ``x`` at fixed ``y`` (the
    study's method one cell at a time, :func:`gearsim.cell.sweep.continuation_chain`). Returns
    one record per cell in increasing ``x``."""
    settings = spec.settings
    xs = list(spec.x_values)
    plist = spec.cells()
    stamps: list[float] = []
    t0 = time.perf_counter()
    results = continuation_chain(
        plist, settings=settings, on_cell=lambda i, r: stamps.append(time.perf_counter())
    )
    return cell_records(spec, xs, results, stamps, t0)


def cell_records(spec: RowSpec, xs, results, stamps, t0: float) -> list[dict[str, Any]]:
    """The tile records of one plane row: grid indices, both parameter values, the cell's
    classification row, Poincare samples, the continuation seed and the wall time per cell."""
    yname, yval = spec.y_name, float(spec.y_value)
    rows = []
    prev = t0
    for i, (x, res, t) in enumerate(zip(xs, results, stamps, strict=True)):
        x = float(x)
        row = {
            "plane": spec.plane,
            "tile": int(spec.tile),
            "i": i,
            "j": int(spec.j),
            "x": x,
            "y": yval,
            spec.x_name: x,
            yname: yval,
        }
        row.update(res.row())
        row["poincare_x"] = res.poincare[:, 0].tolist()
        row["poincare_v"] = res.poincare[:, 1].tolist()
        row["final_state"] = res.final_state.tolist()
        row["final_period"] = int(res.final_period)
        row["elapsed_s"] = t - prev
        prev = t
        rows.append(row)
    return rows


def simulate_rows_batched(specs: Sequence[RowSpec],
                          on_cell: Callable[[], None] | None = None,
                          backend=None) -> list[dict[str, Any]]:
    """Simulate several plane rows at once with the batched RK4 kernel (gearsim.numerics.batch).

    Same records as :func:`simulate_row` for every spec (one lane per row; the rows advance
    together, 8 per SIMD block). The integration is fixed-step RK4 at ``steps_per_period``.
    The specs may come from several planes (:func:`run_tiles`). ``on_cell()``: after each cell.
    ``backend``: where the lanes run (:func:`gearsim.numerics.backend.select`; None: the CPU).
    """
    settings = specs[0].settings
    chains = [spec.cells() for spec in specs]
    stamps: list[list[float]] = [[] for _ in specs]
    t0 = time.perf_counter()
    def done(r, i, res):
        stamps[r].append(time.perf_counter())
        if on_cell is not None:
            on_cell()

    results = simulate_rows(chains, settings=settings, on_cell=done, backend=backend)
    # the Floquet margins of the periodic cells, their monodromies in shared kernel calls
    fill_margins([r for row in results for r in row], settings, backend)
    rows = []
    for spec, res_row, st_row in zip(specs, results, stamps, strict=True):
        rows += cell_records(spec, spec.x_values, res_row, st_row, t0)
    return rows


def row_groups(specs: list[RowSpec], workers: int) -> list[list[RowSpec]]:
    """Split a tile's rows into one group per worker, in multiples of the SIMD block (8 rows)."""
    blocks = -(-len(specs) // LANES)
    n_groups = max(1, min(workers, blocks))
    # whole blocks per group: 80 rows on 8 workers are 5 groups of 16 (2 full blocks each), not
    # 8 groups of 10 (2 blocks each, one with 2 of 8 lanes busy): the same wall, less CPU
    size = LANES * max(1, -(-blocks // n_groups))
    return [specs[k : k + size] for k in range(0, len(specs), size)]


def row_specs(study: Study, plane: str, tile: int) -> list[RowSpec]:
    """The dask tasks of a tile: one spec per row."""
    pl = study.config["planes"][plane]
    base = study.parameters(plane=plane).model
    xs = tuple(float(x) for x in axis_values(pl["x"]))
    ys = axis_values(pl["y"])
    return [RowSpec(plane, tile, j, base, study.settings, pl["x"]["name"], xs, pl["y"]["name"],
                    float(ys[j]))
            for j in tile_rows(study.config, plane, tile)]


def records_to_frame(records: list[dict[str, Any]]) -> pd.DataFrame:
    """Cell records -> DataFrame with stable dtypes (same schema for every tile)."""
    df = pd.DataFrame.from_records(records)
    for c in NULLABLE_INT:
        if c in df:
            df[c] = pd.array(
                [
                    None if v is None or (isinstance(v, float) and math.isnan(v)) else int(v)
                    for v in df[c]
                ],
                dtype="Int64",
            )
    for c in ("I", "n", "window_periods", "periods", "steps", "final_period", "i", "j", "tile"):
        if c in df:
            df[c] = df[c].astype("int64")
    if "converged" in df:
        df["converged"] = df["converged"].astype(bool)
    return df


def run_tile(
    study: Study,
    plane: str,
    tile: int,
    *,
    client=None,
    progress: Callable[[int, int, float], None] | None = None,
    backend=None,
) -> pd.DataFrame:
    """Simulate all cells of a tile (rows mapped over ``client``, or in-process when None, its
    lanes on ``backend``: :func:`gearsim.numerics.backend.select`, None the CPU).

    ``progress(done_cells, total_cells, elapsed_s)`` is called after each finished row.
    """
    specs = row_specs(study, plane, tile)
    nx = int(study.config["planes"][plane]["x"]["n"])
    total = nx * len(specs)
    t0 = time.perf_counter()
    records: list[dict] = []
    done = 0
    if specs and study.settings.method.lanes:
        # fixed-step RK4: the batched kernel, rows advanced together (8 per SIMD block)
        workers = 1 if client is None else max(1, len(client.nthreads()))
        groups = row_groups(specs, workers)
        if client is None:
            results = (simulate_rows_batched(g, backend=backend) for g in groups)
        else:
            results = map_unordered(client, simulate_rows_batched, groups)
        for recs in results:
            records += recs
            done += len(recs)
            if progress:
                progress(done, total, time.perf_counter() - t0)
    elif client is None:
        for spec in specs:
            records += simulate_row(spec)
            done += nx
            if progress:
                progress(done, total, time.perf_counter() - t0)
    else:
        for rows in map_unordered(client, simulate_row, specs):
            records += rows
            done += nx
            if progress:
                progress(done, total, time.perf_counter() - t0)
    df = records_to_frame(records)
    return df.sort_values(["j", "i"], kind="stable").reset_index(drop=True)


def run_tiles(
    study: Study,
    jobs: Sequence[tuple[str, int]],
    *,
    progress: Callable[[int, int, float], None] | None = None,
    backend=None,
) -> list[pd.DataFrame]:
    """The tiles ``jobs`` (``(plane, tile)`` pairs) in one call of the chain driver: every row
    of every tile a chain of one lanes object (on a GPU, one launch holds both planes' chains:
    a plane's 400 rows alone leave it nearly idle). Each frame is :func:`run_tile`'s for its
    tile (the chains are independent lanes). Another method than fixed-step RK4 runs the
    tiles one after the other (:func:`run_tile`, in this process).
    ``progress(done_cells, total_cells, elapsed_s)`` after each cell."""
    groups = [row_specs(study, plane, tile) for plane, tile in jobs]
    specs = [s for g in groups for s in g]
    if specs and not study.settings.method.lanes:  # one cell at a time: tile by tile
        return [run_tile(study, plane, tile, progress=progress, backend=backend)
                for plane, tile in jobs]
    total = sum(len(s.x_values) for s in specs)
    t0 = time.perf_counter()
    count = [0]

    def on_cell() -> None:
        count[0] += 1
        if progress and (count[0] % 1000 == 0 or count[0] == total):
            progress(count[0], total, time.perf_counter() - t0)

    records = simulate_rows_batched(specs, on_cell, backend) if specs else []
    frames = []
    k = 0
    for g in groups:
        n = sum(len(s.x_values) for s in g)
        df = records_to_frame(records[k : k + n])
        k += n
        frames.append(df.sort_values(["j", "i"], kind="stable").reset_index(drop=True))
    return frames
