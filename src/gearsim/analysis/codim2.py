"""Codimension-2 points of a plane's bifurcation curves: where a curve ends inside the plane or
two curves meet (docs/orbits.md, "The plane atlas")."""

from __future__ import annotations

from typing import Any

import pandas as pd

CODIM2_COLUMNS = (
    "point", "plane", "kind", "conditions", "period", "boundary", "name", "value", "name2",
    "value2", "curves", "curve_kinds", "residual_1", "residual_2", "residual", "step",
    "iterations", "converged", "gap_cells", "x", "v", "mu_max", "mu_re", "mu_im",
)


def codim2_points(base, curves: pd.DataFrame, grid, opts: Any) -> pd.DataFrame:
    """The codimension-2 points of ``curves`` (columns :data:`CODIM2_COLUMNS`)."""
    return pd.DataFrame(columns=list(CODIM2_COLUMNS))
