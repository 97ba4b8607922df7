"""Landmark extraction on hand-built orbit-diagram tables (no simulation)."""

import math

import pandas as pd
import pytest
from reference import reference_settings
from sweep_tables import paper_like, row

from gearsim.analysis.landmark_refinement import refine_landmarks
from gearsim.analysis.landmarks import (
    find_landmarks,
    is_subsequence,
    match_paper,
    pattern_sequence,
)
from gearsim.analysis.paper import PAPER_LANDMARKS


def test_every_kind_found_in_order():
    lm = find_landmarks(paper_like())
    kinds = list(lm["kind"])
    assert kinds == ["grazing", "jump", "period_doubling", "grazing", "period_doubling",
                     "grazing", "period_doubling", "chaos_onset", "inverse_period_doubling",
                     "inverse_period_doubling", "inverse_period_doubling", "period_one"]
    g = lm.iloc[0]
    assert g["from_npq"] == "1-0-0" and g["to_npq"] == "1-1-0" and g["direction"] == 1
    assert g["lo"] == pytest.approx(0.55) and g["hi"] == pytest.approx(0.56)
    assert g["value"] == pytest.approx(0.555)
    assert lm.iloc[3]["direction"] == -1  # 2-2-0 -> 2-1-0 loses an impact
    assert lm.iloc[1]["dc_hi"] == pytest.approx(0.66)
    assert set(lm["annotation"]) >= {"G Bif", "PD Bif", "Jump"}


def test_match_paper_errors_are_midpoint_minus_paper():
    m = match_paper(find_landmarks(paper_like()))
    assert m["found"].all() and len(m) == len(PAPER_LANDMARKS)
    by = m.set_index("key")
    assert by.loc["grazing_1", "error"] == pytest.approx(0.555 - 0.569)
    assert by.loc["period_one", "ours"] == pytest.approx(1.855)
    # inside the paper's 1.37-1.384 range the error is zero
    assert by.loc["pd_4_8", "ours"] == pytest.approx(1.365)
    assert by.loc["pd_4_8", "error"] == pytest.approx(1.365 - 1.37)
    assert by["exact_pattern"].all()


def test_missing_landmark_and_out_of_order():
    df = paper_like()
    df = df[(df["value"] < 1.35) | (df["value"] >= 1.37)]  # no 4-3-0 window
    m = match_paper(find_landmarks(df)).set_index("key")
    assert not m.loc["grazing_4", "found"] and math.isnan(m.loc["grazing_4", "ours"])
    assert m.loc["pd_4_8", "found"]  # 4-2-0 -> 8-6-0 is still a period doubling


def test_isolated_quasi_periodic_cell_is_bridged():
    lm = find_landmarks(paper_like(quasi_at=0.98))
    pd12 = lm[lm["kind"] == "period_doubling"].iloc[0]
    assert pd12["lo"] == pytest.approx(0.97) and pd12["hi"] == pytest.approx(0.99)
    kept = find_landmarks(paper_like(quasi_at=0.98), bridge=0)
    assert (kept["kind"] == "other").sum() >= 2


def test_early_grazing_tongue_and_exit():
    rows = [row(0.40, "1-0-0"), row(0.41, "1-1-0", dc=0.02), row(0.42, "1-0-0"),
            row(0.43, "1-1-0", dc=0.1)]
    lm = find_landmarks(pd.DataFrame(rows))
    assert list(lm["kind"]) == ["grazing", "grazing", "grazing"]
    assert list(lm["direction"]) == [1, -1, 1]


def test_jump_without_pattern_change_and_threshold():
    rows = [row(0.6, "1-1-0", dc=0.1), row(0.61, "1-1-0", dc=0.2), row(0.62, "1-1-0", dc=0.6)]
    lm = find_landmarks(pd.DataFrame(rows))
    assert list(lm["kind"]) == ["jump"] and lm.iloc[0]["direction"] == 1
    assert find_landmarks(pd.DataFrame(rows), jump_dc=0.5).empty


