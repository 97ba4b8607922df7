"""Landmarks located to a tolerance: each landmark a sweep read between two grid values,
narrowed by bisection with extra simulations on the branch the sweep followed (the reading
itself, from tables only, is :mod:`gearsim.analysis.landmarks`)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import pandas as pd

from gearsim.cell.simulate import simulate_cell


def _criterion(kind: str, lo_row: dict[str, Any], jump_dc: float) -> Callable[[dict], bool]:
    """A test 'this cell is still on the lo side of the landmark'."""
    lo_state = lo_row["label_npq"] or lo_row["motion"]
    dc_lo = lo_row["dc"]
    if kind == "jump":
        return lambda r: abs(r["dc"] - dc_lo) < 0.5 * jump_dc
    return lambda r: (r["label_npq"] or r["motion"]) == lo_state


def refine_landmarks(
    landmarks: pd.DataFrame,
    params,
    name: str = "w",
    *,
    settings=None,
    tol: float = 1e-3,
    lookback: int = 3,
    step: float | None = None,
    jump_dc: float = 0.15,
    max_iter: int = 20,
) -> pd.DataFrame:
    """Locate each landmark between its ``lo`` and ``hi`` by bisection with extra simulations.

    For each landmark a short continuation chain (``lookback`` cells of spacing ``step``,
    default ``hi - lo``) ending at ``lo`` re-creates the lo-side attractor; bisection then
    continues from the lo side in shrinking steps (each trial starts from the last lo-side
    state), so hysteretic landmarks (jumps) are located on the branch the sweep followed.
    Works for forward and backward sweeps (``lo`` is the side swept first).

    Parameters
    ----------
    landmarks
        Output of :func:`gearsim.analysis.landmarks.find_landmarks`.
    params
        :class:`gearsim.dynamics.parameters.ModelParameters` of the sweep (``name`` is varied).
    tol
        Bisection stops when ``|hi - lo| <= tol``.

    Returns
    -------
    A copy with ``lo``, ``hi``, ``value`` narrowed and ``refined = True`` where it succeeded.
    """
    out = landmarks.copy()
    for idx, lm in landmarks.iterrows():
        lo, hi = float(lm["lo"]), float(lm["hi"])
        h = step if step is not None else hi - lo
        u = None
        period = 0
        res = None
        for k in range(lookback, -1, -1):
            v = lo - math.copysign(k * abs(h), hi - lo)
            res = simulate_cell(params.with_(**{name: v}), u, settings=settings,
                                start_period=period)
            u, period = res.final_state, res.final_period
        if res is None:
            continue
        lo_row = res.row()
        same = _criterion(str(lm["kind"]), lo_row, jump_dc)
        if not same(lo_row):  # the lo side did not reproduce: keep the midpoint
            continue
        it = 0
        while abs(hi - lo) > tol and it < max_iter:
            mid = 0.5 * (lo + hi)
            r = simulate_cell(params.with_(**{name: mid}), u, settings=settings,
                              start_period=period)
            if same(r.row()):
                lo, u, period = mid, r.final_state, r.final_period
            else:
                hi = mid
            it += 1
        out.at[idx, "lo"] = lo
        out.at[idx, "hi"] = hi
        out.at[idx, "value"] = 0.5 * (lo + hi)
        out.at[idx, "refined"] = True
    return out
