"""A plane's periodic cells refined by Newton shooting as one resumable job
(``gearsim refine-orbits``): its checked options, the key of the inputs a partial table must
have been computed from to be resumed, and the refined table with its provenance.

The per-cell refinement is :func:`gearsim.analysis.orbit_cells.refine_cells`; the files (the
partial table beside the output, the output) are written by the caller."""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from gearsim.errors import UsageError
from gearsim.numerics.settings import IntegrationSettings
from gearsim.study import provenance
from gearsim.study.config import Study

if TYPE_CHECKING:  # the command line imports this module for EVERY: numpy and pandas wait
    import pandas as pd

#: the columns of a plane's cells.parquet the refinement reads
CELL_COLUMNS = ("i", "j", "x", "y", "n", "status", "label", "final_state")
#: refined cells between two writes of the partial table (~10 s on one core at ~50 cells/s)
EVERY = 500


def partial_path(out: str | Path) -> Path:
    """Where a run keeps the cells refined so far (removed when the table is written)."""
    out = Path(out)
    return out.with_name(out.name + ".partial")


def inputs_key(cells: pd.DataFrame, plane_subtree: dict, settings: dict,
               limit: int | None) -> str:
    """What a partial table must have been computed from to be resumed: the plane's
    configuration, the shooting settings, the limit, the cells' states and the code."""
    import numpy as np

    h = hashlib.sha256()
    for col in ("i", "j", "n"):
        h.update(np.ascontiguousarray(cells[col].to_numpy(dtype=np.int64)).tobytes())
    h.update(np.ascontiguousarray(np.stack([np.asarray(v, dtype=float)
                                            for v in cells["final_state"]])).tobytes()
             if len(cells) else b"")
    return provenance.config_hash({"plane": plane_subtree, "settings": settings, "limit": limit,
                                   "cells": h.hexdigest(),
                                   "code": provenance.code_version("analysis")})


@dataclass(frozen=True)
class Refinement:
    """One plane's refinement: its cells, those to refine, the shooting settings and the key
    (:func:`inputs_key`) a partial table of it carries."""

    study: Study
    plane: str
    cells: pd.DataFrame
    todo: pd.DataFrame
    settings: IntegrationSettings
    limit: int | None
    key: str

    @property
    def partial_metadata(self) -> dict:
        return {"kind": "orbits-partial", "inputs": self.key}


def plan(study: Study, plane: str, cells: pd.DataFrame, *, cells_path: str,
         rtol: float | None = None, limit: int | None = None, every: int = EVERY
         ) -> Refinement:
    """The refinement of ``plane``'s ``cells``, its options checked (one line each)."""
    from gearsim.analysis.orbit_cells import periodic_cells
    from gearsim.analysis.orbits import shooting_settings

    if limit is not None and limit < 1:
        raise UsageError(f"--limit = {limit} must be >= 1")
    if every < 0:
        raise UsageError(f"--every = {every} must be >= 0 (0: no partial table)")
    if rtol is not None and not 0 < rtol < 1e-3:
        raise UsageError(f"--rtol = {rtol} must be in (0, 1e-3)")
    for col in CELL_COLUMNS:
        if col not in cells.columns:
            raise UsageError(f"{cells_path}: column '{col}' missing (not a plane's cells.parquet)")
    st = shooting_settings(rtol)
    todo = periodic_cells(cells, limit)
    key = inputs_key(todo, provenance.plane_subtree(study, plane), st.to_dict(), limit)
    return Refinement(study, plane, cells, todo, st, limit, key)


def refine(job: Refinement, *, done: pd.DataFrame | None = None, every: int = EVERY,
           checkpoint: Callable[[pd.DataFrame], None] | None = None,
           progress: Callable[[int, int, float], None] | None = None,
           ) -> tuple[pd.DataFrame, dict]:
    """The refined table (``done``: the rows of an interrupted run, kept) and its provenance;
    ``checkpoint(table)`` after every ``every`` refined cells."""
    import time

    from gearsim.analysis.orbit_cells import refine_cells

    pl = job.study.config["planes"][job.plane]
    base = job.study.parameters(plane=job.plane).model
    started, t0 = provenance.now_iso(), time.perf_counter()
    df = refine_cells(job.cells, base, pl["x"]["name"], pl["y"]["name"], job.settings,
                      progress=progress, limit=job.limit, done=done, every=every,
                      checkpoint=checkpoint)
    wall = time.perf_counter() - t0
    prov = provenance.provenance(
        provenance.plane_subtree(job.study, job.plane), kind="orbits", name=job.plane,
        study=job.study, scope="analysis", started=started, finished=provenance.now_iso(),
        wall_s=wall, cells=len(df), settings=job.settings.to_dict(), workers="in-process",
        resumed=0 if done is None else len(done),
    )
    return df, prov
