"""One source of truth: a nonlinearity added in one place reaches every integration path.

The test copies the package, adds a toy cubic mesh-spring term ``k3 x^3`` to the force in
``model.field_state`` and nothing else, and runs the copy in a fresh interpreter with its own
Numba cache. Scalar DP5, scalar RK4 and the batched SIMD kernel must all see the new term:
their Poincare points agree with an independent scipy DOP853 integration of the modified
equations written out here (which differ from the unmodified ones), and the batched kernel stays
bit-identical to the scalar RK4 path.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

ROOT = Path(__file__).resolve().parents[2]
K3 = 0.05

SCRIPT = r"""
import json, sys
import numpy as np
from gearsim.cell.chains import simulate_cells
from gearsim.dynamics.model import static_state
from gearsim.dynamics.parameters import ModelParameters
from gearsim.cell.simulate import IntegrationSettings, run_periods
p = ModelParameters(w=0.8, b=1.0, xi=0.1, Fe=0.05, Fm=0.1, eps=0.0, phi_e=0.0, friction=0.0,
                    model="1dof")
y0 = static_state(p.to_array())
out = {}
for method in ("dp5", "rk4"):
    st = IntegrationSettings(method=method, rtol=1e-11, atol=1e-13, steps_per_period=512)
    out[method] = run_periods(p, y0, 30, st).summaries.section[:, :2].tolist()
st = IntegrationSettings(method="rk4", transient=30, transient_continuation=10, chunk=8,
                         max_periods=16, tangent_lead=0, steps_per_period=256)
from gearsim.cell.simulate import simulate_cell
a = simulate_cells([p], settings=st)[0]
b = simulate_cell(p, settings=st)
out["batched_equals_scalar"] = bool(np.array_equal(a.poincare, b.poincare))
out["batched"] = a.poincare[:, :2].tolist()
print(json.dumps(out))
"""


def _run(src: Path, tmp: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(src), NUMBA_CACHE_DIR=str(tmp / "cache"))
    # a hang guard, not a speed target: the copy compiles every kernel from an empty cache
    # (~170 CPU s) beside the other pytest-xdist worker; 900 s ran out on a loaded machine
    res = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True,
                         text=True, timeout=2400, check=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


def _add_cubic_term(model_py: Path) -> None:
    """The one edit: a cubic mesh-spring term ``k3 x^3`` in the force of ``field_state``.

    Only the state paths are checked here: the tangent stages assume a Jacobian that is constant
    in the state within a contact region (the piecewise-linear field), so a genuinely nonlinear
    term would also need ``field_tangent`` to receive the state (docs/architecture.md).
    """
    text = model_py.read_text()
    old_f = "    F = (1.0 + eps * c) * (s0 * y[0] - r0 * b) + xi2 * y[1]\n"
    assert text.count(old_f) == 1
    text = text.replace(old_f, old_f + f"    F = F + {K3!r} * y[0] * y[0] * y[0]\n")
    model_py.write_text(text)


def _scipy_sections(k3: float, n: int = 30) -> np.ndarray:
    w, b, xi, Fe, Fm = 0.8, 1.0, 0.1, 0.05, 0.1
    T = 2 * math.pi / w

    def f(t, y):
        x, v = y
        fx = x - b if x > b else (x + b if x < -b else 0.0)
        F = fx + 2 * xi * v + k3 * x**3
        return [v, Fm + Fe * w * w * math.cos(w * t) - F]

    y = np.array([b + Fm, 0.0])
    out = [y]
    for k in range(n - 1):
        y = solve_ivp(f, (k * T, (k + 1) * T), y, method="DOP853", rtol=1e-12,
                      atol=1e-14).y[:, -1]
        out.append(y)
    return np.array(out)


def test_a_toy_nonlinearity_in_one_place_reaches_every_path(tmp_path):
    src = tmp_path / "src"
    shutil.copytree(ROOT / "src", src, ignore=shutil.ignore_patterns("__pycache__"))
    _add_cubic_term(src / "gearsim" / "dynamics" / "model.py")
    got = _run(src, tmp_path)
    ref = _scipy_sections(K3)
    plain = _scipy_sections(0.0)
    assert np.abs(ref - plain).max() > 1e-3  # the toy term matters
    for method in ("dp5", "rk4"):
        sec = np.array(got[method])
        np.testing.assert_allclose(sec, ref, atol=1e-6, err_msg=method)
    assert got["batched_equals_scalar"]
