"""The plane atlas's bookkeeping: which edges seed first, and which lost curve ends run into a
codimension-2 point already located (no orbit is computed here)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from gearsim.analysis.atlas import AtlasOptions, _candidates
from gearsim.analysis.atlas_seeds import Grid, boundary_edges
from gearsim.analysis.codim2 import _located_at

GRID = Grid("w", "b", 0.0, 1.0, 4, 0.0, 1.0, 1)


def _cells(rows):
    base = {"motion": "periodic", "status": "ok", "p": 0, "q": 0, "final_state": [0.0] * 10}
    return pd.DataFrame([{**base, "i": i, "j": 0, **r} for i, r in enumerate(rows)])


def test_a_jump_of_one_period_is_tried_as_a_fold_before_its_grazing():
    # cells 0|1: the back contact appears smoothly (a grazing); cells 2|3: it appears with the
    # duty cycle jumping 0.13 -> 0.50 (a jump: the fold first, before every other seed)
    one = {"label": "1/1T", "n": 1, "I": 1, "p": 1, "q": 0}
    two = {"label": "2/1T", "n": 1, "I": 2, "p": 1, "q": 1}
    cells = _cells([{**one, "dc": 0.10, "x_min": -0.5, "x_max": 1.0},
                    {**two, "dc": 0.12, "x_min": -0.55, "x_max": 1.02},
                    {**one, "dc": 0.13, "x_min": -0.56, "x_max": 1.03},
                    {**two, "dc": 0.50, "x_min": -0.19, "x_max": 0.67}])
    edges = boundary_edges(cells)
    cand = _candidates(edges, AtlasOptions())
    got = [(float(r.ci), r.key) for r in cand.itertuples()]
    assert got[0] == (2.5, ("fold", 1, ""))
    assert (2.5, ("grazing", 1, "x=-b")) in got[1:]
    assert (0.5, ("grazing", 1, "x=-b")) in got
    # no jump at 0|1 and 1|2: no fold is looked for there
    assert (0.5, ("fold", 1, "")) not in got and (1.5, ("fold", 1, "")) not in got


def _point(kind, conditions, period, w, y, converged):
    return {"point": 0, "kind": kind, "conditions": conditions, "period": period, "value": w,
            "value2": y, "converged": converged, "_point": {"w": w, "y": y}}


def test_an_end_runs_into_a_located_point_of_its_own_condition_only():
    grid = Grid("w", "b", 0.0, 4.0, 400, 0.0, 1.0, 400)  # cells of 0.01 in w, 0.0025 in b
    pt = _point("pd_grazing", "period_doubling; grazing x=-b", 2, 1.0, 0.5, True)
    near = {"w": 1.01, "y": 0.5}  # one cell away
    far = {"w": 1.02, "y": 0.5}  # two cells away
    # the doubling of period 2 and the back grazing of periods 2 and 4 end there
    assert _located_at(grid, {**near, "kind": "period_doubling", "boundary": "",
                              "period": 2}, [pt])[0] is pt
    assert _located_at(grid, {**near, "kind": "grazing", "boundary": "x=-b",
                              "period": 4}, [pt])[0] is pt
    # not: another period's doubling, the other flank, an end two cells away
    assert _located_at(grid, {**near, "kind": "period_doubling", "boundary": "",
                              "period": 4}, [pt]) is None
    assert _located_at(grid, {**near, "kind": "grazing", "boundary": "x=+b",
                              "period": 2}, [pt]) is None
    assert _located_at(grid, {**far, "kind": "period_doubling", "boundary": "",
                              "period": 2}, [pt]) is None


def test_a_point_that_did_not_converge_is_solved_once_more_then_reused():
    grid = Grid("w", "b", 0.0, 4.0, 400, 0.0, 1.0, 400)
    pt = _point("fold_grazing", "fold; grazing x=-b", 2, 1.0, 0.5, False)
    end = {"w": 1.005, "y": 0.5, "kind": "fold", "boundary": "", "period": 2}
    assert _located_at(grid, dict(end), [pt]) is None  # the next end solves it again
    assert _located_at(grid, dict(end), [pt])[0] is pt  # and the one after runs into it
    assert np.isfinite(pt["value"])