def test_chaos_windows_and_onset_need_a_run():
    seq = ["2-2-0", "chaos", "2-2-0", "chaos", "chaos", "chaos", "4-3-0", "chaos", "chaos",
           "1-1-0"]
    rows = [row(1 + 0.01 * i, None, motion="chaos") if s == "chaos" else row(1 + 0.01 * i, s)
            for i, s in enumerate(seq)]
    lm = find_landmarks(pd.DataFrame(rows))
    assert (lm["kind"] == "chaos_onset").sum() == 1
    onset = lm[lm["kind"] == "chaos_onset"].iloc[0]
    assert onset["lo"] == pytest.approx(1.02)  # the single chaos cell is not the onset
    last = lm.iloc[-1]
    assert last["kind"] == "period_one" and last["from_npq"] == "chaos"


def test_pattern_sequence_and_subsequence():
    df = paper_like()
    seq = pattern_sequence(df)
    assert seq[:3] == ["0/1T", "1/1T", "1/2T"] and "chaos" in seq and seq[-1] == "1/1T"
    npq = pattern_sequence(df, use_npq=True)
    assert npq[:4] == ["1-0-0", "1-1-0", "2-2-0", "2-1-0"]
    assert is_subsequence(["0/1T", "1/2T", "chaos", "1/1T"], seq)
    assert not is_subsequence(["chaos", "0/1T"], seq)


def test_empty_and_backward():
    assert find_landmarks(pd.DataFrame()).empty
    back = paper_like().iloc[::-1]
    lm = find_landmarks(back)
    assert lm.iloc[0]["lo"] > lm.iloc[0]["hi"]  # lo is the side swept first


def test_refine_landmarks_bisects_with_simulations():
    """A real grazing of the single-DOF model, refined by bisection (a few cells)."""
    from gearsim.cell.sweep import orbit_diagram
    from gearsim.dynamics.parameters import ModelParameters

    p = ModelParameters(model="1dof")
    st = reference_settings(rtol=1e-8, transient=80, max_periods=64)
    df = orbit_diagram(p, "w", [0.45, 0.50], settings=st)
    lm = find_landmarks(df)
    assert list(lm["kind"]) == ["grazing"]
    ref = refine_landmarks(lm, p, settings=st, tol=0.01, lookback=0)
    r = ref.iloc[0]
    assert r["refined"] and r["hi"] - r["lo"] <= 0.01 + 1e-12
    assert 0.45 <= r["lo"] < r["hi"] <= 0.50


def test_chaos_onset_through_quasi_periodic_run():
    seq = ["8-5-0", "quasi-periodic", "quasi-periodic", "quasi-periodic", "chaos", "chaos",
           "chaos", "8-6-0"]
    rows = [row(1.3 + 0.01 * i, s) if s[0].isdigit() else row(1.3 + 0.01 * i, None, motion=s)
            for i, s in enumerate(seq)]
    lm = find_landmarks(pd.DataFrame(rows))
    assert list(lm["kind"]) == ["chaos_onset", "inverse_period_doubling"]
    assert lm.iloc[0]["lo"] == pytest.approx(1.30) and lm.iloc[0]["to_npq"] == "quasi-periodic"


def test_chaos_exit_through_quasi_periodic_cells():
    seq = ["chaos", "chaos", "chaos", "quasi-periodic", "quasi-periodic", "quasi-periodic",
           "16-12-0", "8-6-0"]
    rows = [row(1.5 + 0.01 * i, s) if s[0].isdigit() else row(1.5 + 0.01 * i, None, motion=s)
            for i, s in enumerate(seq)]
    lm = find_landmarks(pd.DataFrame([row(1.49, "8-5-0")] + rows))
    assert list(lm["kind"]) == ["chaos_onset", "inverse_period_doubling",
                                "inverse_period_doubling"]
    ex = lm.iloc[1]
    assert ex["from_npq"] == "chaos" and ex["to_npq"] == "16-12-0"
    assert ex["lo"] == pytest.approx(1.52) and ex["hi"] == pytest.approx(1.56)
