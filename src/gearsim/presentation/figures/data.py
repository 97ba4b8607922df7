"""Inputs of the figures: reading sweeps, planes and the recorded motions of point sets and
figure-data tables (the simulations themselves are study-side jobs: :mod:`gearsim.study.sweeps`,
:mod:`gearsim.study.figure_data`).

Tables: a sweep is the :func:`gearsim.cell.sweep.orbit_diagram` table (one row
per parameter value, list columns ``poincare_x`` / ``poincare_v``); a plane is
``results/<plane>/cells.parquet`` (``i``, ``j``, the two axis parameters by name, the
``CellResult.row()`` columns and the Poincare lists).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pandas as pd

from gearsim.dynamics.parameters import ModelParameters

# columns of a cells table that are not axis parameters
_RESERVED = {"i", "j", "tile", "plane", "parameter", "value", "direction", "poincare_x",
             "poincare_v"}


def read_table(path: str | Path) -> pd.DataFrame:
    """Read a sweep or cells Parquet file."""
    return pd.read_parquet(path)


def sweep_axis(df: pd.DataFrame) -> tuple[str, np.ndarray]:
    """Name and values of the swept parameter of an orbit-diagram table."""
    name = str(df["parameter"].iloc[0]) if "parameter" in df.columns and len(df) else "w"
    return name, df["value"].to_numpy(dtype=float)


def plane_axes(df: pd.DataFrame) -> tuple[str, str]:
    """Names of the x (varies with ``i``) and y (varies with ``j``) parameters of a cells table."""
    names = [c for c in df.columns if c in ModelParameters.names() and c not in _RESERVED]
    xname = yname = None
    for c in names:
        if df.groupby("j")[c].nunique().max() > 1 and xname is None:
            xname = c
        elif df.groupby("i")[c].nunique().max() > 1 and yname is None:
            yname = c
    if xname is None or yname is None:
        # degenerate (one row or column): fall back on column order
        rest = [c for c in names if c not in (xname, yname)]
        xname = xname or (rest.pop(0) if rest else "w")
        yname = yname or (rest.pop(0) if rest else "b")
    return xname, yname


def plane_grid(df: pd.DataFrame, column: str, fill=np.nan) -> np.ndarray:
    """``column`` as an (ny, nx) array indexed ``[j, i]``."""
    nx = int(df["i"].max()) + 1
    ny = int(df["j"].max()) + 1
    vals = df[column].to_numpy()
    out = np.full((ny, nx), fill, dtype=vals.dtype if vals.dtype != bool else float)
    if out.dtype.kind in "iu":
        out = out.astype(float)
    out[df["j"].to_numpy(dtype=int), df["i"].to_numpy(dtype=int)] = vals
    return out


def plane_centres(df: pd.DataFrame) -> tuple[str, np.ndarray, str, np.ndarray]:
    """Axis names and cell-centre values ``(xname, xs[i], yname, ys[j])`` of a cells table."""
    xname, yname = plane_axes(df)
    xs = df.groupby("i")[xname].first().sort_index().to_numpy(dtype=float)
    ys = df.groupby("j")[yname].first().sort_index().to_numpy(dtype=float)
    return xname, xs, yname, ys


def cell_edges(centres: np.ndarray) -> np.ndarray:
    """Edges of uniform cells from their centres (``v_i = min + (i + 0.5) d``)."""
    c = np.asarray(centres, dtype=float)
    if len(c) == 1:
        return np.array([c[0] - 0.5, c[0] + 0.5])
    d = np.diff(c)
    return np.concatenate([[c[0] - d[0] / 2], c[:-1] + d / 2, [c[-1] + d[-1] / 2]])


def explode_poincare(df: pd.DataFrame, xcol: str = "value", max_points: int | None = None):
    """Flatten the Poincare lists: arrays (parameter value, x, I, row index) of every point."""
    vals, xs, Is, rows = [], [], [], []
    for k, (v, px, I) in enumerate(zip(df[xcol], df["poincare_x"], df["I"], strict=True)):
        px = np.asarray(px, dtype=float)
        if max_points is not None and len(px) > max_points:
            px = px[-max_points:]
        vals.append(np.full(len(px), float(v)))
        xs.append(px)
        Is.append(np.full(len(px), int(I)))
        rows.append(np.full(len(px), k))
    if not xs:
        e = np.zeros(0)
        return e, e, e.astype(int), e.astype(int)
    return (np.concatenate(vals), np.concatenate(xs), np.concatenate(Is),
            np.concatenate(rows))


# ------------------------------------------------------------------------------------- points
@dataclass
class Track:
    """A recorded trajectory: times ``tau``, ``state`` columns ``(x, x')``, the mesh force and
    the section points ``(x, x')``."""

    tau: np.ndarray
    state: np.ndarray
    mesh_force: np.ndarray
    section: np.ndarray


@dataclass
class Recorded:
    """What a table row says of a steady motion: its ``classification`` (the row's
    classification columns as attributes: ``label``, ``label_npq``, ``I``, ``n``, ...)."""

    classification: Any


@dataclass
class PointMotion:
    """One recorded steady motion ready for phase / time / spectrum plots."""

    params: ModelParameters
    result: Recorded
    traj: Track
    samples_per_period: int
    seed: str = "static state"  # how the motion was reached
    notes: list[str] = field(default_factory=list)

    @property
    def label(self) -> str:
        c = self.result.classification
        return f"{c.label_npq} ({c.label})" if c.label_npq else c.label

    @property
    def npq(self) -> str:
        c = self.result.classification
        return c.label_npq or c.label


def spectrum(pm: PointMotion, periods: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """One-sided amplitude spectrum of ``x`` on the recorded uniform samples.

    Returns angular frequency (units of ``w_n``, same axis as ``w``) and amplitude (units of
    ``x``; a pure cosine of amplitude A shows as A). Uses a whole number of mesh periods (a
    multiple of the motion period), so periodic lines fall on exact bins; Hann window, amplitude
    corrected for its coherent gain.
    """
    spp = pm.samples_per_period
    x = pm.traj.state[:-1, 0]
    if periods is not None:
        x = x[: periods * spp]
    x = x - x.mean()
    win = np.hanning(len(x))
    amp = 2.0 * np.abs(np.fft.rfft(x * win)) / win.sum()
    dtau = pm.params.mesh_period / spp
    freq = 2.0 * np.pi * np.fft.rfftfreq(len(x), d=dtau)
    return freq, amp



#: the list columns of a recorded motion's row (not classification)
_TRACK = {"tau", "x", "xdot", "mesh_force", "section_x", "section_v", "poincare_x", "poincare_v",
          "final_state"}


def motion_of(r: pd.Series, params: ModelParameters, seed: str) -> PointMotion:
    """The motion of one recorded row (``gearsim sweep --points``, ``gearsim figure-data``):
    ``tau, x, xdot, mesh_force, section_x, section_v`` lists and the classification columns,
    parameters ``params``; its samples per period from the row when it has them."""
    cls = SimpleNamespace(**{k: (None if k in ("p", "q") and pd.isna(v) else v)
                             for k, v in r.items() if k not in _TRACK})
    tau = np.asarray(r["tau"], dtype=float)
    state = np.c_[np.asarray(r["x"], dtype=float), np.asarray(r["xdot"], dtype=float)]
    sec = np.c_[np.asarray(r["section_x"], dtype=float), np.asarray(r["section_v"], dtype=float)]
    tr = Track(tau, state, np.asarray(r["mesh_force"], dtype=float), sec)
    if "samples_per_period" in r.index:
        spp = int(r["samples_per_period"])
    else:
        spp = int(round(params.mesh_period / (tau[1] - tau[0]))) if len(tau) > 1 else 1
    return PointMotion(params, Recorded(cls), tr, spp, seed)


def row_params(r: pd.Series, params: ModelParameters) -> ModelParameters:
    """``params`` with the parameter values a row records."""
    fixed = {k: float(r[k]) for k in ModelParameters.names() if k in r.index and
             not isinstance(r[k], (list, np.ndarray)) and pd.notna(r[k])}
    return params.with_(**fixed)


def points_from_table(df: pd.DataFrame, params: ModelParameters, *,
                      start: str = "continuation") -> list[PointMotion]:
    """Motions recorded by the pipeline (``results/points/<set>.parquet``, ``gearsim sweep
    --points``); ``start`` picks the rows reached by continuation or from rest."""
    rows = df[df["start"] == start] if "start" in df.columns else df
    return [motion_of(r, row_params(r, params), f"pipeline points ({start})")
            for _, r in rows.sort_values("point" if "point" in rows.columns else "w").iterrows()]


def motions_from_table(df: pd.DataFrame, params: ModelParameters) -> list[tuple[str, str, int,
                                                                                PointMotion]]:
    """``(key, role, hits, motion)`` of every row of a figure-data table
    (:mod:`gearsim.study.figure_data`), in the table's order."""
    return [(str(r["key"]), str(r["role"]), int(r["hits"]),
             motion_of(r, row_params(r, params), str(r["seed"]))) for _, r in df.iterrows()]


def figure_data(ctx, name: str) -> tuple[pd.DataFrame, dict[str, Any]]:
    """The figure-data table ``name`` of ``ctx`` and what it states beside its rows; one line
    naming it when the figure job was not given it."""
    from gearsim.errors import UsageError

    if name not in ctx.figure_data:
        raise UsageError(f"this figure reads the figure-data table '{name}' (gearsim "
                         f"figure-data --name {name}): give it as --figure-data {name}=PATH")
    df = ctx.figure_data[name]
    return df, dict(df.attrs.get("figure_data") or {})
