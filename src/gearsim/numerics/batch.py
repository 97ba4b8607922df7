"""Batched runs: the lane storage of the SIMD kernel and the runs built on it.

:class:`Lanes` holds ``n`` lanes (cells) in the block layout of :mod:`gearsim.numerics.kernel`
and runs its :func:`~gearsim.numerics.kernel.advance`; :func:`run_periods_batched` is the batched
counterpart of :func:`gearsim.numerics.integrate.run_periods` and :func:`tangent_lanes_many` the
RK4 tangent map of :mod:`gearsim.numerics.variational` with one lane per tangent column. The chain
driver that moves lanes from cell to cell is :mod:`gearsim.cell.chains`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from gearsim.dynamics.model import N_MODE, N_PARAMS, N_STATE, N_SWITCH, pack_parameters
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.numerics.backend import CPU, CpuLanes, Part
from gearsim.numerics.integrate import IntegrationSettings, PeriodSummaries
from gearsim.numerics.kernel import lane_reset_modes
from gearsim.numerics.lanes_layout import (
    BLOCK,
    IST_DONE,
    IST_K,
    IST_POS,
    IST_ST,
    IST_STEPS,
    LANES,
    NI,
    NROW,
    O_FMAX,
    O_FMIN,
    O_LYAP,
    O_TDIS,
    O_XMAX,
    O_XMIN,
    ROW_H,
    ROW_PAR,
    ROW_Y,
)
from gearsim.numerics.steps import phase_tables, rk4_steps_per_period


# ============================================================================ lanes
def _counter(row: int, doc: str) -> property:
    """A lane counter: row ``row`` of ``ist`` (one entry per lane), a writable view."""
    return property(lambda self: self.ist[row], doc=doc)


class Lanes:
    """Storage of ``n`` lanes in blocks of :data:`LANES` (padding lanes are frozen).

    The lanes run on ``backend`` (:mod:`gearsim.numerics.backend`: the SIMD kernel by
    default, or the CUDA lane kernel with the same rows and records copied to the GPU and back).
    Callers read and write a lane through the accessors below, not the row constants.
    """

    def __init__(self, n: int, capacity: int, backend: CpuLanes | None = None):
        self.backend = CPU if backend is None else backend
        self.n = n
        self.n_blocks = max(1, -(-n // LANES))
        self.size = self.n_blocks * LANES
        self.blk = np.zeros(self.n_blocks * BLOCK)
        self.view = self.blk.reshape(self.n_blocks, NROW, LANES)
        self.ist = np.zeros((NI, self.size), dtype=np.int64)
        self.ist[IST_ST] = -1
        self.ist[IST_POS] = -1
        cap = max(1, int(capacity))
        self.sec = np.zeros((self.size, cap, N_STATE))
        self.nface = np.zeros((self.size, cap), dtype=np.int64)
        self.nback = np.zeros((self.size, cap), dtype=np.int64)
        self.fout = np.zeros((self.size, cap, 6))

    def _lane(self, lane: int) -> np.ndarray:
        return self.view[lane // LANES, :, lane % LANES]

    def set(self, lane: int, row: int, value) -> None:
        self._lane(lane)[row] = value

    def set_rows(self, lane: int, row: int, values) -> None:
        vals = np.asarray(values, dtype=float)
        self._lane(lane)[row : row + len(vals)] = vals

    def get_rows(self, lane: int, row: int, n: int) -> np.ndarray:
        return self._lane(lane)[row : row + n].copy()

    def set_column(self, row: int, values: np.ndarray) -> None:
        self.view[:, row, :] = np.asarray(values, dtype=float).reshape(self.n_blocks, LANES)

    def load_params(self, lane: int, params: ModelParameters, N: int,
                    packed: np.ndarray | None = None) -> None:
        """Write the packed parameters of ``params`` (``packed`` if given: the same array
        computed before) for ``N`` steps per period."""
        v = self._lane(lane)
        v[ROW_PAR : ROW_PAR + N_PARAMS] = pack_parameters(params) if packed is None else packed
        v[ROW_H] = params.mesh_period / N

    def load_state(self, lane: int, y: np.ndarray) -> None:
        """Set the state (10 or 20 entries) and the frozen regions as ``integrate_periods`` does."""
        self._lane(lane)[ROW_Y : ROW_Y + len(y)] = y
        self.reset_modes(lane)

    def reset_modes(self, lane: int) -> None:
        """Regions from the state (what ``integrate_periods`` does at the start of every call)."""
        lane_reset_modes(self.blk, lane, np.empty(N_PARAMS), np.empty(N_MODE, dtype=np.int64),
                         np.empty(N_STATE), np.empty(N_SWITCH), np.empty(N_SWITCH, dtype=np.bool_))

    def state(self, lane: int, n: int = 20) -> np.ndarray:
        return self.get_rows(lane, ROW_Y, n)

    def states(self, k: int, n: int = 20) -> np.ndarray:
        """The first ``n`` state rows of lanes ``0 .. k-1`` as a ``(k, n)`` copy."""
        idx = np.arange(k)
        return self.view[idx // LANES, ROW_Y : ROW_Y + n, idx % LANES]

    def run(self, N: int, m: int, nu: float, bound: float, tangent: bool = True) -> None:
        """Advance the lanes with status 0 by ``m`` periods on the backend."""
        self.backend.advance(self, N, m, phase_tables(N, nu), nu, bound, tangent)

    def run_part(self, N: int, nu: float, bound: float, tangent: bool, part: Part) -> int:
        """The lanes with status 0 through one part of a chain plan on the backend (its
        verdicts read back into ``part``); returns the periods run
        (:meth:`gearsim.numerics.backend.CpuLanes.run_part`)."""
        return self.backend.run_part(self, N, nu, bound, tangent, part)

    # ---- the lane counters (rows of ``ist``, one entry per lane; writable views)
    status = _counter(IST_ST, "0 running, 1 diverged, -1 not taking part in the next call.")
    done = _counter(IST_DONE, "Periods completed in the last call.")
    position = _counter(IST_POS, "Record position of the next call's first period (-1: not "
                        "recorded).")
    period = _counter(IST_K, "Absolute period index at the start of the next call (the "
                      "variable-ratio phase).")
    steps = _counter(IST_STEPS, "RK4 steps taken in the last call (the event layer's trial steps "
                     "included).")

    def begin_call(self) -> None:
        """No lane takes part and the per-call counters are zero (callers then enrol lanes)."""
        self.ist[IST_ST] = -1
        self.ist[IST_DONE] = 0
        self.ist[IST_STEPS] = 0

    # ---- a lane's rows
    def set_step(self, lane: int, h: float) -> None:
        """The lane's RK4 step (0 freezes it)."""
        self._lane(lane)[ROW_H] = h

    def set_steps(self, h: np.ndarray) -> None:
        """Every lane's RK4 step (0 freezes a lane)."""
        self.set_column(ROW_H, h)

    def freeze(self, lane: int) -> None:
        """The lane takes part in no call until it is loaded again."""
        self.ist[IST_ST, lane] = -1
        self._lane(lane)[ROW_H] = 0.0

    def set_tangent(self, lane: int, z) -> None:
        """The lane's tangent vector (10 entries)."""
        self.set_rows(lane, ROW_Y + N_STATE, z)

    def load_packed(self, lane: int, packed: np.ndarray, h: float) -> None:
        """Packed parameters (:func:`gearsim.dynamics.model.pack_parameters`) and the step."""
        v = self._lane(lane)
        v[ROW_PAR : ROW_PAR + N_PARAMS] = packed
        v[ROW_H] = h

    def column(self, lane: int) -> np.ndarray:
        """A copy of every row of the lane (to park it and :meth:`restore` it bit for bit)."""
        return self._lane(lane).copy()

    def restore(self, lane: int, col: np.ndarray) -> None:
        """Put back rows that :meth:`column` returned."""
        self.view[lane // LANES, :, lane % LANES] = col

    def gather(self, other: Lanes, old: np.ndarray) -> None:
        """Lanes ``old`` of ``other`` (rows, counters, records) into this one's first lanes."""
        old = np.asarray(old, dtype=np.int64)
        idx = np.arange(len(old))
        self.view[idx // LANES, :, idx % LANES] = other.view[old // LANES, :, old % LANES]
        self.ist[:, idx] = other.ist[:, old]
        for a in ("sec", "nface", "nback", "fout"):
            getattr(self, a)[idx] = getattr(other, a)[old]

    def summaries(self, lane: int, n: int, copy: bool = True) -> PeriodSummaries:
        """The first ``n`` recorded periods of ``lane`` (copies, or views into the buffers)."""
        f = self.fout[lane, :n]
        parts = (
            self.sec[lane, :n], self.nface[lane, :n], self.nback[lane, :n], f[:, O_TDIS],
            f[:, O_FMAX], f[:, O_FMIN], f[:, O_XMAX], f[:, O_XMIN], f[:, O_LYAP],
        )  # fmt: skip
        if copy:
            parts = tuple(a.copy() for a in parts)
        return PeriodSummaries(*parts)


def steps_per_period(params: ModelParameters, settings: IntegrationSettings) -> int:
    """RK4 steps per mesh period (:func:`gearsim.numerics.steps.rk4_steps_per_period`)."""
    return rk4_steps_per_period(params, settings)


def run_periods_batched(
    params_list: Sequence[ModelParameters],
    states: np.ndarray,
    n_periods: int,
    settings: IntegrationSettings | None = None,
    *,
    start_periods: Sequence[int] | None = None,
    tangent: bool = True,
    backend: CpuLanes | None = None,
) -> tuple[list[PeriodSummaries], np.ndarray, np.ndarray, np.ndarray]:
    """Integrate every cell ``n_periods`` periods from ``states`` (rows of 20: state, tangent).

    The batched counterpart of ``simulate.run_periods(..., tangent=tangent)`` with RK4 (all
    cells must have the same steps per period). Returns ``(summaries, final_states, status,
    steps)``. With ``tangent=False`` the tangent rows are not integrated (the summaries'
    ``lyap`` and the final tangent are then meaningless); the state, section points and event
    records are bit-identical to ``tangent=True`` (the event layer decides on the state only;
    tests/integration/test_attractors.py). ``backend``: where the lanes run (default the CPU).
    """
    st = settings or IntegrationSettings(method="rk4")
    n = len(params_list)
    Ns = {steps_per_period(p, st) for p in params_list}
    if len(Ns) != 1:
        raise ParameterError("run_periods_batched: all cells need the same steps per period")
    N = Ns.pop()
    nus = {p.var_ratio_order for p in params_list if p.var_ratio != 0.0}
    if len(nus) > 1:
        raise ParameterError("run_periods_batched: cells with different var_ratio_order")
    nu = nus.pop() if nus else 0.0
    lanes = Lanes(n, n_periods, backend)
    ks = [0] * n if start_periods is None else list(start_periods)
    for l, p in enumerate(params_list):
        lanes.load_params(l, p, N)
        lanes.load_state(l, np.asarray(states[l], dtype=float))
        lanes.ist[IST_ST, l] = 0
        lanes.ist[IST_POS, l] = 0
        lanes.ist[IST_K, l] = ks[l]
    lanes.run(N, n_periods, nu, getattr(st, "divergence_bound", 1.0e6), bool(tangent))
    out = []
    for l in range(n):
        out.append(lanes.summaries(l, int(lanes.ist[IST_DONE, l])))
    finals = np.array([lanes.state(l) for l in range(n)])
    return out, finals, lanes.ist[IST_ST, :n].copy(), lanes.ist[IST_STEPS, :n].copy()



def tangent_lanes_many(
    params_list: Sequence[ModelParameters],
    y0s: Sequence[np.ndarray],
    n_periods: int,
    settings: IntegrationSettings,
    Zs: Sequence[np.ndarray],
    start_periods: Sequence[int] | None = None,
    packed: Sequence[np.ndarray] | None = None,
    backend: CpuLanes | None = None,
) -> list[tuple[np.ndarray, np.ndarray, int]]:
    """:func:`gearsim.numerics.variational.tangent_map` for RK4 of many cells in one kernel
    call, one SIMD lane per cell and tangent column (the blocks full). Every lane of a cell
    carries its state and parameters and one column of its ``Z``: the state's steps, and so
    every event redo, are those of the scalar RK4 path, and each column's image is the product
    of the same per-step tangent maps (bit-identical to one scalar run per column,
    tests/unit/test_batch.py). The cells must share the step grid (steps per period,
    variable-ratio order); lanes are independent, so each cell's result is that of its own
    call. ``packed``: the cells' packed parameters if the caller has them; ``backend``: where
    the lanes run (default the CPU). Returns one
    ``(y_end, DPhi Z, status)`` per cell."""
    N = steps_per_period(params_list[0], settings)
    p0 = params_list[0]
    nu = p0.var_ratio_order if p0.var_ratio != 0.0 else 0.0
    for p in params_list:
        if steps_per_period(p, settings) != N or (p.var_ratio != 0.0 and p.var_ratio_order != nu):
            raise ParameterError("tangent_lanes_many: all cells need one step grid")
    ks = [0] * len(params_list) if start_periods is None else list(start_periods)
    plan = []  # (columns, indices of the nonzero ones, first lane, norms)
    lane = 0
    for Z in Zs:
        Z = np.asarray(Z, dtype=float).reshape(N_STATE, -1)
        norms = np.linalg.norm(Z, axis=0)
        cols = np.flatnonzero(norms > 0.0)
        plan.append((Z, cols, lane, norms))
        lane += len(cols)
    out: list[tuple[np.ndarray, np.ndarray, int]] = []
    if lane == 0:
        return [(np.asarray(y, dtype=float)[:N_STATE].copy(), np.zeros_like(Z), 0)
                for y, (Z, *_rest) in zip(y0s, plan, strict=True)]
    lanes = Lanes(lane, n_periods, backend)
    v = lanes.view
    unit = np.zeros((lane, N_STATE))  # each lane's unit tangent column
    scale = np.zeros(lane)  # its norm
    for c, (Z, cols, l0, norms) in enumerate(plan):
        if len(cols) == 0:
            continue
        y0 = np.asarray(y0s[c], dtype=float)[:N_STATE]
        lanes.load_params(l0, params_list[c], N, None if packed is None else packed[c])
        lanes.load_state(l0, y0)
        idx = np.arange(l0, l0 + len(cols))
        # the first lane's rows (parameters, state, regions) into the cell's other lanes
        v[idx // LANES, :, idx % LANES] = v[l0 // LANES, :, l0 % LANES]
        unit[idx] = (Z[:, cols] / norms[cols]).T
        scale[idx] = norms[cols]
        lanes.ist[IST_K, idx] = ks[c]
    every = np.arange(lane)
    v[every // LANES, ROW_Y + 10 : ROW_Y + 20, every % LANES] = unit
    lanes.ist[IST_ST, :lane] = 0
    lanes.ist[IST_POS, :lane] = 0
    lanes.run(N, n_periods, nu, float(getattr(settings, "divergence_bound", 1.0e6)), True)
    growth = np.ascontiguousarray(lanes.fout[:lane, :n_periods, O_LYAP]).sum(axis=1)
    image = v[every // LANES, ROW_Y + 10 : ROW_Y + 20, every % LANES]  # (lanes, 10)
    status = lanes.ist[IST_ST, :lane]
    for ln in range(lane):
        scale[ln] *= math.exp(growth[ln])  # math.exp: the scalar path's rounding
    image = image * scale[:, None]
    image[status != 0] = np.nan
    finals = v[every // LANES, ROW_Y : ROW_Y + N_STATE, every % LANES]
    for c, (Z, cols, l0, _) in enumerate(plan):
        res = np.zeros_like(Z)
        y0 = np.asarray(y0s[c], dtype=float)[:N_STATE]
        if len(cols) == 0:
            out.append((y0.copy(), res, 0))
            continue
        st = int(status[l0 : l0 + len(cols)].max())
        res[:, cols] = image[l0 : l0 + len(cols)].T
        out.append((finals[l0].copy() if st == 0 else y0.copy(), res, st))
    return out
