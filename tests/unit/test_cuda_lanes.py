"""The CUDA lane kernel (gearsim.numerics.cuda_lanes) against the CPU kernel, lane by lane.

Runs under Numba's CUDA simulator (``NUMBA_ENABLE_CUDASIM=1`` set before Numba is imported:
``make test``'s own pytest step) or on a GPU; skipped elsewhere. The simulator executes the
kernel's own code (the thread's period loop, the flagged-step redo, the divergence stop, the
record placement) and calls the one ``@njit`` field, step and event layer, so a wrong index, a
missed redo or a misplaced record shows here; the PTX compile of the same kernel for the GPU is
tests/unit/test_cuda_ptx.py.

The two kernels run the same algorithm on the same lane rows; they differ only where the
compilers round differently (multiply-add contraction). Over a few periods that is far below the
RK4 step's own error (h^5 ~ 1e-8 at 256 steps a period): the tolerances are the CPU kernel's
against the scalar path (tests/unit/test_batch.py), and the impact counts and status are equal.
"""

from __future__ import annotations

import os

import numpy as np
import pytest
from reference import reference_settings

from gearsim.cell.simulate import initial_tangent, run_periods
from gearsim.dynamics.model import static_state
from gearsim.dynamics.parameters import ModelParameters
from gearsim.numerics import batch
from gearsim.numerics.backend import select
from gearsim.numerics.device import _probe

_name, _version, _simulated, _why = _probe()
pytestmark = pytest.mark.skipif(
    bool(_why) or not (_simulated or os.environ.get("GEARSIM_TEST_GPU") == "1"),
    reason="the CUDA lane kernel runs under NUMBA_ENABLE_CUDASIM=1 (make test) or on a GPU "
    f"with GEARSIM_TEST_GPU=1 ({_why or 'no simulator'})",
)

RK4 = reference_settings(method="rk4")
SUMMARY_ATOL = 1e-9  # the CPU kernel's tolerance against the scalar path (test_batch)
LYAP_ATOL = 1e-8

#: The kernel test cells: impacts (double-sided), bearing clearances, every model form,
#: friction with the arm's variation, variable ratio, the single-DOF model, chaos.
CELLS = [
    ModelParameters(w=0.76, b=0.15),  # double-sided impacts
    ModelParameters(w=0.9, b=0.3, b_py=0.002, b_gz=0.003),  # bearing channels switch
    ModelParameters(w=1.0, b=0.3, te_damping=0.5),  # model form: TE rate in the damper
    ModelParameters(w=1.1, b=0.3, mesh_damping_contact=0.5),  # form: damping only in contact
    ModelParameters(w=1.2, b=0.3, friction=0.1, friction_arm_var=0.3),  # friction, its arm
    ModelParameters(w=1.25, b=0.3, var_ratio=0.02),  # variable ratio
    ModelParameters(w=0.8, b=0.3, model="1dof"),  # single-DOF
    ModelParameters(w=1.45, b=1.0),  # chaos
]
PERIODS = 3


def _lanes(device, cells, y0, n_lanes, start=60):
    """Lanes of ``cells`` (one each, then frozen padding lanes up to ``n_lanes``)."""
    N = batch.steps_per_period(cells[0], RK4)
    lanes = batch.Lanes(n_lanes, PERIODS + 2, select(device))
    lanes.begin_call()
    for l, p in enumerate(cells):
        lanes.load_params(l, p, N)
        lanes.load_state(l, y0[l])
        lanes.status[l] = 0
        lanes.position[l] = 1  # records placed after an existing one
        lanes.period[l] = start
    return lanes, N


def _start(cells):
    ys = []
    for p in cells:
        r = run_periods(p, static_state(p.to_array()), 60, RK4)
        ys.append(np.concatenate([r.state, initial_tangent(p)]))
    return np.array(ys)


@pytest.fixture(scope="module")
def both():
    """The same lanes run on the CPU kernel and on the CUDA kernel."""
    groups = {}
    for nu, cells in ((0.0, [c for c in CELLS if c.var_ratio == 0.0]),
                      (1.0, [c for c in CELLS if c.var_ratio != 0.0])):
        y0 = _start(cells)
        runs = []
        for device in ("cpu", "cuda"):
            lanes, N = _lanes(device, cells, y0, len(cells) + 3)
            lanes.run(N, PERIODS, nu, 1.0e6, True)
            runs.append(lanes)
        groups[nu] = (cells, *runs)
    return groups


def test_cuda_lanes_match_the_cpu_kernel(both):
    impacts = 0
    for cells, cpu, gpu in both.values():
        n = len(cells)
        np.testing.assert_array_equal(gpu.status[:n], 0)
        np.testing.assert_array_equal(gpu.done[:n], PERIODS)
        np.testing.assert_array_equal(gpu.ist, cpu.ist)  # steps, counters, frozen padding
        np.testing.assert_array_equal(gpu.nface, cpu.nface)
        np.testing.assert_array_equal(gpu.nback, cpu.nback)
        np.testing.assert_allclose(gpu.sec, cpu.sec, rtol=0, atol=SUMMARY_ATOL)
        f = batch.O_LYAP
        np.testing.assert_allclose(gpu.fout[..., :f], cpu.fout[..., :f], rtol=0,
                                   atol=SUMMARY_ATOL)
        np.testing.assert_allclose(gpu.fout[..., f], cpu.fout[..., f], rtol=0, atol=LYAP_ATOL)
        for l in range(n):
            np.testing.assert_allclose(gpu.state(l), cpu.state(l), rtol=0, atol=SUMMARY_ATOL)
        # records land at each lane's position; slot 0 and the padding lanes stay untouched
        assert not gpu.sec[:, 0].any() and not gpu.sec[n:].any()
        assert gpu.sec[:n, 1 : 1 + PERIODS].any()
        impacts += int(cpu.nface.sum() + cpu.nback.sum())
    assert impacts > 10  # not vacuous: the event layer ran inside the threads


def test_cuda_lane_that_diverges_stops_alone():
    good = ModelParameters(w=1.0, b=0.3)
    y = np.tile(np.concatenate([static_state(good.to_array()), initial_tangent(good)]), (2, 1))
    y[1, 0] = 1e7  # beyond the divergence bound after the first step
    out = []
    for device in ("cpu", "cuda"):
        lanes, N = _lanes(device, [good, good], y, 2, start=0)
        lanes.run(N, 2, 0.0, 1.0e6, True)
        out.append(lanes)
    cpu, gpu = out
    assert list(gpu.status[:2]) == [0, 1]
    assert list(gpu.done[:2]) == [2, 0]
    np.testing.assert_array_equal(gpu.steps[:2], cpu.steps[:2])
    np.testing.assert_allclose(gpu.sec[0], cpu.sec[0], rtol=0, atol=SUMMARY_ATOL)
    np.testing.assert_array_equal(gpu.state(1), cpu.state(1))  # frozen where it stopped
