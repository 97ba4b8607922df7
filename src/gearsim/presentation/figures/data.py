"""Inputs of the figures: reading sweeps and planes, simulating the figures' single points.

Tables: a sweep is the :func:`gearsim.cell.sweep.orbit_diagram` table (one row
per parameter value, list columns ``poincare_x`` / ``poincare_v``); a plane is
``results/<plane>/cells.parquet`` (``i``, ``j``, the two axis parameters by name, the
``CellResult.row()`` columns and the Poincare lists).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from gearsim.dynamics.parameters import ModelParameters

if TYPE_CHECKING:
    from gearsim.cell.simulate import CellResult, IntegrationSettings, Trajectory

# The simulating helpers below (seed states, point simulations, continuation, points of a point
# table) import the integrators where they run: a figure job that only reads tables does not
# load Numba and the kernels.

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
class PointMotion:
    """One simulated steady motion ready for phase / time / spectrum plots."""

    params: ModelParameters
    result: CellResult
    traj: Trajectory
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


def seed_state(params: ModelParameters, x: float, v: float) -> np.ndarray:
    """A section state with mesh coordinates ``(x, v)`` and the bearings at their static state."""
    from gearsim.dynamics.model import static_state

    y = static_state(params.to_array())
    y[0], y[1] = float(x), float(v)
    return y


def seed_from_sweep(sweep: pd.DataFrame | None, params: ModelParameters,
                    name: str = "w") -> tuple[np.ndarray | None, str]:
    """Initial state from the swept row nearest to ``params.<name>`` (continuation seed).

    Uses the row's full ``final_state`` when the table has it (``gearsim sweep`` writes it);
    otherwise only ``(x, x')`` of its last section point are known and the bearing coordinates
    start from the static state.
    """
    from gearsim.dynamics.model import static_state

    if sweep is None or len(sweep) == 0:
        return None, "static state"
    target = getattr(params, name)
    k = int(np.argmin(np.abs(sweep["value"].to_numpy(dtype=float) - target)))
    row = sweep.iloc[k]
    if "final_state" in sweep.columns and row["final_state"] is not None:
        fs = np.asarray(row["final_state"], dtype=float)
        if fs.shape == (len(static_state(params.to_array())),) and np.all(np.isfinite(fs)):
            return fs.copy(), f"sweep state at {name} = {row['value']:.4g}"
    px, pv = np.asarray(row["poincare_x"]), np.asarray(row["poincare_v"])
    if len(px) == 0:
        return None, "static state"
    return seed_state(params, px[-1], pv[-1]), f"sweep section point {name} = {row['value']:.4g}"


def reach(params: ModelParameters, targets: Sequence[float], *, sweep: pd.DataFrame | None,
          settings: IntegrationSettings | None = None) -> tuple[dict[float, CellResult], str]:
    """Steady motions at ``targets`` (values of ``w``) on the branch the forward sweep followed.

    With the sweep's full final states: one continuation step from the nearest swept value at
    or below each target. Otherwise a forward continuation chain (:func:`continuation_to`).
    """
    from gearsim.cell.simulate import simulate_cell

    if sweep is not None and len(sweep) and "final_state" in sweep.columns:
        out = {}
        vals = sweep["value"].to_numpy(dtype=float)
        for t in targets:
            below = np.where(vals <= float(t) + 1e-12)[0]
            k = int(below[np.argmax(vals[below])]) if len(below) else int(np.argmin(vals))
            fs = np.asarray(sweep["final_state"].iloc[k], dtype=float)
            out[float(t)] = simulate_cell(params.with_(w=float(t)), fs, settings=settings)
        return out, "continuation from the sweep state"
    values = sweep["value"].to_numpy(dtype=float) if sweep is not None and len(sweep) else None
    return (continuation_to(params, targets, settings=settings, values=values),
            "forward continuation in w")


def continuation_to(
    params: ModelParameters,
    targets: Sequence[float],
    *,
    name: str = "w",
    settings: IntegrationSettings | None = None,
    values: Sequence[float] | np.ndarray | None = None,
    start: float | None = None,
    step: float = 0.01,
    min_step: float = 0.005,
) -> dict[float, CellResult]:
    """Steady motions at ``targets`` reached by forward continuation in ``name``.

    The chain runs over ``values`` (e.g. the swept values of the matching sweep, so the figure
    follows the branch of the bifurcation diagram) or a uniform grid of spacing ``step`` from
    ``start`` (default 0.1 for ``w``), up to the largest target, with the targets inserted;
    ``values`` closer than ``min_step`` are thinned out (cost).
    Seeding a single point from a stored section state is not enough: the sweep tables keep only
    ``(x, x')``, and with the bearings reset the motion can land on a coexisting attractor.
    """
    from gearsim.cell.sweep import continuation_chain

    tg = sorted(float(t) for t in targets)
    if not tg:
        return {}
    if values is None:
        lo = (0.1 if name == "w" else tg[0]) if start is None else start
        values = np.arange(lo, tg[-1], step) if tg[-1] > lo else np.zeros(0)
    vals = np.sort(np.asarray(values, dtype=float))
    vals = vals[vals < tg[-1]]
    if min_step > 0 and len(vals) > 1:  # thin a fine sweep grid (cost), keep its first value
        keep = [0]
        for k in range(1, len(vals)):
            if vals[k] - vals[keep[-1]] >= min_step:
                keep.append(k)
        vals = vals[keep]
    chain = np.unique(np.concatenate([vals, tg]))
    res = continuation_chain([params.with_(**{name: float(v)}) for v in chain],
                             settings=settings)
    by_value = dict(zip(chain.tolist(), res, strict=True))
    return {t: by_value[t] for t in tg}


def simulate_point(
    params: ModelParameters,
    *,
    settings: IntegrationSettings | None = None,
    u0: np.ndarray | None = None,
    seed: str = "static state",
    periods: int | None = None,
    samples_per_period: int = 128,
    min_periods: int = 32,
    result: CellResult | None = None,
) -> PointMotion:
    """Settle the motion at ``params`` (from ``u0``) and record a trajectory on it.

    ``periods`` defaults to a whole number of motion periods, at least ``min_periods``
    (chaotic motion: ``4 * min_periods``).
    """
    from gearsim.cell.simulate import simulate_cell, trajectory

    st = settings or IntegrationSettings()
    res = result if result is not None else simulate_cell(params, u0, settings=st)
    n = res.classification.n
    if periods is None:
        periods = max(min_periods, n * int(np.ceil(min_periods / n))) if n > 0 else 4 * min_periods
    tr = trajectory(params, res.final_state, periods=periods,
                    samples_per_period=samples_per_period, settings=st,
                    start_period=res.final_period)
    return PointMotion(params, res, tr, samples_per_period, seed)


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



def points_from_table(df: pd.DataFrame, params: ModelParameters, *,
                      start: str = "continuation") -> list[PointMotion]:
    """Motions recorded by the pipeline (``results/points/<set>.parquet``, ``gearsim sweep
    --points``): rows with ``tau, x, xdot, mesh_force, section_x, section_v`` lists and the
    classification columns; ``start`` picks the rows reached by continuation or from rest."""
    from gearsim.cell.classify import Classification
    from gearsim.cell.simulate import CellResult, Trajectory


    rows = df[df["start"] == start] if "start" in df.columns else df
    fields = Classification.__dataclass_fields__
    out = []
    for _, r in rows.sort_values("point" if "point" in rows.columns else "w").iterrows():
        fixed = {k: float(r[k]) for k in ModelParameters.names() if k in r.index and
                 not isinstance(r[k], (list, np.ndarray)) and pd.notna(r[k])}
        p = params.with_(**fixed)
        cls = Classification(**{f: (None if (f in ("p", "q") and pd.isna(r[f])) else r[f])
                                for f in fields})
        tau = np.asarray(r["tau"], dtype=float)
        state = np.c_[np.asarray(r["x"], dtype=float), np.asarray(r["xdot"], dtype=float)]
        sec = np.c_[np.asarray(r["section_x"], dtype=float),
                    np.asarray(r["section_v"], dtype=float)]
        tr = Trajectory(tau, state, np.asarray(r["mesh_force"], dtype=float), np.zeros(0),
                        np.zeros(0, dtype=int), sec)
        spp = int(round(p.mesh_period / (tau[1] - tau[0]))) if len(tau) > 1 else 1
        res = CellResult(cls, np.zeros(0), 0, sec, 0, 0, p)
        out.append(PointMotion(p, res, tr, spp, f"pipeline points ({start})"))
    return out
