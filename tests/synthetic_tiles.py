"""Hand-built tiles written through the real tile writer (catalogue tests and the scale benchmark).

A tile here has every column of a simulated tile (``gearsim.study.tiles.cell_records``) with
deterministic values computed from ``(i, j)``: label ``1/1T`` where ``(i + j)`` is even, else
``2/1T`` with ``I = 2``; ``kmax = 1 + i / nx``, ``dc = j / ny``; two Poincare points per cell.
Its provenance is the real one (:func:`gearsim.study.provenance.provenance` of the plane's subtree),
so only the cell values are not simulated.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from gearsim.results import catalogue as gc
from gearsim.study import grid as ggrid
from gearsim.study import provenance as gprov
from gearsim.study.config import Study


def tile_frame(config: dict, plane: str, tile: int) -> pd.DataFrame:
    pl = config["planes"][plane]
    nx, ny = int(pl["x"]["n"]), int(pl["y"]["n"])
    rows = np.array(ggrid.tile_rows(config, plane, tile))
    xs, ys = ggrid.axis_values(pl["x"]), ggrid.axis_values(pl["y"])
    i = np.tile(np.arange(nx), len(rows))
    j = np.repeat(rows, nx)
    n = len(i)
    odd = (i + j) % 2 == 1
    df = pd.DataFrame(
        {
            "plane": plane,
            "tile": np.full(n, tile, dtype=np.int64),
            "i": i.astype(np.int64),
            "j": j.astype(np.int64),
            "x": xs[i],
            "y": ys[j],
            pl["x"]["name"]: xs[i],
            pl["y"]["name"]: ys[j],
            "motion": "periodic",
            "status": "ok",
            "I": np.where(odd, 2, 1).astype(np.int64),
            "n": np.where(odd, 2, 1).astype(np.int64),
            "p": pd.array(np.ones(n, dtype=np.int64), dtype="Int64"),
            "q": pd.array(np.where(odd, 1, 0), dtype="Int64"),
            "label": np.where(odd, "2/1T", "1/1T"),
            "label_npq": np.where(odd, "2-1-1", "1-1-0"),
            "dc": j / ny,
            "kmax_peak_mean": 1.0 + i / nx,
            "kmax_peak_static": 1.0 + i / nx,
            "kmax_section_mean": 0.9 + i / nx,
            "kmax_section_static": 0.8 + i / nx,
            "kmin_peak_mean": np.zeros(n),
            "lyapunov": -0.1 - 0.001 * i,
            "x_min": -np.ones(n),
            "x_max": 1.0 + j / ny,
            "converged": np.ones(n, dtype=bool),
            "window_periods": np.full(n, 16, dtype=np.int64),
            "mu_max": np.full(n, np.nan),
            "critical": np.full(n, "", dtype=object),
            "refined": np.zeros(n, dtype=bool),
            "settle": np.full(n, np.nan),
            "kmax": 1.0 + i / nx,
            "periods": np.full(n, 100, dtype=np.int64),
            "steps": np.full(n, 25600, dtype=np.int64),
            "poincare_x": [[0.5, 0.6]] * n,
            "poincare_v": [[0.1, 0.2]] * n,
            "final_state": [[0.0] * 10] * n,
            "final_period": np.full(n, 100, dtype=np.int64),
            "elapsed_s": np.full(n, 0.01),
        }
    )
    return df


def write_tile(config: dict, plane: str, tile: int, path: Path, df: pd.DataFrame | None = None,
               **prov_overrides) -> Path:
    """Write ``df`` (default: :func:`tile_frame`) with the provenance a tile job records."""
    if df is None:
        df = tile_frame(config, plane, tile)
    rows = ggrid.tile_rows(config, plane, tile)
    prov = gprov.provenance(
        gprov.plane_subtree(Study.of(config), plane), kind="tile", name=plane,
        study=Study.of(config), tile=tile,
        rows=[rows.start, rows.stop], workers="in-process", started=gc.now_iso(),
        finished=gc.now_iso(), wall_s=1.0, cells=len(df),
    )
    prov.update(prov_overrides)
    return gc.write_parquet(df, path, {gc.PROVENANCE_KEY: prov})
