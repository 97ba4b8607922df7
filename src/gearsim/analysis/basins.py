"""Basins of attraction of one gear cell: a grid of starts in ``(x, x')`` coloured by attractor.

The grid spans the start box of :func:`gearsim.analysis.attractors.start_box` (or a given box) at
``n x n`` cell centres; bearings start at their static deflection and at rest. Every start is a
job of the finder :func:`gearsim.analysis.attractors.find_attractors` (recurrence-based
early labelling), so a 200 x 200 picture costs ~40 000 starts of a few dozen periods each.

Units: ``x`` is the mesh displacement over the nominal length ``b_c``; ``x' = dx/dtau`` with
``tau = w_n t``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from gearsim.analysis.attractors import (
    CellAttractors,
    FinderOptions,
    GearCells,
    find_attractors,
    start_box,
)
from gearsim.dynamics.parameters import ModelParameters, ParameterError


@dataclass
class BasinGrid:
    """Attractor reached from each start of an ``n x n`` grid (``labels[iv, ix]``, -1 diverged)."""

    params: ModelParameters
    x: np.ndarray  # (n,) start displacements
    v: np.ndarray  # (n,) start velocities
    labels: np.ndarray  # (n, n) attractor index, rows = v, columns = x
    early: np.ndarray  # (n, n) labelled by recurrence
    periods: np.ndarray  # (n, n) mesh periods integrated
    cell: CellAttractors

    def frame(self) -> pd.DataFrame:
        """One row per start: grid indices, start state, attractor index and labels."""
        n_v, n_x = self.labels.shape
        iv, ix = np.meshgrid(np.arange(n_v), np.arange(n_x), indexing="ij")
        names = {a.index: a.label for a in self.cell.attractors}
        npq = {a.index: a.steady.info.get("label_npq", "") for a in self.cell.attractors}
        lab = self.labels.ravel()
        return pd.DataFrame(
            {
                "ix": ix.ravel(),
                "iv": iv.ravel(),
                "x0": self.x[ix.ravel()],
                "v0": self.v[iv.ravel()],
                "attractor": lab,
                "label": [names.get(int(k), "diverged") for k in lab],
                "label_npq": [npq.get(int(k), "") for k in lab],
                "early": self.early.ravel(),
                "periods": self.periods.ravel(),
            }
        )

    def attractor_table(self) -> pd.DataFrame:
        rows = []
        for a in self.cell.attractors:
            r = a.record()
            rows.append({k: r.get(k) for k in ATTRACTOR_COLUMNS})
        return pd.DataFrame(rows, columns=list(ATTRACTOR_COLUMNS))


ATTRACTOR_COLUMNS = ("attractor", "label", "label_npq", "I", "n", "p", "q", "dc", "kmax",
                     "lyapunov", "basin_fraction", "n_starts", "n_early", "found_by",
                     "poincare_x", "poincare_v")  # fmt: skip


def basin_grid(
    params: ModelParameters,
    *,
    n: int = 200,
    settings=None,
    box: tuple[float, float, float, float] | None = None,
    options: FinderOptions | None = None,
    backend=None,
) -> BasinGrid:
    """Classify the starts of an ``n x n`` grid over ``box = (xmin, xmax, vmin, vmax)``.

    Default box: the :func:`~gearsim.analysis.attractors.start_box` of ``params``. ``options``: the
    finder's :class:`~gearsim.analysis.attractors.FinderOptions` (e.g. ``early=False``; its
    ``starts`` and ``seed`` are replaced by the grid). ``backend``: where the starts' lanes run
    (:func:`gearsim.numerics.backend.select`; None: the CPU).
    """
    if isinstance(n, bool) or not isinstance(n, int) or not 2 <= n <= 2000:
        raise ParameterError(f"setting 'n' = {n!r} must be an integer in [2, 2000]")
    if box is None:
        x0, hx, v0, hv = start_box(params)
        box = (x0 - hx, x0 + hx, v0 - hv, v0 + hv)
    xmin, xmax, vmin, vmax = (float(b) for b in box)
    if not (np.isfinite([xmin, xmax, vmin, vmax]).all() and xmax > xmin and vmax > vmin):
        raise ParameterError(f"setting 'box' = {box!r}: need xmin < xmax and vmin < vmax")
    xs = xmin + (np.arange(n) + 0.5) * (xmax - xmin) / n
    vs = vmin + (np.arange(n) + 0.5) * (vmax - vmin) / n
    system = GearCells([params], settings, backend)
    V, X = np.meshgrid(vs, xs, indexing="ij")
    unit = np.column_stack([(X.ravel() - xmin) / (xmax - xmin), (V.ravel() - vmin) / (vmax - vmin)])
    # the unit square maps to the start box; a custom box maps through its own affine map
    states = system.start_states(0, unit)
    states[:, 0] = X.ravel()
    states[:, 1] = V.ravel()
    ca = find_attractors(params, options, settings=settings, start_states=states,
                         backend=backend)
    shape = (n, n)
    return BasinGrid(
        params=params,
        x=xs,
        v=vs,
        labels=ca.start_labels.reshape(shape),
        early=ca.early.reshape(shape),
        periods=ca.start_periods_run.reshape(shape),
        cell=ca,
    )


def write_basin_grid(grid: BasinGrid, path: str | Path) -> Path:
    """Write the grid (one row per start) to Parquet; parameters and attractors in metadata."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    table = pa.Table.from_pandas(grid.frame(), preserve_index=False)
    meta = {
        b"gearsim.params": json.dumps(grid.params.to_dict()).encode(),
        b"gearsim.analysis.attractors": grid.attractor_table().to_json(orient="records").encode(),
    }
    table = table.replace_schema_metadata({**(table.schema.metadata or {}), **meta})
    pq.write_table(table, path)
    return path


def read_basin_grid(path: str | Path) -> tuple[pd.DataFrame, pd.DataFrame, dict[str, Any]]:
    """``(starts, attractors, params)`` of a file written by :func:`write_basin_grid`."""
    import pyarrow.parquet as pq

    t = pq.read_table(path)
    meta = t.schema.metadata or {}
    att = pd.DataFrame(json.loads(meta.get(b"gearsim.analysis.attractors", b"[]")))
    params = json.loads(meta.get(b"gearsim.params", b"{}"))
    return t.to_pandas(), att, params
