"""Sweeps and named point sets of the study as tables: one-parameter sweeps (continuation chains)
and the figures' points, each reached by a ramp and from rest, with recorded trajectories."""

from __future__ import annotations

import itertools
import time
from typing import Any

import numpy as np
import pandas as pd

from gearsim.cell.simulate import simulate_cell, trajectory
from gearsim.cell.sweep import continuation_chain, sweep_records
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.study.config import Study
from gearsim.study.tiles import records_to_frame


def sweep_frame(
    base, name: str, values: np.ndarray, direction: str, settings, progress=None,
    start: str = "continuation", backend=None,
) -> pd.DataFrame:
    """The records of :func:`gearsim.cell.sweep.sweep_records` with the catalogue's stable dtypes.

    ``start="rest"``: every cell from the static state instead of the previous cell's state;
    ``backend``: where its lane runs (None: the CPU).
    """
    return records_to_frame(sweep_records(base, name, values, direction=direction,
                                          settings=settings, progress=progress,
                                          continuation=start == "continuation",
                                          backend=backend))


def point_list(spec) -> list[dict[str, float]]:
    """The points of a configured point set: a list of w values, or a mapping of parameter
    values (a value may be a list: every combination)."""
    if isinstance(spec, list):
        return [{"w": float(w)} for w in spec]
    keys = list(spec)
    lists = [v if isinstance(v, list) else [v] for v in spec.values()]
    return [dict(zip(keys, map(float, combo), strict=True)) for combo in itertools.product(*lists)]


def motion_row(res, tr) -> dict[str, Any]:
    """The record of a steady motion ``res`` (a :class:`~gearsim.cell.simulate.CellResult`)
    with the trajectory ``tr`` recorded on it: its classification, section points and final
    state, and the trajectory's ``tau, x, xdot, mesh_force, section_x, section_v``."""
    row = dict(res.row())
    row["poincare_x"] = res.poincare[:, 0].tolist()
    row["poincare_v"] = res.poincare[:, 1].tolist()
    row["tau"] = tr.tau.tolist()
    row["x"] = tr.state[:, 0].tolist()
    row["xdot"] = tr.state[:, 1].tolist()
    row["mesh_force"] = tr.mesh_force.tolist()
    row["section_x"] = tr.section[:, 0].tolist()
    row["section_v"] = tr.section[:, 1].tolist()
    row["final_state"] = res.final_state.tolist()
    return row


def points_frame(study: Study, fig: str, *, ramp_from: float, ramp_step: float, periods: int,
                 samples_per_period: int, progress=None) -> pd.DataFrame:
    """Each point twice: reached by a forward ramp in w from ``ramp_from`` in steps of
    ``ramp_step`` (as in the sweeps) and from rest; ``periods`` periods of trajectory recorded
    at ``samples_per_period`` samples each."""
    values = study.parameters().model.to_dict()
    settings = study.settings
    points = point_list(study.config["points"][fig])
    for pt in points:
        if "w" not in pt:
            raise ParameterError(f"config key 'points.{fig}': every point needs a value of w")
    rows: list[dict[str, Any]] = []
    groups: dict[tuple, list[int]] = {}
    for k, pt in enumerate(points):
        groups.setdefault(tuple(sorted((n, v) for n, v in pt.items() if n != "w")), []).append(k)
    done = 0
    t0 = time.perf_counter()
    for other, idx in groups.items():
        base = ModelParameters.from_mapping({**values, **dict(other)})
        targets = sorted({points[k]["w"] for k in idx})
        ramp = np.arange(ramp_from, max(targets), ramp_step)
        ws = sorted(set(np.round(ramp, 12).tolist()) | set(targets))
        chain = continuation_chain([base.with_(w=float(w)) for w in ws], settings=settings)
        at = {w: r for w, r in zip(ws, chain, strict=True)}
        for k in idx:
            pt = points[k]
            params = base.with_(w=pt["w"])
            for start, res in (
                ("continuation", at[pt["w"]]),
                ("rest", simulate_cell(params, settings=settings)),
            ):
                tr = trajectory(
                    params,
                    res.final_state,
                    periods=periods,
                    samples_per_period=samples_per_period,
                    settings=settings,
                    start_period=res.final_period,
                )
                rows.append({"figure": fig, "point": k, "start": start, **pt,
                             **motion_row(res, tr)})
            done += 1
            if progress:
                progress(done, len(points), time.perf_counter() - t0)
    return records_to_frame(rows)
