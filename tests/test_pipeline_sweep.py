"""``gearsim sweep``: its table is orbit_diagram's plus the continuation seeds."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from gearsim import config as gcfg
from gearsim.commands.sweep import _point_list, sweep_frame
from gearsim.parameters import ModelParameters
from gearsim.sweep import orbit_diagram

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("direction", ["forward", "backward"])
def test_sweep_frame_is_orbit_diagram_plus_seeds(direction):
    cfg = gcfg.load_config([ROOT / "config/config.yaml", ROOT / "config/tiny.yaml"])
    st = gcfg.integration_settings(cfg)
    p = ModelParameters(b=0.25)
    vals = np.array([0.6, 1.1, 1.6, 2.1])
    ours = sweep_frame(p, "w", vals, direction, st)
    ref = orbit_diagram(p, "w", vals, direction=direction, settings=st)
    assert list(ours.columns[: len(ref.columns)]) == list(ref.columns)
    assert set(ours.columns) - set(ref.columns) == {"final_state", "final_period", "elapsed_s"}
    for col in ("value", "label", "label_npq", "I", "n", "dc", "kmax", "lyapunov"):
        a, b = ours[col].to_numpy(), ref[col].to_numpy()
        if a.dtype.kind == "f":
            np.testing.assert_allclose(a, b, equal_nan=True)
        else:
            assert list(a) == list(b), col
    pd.testing.assert_series_equal(ours["poincare_x"].map(list), ref["poincare_x"].map(list))


def test_point_sets():
    assert _point_list([0.48, 1.02]) == [{"w": 0.48}, {"w": 1.02}]
    assert _point_list({"b": 0.15, "w": 0.82}) == [{"b": 0.15, "w": 0.82}]
    assert _point_list({"b": [0.1, 0.2], "w": 1.0}) == [{"b": 0.1, "w": 1.0},
                                                        {"b": 0.2, "w": 1.0}]
