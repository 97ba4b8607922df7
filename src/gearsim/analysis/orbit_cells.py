"""Per-cell Newton refinement of a plane's periodic cells (Poincare-Newton-Floquet per cell).

For every periodic cell (``n >= 1``, status ok) of a plane's ``cells.parquet`` the simulated
section state (``final_state``, on the section ``tau = final_period T``; the map is autonomous
because the variable-ratio forcing is off) seeds Newton shooting for period ``n``
(:func:`gearsim.analysis.orbits.newton_orbit`). Stored per cell:

``orbit_converged``, ``orbit_residual``, ``orbit_iterations``
    Newton's outcome (residual ``max |P^n(y) - y|``, dimensionless state units).
``orbit_mu_max``, ``orbit_kind``
    Largest Floquet multiplier modulus (per ``n`` mesh periods) and its kind (``fold`` real
    positive, ``period_doubling`` real negative, ``neimark_sacker`` complex pair).
``orbit_grazing_margin``
    Smallest distance of a turning point of ``x`` (or a bearing coordinate with clearance) to a
    contact boundary (units of ``b_c``).
``orbit_shift``
    ``max |y_orbit - y_simulated|`` over ``(x, x')``: how far the simulation's section point was.
``orbit_minimal_period``
    True period of the refined orbit (a divisor of ``n``).
``orbit_flag``
    ``""`` when Newton confirms the simulation; otherwise ``no_convergence``, ``unstable``
    (``|mu|max >= 1``: the simulated motion is not this orbit) or ``period`` (the refined orbit's
    minimal period differs from the simulated ``n``).
``orbit_ms``
    Wall time of the refinement (milliseconds).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
import pandas as pd

from gearsim.analysis.orbits import SHOOTING, OrbitError, grazing_margin, make_orbit, newton_orbit
from gearsim.cell.simulate import IntegrationSettings
from gearsim.dynamics.parameters import ModelParameters

COLUMNS = (
    "plane", "i", "j", "x", "y", "label", "n", "orbit_converged", "orbit_residual",
    "orbit_iterations", "orbit_mu_max", "orbit_kind", "orbit_grazing_margin", "orbit_shift",
    "orbit_minimal_period", "orbit_flag", "orbit_ms",
)


def refine_cell(
    params: ModelParameters,
    n: int,
    state: np.ndarray,
    settings: IntegrationSettings = SHOOTING,
    *,
    max_iter: int = 15,
    substeps: int = 128,
) -> dict:
    """Refine one simulated periodic cell; returns the ``orbit_*`` fields of :data:`COLUMNS`."""
    t0 = time.perf_counter()
    out = {
        "orbit_converged": False, "orbit_residual": math.nan, "orbit_iterations": 0,
        "orbit_mu_max": math.nan, "orbit_kind": "", "orbit_grazing_margin": math.nan,
        "orbit_shift": math.nan, "orbit_minimal_period": 0, "orbit_flag": "no_convergence",
    }
    try:
        y, _, M, r, it = newton_orbit(params, n, state, settings, max_iter=max_iter)
    except OrbitError:
        out["orbit_ms"] = (time.perf_counter() - t0) * 1e3
        return out
    orbit = make_orbit(params, n, y, M, r, it, settings, grazing=False)
    gm = grazing_margin(params, y, n, settings, substeps=substeps)
    flag = ""
    if not orbit.stable:
        flag = "unstable"
    elif orbit.minimal_period != n:
        flag = "period"
    out.update(
        orbit_converged=True, orbit_residual=r, orbit_iterations=it,
        orbit_mu_max=orbit.mu_max, orbit_kind=orbit.critical_kind,
        orbit_grazing_margin=gm.smallest,
        orbit_shift=float(np.max(np.abs(y[:2] - np.asarray(state, dtype=float)[:2]))),
        orbit_minimal_period=orbit.minimal_period, orbit_flag=flag,
    )
    out["orbit_ms"] = (time.perf_counter() - t0) * 1e3
    return out


def refine_cells(
    cells: pd.DataFrame,
    base: ModelParameters,
    x_name: str,
    y_name: str,
    settings: IntegrationSettings = SHOOTING,
    *,
    progress: Callable[[int, int, float], None] | None = None,
    limit: int | None = None,
    done: pd.DataFrame | None = None,
    checkpoint: Callable[[pd.DataFrame], None] | None = None,
    every: int = 0,
) -> pd.DataFrame:
    """Refine every periodic cell of a plane (``cells.parquet`` rows); one row per cell, in the
    order of ``cells``.

    ``done``: rows of an interrupted run (:data:`COLUMNS`), kept and not refined again (each
    cell is refined alone from its own simulated state, so a resumed run gives the same table).
    ``checkpoint(table)`` is called with the rows so far after every ``every`` refined cells.
    """
    periodic = periodic_cells(cells, limit)
    rows = [] if done is None else done.to_dict("records")
    have = {(int(r["i"]), int(r["j"])) for r in rows}
    t0 = time.perf_counter()
    fresh = 0
    for _, c in periodic.iterrows():
        if (int(c["i"]), int(c["j"])) in have:
            continue
        params = base.with_(**{x_name: float(c["x"]), y_name: float(c["y"])})
        rec = {"plane": c.get("plane", ""), "i": int(c["i"]), "j": int(c["j"]),
               "x": float(c["x"]), "y": float(c["y"]), "label": c["label"], "n": int(c["n"])}
        rec.update(refine_cell(params, int(c["n"]), np.asarray(c["final_state"], dtype=float),
                               settings))
        rows.append(rec)
        fresh += 1
        if checkpoint is not None and every > 0 and fresh % every == 0:
            checkpoint(_table(rows, periodic))
        if progress:
            progress(len(rows), len(periodic), time.perf_counter() - t0)
    return _table(rows, periodic)


def periodic_cells(cells: pd.DataFrame, limit: int | None = None) -> pd.DataFrame:
    """The cells :func:`refine_cells` refines: periodic, not diverged; the first ``limit``."""
    periodic = cells[(cells["n"] >= 1) & (cells["status"] != "diverged")]
    return periodic if limit is None else periodic.iloc[:limit]


def _table(rows: list[dict], periodic: pd.DataFrame) -> pd.DataFrame:
    """``rows`` as a table in the order of ``periodic`` (resumed rows come first in ``rows``)."""
    order = {(int(i), int(j)): k for k, (i, j) in enumerate(zip(periodic["i"], periodic["j"],
                                                              strict=True))}
    rows = sorted(rows, key=lambda r: order.get((int(r["i"]), int(r["j"])), len(order)))
    return pd.DataFrame(rows, columns=list(COLUMNS))
