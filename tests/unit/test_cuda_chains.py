"""The chain driver on the CUDA lane kernel (the period test's verdict inside the thread) against
the CPU driver, and the device faults a launch reports in one line.

Runs under Numba's CUDA simulator (``NUMBA_ENABLE_CUDASIM=1`` before Numba is imported: ``make
test``'s own pytest step) or on a GPU; skipped elsewhere. The simulator runs the thread's own
code: the chunks, the verdict (:func:`gearsim.cell.classify.window_period` and
:func:`gearsim.cell.verdict.measure_verdict`, the host's functions), the regions' reset between
chunks and the records read by the verdict, so a wrong chunk boundary or record shows as a
label, a period or a step count that differs from the CPU path's.

Few cells, few periods (the simulator runs the thread's loop in Python): two chains of three
cells, from rest and continued, periodic motions of periods 1 and 2 that settle after one or
several chunks. Tolerances: the CUDA kernel's against the CPU kernel's (test_cuda_lanes: the
compilers' multiply-add contraction, far below the step error), labels, periods, step counts
and status equal.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from gearsim.cell.chains import simulate_rows
from gearsim.cell.simulate import IntegrationSettings
from gearsim.dynamics.parameters import ModelParameters
from gearsim.numerics import batch, kernel
from gearsim.numerics.backend import CudaLanes, select
from gearsim.numerics.device import DeviceError, _probe

_name, _version, _simulated, _why = _probe()
pytestmark = pytest.mark.skipif(
    bool(_why) or not (_simulated or os.environ.get("GEARSIM_TEST_GPU") == "1"),
    reason="the CUDA lane kernel runs under NUMBA_ENABLE_CUDASIM=1 (make test) or on a GPU "
    f"with GEARSIM_TEST_GPU=1 ({_why or 'no simulator'})",
)

ATOL = 1e-9  # test_cuda_lanes' SUMMARY_ATOL: the CPU kernel's against the scalar path
ST = IntegrationSettings(method="rk4", transient=24, transient_continuation=8, chunk=8,
                         max_periods=32, n_max=8, tangent_lead=4, steps_per_period=64)
ROWS = [[ModelParameters(w=w, b=b) for w in (0.9, 1.0, 1.1)] for b in (0.1, 0.6)]
#: a chaotic cell: measured to max_periods, the verdict's other stop (its records part from the
#: CPU's at the chaos' rate: its label, period and status compared, not its numbers)
CHAOS = [ModelParameters(w=1.45, b=1.0)]


@pytest.fixture(scope="module")
def both():
    """The same chains on the CPU and on the CUDA lanes, with the kernel calls counted."""
    from gearsim.numerics import cuda_lanes

    calls = {"cpu": 0, "cuda": 0}
    real = {"cpu": kernel.advance, "cuda": cuda_lanes.advance_device}

    def counted(kind):
        def call(*a, **k):
            calls[kind] += 1
            return real[kind](*a, **k)
        return call

    mp = pytest.MonkeyPatch()
    mp.setattr(kernel, "advance", counted("cpu"))
    mp.setattr(cuda_lanes, "advance_device", counted("cuda"))
    out = {}
    try:
        for kind in ("cpu", "cuda"):
            out[kind] = simulate_rows(ROWS + [CHAOS], settings=ST, backend=select(kind))
    finally:
        mp.undo()
    return out, calls


def test_chains_on_the_gpu_match_the_cpu_driver(both):
    out, _ = both
    labels = set()
    (c,), (g,) = out["cpu"][-1], out["cuda"][-1]
    assert c.classification.n == 0 and c.final_period == ST.transient + ST.max_periods
    assert (g.classification.label, g.classification.n, g.classification.status,
            g.final_period) == (c.classification.label, 0, c.classification.status,
                                c.final_period)
    for cpu_row, gpu_row in zip(out["cpu"][:-1], out["cuda"][:-1], strict=True):
        for c, g in zip(cpu_row, gpu_row, strict=True):
            assert g.classification.label == c.classification.label
            assert g.classification.n == c.classification.n
            assert g.classification.status == c.classification.status
            assert (g.final_period, g.periods, g.steps) == (c.final_period, c.periods, c.steps)
            np.testing.assert_allclose(g.final_state, c.final_state, rtol=0, atol=ATOL)
            np.testing.assert_allclose(g.poincare, c.poincare, rtol=0, atol=ATOL)
            labels.add(c.classification.label)
    # not vacuous: both periods, and cells measured over more than one chunk (the device went
    # on from a chunk whose verdict was "measure on")
    assert {"1/1T", "1/2T"} <= labels
    assert max(r.periods - ST.transient_continuation for row in out["cpu"][:-1] for r in row[1:]) \
        > ST.chunk + ST.tangent_lead


def test_gpu_chains_take_the_verdict_on_the_device(both):
    _, calls = both
    # the CPU driver returns to the host at every measuring chunk's end; the GPU lanes go on
    assert 0 < calls["cuda"] < calls["cpu"]


def _lanes(n: int, m: int) -> tuple[batch.Lanes, int]:
    p = ModelParameters(w=1.0, b=0.3)
    N = batch.steps_per_period(p, ST)
    lanes = batch.Lanes(n, m, select("cuda"))
    lanes.begin_call()
    for l in range(n):
        lanes.load_params(l, p, N)
        lanes.load_state(l, np.zeros(20))
        lanes.status[l] = 0
        lanes.position[l] = 0
    return lanes, N


def test_lanes_beyond_the_gpus_memory_are_refused_before_launch(monkeypatch):
    from gearsim.numerics import cuda_lanes

    lanes, N = _lanes(16, 4)
    need = cuda_lanes.launch_bytes(lanes.size, 4, N)
    monkeypatch.setattr(cuda_lanes, "free_bytes", lambda: need - 1)
    blk, ist = lanes.blk.copy(), lanes.ist.copy()
    with pytest.raises(DeviceError) as err:
        lanes.run(N, 4, 0.0, 1.0e6)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith("execution.device: cuda (")
    assert "GiB" in msg and "execution.lanes" in msg and f"{lanes.size} lanes x 4 periods" in msg
    np.testing.assert_array_equal(lanes.blk, blk)  # nothing changed on the host
    np.testing.assert_array_equal(lanes.ist, ist)
    monkeypatch.setattr(cuda_lanes, "free_bytes", lambda: need)
    lanes.run(N, 4, 0.0, 1.0e6)  # exactly what it needs: runs
    assert list(lanes.done[:16]) == [4] * 16


def test_a_fault_inside_a_launch_is_one_line_and_leaves_the_host_arrays(monkeypatch):
    from numba.cuda.cudadrv import driver

    from gearsim.numerics import cuda_lanes

    class Faulting:
        def __getitem__(self, config):
            def launch(*args):
                raise driver.CudaAPIError(700, "an illegal memory access was encountered\nmore")
            return launch

    lanes, N = _lanes(8, 2)
    blk, sec = lanes.blk.copy(), lanes.sec.copy()
    monkeypatch.setattr(cuda_lanes, "advance_kernel", Faulting())
    with pytest.raises(DeviceError) as err:
        lanes.run(N, 2, 0.0, 1.0e6)
    msg = str(err.value)
    assert "\n" not in msg and "illegal memory access" in msg and "execution.device: cuda" in msg
    np.testing.assert_array_equal(lanes.blk, blk)
    np.testing.assert_array_equal(lanes.sec, sec)


def test_the_finder_on_the_gpu_fills_it_and_keeps_its_labels(monkeypatch):
    """The lane pool on cuda is as wide as the GPU holds (multiprocessors x
    POOL_LANES_PER_SM), its measuring lanes take the verdict on the device, and it finds the
    CPU's attractors with the same labels and periods."""
    from gearsim.analysis.attractors import FinderOptions, find_attractors
    from gearsim.cell import pool

    widths = []
    real = pool._Pool.__init__

    def init(self, capacity, records, history=0, backend=None):
        widths.append(capacity)
        real(self, capacity, records, history, backend)

    monkeypatch.setattr(pool._Pool, "__init__", init)
    from gearsim.numerics import cuda_lanes

    planned = []
    launch = cuda_lanes.advance_device

    def counted(*a, **kw):
        planned.append(kw.get("plan") is not None)
        return launch(*a, **kw)

    monkeypatch.setattr(cuda_lanes, "advance_device", counted)
    cell = ModelParameters(w=1.0, b=0.1)
    opts = FinderOptions(starts=4, seed=0, lanes=2)
    found = {}
    for kind in ("cpu", "cuda"):
        backend = select(kind)
        widths.clear()
        found[kind] = find_attractors(cell, opts, settings=ST, backend=backend)
        probe_width = widths[1] if len(widths) > 1 else None  # the measuring pool is first
        want = 2 if kind == "cpu" else max(
            2, backend.device.multiprocessors * CudaLanes.POOL_LANES_PER_SM)
        assert probe_width == want
    # the probing pool's chunks go back to the judge; the measuring lanes take the verdict on
    # the GPU (the chain driver's plan)
    assert any(planned) and not all(planned)
    cpu, gpu = found["cpu"], found["cuda"]
    labels = [a.steady.label for a in cpu.attractors]
    assert [a.steady.label for a in gpu.attractors] == labels
    assert [a.steady.period for a in gpu.attractors] == [a.steady.period for a in cpu.attractors]
    assert [a.n_starts for a in gpu.attractors] == [a.n_starts for a in cpu.attractors]
    np.testing.assert_array_equal(gpu.start_labels, cpu.start_labels)
    assert labels  # not vacuous
