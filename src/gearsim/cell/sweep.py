"""One-parameter sweeps with continuation (orbit / bifurcation diagrams)."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pandas as pd

from gearsim.cell.chains import simulate_rows
from gearsim.cell.simulate import CellResult, IntegrationSettings, seeds_continuation, simulate_cell
from gearsim.cell.verify import fill_margins
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.numerics.settings import Method


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


def sweep_records(
    params: ModelParameters,
    name: str,
    values: Sequence[float] | np.ndarray,
    *,
    continuation: bool = True,
    direction: str = "forward",
    settings: IntegrationSettings | None = None,
    progress: Callable[[int, int, float], None] | None = None,
    backend=None,
) -> list[dict[str, Any]]:
    """One record per swept value: the one sweep builder (orbit_diagram, ``gearsim sweep``).

    Parameters
    ----------
    direction
        ``"forward"`` sweeps ``values`` in increasing order, ``"backward"`` in decreasing order
        (hysteresis shows as a difference between the two), ``"both"`` forward then backward.
    settings
        RK4 settings run the chain through the batched kernel
        (:func:`gearsim.cell.chains.simulate_rows`,
        bit-identical to the scalar chain); DP5 through :func:`continuation_chain`.
    progress
        Called as ``progress(done, total, elapsed_s)`` every 25 cells and at the end.
    backend
        Where the batched chain's lane runs (:func:`gearsim.numerics.backend.select`; None: the
        CPU).

    Records: ``parameter``, ``value``, ``direction``, the classification columns
    (:meth:`CellResult.row`), ``poincare_x`` / ``poincare_v`` (section samples of the analysed
    window), ``final_state`` / ``final_period`` (the continuation state) and ``elapsed_s`` (wall
    seconds of the cell).
    """
    if name not in ModelParameters.names():
        raise ParameterError(
            f"unknown sweep parameter '{name}'; allowed: {', '.join(ModelParameters.names())}"
        )
    if direction not in ("forward", "backward", "both"):
        raise ParameterError(f"direction = {direction!r}; allowed: forward, backward, both")
    if direction == "both":
        return [rec for d in ("forward", "backward")
                for rec in sweep_records(params, name, values, continuation=continuation,
                                         direction=d, settings=settings, progress=progress,
                                         backend=backend)]
    vals = np.sort(np.asarray(values, dtype=float))
    if direction == "backward":
        vals = vals[::-1]
    plist = [params.with_(**{name: float(v)}) for v in vals]
    stamps: list[float] = []
    t0 = time.perf_counter()

    def on_cell(i: int, _res: CellResult) -> None:
        stamps.append(time.perf_counter())
        if progress and ((i + 1) % 25 == 0 or i + 1 == len(plist)):
            progress(i + 1, len(plist), stamps[-1] - t0)

    if settings is not None and settings.method is Method.RK4:
        results = simulate_rows([plist], settings=settings, continuation=continuation,
                                on_cell=lambda _r, i, res: on_cell(i, res), backend=backend)[0]
        fill_margins(results, settings, backend)  # the Floquet margins, in shared kernel calls
    else:
        results = continuation_chain(plist, settings=settings, continuation=continuation,
                                     on_cell=on_cell)
    return _records(name, vals, direction, results, [t - prev for t, prev in
                                                      zip(stamps, [t0, *stamps[:-1]], strict=True)])


def _records(name: str, vals: np.ndarray, direction: str, results: Sequence[CellResult],
             elapsed: Sequence[float]) -> list[dict[str, Any]]:
    """The records of :func:`sweep_records` from a chain's results."""
    rows: list[dict[str, Any]] = []
    for v, r, dt in zip(vals, results, elapsed, strict=True):
        row = {"parameter": name, "value": float(v), "direction": direction}
        row.update(r.row())
        row["poincare_x"] = r.poincare[:, 0].tolist()
        row["poincare_v"] = r.poincare[:, 1].tolist()
        row["final_state"] = r.final_state.tolist()
        row["final_period"] = int(r.final_period)
        row["elapsed_s"] = dt
        rows.append(row)
    return rows


def sweep_records_many(
    specs: Sequence[tuple[ModelParameters, Sequence[float] | np.ndarray]],
    name: str,
    *,
    settings: IntegrationSettings,
    continuation: bool = True,
) -> list[list[dict[str, Any]]]:
    """Many forward sweeps of parameter ``name`` in one batched-kernel call: ``specs[k] =
    (params, values)``; ``out[k] == sweep_records(params, name, values, settings=settings,
    continuation=continuation)`` (each sweep one chain of :func:`simulate_rows`, the Floquet
    margins in shared kernel calls). ``settings.method`` must be ``"rk4"``; ``elapsed_s`` is the
    call's wall time shared out over its cells."""
    if settings.method is not Method.RK4:
        raise ParameterError("sweep_records_many: the batched path needs method rk4")
    if name not in ModelParameters.names():
        raise ParameterError(
            f"unknown sweep parameter '{name}'; allowed: {', '.join(ModelParameters.names())}"
        )
    vals = [np.sort(np.asarray(v, dtype=float)) for _p, v in specs]
    rows = [[p.with_(**{name: float(x)}) for x in vs] for (p, _v), vs in zip(specs, vals,
                                                                          strict=True)]
    t0 = time.perf_counter()
    results = simulate_rows(rows, settings=settings, continuation=continuation)
    fill_margins([r for chain in results for r in chain], settings)
    n = sum(len(v) for v in vals)
    dt = (time.perf_counter() - t0) / max(n, 1)
    return [_records(name, vs, "forward", res, [dt] * len(vs))
            for vs, res in zip(vals, results, strict=True)]


def orbit_diagram(params: ModelParameters, name: str, values: Sequence[float] | np.ndarray,
                  **options: Any) -> pd.DataFrame:
    """Sweep parameter ``name`` over ``values`` and classify the steady motion at each value.

    A DataFrame of :func:`sweep_records` (one row per value, sorted as swept); ``options`` are
    its keywords (continuation, direction, settings, progress).
    """
    return pd.DataFrame(sweep_records(params, name, values, **options))
