"""The RK4 grid step's event test (gearsim.numerics.steps.grid_step_flag) against the event layer.

A grid step with a turning point of x (x' changes sign) stands without the event layer only
when the Hermite cubic of x over the step cannot leave its contact region; the event layer's
grazing test (:func:`gearsim.numerics.events.scan_switches`) would then find no switch in it.
"""

from __future__ import annotations

import numpy as np
import pytest

from gearsim.dynamics.model import N_SWITCH, field_params, region_of
from gearsim.dynamics.parameters import ModelParameters
from gearsim.numerics.events import scan_switches, turn_extremum
from gearsim.numerics.steps import grid_step_flag


def _step(x0, v0, x1, v1, rest=0.0):
    y = (x0, v0) + (rest,) * 8
    yn = (x1, v1) + (rest,) * 8
    return y, yn


@pytest.mark.parametrize("b", [0.15, 1.0])
def test_a_turning_point_stands_only_where_the_event_layer_sees_no_switch(b):
    """Random steps around every mesh boundary and region: whenever the flag lets a step with a
    turning point stand, the event layer's scan of the same step finds no switch (no region
    change, no grazing excursion) and the turning point's extremum lies in the step's region;
    steps near a boundary are flagged as events (the test is not vacuous either way)."""
    p = ModelParameters(w=1.1, b=b).to_array()
    P = field_params(p, 0, 1)
    A = (0.0, 0.0, 0.0, 0.0)
    gaps = np.zeros(N_SWITCH)
    gaps[0] = b
    active = np.zeros(N_SWITCH, dtype=np.bool_)
    active[0] = True
    mode = np.zeros(N_SWITCH + 1, dtype=np.int64)
    rng = np.random.default_rng(7)
    h = 2 * np.pi / 1.1 / 192
    stood = flagged = 0
    for _ in range(4000):
        x0 = b * (rng.choice([-1.0, 1.0]) + 0.05 * rng.standard_normal())
        r0 = region_of(x0, b)
        v0 = rng.standard_normal() * b
        v1 = -np.sign(v0) * abs(rng.standard_normal()) * b
        x1 = x0 + 0.5 * h * (v0 + v1) + 0.02 * b * rng.standard_normal()
        y, yn = _step(x0, v0, x1, v1)
        M = (float(r0), float(abs(r0))) + (1.0,) * 4 + (1.0,) * 4
        event, turn = grid_step_flag(y, yn, h, P, M, A, 1e6, False)
        assert not (event and turn)
        mode[0] = r0
        c, _, _ = scan_switches(np.array(y), np.array(yn), h, mode, gaps, active)
        if turn:
            stood += 1
            assert c == -1
            found, xe, _ = turn_extremum(x0, v0, x1, v1, h, 0.0, 1.1, P, float(r0))
            assert found and region_of(xe, b) == r0
        else:
            flagged += 1
    assert stood > 500 and flagged > 500


def test_a_step_without_turning_point_or_switch_is_no_event():
    p = ModelParameters(w=1.1, b=0.3).to_array()
    P = field_params(p, 0, 1)
    M = (1.0, 1.0) + (1.0,) * 8
    y, yn = _step(0.8, 0.1, 0.81, 0.09)
    assert grid_step_flag(y, yn, 0.03, P, M, (0.0,) * 4, 1e6, False) == (False, False)
    y, yn = _step(0.8, 0.1, 0.29, -0.09)  # left face contact: an event
    assert grid_step_flag(y, yn, 0.03, P, M, (0.0,) * 4, 1e6, False) == (True, False)
    y, yn = _step(0.8, 0.1, 0.81, 2e6)  # beyond the divergence bound: an event
    assert grid_step_flag(y, yn, 0.03, P, M, (0.0,) * 4, 1e6, False) == (True, False)
