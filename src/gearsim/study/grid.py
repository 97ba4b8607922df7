"""Plane and sweep grids and the tiles of a plane (pure functions of the configuration).

A *plane* spans two :class:`~gearsim.dynamics.parameters.ModelParameters` names (axes ``x`` and
``y``) at
cell centres ``v_i = min + (i + 0.5) (max - min) / n``; a *sweep* has its end points included,
``v_k = min + k (max - min) / (n - 1)``. A *tile* is ``tile_rows`` consecutive rows (``y``
indices) of a plane, one Snakemake job. Values are in the units of the named parameter
(dimensionless, see docs/model.md).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from gearsim.errors import ConfigError


def axis_values(axis: Mapping[str, Any]) -> np.ndarray:
    """Cell centres ``min + (i + 0.5) (max - min) / n`` of a plane axis."""
    lo, hi, n = float(axis["min"]), float(axis["max"]), int(axis["n"])
    return lo + (np.arange(n) + 0.5) * (hi - lo) / n


def sweep_values(sweep: Mapping[str, Any]) -> np.ndarray:
    """Sweep values, end points included: ``min + k (max - min) / (n - 1)``."""
    return np.linspace(float(sweep["min"]), float(sweep["max"]), int(sweep["n"]))


def n_tiles(config: Mapping, plane: str) -> int:
    """Tiles of ``plane``: ``ceil(ny / tile_rows)``."""
    return -(-int(config["planes"][plane]["y"]["n"]) // int(config["tile_rows"]))


def tile_ids(config: Mapping, plane: str) -> list[int]:
    """Indices ``0 .. n_tiles - 1`` of the tiles of ``plane``."""
    return list(range(n_tiles(config, plane)))


def tile_rows(config: Mapping, plane: str, tile: int) -> range:
    """Row indices ``j`` (y) of ``tile``."""
    if not 0 <= tile < n_tiles(config, plane):
        raise ConfigError(
            f"tile {tile} does not exist for plane '{plane}' (0..{n_tiles(config, plane) - 1})"
        )
    rows = int(config["tile_rows"])
    ny = int(config["planes"][plane]["y"]["n"])
    return range(tile * rows, min((tile + 1) * rows, ny))
