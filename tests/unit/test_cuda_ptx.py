"""The CUDA lane kernel compiles to PTX for the H200's compute capability (9.0), no GPU present.

numba-cuda compiles the kernel and the ``@njit`` field, step and event layer it calls as device
code; this catches what the CUDA target cannot type or lower (an allocation, an unsupported
intrinsic) without a GPU. Skipped where numba-cuda or libNVVM (its ``[cu13]`` extra) is not
installed, and under the simulator (which has no compiler).
"""

from __future__ import annotations

import importlib.util
import os
import types

import pytest

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("numba_cuda") is None
    or os.environ.get("NUMBA_ENABLE_CUDASIM") == "1",
    reason="needs numba-cuda (pip install -e '.[gpu]') and no simulator",
)


def test_lane_kernels_compile_to_ptx_for_cc90(monkeypatch):
    from numba import cuda
    from numba import types as nt
    from numba.cuda import dispatcher

    # the device functions' compile asks the driver for the current GPU's compute capability:
    # answer it as an H200 would (no driver here)
    monkeypatch.setattr(dispatcher, "get_current_device",
                        lambda: types.SimpleNamespace(compute_capability=(9, 0)))
    from gearsim.numerics import cuda_lanes

    f1, i2, f3 = nt.float64[::1], nt.int64[:, ::1], nt.float64[:, :, ::1]
    sig = (f1, i2, nt.int64, nt.int64, f1, f1, f1, f1, f1, f1, nt.float64, nt.float64, f3, i2,
           i2, f3, nt.boolean, nt.boolean, i2, nt.int64, nt.int64, nt.int64, nt.float64,
           nt.int64)
    try:
        ptx, _ = cuda.compile_ptx(cuda_lanes.advance_kernel.py_func, sig, cc=(9, 0))
    except Exception as exc:  # libNVVM missing: the [cu13] extra did not install here
        if "NVVM" in type(exc).__name__ or "libNVVM" in str(exc):
            pytest.skip(f"libNVVM not available: {str(exc).splitlines()[0]}")
        raise
    assert ".target sm_90" in ptx
    assert ".entry" in ptx
    # the RK4 step's arithmetic is there as fused multiply-adds (~1 800 with the event layer)
    assert ptx.count("fma.rn.f64") > 500

    # the chain kernel: the same lanes with the chain driver's verdict (the period test of
    # cell/classify and the driver's rule) compiled into the thread, no allocation in it
    from gearsim.cell import device_chains

    chain, _ = cuda.compile_ptx(device_chains.chain_kernel.py_func, sig, cc=(9, 0))
    assert ".target sm_90" in chain
    assert chain.count("fma.rn.f64") >= ptx.count("fma.rn.f64")
    # the period test's comparisons and divisions are in it, and no call into the allocator
    assert chain.count("div.rn.f64") > ptx.count("div.rn.f64")
    assert "NRT_MemInfo" not in chain and "malloc" not in chain
