"""The numerically sensitive tests pass on AVX2 code as well as on this CPU's native code.

The double-sided impacting cells amplify rounding differences of the instruction set (FMA
contraction, vector width) along the horizon; their tolerances come from the problem's
conditioning (tests/unit/test_integrate.py), so the same assertions must hold when Numba compiles
for an AVX2 target (``NUMBA_CPU_NAME=haswell``, the host's features without AVX-512) on this
machine, whatever its own CPU.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from gearsim.numerics.cache import avx2_features

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.timeout(1800)
def test_switch_time_tests_pass_on_avx2_code(tmp_path):
    # the CPU name alone keeps the host's features (AVX-512 code on an AVX-512 machine)
    env = {**os.environ, "NUMBA_CPU_NAME": "haswell", "NUMBA_CPU_FEATURES": avx2_features()}
    env.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".numba_cache"))
    res = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist",
         "tests/unit/test_integrate.py", "-k", "poincare_points_and_switch_times"],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=1700,
    )
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-2000:]
    assert "8 passed" in res.stdout
