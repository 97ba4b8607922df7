"""The report's plane atlas and the scorecard's mechanism rows, from atlas summaries of a
synthetic plane (gearsim.presentation.report_atlas, gearsim.presentation.scorecard)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd

from gearsim.analysis.atlas_summary import plane_atlas
from gearsim.presentation.report_atlas import atlas_lines
from gearsim.presentation.scorecard import _atlas_rows


def _plane(y_name: str):
    """8 x 4 cells: 0/1T | 1/1T | 1/2T along x; a face grazing on the first border only."""
    rows = []
    for j in range(4):
        for i in range(8):
            I, n = (0, 1) if i < 3 else (1, 1) if i < 6 else (1, 2)
            if y_name == "xi" and j == 3 and i >= 3:
                I = 0  # less impact at the top of the xi range
            rows.append({"i": i, "j": j, "x": 0.5 + 0.1 * i, "y": 0.1 * j,
                         "label": f"{I}/{n}T", "motion": "periodic", "I": I, "n": n,
                         "dc": 0.3 * I, "x_min": -1.0, "x_max": 1.0})
    curves = pd.DataFrame({"curve": 0, "kind": "grazing", "period": 1, "boundary": "x=+b",
                           "name": "w", "value": 0.75, "name2": y_name,
                           "value2": [-1.0, 1.0]})
    _, s = plane_atlas(pd.DataFrame(rows), curves, plane=f"w{y_name}", x_name="w",
                       y_name=y_name)
    return json.loads(json.dumps(s, default=float))


def test_the_atlas_section_names_every_mechanism_and_the_target():
    a = _plane("b")
    a["unexplained_file"] = "atlas/wb_unexplained.csv"
    text = "\n".join(atlas_lines([a]))
    assert "### Plane wb: boundary length by mechanism" in text
    assert "| on a grazing curve | 4 (100.0 %) |" in text
    assert "| unexplained (a missed curve or a wrong label) | — | 4 (100.0 %) |" in text
    assert "I changes: 4 of 4 (100.0 %); I the same: 0 of 4 (0.0 %)" in text
    assert "**not met**" in text and "[atlas/wb_unexplained.csv]" in text


def test_the_scorecard_rows_measure_the_mechanisms():
    rows = {r.item: r for r in _atlas_rows([_plane("b"), _plane("xi")])}
    g = rows["non-impact <-> impact boundaries by grazing, plane wb"]
    assert g.ours.startswith("100.0 % of 4 edges on grazing curves")
    d = rows["adjacent impact motions by period doubling, plane wb"]
    assert d.ours.startswith("0.0 % of 4 edges")
    b = rows["patterns independent of b above b = 0.4125, plane wb"]
    assert "largest |dw/db| of any curve above it 0" in b.ours
    m = rows["more damping shrinks the impact and chaotic regions, plane wxi"]
    assert m.ok is False  # no chaos at all: nothing shrinks
    assert np.isfinite(float(m.ours.split("impact ")[1].split(" %")[0]))


def test_the_report_reads_each_planes_atlas_and_links_its_unexplained_edges(tmp_path):
    from gearsim.presentation.report_inputs import load_atlas

    (tmp_path / "atlas").mkdir()
    a = _plane("b")
    (tmp_path / "atlas" / "wb.json").write_text(json.dumps(a))
    (tmp_path / "atlas" / "wb_unexplained.csv").write_text("plane,axis\n")
    got = load_atlas(tmp_path, ["wb", "wxi"])
    assert [g["plane"] for g in got] == ["wb"]
    assert got[0]["unexplained_file"] == "atlas/wb_unexplained.csv"


def test_newtons_reading_counts_in_the_summary_and_the_report():
    """A Newton reading (here given: the first 1/1T | 1/2T edge's motions coexist, the next
    one's 1/2T cell converges to the period-1 orbit) turns the first edge into ``coexist``
    (explained) and names the second a wrong label with its evidence."""
    rows = []
    for j in range(4):
        for i in range(8):
            I, n = (0, 1) if i < 3 else (1, 1) if i < 6 else (1, 2)
            rows.append({"i": i, "j": j, "x": 0.5 + 0.1 * i, "y": 0.1 * j,
                         "label": f"{I}/{n}T", "motion": "periodic", "I": I, "n": n,
                         "dc": 0.3 * I, "x_min": -1.0, "x_max": 1.0})
    cells = pd.DataFrame(rows)
    curves = pd.DataFrame({"curve": 0, "kind": "grazing", "period": 1, "boundary": "x=+b",
                           "name": "w", "value": 0.75, "name2": "b", "value2": [-1.0, 1.0]})

    def newton(sub):
        k = len(sub)
        return pd.DataFrame({"newton_n0": [1] * k, "newton_n1": [2] + [1] * (k - 1),
                             "coexist": [True] + [False] * (k - 1)}, index=sub.index)

    edges, s = plane_atlas(cells, curves, plane="wb", x_name="w", y_name="b", newton=newton)
    assert (edges["mechanism"] == "coexist").sum() == 1
    assert s["explained"]["I the same"] == [1, 4]
    assert s["newton"]["I the same"] == {"read": 4, "coexist": 1, "wrong_label": 3}
    s = json.loads(json.dumps(s, default=float))
    text = "\n".join(atlas_lines([s]))
    assert "| both motions stable on both sides (Newton): a hysteresis band | — | 1 (25.0 %) |" \
        in text
    assert "I the same: 4 read, 1 across two motions stable on both sides, 3 beside a cell" \
        in text
    from gearsim.analysis.boundaries import unexplained
    u = unexplained(edges, cells)
    assert set(u["verdict"]) == {"wrong label"} and set(u["evidence"]) == {"Newton"}
