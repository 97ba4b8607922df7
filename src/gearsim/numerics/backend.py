"""The lanes backends: where the periods of a lanes object run, and the one way to run a part of
a chain plan and read the verdicts back.

:func:`select` returns one of two backends, and the callers
(:mod:`gearsim.cell`, :mod:`gearsim.analysis`, the commands) hand it on; none of them asks which
it is:

* :data:`CPU`: the SIMD kernel (:func:`gearsim.numerics.kernel.advance`). A part runs until the
  first of its lanes reaches its next decision; every verdict is taken on the host.
* :class:`CudaLanes`: the CUDA lane kernel (:mod:`gearsim.numerics.cuda_lanes`). A measuring lane
  goes on from chunk to chunk inside the launch and takes its verdict there (the caller's verdict
  kernel, :attr:`Part.verdict`), so only the other lanes' next decisions end the launch.

A :class:`Part` says, per lane, how many periods are left to its next decision, whether it
measures, and what it measured and stepped before; after :meth:`run_part` its ``left`` holds
the periods still left and ``period`` the period a verdict taken inside the call stopped the
lane with (-1: none, the caller decides on the host when ``left`` is 0).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gearsim.numerics.device import Device, resolve


@dataclass
class Part:
    """One call of a chain plan over the lanes that take part (arrays over every lane)."""

    left: np.ndarray  # in: periods to each lane's next decision; out: periods still left
    measuring: np.ndarray  # a measuring lane (a verdict may be taken inside the call)
    measured: np.ndarray  # periods the lane measured before the call (its records' position)
    steps: np.ndarray  # RK4 steps of the lane's cell before the call (the budget's count)
    #: ``(chunk, max_periods, n_max, period_rtol, max_steps)`` of the verdict
    test: tuple = (1, 1, 1, 0.0, 0)
    #: the lane kernel that takes the verdict inside a launch, made on demand (a device's only)
    verdict: Callable[[], Any] | None = None
    period: np.ndarray = field(init=False)  # out: a verdict's period (-1: none)

    def __post_init__(self) -> None:
        self.period = np.full(len(self.left), -1, dtype=np.int64)

    @classmethod
    def empty(cls, size: int, **kw: Any) -> Part:
        z = np.zeros(size, dtype=np.int64)
        return cls(z, np.zeros(size, dtype=bool), z.copy(), z.copy(), **kw)


class CpuLanes:
    """The SIMD kernel on this CPU (:data:`CPU`). Its methods take a lanes object
    (:class:`gearsim.numerics.batch.Lanes`, which runs on a backend: this module does not
    import it)."""

    kind = "cpu"
    #: a job's rows go best into one lanes object in one process (a GPU: one launch fills it),
    #: not mapped over worker processes
    one_lanes_object = False

    def __init__(self, device: Device | None = None):
        self.device = device or Device()

    def record(self) -> dict | None:
        """The provenance record of the device (None for the default CPU run: its files stay
        as they were)."""
        return self.device.record()

    def pool_lanes(self, cpu_lanes: int) -> int:
        """The width of the finder's probing pool: ``cpu_lanes`` (its ``lanes`` option)."""
        return cpu_lanes

    def advance(self, lanes, N: int, m: int, tables: tuple, nu: float, bound: float,
                tangent: bool) -> None:
        """Every lane with status 0 advanced by ``m`` periods (:func:`kernel.advance`)."""
        from gearsim.numerics import kernel

        kernel.advance(lanes.blk, lanes.ist, int(N), int(m), *tables, float(nu), float(bound),
                       lanes.sec, lanes.nface, lanes.nback, lanes.fout, bool(tangent))

    def run_part(self, lanes, N: int, nu: float, bound: float, tangent: bool,
                 part: Part) -> int:
        """The lanes with status 0 until the first reaches its next decision; returns the
        periods run. No verdict is taken here: ``part.period`` stays -1."""
        idx = np.flatnonzero(lanes.status == 0)
        m = int(part.left[idx].min())
        lanes.run(N, m, nu, bound, tangent)
        part.left[idx] -= lanes.done[idx]
        return m


#: the CPU backend (the default of every lanes object)
CPU = CpuLanes()


class CudaLanes(CpuLanes):
    """The CUDA lane kernel on the GPU of ``device`` (its records copied to the host after each
    launch; :mod:`gearsim.numerics.cuda_lanes` is loaded on the first launch)."""

    kind = "cuda"
    one_lanes_object = True

    #: lanes of the finder's probing pool per multiprocessor: 8 blocks of 128 threads, half of
    #: the 2 048 threads a multiprocessor of compute capability 9.0 keeps resident (the lane
    #: kernel's registers and ~1 kB of local memory per thread leave no more;
    #: docs/decisions.md)
    POOL_LANES_PER_SM = 1024

    def pool_lanes(self, cpu_lanes: int) -> int:
        """At least the GPU's multiprocessors x :data:`POOL_LANES_PER_SM` (an H200's 132:
        135 168 lanes), so that a launch fills it."""
        return max(cpu_lanes, self.device.multiprocessors * self.POOL_LANES_PER_SM)

    def advance(self, lanes, N: int, m: int, tables: tuple, nu: float, bound: float,
                tangent: bool, *, kernel=None, plan: np.ndarray | None = None,
                test: tuple = (1, 1, 1, 0.0, 0)) -> None:
        from gearsim.numerics import cuda_lanes

        cuda_lanes.advance_device(lanes.blk, lanes.ist, int(N), int(m), tables, float(nu),
                                  float(bound), lanes.sec, lanes.nface, lanes.nback, lanes.fout,
                                  bool(tangent), kernel=kernel, plan=plan, test=test,
                                  device=self.device)

    def run_part(self, lanes, N: int, nu: float, bound: float, tangent: bool,
                 part: Part) -> int:
        """One launch: the measuring lanes take their verdicts inside it, chunk after chunk,
        so only the other lanes' next decisions end it (all measuring: the longest measurement
        left). Returns the launch's periods."""
        from gearsim.numerics import cuda_lanes
        from gearsim.numerics.steps import phase_tables

        idx = np.flatnonzero(lanes.status == 0)
        meas = idx[part.measuring[idx]]
        others = idx[~part.measuring[idx]]
        max_periods = part.test[1]
        m = int(part.left[others].min()) if len(others) else \
            int((max_periods - part.measured[meas]).max())
        plan = cuda_lanes.make_plan(len(part.left), idx, meas, m, part.left, part.measured,
                                    part.steps)
        self.advance(lanes, N, m, phase_tables(N, nu), nu, bound, tangent,
                     kernel=part.verdict() if part.verdict else None, plan=plan,
                     test=part.test)
        part.left[others] -= lanes.done[others]
        part.left[meas] = plan[cuda_lanes.PLAN_NEXT, meas]
        part.period[meas] = plan[cuda_lanes.PLAN_N, meas]
        return m


def select(asked: str, setting: str = "execution.device") -> CpuLanes:
    """The lanes backend of ``asked`` (cpu, cuda or auto: :func:`gearsim.numerics.device.resolve`,
    one line where it cannot run)."""
    dev = resolve(asked, setting)
    if dev.kind == "cuda":
        return CudaLanes(dev)
    return CPU if dev == CPU.device else CpuLanes(dev)
