"""Newton's reading of boundary edges (gearsim.analysis.coexistence) on a known hysteresis.

The single-DOF standard set has a softening fold pair on its period-1 branch: continuation
locates the folds at w ~ 0.582 and ~ 0.682 (multiplier +1), and between them the non-impact
and the impact orbit are both stable. Forward and backward chains of simulated cells (as a
plane row or a sweep runs them) give each branch's state. Checked against that reference:

* an edge inside the band whose cells sit on different branches is read as coexisting;
* an edge across the upper fold is not (the lower branch does not reach the far cell);
* a cell labelled period 2 whose state is the period-1 orbit (a decaying transient read as
  period 2) is refuted: Newton's least period is 1.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from gearsim.analysis.boundaries import apply_newton, newton_refuted
from gearsim.analysis.coexistence import least_period, newton_edges
from gearsim.analysis.continuation import continue_orbit
from gearsim.analysis.continuation_options import Continuation
from gearsim.analysis.orbits import find_periodic_orbit, shooting_settings
from gearsim.cell.simulate import simulate_cell
from gearsim.dynamics.parameters import ModelParameters
from gearsim.study.config_io import load_standard_parameters

ONE = ModelParameters.from_mapping(
    load_standard_parameters("config/standard_parameters.yaml")).with_(model="1dof")
SETTINGS = shooting_settings(1e-9)


@pytest.fixture(scope="module")
def folds():
    br = continue_orbit(ONE, "w", 0.4, 0.95, n=1,
                        config=Continuation(ds=0.02, ds_max=0.05, switch_depth=0))
    f = sorted(br.loc[br["event"] == "fold", "value"].astype(float))
    assert len(f) == 2
    return f


def _chain(ws):
    """Final states of a continuation chain of simulated cells over ``ws`` (in order)."""
    u0, out = None, {}
    for w in ws:
        res = simulate_cell(ONE.with_(w=float(w)), u0)
        u0 = res.final_state
        out[round(float(w), 10)] = np.asarray(u0, dtype=float)
    return out


def _line(start, near, last):
    """Chain values from ``start`` to ``near`` in map-cell steps (0.006), then ``last``."""
    k = int(round(abs(near - start) / 0.006))
    ws = [near + np.sign(start - near) * 0.006 * m for m in range(k, -1, -1)]
    return np.round([*ws, last] if last != near else ws, 10)


def _read(cells_w_state_n):
    """newton_edges on one edge between two cells given as (w, state, n)."""
    (wa, ya, na), (wb, yb, nb) = cells_w_state_n
    cells = pd.DataFrame({"i": [0, 1], "j": [0, 0], "w": [wa, wb], "b": [ONE.b, ONE.b],
                          "final_state": [ya, yb]})
    edges = pd.DataFrame({"i0": [0], "j0": [0], "i1": [1], "j1": [0], "n0": [na],
                          "n1": [nb]})
    return newton_edges(ONE, cells, edges, x_name="w", y_name="b", settings=SETTINGS).iloc[0]


def test_two_branches_inside_the_fold_band_coexist_and_not_across_its_fold(folds):
    lo, hi = folds
    assert 0.55 < lo < 0.61 and 0.66 < hi < 0.70
    w1, w2 = 0.62, 0.626  # inside the band, a map cell apart
    up = _chain(_line(0.50, w1, w2))  # from below: stays on the lower branch
    down = _chain(_line(0.76, w2, w1))  # from above: on the upper branch
    lower, upper = up[round(w1, 10)], down[round(w2, 10)]
    # the two states are different motions (the impact orbit reaches farther)
    assert abs(upper[0] - lower[0]) > 1e-3
    r = _read([(w1, lower, 1), (w2, upper, 1)])
    assert (r["newton_n0"], r["newton_n1"], bool(r["coexist"])) == (1, 1, True)

    # across the upper fold: the lower branch's orbit at w = 0.678 does not exist at 0.69
    wa, wb = 0.678, 0.690
    assert wa < hi < wb
    up2 = _chain(_line(0.50, wa, wa))
    down2 = _chain(_line(0.76, wb, wb))
    r = _read([(wa, up2[round(wa, 10)], 1), (wb, down2[round(wb, 10)], 1)])
    assert r["newton_n0"] == 1 and r["newton_n1"] == 1 and not bool(r["coexist"])


def test_a_period_two_label_on_the_period_one_orbit_is_refuted():
    p = ONE.with_(w=0.9)
    o = find_periodic_orbit(p, 1, None, SETTINGS)
    assert o.stable and least_period(o) == 1
    # the same state solved as period 2 repeats after one period: least period 1
    o2 = find_periodic_orbit(p, 2, o.state, SETTINGS)
    assert o2.n == 2 and least_period(o2) == 1
    r = _read([(0.9, o.state, 1), (0.906, o.state, 2)])
    assert (r["newton_n0"], r["newton_n1"], bool(r["coexist"])) == (1, 1, False)
    e = pd.DataFrame({"n0": [1], "n1": [2], "newton_n0": [r["newton_n0"]],
                      "newton_n1": [r["newton_n1"]]})
    assert newton_refuted(e).tolist() == [True]


def test_apply_newton_marks_only_the_unexplained_periodic_edges():
    e = pd.DataFrame({"mechanism": ["unexplained", "grazing", "unexplained", "unexplained"],
                      "group": ["I the same", "I changes", "chaos", "I changes"],
                      "n0": [1, 1, 1, 2], "n1": [2, 1, 0, 2]})
    seen = []

    def newton(sub):
        seen.append(list(sub.index))
        return pd.DataFrame({"newton_n0": [1, 2], "newton_n1": [1, 2],
                             "coexist": [False, True]}, index=sub.index)

    out = apply_newton(e, newton)
    assert seen == [[0, 3]]
    assert out["mechanism"].tolist() == ["unexplained", "grazing", "unexplained", "coexist"]
    assert newton_refuted(out).tolist() == [True, False, False, False]


def test_the_atlas_command_names_a_refuted_label_with_newtons_evidence(tmp_path, capsys):
    """``gearsim atlas`` on two cells of the default (w, b) plane, no curves: a 1/1T cell
    and a 1/2T cell that sits on the same period-1 orbit. The edge is unexplained; Newton
    reads it and the CSV names it a wrong label with evidence ``Newton``."""
    import json

    from gearsim.cli.main import main
    from gearsim.study.config import Study

    base = Study.load(["config/config.yaml"]).parameters(plane="wb").model
    w0, b0 = 0.9, 1.0
    o = find_periodic_orbit(base.with_(w=w0, b=b0), 1, None, SETTINGS)
    assert o.stable
    rows = [{"i": i, "j": 0, "x": w, "y": b0, "w": w, "b": b0, "label": lab,
             "motion": "periodic", "I": 1, "n": n, "dc": 0.5, "x_min": -0.5, "x_max": 1.0,
             "final_state": o.state.tolist()}
            for i, (w, lab, n) in enumerate(((w0, "1/1T", 1), (w0 + 0.006, "1/2T", 2)))]
    cells = tmp_path / "cells.parquet"
    pd.DataFrame(rows).to_parquet(cells)
    out = tmp_path / "atlas" / "wb.json"
    assert main(["atlas", "--plane", "wb", "--cells", str(cells), "--depth", "0",
                 "--out", str(out)]) == 0
    assert "1 of 1 edges, 0 with both motions on both sides" in capsys.readouterr().err
    s = json.loads(out.read_text())
    assert s["newton"]["I the same"] == {"read": 1, "coexist": 0, "wrong_label": 1}
    u = pd.read_csv(tmp_path / "atlas" / "wb_unexplained.csv")
    assert u[["verdict", "evidence"]].values.tolist() == [["wrong label", "Newton"]]
