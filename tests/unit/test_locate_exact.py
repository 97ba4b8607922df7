"""fidelity.locate_exact against independent references.

Two 1-DOF cases whose bifurcation points are known without gearsim:

- grazing: with ``eps = 0`` the orbit in contact is the linear forced oscillator
  ``x'' + 2 xi x' + (x - b) = Fm + Fe w^2 cos(w tau + phi)``; its steady amplitude is
  ``A(w) = Fe w^2 / sqrt((1 - w^2)^2 + (2 xi w)^2)`` and it grazes the backlash edge where
  ``A(w) = Fm`` (closed form, root by brentq);
- period doubling: in contact the 1T orbit's Floquet multipliers are those of the damped
  Mathieu equation ``y'' + 2 xi y' + (1 + eps cos w tau) y = 0`` (the forcing does not enter);
  the doubling is where one multiplier is -1, located here by brentq on the monodromy matrix
  integrated with scipy's DOP853 (the equation written out in this file, not gearsim's field).
"""

import math

import numpy as np
import pandas as pd
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from gearsim.calibration.fidelity import locate_exact
from gearsim.dynamics.parameters import ModelParameters

BASE = dict(model="1dof", Fm=0.1, b=1.0, xi=0.05, phi_e=0.0, friction=0.0, var_ratio=0.0)


def _sweep(params, w_lo, w_hi, state):
    """Two cells of a sweep: the flanking values of a grid interval, the lower with its
    (approximate) section state as the continuation would have left it."""
    return pd.DataFrame({"value": [w_lo, w_hi], "final_state": [state, state]})


def _row(kind, w_lo, w_hi, fr, to):
    return {"kind": kind, "value": 0.5 * (w_lo + w_hi), "lo": w_lo, "hi": w_hi, "i_lo": 0,
            "i_hi": 1, "from_npq": fr, "to_npq": to, "n_from": 1, "n_to": int(to[0])}


def _section_state(p):
    """Steady linear response at tau = 0 (the section): x = b + Fm + A cos(phi - theta)."""
    w = p.w
    amp = p.Fe * w * w / math.hypot(1 - w * w, 2 * p.xi * w)
    theta = math.atan2(2 * p.xi * w, 1 - w * w)
    y = np.zeros(10)
    y[0] = p.b + p.Fm + amp * math.cos(p.phi_e - theta)
    y[1] = -amp * w * math.sin(p.phi_e - theta)
    return y


def _assert_located(p, w_ref, kind, label_before, label_after):
    """locate_exact, given the sweep over the 0.002 grid interval holding ``w_ref``, must return
    the exact point (not its grid fallback) to 1e-6 and inside the interval."""
    lo = math.floor(w_ref * 500) / 500
    hi = lo + 0.002
    df = _sweep(p, lo, hi, _section_state(p.with_(w=lo)))
    w, how = locate_exact(p, df, _row(kind, lo, hi, label_before, label_after))
    assert how == "exact"
    assert w == pytest.approx(w_ref, abs=1e-6)
    assert lo <= w <= hi


def test_grazing_point_matches_the_closed_form():
    p = ModelParameters(**BASE, eps=0.0, Fe=0.1724)

    def excess(w):
        return p.Fe * w * w / math.hypot(1 - w * w, 2 * p.xi * w) - p.Fm

    w_ref = brentq(excess, 0.3, 0.9, xtol=1e-14)
    _assert_located(p, w_ref, "grazing", "1-0-0", "1-1-0")


def _mathieu_multipliers(w, eps, xi):
    T = 2 * math.pi / w

    def f(t, z):
        k = 1 + eps * math.cos(w * t)
        return [z[1], -2 * xi * z[1] - k * z[0], z[3], -2 * xi * z[3] - k * z[2]]

    s = solve_ivp(f, (0, T), [1, 0, 0, 1], method="DOP853", rtol=1e-12, atol=1e-14)
    return np.linalg.eigvals(s.y[:, -1].reshape(2, 2).T)


def test_period_doubling_matches_the_mathieu_tongue():
    eps, xi = 0.4, 0.05
    p = ModelParameters(**BASE, eps=eps, Fe=0.01)
    w_ref = brentq(lambda w: min(_mathieu_multipliers(w, eps, xi).real) + 1.0, 1.7, 2.0,
                   xtol=1e-12)
    assert 1.8 < w_ref < 1.85  # the lower edge of the principal parametric tongue
    _assert_located(p, w_ref, "period_doubling", "1-1-0", "2-2-0")
