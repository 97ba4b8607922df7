"""The boundary accounting of a plane (gearsim.analysis.boundaries) and the cascade reading
(gearsim.analysis.cascade) on synthetic maps whose answer is known by construction."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from gearsim.analysis import boundaries as bd
from gearsim.analysis.cascade import FEIGENBAUM, accumulation, cascade_doublings, grid_cascade

NX, NY = 10, 6
X0, DX, Y0, DY = 0.5, 0.1, 0.0, 0.2


def _cells(label_of) -> pd.DataFrame:
    """A NX x NY plane; ``label_of(i, j)`` -> (motion, I, n); dc and range follow I."""
    rows = []
    for j in range(NY):
        for i in range(NX):
            motion, I, n = label_of(i, j)
            label = f"{I}/{n}T" if motion == "periodic" else motion
            rows.append({"i": i, "j": j, "x": X0 + (i + 0.5) * DX, "y": Y0 + (j + 0.5) * DY,
                         "label": label, "motion": motion, "I": I, "n": n,
                         "dc": 0.3 * abs(I), "x_min": -1.0, "x_max": 1.0})
    return pd.DataFrame(rows)


def _curve(cid, kind, period, pts, boundary=""):
    pts = np.asarray(pts, float)
    return pd.DataFrame({"curve": cid, "kind": kind, "period": period, "boundary": boundary,
                         "name": "w", "value": pts[:, 0], "name2": "b", "value2": pts[:, 1]})


def _vertical(cid, kind, period, x, boundary=""):
    return _curve(cid, kind, period, [(x, -1.0), (x, 3.0)], boundary)


X_EDGE = X0 + 5 * DX  # the border between columns 4 and 5


def test_edges_are_the_label_changes_along_both_axes():
    cells = _cells(lambda i, j: ("periodic", 0 if i < 5 else 1, 1) if j < 3
                   else ("periodic", 0, 1 if i < 5 else 2))
    e = bd.boundary_edges(cells)
    # along x: one edge per row at the border; along y: none (labels equal across j = 2 | 3
    # except on the right: 1/1T above 0/2T)
    assert (e["axis"] == "x").sum() == NY
    assert set(e.loc[e["axis"] == "y", "i0"]) == set(range(5, NX))
    assert np.allclose(e.loc[e["axis"] == "x", "x"], X_EDGE)
    assert set(e["group"]) == {"I changes", "I the same"}


@pytest.mark.parametrize("kind, period, boundary, shift, want", [
    ("grazing", 1, "x=+b", 0.0, "grazing"),          # on the border, right flank
    ("grazing", 1, "x=+b", 1.4 * DX, "grazing"),     # 1.4 cells away: still near
    ("grazing", 1, "x=+b", 1.6 * DX, "unexplained"),  # 1.6 cells: too far
    ("grazing", 1, "x=-b", 0.0, "unexplained"),      # 0 -> 1 is the face's contact
    ("grazing", 2, "x=+b", 0.0, "unexplained"),      # another orbit's grazing
    ("period_doubling", 1, "", 0.0, "unexplained"),  # the wrong kind
])
def test_a_grazing_edge_needs_a_grazing_curve_of_its_flank_and_period(kind, period, boundary,
                                                                      shift, want):
    cells = _cells(lambda i, j: ("periodic", 0 if i < 5 else 1, 1))
    e = bd.classify_edges(cells, _vertical(0, kind, period, X_EDGE + shift, boundary))
    assert set(e["mechanism"]) == {want}
    assert e["near_any"].all() == (abs(shift) <= 1.5 * DX)


def test_the_back_flank_explains_one_to_two():
    cells = _cells(lambda i, j: ("periodic", 1 if i < 5 else 2, 1))
    e = bd.classify_edges(cells, _vertical(0, "grazing", 1, X_EDGE, "x=-b"))
    assert set(e["mechanism"]) == {"grazing"}


def test_a_doubling_explains_only_its_own_period():
    cells = _cells(lambda i, j: ("periodic", 1, 2 if i < 5 else 4))
    assert set(bd.classify_edges(cells, _vertical(0, "period_doubling", 2, X_EDGE))[
        "mechanism"]) == {"period_doubling"}
    assert set(bd.classify_edges(cells, _vertical(0, "period_doubling", 1, X_EDGE))[
        "mechanism"]) == {"unexplained"}


def test_a_fold_explains_a_jump_not_a_continuous_change():
    def jump(i, j):
        return ("periodic", 0 if i < 5 else 1, 1)
    cells = _cells(jump)
    e = bd.classify_edges(cells, _vertical(0, "fold", 1, X_EDGE))
    assert set(e["mechanism"]) == {"fold"}  # dc 0 -> 0.3: a jump
    cells["dc"] = 0.0  # no jump of DC or range: the fold does not explain it
    assert set(bd.classify_edges(cells, _vertical(0, "fold", 1, X_EDGE))["mechanism"]) == {
        "unexplained"}


def test_edges_inside_a_fold_band_are_the_branch_the_chain_followed():
    # two fold curves at x = 0.75 and 1.25 (columns 2.5 and 7.5): rows alternate their label
    # inside the band (the chain of each row jumped at its own place), outside they agree
    def lab(i, j):
        inside = 3 <= i <= 6
        return ("periodic", 1 if (inside and j % 2) else 0, 1)
    cells = _cells(lab)
    cells.loc[cells["I"] == 1, "dc"] = 0.0  # no jump: only the band explains them
    folds = pd.concat([_vertical(0, "fold", 1, 0.75), _vertical(1, "fold", 1, 1.25)])
    e = bd.classify_edges(cells, folds)
    inner = e[(e["x"] > 0.75) & (e["x"] < 1.25)]
    assert len(inner) and set(inner["mechanism"]) == {"fold_band"}
    assert bd.fold_bands(bd.curve_polylines(folds, "w"), "x", 0.3) == {1: [(0.75, 1.25)]}


def test_chaos_beside_the_cascade_is_its_onset_a_jump_a_crisis():
    cells = _cells(lambda i, j: ("periodic", 1, 8) if i < 5 else ("chaos", 1, 0))
    e = bd.classify_edges(cells, _vertical(0, "period_doubling", 8, X_EDGE))
    assert set(e["mechanism"]) == {"chaos_onset"}
    e = bd.classify_edges(cells, _vertical(0, "period_doubling", 2, X_EDGE))
    assert set(e["mechanism"]) == {"unexplained"}  # no cascade, no jump
    cells.loc[cells["motion"] == "chaos", "x_max"] = 3.0  # the band ends abruptly: a jump
    e = bd.classify_edges(cells, _vertical(0, "period_doubling", 2, X_EDGE))
    assert set(e["mechanism"]) == {"crisis"}


def test_segment_distance_against_a_dense_polyline():
    rng = np.random.default_rng(3)
    line = np.cumsum(rng.normal(size=(12, 2)), axis=0)
    p = rng.normal(scale=4.0, size=(200, 2))
    t = np.linspace(0.0, 1.0, 4001)[:, None]
    dense = np.concatenate([a + t * (b - a) for a, b in zip(line[:-1], line[1:], strict=True)])
    brute = np.sqrt(((p[:, None, :] - dense[None]) ** 2).sum(2)).min(1)
    got = bd._segment_distance(p, line[:-1], line[1:])
    seg = np.sqrt((np.diff(line, axis=0) ** 2).sum(1)).max() / 4000
    assert np.all(got <= brute + 1e-12) and np.all(brute - got <= seg)


def test_the_summaries_count_every_edge_once():
    cells = _cells(lambda i, j: ("periodic", 0 if i < 5 else 1, 1 if j < 3 else 2))
    e = bd.classify_edges(cells, _vertical(0, "grazing", 1, X_EDGE, "x=+b"))
    t = bd.mechanism_table(e)
    assert t["edges"].sum() == len(e)
    near = bd.near_table(e).set_index("group")
    assert near.loc["all", "edges"] == len(e)
    ok, n = bd.explained_share(e)["I changes"]
    assert (ok, n) == (3, NY)  # the rows of period 1; the period-2 rows' grazing is missing
    assert len(bd.unexplained(e)) == len(e) - 3


def test_cascade_ratios_and_accumulation_of_a_geometric_cascade():
    w_inf, c, delta = 1.4, 0.4, FEIGENBAUM
    w = [w_inf - c * delta ** -k for k in range(5)]
    rows = [{"event": "period_doubling", "period": 2 ** k, "value": v}
            for k, v in enumerate(w)]
    rows.append({"event": "grazing", "period": 8, "value": 0.5 * (w[2] + w[3])})
    rows.append({"event": "period_doubling", "period": 2, "value": 1.9})  # the other side
    d = cascade_doublings(pd.DataFrame(rows), 0.9, 1.39999)
    assert list(d["period"]) == [1, 2, 4, 8, 16]
    assert np.allclose(d["ratio"].dropna(), delta)
    assert list(d["grazing_before"]) == [False, False, False, True, False]
    got, used = accumulation(d)
    assert used == pytest.approx(delta) and got == pytest.approx(w_inf, abs=1e-12)


def test_grid_cascade_reads_the_band_and_a_crisis_exit():
    seq = ["1/1T"] * 3 + ["1/2T"] * 3 + ["1/4T", "1/8T"] + ["chaos"] * 4 + ["2/3T"] * 3
    row = pd.DataFrame({"x": np.arange(len(seq)) * 0.1, "label": seq,
                        "motion": ["chaos" if s == "chaos" else "periodic" for s in seq],
                        "n": [0 if s == "chaos" else int(s.split("/")[1][:-1]) for s in seq],
                        "I": 1})
    g = grid_cascade(row)
    assert g["periods"] == [1, 2, 4, 8]
    assert g["start"] == pytest.approx(0.2) and g["onset"] == pytest.approx(0.8)
    assert g["end"] == pytest.approx(1.1) and g["exit"] == "crisis"
    assert g["after_end"] == "2/3T"


def test_the_mechanisms_of_the_summary():
    from gearsim.analysis.atlas_summary import b_independence, damping, mechanisms

    # non-impact | impact on a face grazing; the impact side doubles on a doubling curve
    cells = _cells(lambda i, j: ("periodic", 0, 1) if i < 5 else ("periodic", 1,
                                                                 1 if i < 8 else 2))
    curves = pd.concat([_vertical(0, "grazing", 1, X_EDGE, "x=+b"),
                        _curve(1, "period_doubling", 1, [(X0 + 8 * DX, 0.0),
                                                         (X0 + 8 * DX + 0.05, 1.2)])])
    e = bd.classify_edges(cells, curves)
    m = mechanisms(e)
    assert m["grazing"] == {"edges": NY, "grazing": NY}
    assert m["doubling"] == {"edges": NY, "period_doubling": NY}
    bi = b_independence(curves, e, "b", above=0.5)
    assert bi["max_slope"] == pytest.approx(0.05 / 1.2) and bi["curve"].startswith(
        "period_doubling")
    assert bi["edges_along_y"] == 0
    # impact shrinking with y: the rows' impact share falls, the chaotic share is zero
    cells = _cells(lambda i, j: ("periodic", 1 if i < NX - 1 - j else 0, 1))
    d = damping(cells, quarters=2)
    assert d["rho_impact"] == pytest.approx(-1.0)
    assert d["bands"][0]["impact"] > d["bands"][1]["impact"]
    assert d["bands"][0]["chaos"] == 0.0 and np.isnan(d["rho_chaos"])


def test_the_chaotic_band_is_located_from_both_ends(monkeypatch):
    """chaotic_band reads the row nearest the line, continues from the cascade's start towards
    the onset and, after an inverse cascade, from the first period-1 cell back (the
    continuation replaced by a table of known doublings)."""
    from gearsim.analysis import atlas_summary, cascade
    from gearsim.dynamics.parameters import ModelParameters

    seq = (["1/1T"] * 3 + ["1/2T"] * 3 + ["1/4T", "1/8T"] + ["chaos"] * 4
           + ["1/8T", "1/4T", "1/2T", "1/1T", "1/1T"])
    cells = pd.DataFrame([{"x": 1.0 + 0.1 * k, "y": y, "label": s,
                           "motion": "chaos" if s == "chaos" else "periodic",
                           "n": 0 if s == "chaos" else int(s.split("/")[1][:-1]), "I": 1}
                          for y in (0.95, 1.05) for k, s in enumerate(seq)])
    calls = []

    def fake(params, name, start, stop, **kw):
        calls.append((round(params.b, 12), start, stop))
        d = 1.0 if stop > start else -1.0
        w = [start + d * abs(stop - start) * v for v in (0.1, 0.6, 0.8, 0.84)]
        return pd.DataFrame({"event": "period_doubling", "period": [1, 2, 4, 8], "value": w})

    monkeypatch.setattr(cascade, "locate_cascade", fake)
    out = atlas_summary.chaotic_band(cells, ModelParameters(), x_name="w", y_name="b",
                                     y_value=1.0)
    assert out["row"] == 0.95 and out["value"] == 1.0  # the line itself, read on its row
    assert calls == [(1.0, pytest.approx(1.2), pytest.approx(1.8)),
                     (1.0, pytest.approx(2.5), pytest.approx(2.1))]
    assert [d["period"] for d in out["onset"]["doublings"]] == [1, 2, 4, 8]
    assert out["exit"]["doublings"][1]["ratio"] is None
    assert [d["ratio"] for d in out["exit"]["doublings"][2:]] == [pytest.approx(2.5),
                                                                  pytest.approx(5.0)]


@pytest.mark.parametrize("extra, words", [
    (["--cells", "missing.parquet"], ["missing.parquet", "no such file"]),
    (["--cells", "missing.parquet", "--depth", "9"], ["--depth = 9", "[0, 6]"]),
    (["--cells", "missing.parquet", "--plane", "nope"], ["unknown plane 'nope'"]),
])
def test_atlas_command_refuses_bad_input_in_one_line(tmp_path, capsys, extra, words):
    from gearsim.cli.main import main

    args = ["atlas", "--plane", "wb", "--out", str(tmp_path / "a.json"), *extra]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and all(w in err[0] for w in words), err
    assert not list(tmp_path.iterdir())


def test_an_unexplained_edge_is_a_wrong_label_beside_an_island_else_a_missed_curve():
    def lab(i, j):
        if (i, j) == (2, 2):
            return ("periodic", 1, 3)  # one odd cell inside the 0/1T region
        return ("periodic", 0 if i < 5 else 1, 1)
    cells = _cells(lab)
    assert bd.islands(cells) == {(2, 2)}
    u = bd.unexplained(bd.classify_edges(cells, None), cells)
    assert set(u.loc[u["pair"] == "0/1T | 1/3T", "verdict"]) == {"wrong label"}
    assert (u["pair"] == "0/1T | 1/3T").sum() == 4
    assert set(u.loc[u["pair"] == "0/1T | 1/1T", "verdict"]) == {"missed curve"}


def test_label_pairs_are_neighbours_with_different_labels_and_skip_missing_cells():
    """A 3 x 2 grid at an offset, one cell missing: each pair is one step apart along its
    axis, labels differ, ``a`` in (i, j) order, and no pair reaches the missing cell."""
    i = np.array([5, 6, 7, 5, 7])  # (6, 11) missing
    j = np.array([10, 10, 10, 11, 11])
    lab = np.array(["A", "B", "B", "A", "C"], dtype=object)
    got = {axis: sorted(zip(i[a], j[a], i[b], j[b], strict=True))
           for axis, a, b in bd.label_pairs(i, j, lab)}
    assert got == {"x": [(5, 10, 6, 10)], "y": [(7, 10, 7, 11)]}
