"""The reproduction report on hand-built sweeps and planes (no simulation)."""

import numpy as np
import pandas as pd
import pytest
from sweep_tables import paper_like, row

from gearsim.cli.main import main
from gearsim.presentation.report import (
    analyse,
    build_report,
    double_sided_rows,
    not_period_one,
    row_threshold,
)
from gearsim.presentation.report_markdown import to_markdown


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
    th = row_threshold(plane_wb(), "b", double_sided_rows(plane_wb()), name="b", paper=0.4125)
    assert th.last_with < 0.41 < th.first_without
    assert abs(th.difference) < 0.02
    th2 = row_threshold(plane_wxi(), "xi", not_period_one(plane_wxi()), name="xi",
                        paper=0.1436)
    assert th2.last_with < 0.1436 < th2.first_without
    none = row_threshold(plane_wb(0.0), "b", double_sided_rows(plane_wb(0.0)), name="b",
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
    assert "## What does not match, and why" in md
    # the scorecard leads: within the first screen, one row per paper result
    head = md.splitlines()[:40]
    assert head[0] == "# Reproduction report" and "## Scorecard" in head
    rows = [line for line in head if line.startswith("| w: ")]
    assert len(rows) == len(rep.matched) == 12
    assert any(line.startswith("| b above which no double-sided impact occurs | 0.4125 | 0.4000")
               and line.endswith("| **no** |") for line in head)  # 0.0125 > 0.01 off
    assert any(line.startswith("| sequence xi = 0.15 (xi015) |") and line.endswith("| yes |")
               for line in head)
    assert "issue" not in md.lower()


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


def test_scorecard_counts_and_verdicts():
    """Every judged row counts once; a landmark off by more than the tolerance is 'no'."""
    from gearsim.analysis.paper import LANDMARK_TOL
    from gearsim.presentation.scorecard import scorecard

    std = paper_like()
    rep = analyse({"standard": std}, {}, plane_axes={}, configured_sweeps=["standard"])
    rows = scorecard(rep)
    marks = [r for r in rows if r.item.startswith("w: ")]
    assert len(marks) == 12 and all(r.ok for r in marks)  # paper_like lies within 0.02
    shifted = std.assign(value=std["value"] + 3 * LANDMARK_TOL)
    bad = scorecard(analyse({"standard": shifted}, {}, plane_axes={},
                            configured_sweeps=["standard"]))
    assert not any(r.ok for r in bad if r.item.startswith("w: "))


def test_a_study_of_ones_own_gets_a_report_about_itself(tmp_path):
    """No paper material: the report is titled by the study, opens with its plane and sweep,
    gives the sweep's transitions in its own units and links the sweep's diagram."""
    from gearsim.results import catalogue

    (tmp_path / "sweeps").mkdir()
    sweep = seq_sweep(["1-0-0", "1-1-0", "2-2-0"]).assign(parameter="Fm")
    spec = {"name": "Fm", "min": 0.05, "max": 0.1, "n": len(sweep),
            "physical": {"name": "torque_Nm", "unit": "N m", "min": 5.0, "max": 10.0}}
    catalogue.write_parquet(sweep, tmp_path / "sweeps" / "torque.parquet",
                            {catalogue.PROVENANCE_KEY: {"subtree": {"sweep": spec}}})
    (tmp_path / "figures" / "sweeps").mkdir(parents=True)
    (tmp_path / "figures" / "sweeps" / "torque.png").write_bytes(b"png")
    (tmp_path / "weps").mkdir()
    plane = plane_wb().rename(columns={"b": "eps"})
    plane.to_parquet(tmp_path / "weps" / "cells.parquet")
    rep, md = build_report(sweeps_dir=tmp_path / "sweeps", catalogue=None, results=tmp_path,
                           calibration=None, planes={"weps": ("w", "eps")},
                           sweeps=["torque"], study="weps")
    lines = md.splitlines()
    assert lines[0] == "# Study report: weps"
    assert "Scorecard" not in md and "Landmarks of the standard sweep" not in md
    assert "paper" not in lines[2] or "nothing is compared" in lines[2]
    assert lines.index("## Planes") < lines.index("## Sweeps")
    assert "| weps | (w, eps) | 480 |" in md
    assert "**torque**: torque_Nm [N m]" in md
    assert "![bifurcation diagram of sweep torque](figures/sweeps/torque.png)" in md
    # transitions in N m: Fm 0.05..0.1 maps to 5..10 N m (factor 100)
    t = [line for line in lines if line.strip().startswith("- grazing between")]
    assert t, md
    lo = float(t[0].split("between ")[1].split(" and")[0])
    assert 5.0 <= lo <= 10.0
    assert "issue" not in md.lower()


def test_a_difference_of_exactly_the_tolerance_is_within():
    """Grid midpoints carry rounding (1.31 - 1.33 = -0.020000000000000018): a difference of the
    tolerance itself counts as within, one a grid step beyond does not."""
    from gearsim.analysis.paper import LANDMARK_TOL, within

    assert 1.31 - 1.33 < -LANDMARK_TOL  # the rounding the rule absorbs
    assert within(1.31 - 1.33, LANDMARK_TOL) and within(0.02, LANDMARK_TOL)
    assert not within(0.0201, LANDMARK_TOL) and not within(float("nan"), LANDMARK_TOL)


def test_verified_motions_table_counts_each_plane():
    import numpy as np
    import pandas as pd

    from gearsim.presentation.report import verified_summary
    from gearsim.presentation.report_markdown import verified_lines

    cells = pd.DataFrame({
        "n": [1, 1, 2, 0, 1, 0],
        "motion": ["periodic"] * 3 + ["chaos", "periodic", "quasi-periodic"],
        "status": ["ok", "bifurcation", "ok", "ok", "not_converged", "ok"],
        "refined": [False, True, True, False, False, False],
        "mu_max": [0.5, 0.9995, 0.97, np.nan, np.nan, np.nan],
        "n_attractors": [1, 2, np.nan, 3, 1, 1],
    })  # fmt: skip
    v = verified_summary("wb", cells)
    assert v == {"plane": "wb", "cells": 6, "periodic": 4, "refined": 2, "bifurcation": 1,
                 "not_converged": 1, "with_margin": 3, "near_one": 1, "quasi_periodic": 1,
                 "searched": 5, "multistable": 2}
    text = "\n".join(verified_lines([v]))
    assert "| wb | 6 | 2 | 1 | 1 | 3 (of 4) | 1 | 1 | 2 (of 5) |" in text
    assert "Before" not in text  # a generated report states this run only
    assert verified_summary("wb", cells.drop(columns="status")) is None
