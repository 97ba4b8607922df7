"""One-parameter sweeps with continuation (orbit / bifurcation diagrams)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pandas as pd

from .parameters import ModelParameters, ParameterError
from .simulate import CellResult, IntegrationSettings, seeds_continuation, simulate_cell


def continuation_chain(
    params_list: Sequence[ModelParameters],
    *,
    settings: IntegrationSettings | None = None,
    continuation: bool = True,
    u0: np.ndarray | None = None,
    on_cell: Callable[[int, CellResult], None] | None = None,
) -> list[CellResult]:
    """Simulate cells in order, each starting from the previous steady state when ``continuation``.

    A cell that diverged or ran out of its step budget does not seed the next one (it restarts
    from the static state).
    """
    results: list[CellResult] = []
    start = u0
    period = 0
    for idx, params in enumerate(params_list):
        res = simulate_cell(
            params, start if continuation else u0, settings=settings, start_period=period
        )
        results.append(res)
        if on_cell is not None:
            on_cell(idx, res)
        if continuation and seeds_continuation(res):
            start, period = res.final_state, res.final_period
        else:
            start, period = u0, 0
    return results


def orbit_diagram(
    params: ModelParameters,
    name: str,
    values: Sequence[float] | np.ndarray,
    *,
    continuation: bool = True,
    direction: str = "forward",
    settings: IntegrationSettings | None = None,
) -> pd.DataFrame:
    """Sweep parameter ``name`` over ``values`` and classify the steady motion at each value.

    Parameters
    ----------
    direction
        ``"forward"`` sweeps ``values`` in increasing order, ``"backward"`` in decreasing order
        (hysteresis shows as a difference between the two).

    Returns
    -------
    DataFrame with one row per value (sorted as swept): ``value``, the classification columns and
    ``poincare_x`` / ``poincare_v`` (the section samples of the analysed window).
    """
    if name not in ModelParameters.names():
        raise ParameterError(
            f"unknown sweep parameter '{name}'; allowed: {', '.join(ModelParameters.names())}"
        )
    if direction not in ("forward", "backward"):
        raise ParameterError(f"direction = {direction!r}; allowed: forward, backward")
    vals = np.sort(np.asarray(values, dtype=float))
    if direction == "backward":
        vals = vals[::-1]
    plist = [params.with_(**{name: float(v)}) for v in vals]
    results = continuation_chain(plist, settings=settings, continuation=continuation)
    rows: list[dict[str, Any]] = []
    for v, r in zip(vals, results, strict=True):
        row = {"parameter": name, "value": float(v), "direction": direction}
        row.update(r.row())
        row["poincare_x"] = r.poincare[:, 0].tolist()
        row["poincare_v"] = r.poincare[:, 1].tolist()
        rows.append(row)
    return pd.DataFrame(rows)
