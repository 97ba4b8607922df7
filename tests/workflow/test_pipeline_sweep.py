"""``gearsim sweep``: its table is the scalar continuation chain's, cell by cell, plus the seeds."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gearsim.cell.sweep import continuation_chain, orbit_diagram
from gearsim.dynamics.parameters import ModelParameters
from gearsim.study import config as gcfg
from gearsim.study.sweeps import point_list as _point_list
from gearsim.study.sweeps import sweep_frame

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("direction", ["forward", "backward"])
def test_sweep_frame_is_the_scalar_chain(direction):
    """RK4 sweeps run through the batched kernel; the reference is the scalar simulate_cell
    chain in the same order, which must agree to the last bit (one algorithm)."""
    cfg = gcfg.load_config([ROOT / "config/config.yaml", ROOT / "config/tiny.yaml"])
    st = gcfg.integration_settings(cfg).with_(method="rk4")  # tiny.yaml's budgets, production RK4
    p = ModelParameters(b=0.25)
    vals = np.array([1.1, 0.6, 2.1, 1.6])  # unsorted on purpose: the builder orders them
    ours = sweep_frame(p, "w", vals, direction, st)
    order = np.sort(vals) if direction == "forward" else np.sort(vals)[::-1]
    ref = continuation_chain([p.with_(w=float(w)) for w in order], settings=st)
    np.testing.assert_array_equal(ours["value"].to_numpy(), order)
    assert (ours["direction"] == direction).all()
    for k, r in enumerate(ref):
        row = r.row()
        for col in ("label", "label_npq", "I", "n", "status"):
            assert ours[col].iloc[k] == row[col], (k, col)
        for col in ("dc", "kmax", "lyapunov"):  # running sums: batched order, equal to rounding
            np.testing.assert_allclose(ours[col].iloc[k], row[col], rtol=1e-12, atol=1e-15)
        np.testing.assert_array_equal(ours["poincare_x"].iloc[k], r.poincare[:, 0])
        np.testing.assert_array_equal(ours["final_state"].iloc[k], r.final_state)
        assert ours["final_period"].iloc[k] == r.final_period
    # orbit_diagram is the same table without the catalogue dtypes
    od = orbit_diagram(p, "w", vals, direction=direction, settings=st)
    assert list(od.columns) == list(ours.columns)
    assert list(od["label"]) == list(ours["label"])


def test_point_sets():
    assert _point_list([0.48, 1.02]) == [{"w": 0.48}, {"w": 1.02}]
    assert _point_list({"b": 0.15, "w": 0.82}) == [{"b": 0.15, "w": 0.82}]
    assert _point_list({"b": [0.1, 0.2], "w": 1.0}) == [{"b": 0.1, "w": 1.0},
                                                        {"b": 0.2, "w": 1.0}]
