"""The reproduction report on hand-built sweeps and planes (no simulation)."""

import numpy as np
import pandas as pd
import pytest
from test_landmarks import paper_like, row

from gearsim.cli.main import main
from gearsim.presentation.report import (
    analyse,
    build_report,
    double_sided,
    not_period_one,
    row_threshold,
    to_markdown,
)


def plane_wb(threshold=0.41):
    rows = []
    for b in np.linspace(0.0125, 0.9875, 40):
        for w in np.linspace(0.2, 2.4, 12):
            r = row(w, "2-2-1" if (b < threshold and 1.0 < w < 1.5) else "1-1-0")
            r.update(w=w, b=b)
            rows.append(r)
    return pd.DataFrame(rows)


def plane_wxi(threshold=0.1436):
    rows = []
    for xi in np.linspace(0.0415, 0.1585, 40):
        for w in np.linspace(0.2, 2.4, 12):
            r = row(w, "2-2-0" if (xi < threshold and 1.0 < w < 1.5) else "1-1-0")
            r.update(w=w, xi=xi)
            rows.append(r)
    return pd.DataFrame(rows)


def seq_sweep(patterns):
    return pd.DataFrame([row(0.1 + 0.01 * i, p) if p != "chaos" else
                         row(0.1 + 0.01 * i, None, motion="chaos")
                         for i, p in enumerate(patterns) for _ in range(3)])


def test_thresholds_from_planes():
    th = row_threshold(plane_wb(), "b", double_sided(plane_wb()), name="b", paper=0.4125)
    assert th.last_with < 0.41 < th.first_without
    assert abs(th.difference) < 0.02
    th2 = row_threshold(plane_wxi(), "xi", not_period_one(plane_wxi()), name="xi",
                        paper=0.1436)
    assert th2.last_with < 0.1436 < th2.first_without
    none = row_threshold(plane_wb(0.0), "b", double_sided(plane_wb(0.0)), name="b",
                         paper=0.4125)
    assert np.isnan(none.value)


def test_analyse_full_and_markdown():
    sweeps = {
        "standard": paper_like(),
        "b015": seq_sweep(["1-0-0", "1-1-0", "1-1-1", "2-2-2", "2-2-0", "1-1-0"]),
        "xi015": seq_sweep(["1-0-0", "1-1-0"]),
        "xi009": seq_sweep(["1-0-0", "1-1-0", "2-2-0", "1-1-0"]),
    }
    rep = analyse(sweeps, {"wb": plane_wb(), "wxi": plane_wxi(0.2)})
    assert rep.matched["found"].all()
    assert rep.jump["dc_after"] == pytest.approx(0.66)
    assert set(rep.jump["kmax_after"]) == {"kmax_peak_mean", "kmax_peak_static",
                                           "kmax_section_mean", "kmax_section_static"}
    assert rep.sequences["b015"]["in_order"] and rep.sequences["xi015"]["exact"]
    assert not rep.sequences["xi009"]["in_order"]  # 1/4T missing
    assert rep.sequences["b025"]["ours"] is None
    assert any("xi above which" in m for m in rep.misses)  # threshold 0.2 is off by > 0.01
    assert any("sequence xi009" in m for m in rep.misses)
    md = to_markdown(rep)
    assert "| grazing 1-0-0 -> 1-1-0 (I 0 -> 1) | 0.569 | 0.5550 |" in md
    assert "not computed" in md  # b025 / b035 sweeps absent
    assert "## 5. What does not match" in md


def test_missing_inputs_never_use_paper_values(tmp_path):
    rep, md = build_report(sweeps_dir=tmp_path / "none", catalogue=None, results=tmp_path,
                           calibration=None)
    assert rep.matched is None and rep.b_threshold is None
    assert "0.4125 | not computed" in md and "Not computed" in md


def test_report_cli_reads_sweeps_and_cells(tmp_path):
    (tmp_path / "sweeps").mkdir()
    paper_like().to_parquet(tmp_path / "sweeps" / "standard.parquet")
    (tmp_path / "wb").mkdir()
    plane_wb().to_parquet(tmp_path / "wb" / "cells.parquet")
    out = tmp_path / "report.md"
    assert main(["report", "--sweeps", str(tmp_path / "sweeps"), "--catalogue",
                 str(tmp_path / "missing.sqlite"), "--results", str(tmp_path),
                 "--calibration", str(tmp_path / "none.json"), "--out", str(out)]) == 0
    text = out.read_text()
    assert "b: no double-sided impact above | 0.4125 | 0.4" in text


def test_report_lists_exact_landmarks_from_the_standard_continuation(tmp_path):
    """results/orbits/standard_points.parquet (workflow/rules/orbits.smk) puts each landmark's
    exact bifurcation point beside the grid-read one and the paper's."""
    (tmp_path / "sweeps").mkdir()
    std = paper_like()
    std.to_parquet(tmp_path / "sweeps" / "standard.parquet")
    (tmp_path / "orbits").mkdir()
    lm = analyse({"standard": std}, {}).matched.set_index("key")
    g, pd12 = lm.loc["grazing_1"], lm.loc["pd_1_2"]
    pts = pd.DataFrame([
        {"kind": "grazing", "value": 0.5 * (g.lo + g.hi), "period": 1, "stable": True},
        {"kind": "period_doubling", "value": pd12.hi + 0.01, "period": 1, "stable": True},
        {"kind": "period_doubling", "value": pd12.hi + 0.01, "period": 2, "stable": True},
    ])
    pts.to_parquet(tmp_path / "orbits" / "standard_points.parquet")
    rep, md = build_report(sweeps_dir=tmp_path / "sweeps", catalogue=None, results=tmp_path,
                           calibration=None)
    ex = rep.exact.set_index("key")
    assert ex.loc["grazing_1", "inside"] and ex.loc["grazing_1", "exact_period"] == 1
    # the doubling of the 1T orbit, just outside the grid interval (the labels change early)
    assert ex.loc["pd_1_2", "exact_period"] == 1 and not ex.loc["pd_1_2", "inside"]
    assert "Exact bifurcation points" in md and "exact - grid" in md
    assert f"{0.5 * (g.lo + g.hi):.8f}" in md
    # the model form: from the sweep's provenance (none here: said, not guessed)
    assert "| model form |" in md and "Model form (?): model form unknown" in md


def test_exact_landmark_table_names_the_model_form_from_the_sweep_provenance(tmp_path):
    from gearsim.results import catalogue

    (tmp_path / "sweeps").mkdir()
    subtree = {"sweep": {"name": "w", "fixed": {}, "start": "rest"},
               "parameters": {"te_damping": 1.0, "mesh_damping_contact": 0.0, "model": "1dof"},
               "integration": {"method": "rk4", "steps_per_period": 256}}
    catalogue.write_parquet(paper_like(), tmp_path / "sweeps" / "standard.parquet",
                            {catalogue.PROVENANCE_KEY: {"subtree": subtree}})
    (tmp_path / "orbits").mkdir()
    pd.DataFrame([{"kind": "grazing", "value": 0.6, "period": 1, "stable": True}]).to_parquet(
        tmp_path / "orbits" / "standard_points.parquet")
    _, md = build_report(sweeps_dir=tmp_path / "sweeps", catalogue=None, results=tmp_path,
                         calibration=None)
    assert "Model form (1dof+fixed_start): 1DOF; rigid bearings;" in md
    assert "sweep start: rest; RK4, 256 steps per period." in md
    assert "| 1dof+fixed_start |" in md
