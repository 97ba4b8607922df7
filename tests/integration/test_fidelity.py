"""The fidelity objective on hand-built inputs with known answers; the DE harness on a toy."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from gearsim.analysis.paper import PAPER_COEXIST, PAPER_LANDMARKS, PAPER_SEQUENCES
from gearsim.calibration.search import refine, run_de, sobol_population
from gearsim.calibration.sweeps import backlash_from_sweep
from gearsim.calibration.targets import (
    CAP,
    TARGETS,
    Measured,
    score,
    sequence_distance,
    target_errors,
)
from gearsim.study.config import Study


def perfect() -> Measured:
    """Every target exactly at the paper's value."""
    return Measured(
        landmarks={pl.key: pl.w for pl in PAPER_LANDMARKS},
        b_threshold=0.4125, xi_threshold=0.1436, dc_jump=0.66, gap=0.091,
        sequences={k: [t for t in v if t != "..."] for k, v in PAPER_SEQUENCES.items()},
        coexist=list(PAPER_COEXIST),
    )


def test_sequence_distance_known_values():
    assert sequence_distance(["a", "b", "c"], ["a", "b", "c"]) == 0
    assert sequence_distance(["a", "b", "c"], ["a", "c"]) == 1  # one missing
    assert sequence_distance(["a", "c"], ["a", "x", "c"]) == 1  # one extra
    assert sequence_distance(["a", "b"], ["a", "x"]) == 2  # substitution = delete + insert
    assert sequence_distance([], ["a", "b"]) == 2
    # the ellipsis absorbs any run, also an empty one, but nothing else
    assert sequence_distance(["a", "...", "c"], ["a", "x", "y", "c"]) == 0
    assert sequence_distance(["a", "...", "c"], ["a", "c"]) == 0
    assert sequence_distance(["a", "...", "c"], ["x", "a", "c"]) == 1
    # the paper's xi = 0.05 sequence against a cascade with 1/8T, 1/16T before the chaos
    ours = ["0/1T", "1/1T", "1/2T", "1/4T", "1/8T", "1/16T", "chaos", "1/8T", "1/4T", "1/2T",
            "1/1T"]
    assert sequence_distance(PAPER_SEQUENCES["xi005"], ours) == 0
    # Fig 15c against a sweep at xi = 0.15 with a period-2 window left
    assert sequence_distance(PAPER_SEQUENCES["xi015"], ["0/1T", "1/1T", "1/2T", "1/1T"]) == 2


def test_score_perfect_is_zero_and_terms_cover_targets():
    J, terms = score(perfect())
    assert J == 0.0
    assert set(terms) == {t.key for t in TARGETS}
    assert len(TARGETS) == 21


def test_score_known_errors():
    m = perfect()
    m.landmarks["grazing_1"] = 0.569 + 0.04  # 2 tolerances -> c = 4
    m.landmarks["pd_4_8"] = 1.38  # inside the paper's range 1.37-1.384 -> 0
    m.xi_threshold = 0.1436 + 0.005  # half a tolerance -> 0.25
    m.sequences["xi015"] = ["0/1T", "1/1T", "1/2T", "1/1T"]  # distance 2 -> 4
    m.coexist = ["1-1-1"]  # two of three missing -> 4
    J, terms = score(m)
    assert terms["grazing_1"] == pytest.approx(4.0)
    assert terms["pd_4_8"] == 0.0
    assert terms["xi_threshold"] == pytest.approx(0.25)
    assert terms["seq_xi015"] == pytest.approx(4.0)
    assert terms["coexist"] == pytest.approx(4.0)
    assert J == pytest.approx(math.sqrt((4 + 0.25 + 4 + 4) / 21))


def test_missing_targets_count_the_cap():
    m = perfect()
    m.landmarks["period_one"] = None
    m.dc_jump = math.nan
    m.coexist = None
    J, terms = score(m)
    assert terms["period_one"] == terms["dc_jump"] == terms["coexist"] == CAP**2
    assert J == pytest.approx(math.sqrt(3 * CAP**2 / 21))
    e = target_errors(m)
    assert math.isnan(e["period_one"]) and math.isnan(e["dc_jump"])
    # a huge error is capped like a missing target
    m2 = perfect()
    m2.landmarks["jump"] = 5.0
    assert score(m2)[1]["jump"] == CAP**2


def test_backlash_from_sweep():
    # without back contact: b* = (b0 - min x_min) / 2
    df = pd.DataFrame({"I": [0, 1, 1], "q": [0, 0, 0], "x_min": [0.9, 0.2, -0.3]})
    assert backlash_from_sweep(df, 1.0) == pytest.approx(0.65)
    # back contact at b0: no reading
    df2 = df.assign(I=[0, 2, 1], q=[0, 1, 0])
    assert math.isnan(backlash_from_sweep(df2, 1.0))


def _rosen(x):
    x = np.asarray(x)
    return float(np.sum(100.0 * (x[1:] - x[:-1] ** 2) ** 2 + (1 - x[:-1]) ** 2))


def test_de_harness_reproducible_with_seed_and_finds_minimum():
    bounds = [(-2.0, 2.0)] * 3
    a = run_de(_rosen, bounds, seed=7, generations=60, population=16, x0=[0.0, 0.0, 0.0])
    b = run_de(_rosen, bounds, seed=7, generations=60, population=16, x0=[0.0, 0.0, 0.0])
    c = run_de(_rosen, bounds, seed=8, generations=60, population=16, x0=[0.0, 0.0, 0.0])
    assert a["x"] == b["x"] and a["J"] == b["J"] and a["nfev"] == b["nfev"]
    assert a["x"] != c["x"]
    assert a["nfev"] == 16 * 61
    r = refine(_rosen, a["x"], bounds, maxfev=400)
    assert r["J"] <= a["J"]
    assert np.allclose(r["x"], 1.0, atol=0.05)


def test_sobol_population_seeded_in_bounds_with_start():
    bounds = [(0.0, 1.0), (-5.0, 5.0)]
    p1 = sobol_population(bounds, 16, 3, x0=[0.5, 9.0])
    p2 = sobol_population(bounds, 16, 3, x0=[0.5, 9.0])
    assert np.array_equal(p1, p2)
    assert p1.shape == (16, 2)
    assert list(p1[0]) == [0.5, 5.0]  # start clipped into the box
    assert (p1[:, 0] >= 0).all() and (p1[:, 0] <= 1).all()


def test_form_table_and_report_lines_show_every_target():
    from gearsim.calibration.tables import form_report_lines, form_table_lines

    m = perfect()
    m.landmark_source = {pl.key: "exact" for pl in PAPER_LANDMARKS}
    m.landmark_source["chaos_onset"] = "grid"
    m.landmarks["period_one"] = None
    rec = {"J": score(m)[0], "measured": m.to_dict(), "text": "hand-built"}
    lines = form_table_lines({"hand": rec, "skipped": {"skipped": "needs te_damping"}})
    assert len(lines) == 5
    cells = [c.strip() for c in lines[3].strip("|").split("|")]
    assert len(cells) == 2 + len(TARGETS)
    assert cells[0] == "hand" and cells[2] == "0.5690"
    assert "1.3960g" in cells  # the grid-read chaos onset is marked
    assert "miss" in cells  # the missing landmark
    assert cells[-1] == "1-1-1/2-2-1/4-4-2"
    rep = form_report_lines({"records": {"hand": rec}, "adopted": "hand", "decision": "why"})
    assert any("Adopted: **hand**" in x for x in rep)


# ---------------------------------------------------------------- --stage forms --no-search
def _hand_sweep(p, grid, settings, u0=None, k=0):
    """A forward continuation sweep built here from the public ``simulate_cell`` (each cell
    from the previous cell's final section state and period; the first from ``u0``)."""
    from gearsim.cell.simulate import simulate_cell

    rows = []
    for w in grid:
        r = simulate_cell(p.with_(w=float(w)), u0, settings=settings, start_period=k)
        rows.append({**r.row(), "final_state": r.final_state, "final_period": r.final_period})
        u0, k = r.final_state, r.final_period
    return rows


def _min_x(p, u0, settings):
    """Smallest mesh displacement of the steady motion at ``p`` (from ``u0``): 100 periods of
    transient, then 4 periods sampled 1024 times each (direct integration)."""
    from gearsim.cell.simulate import trajectory

    tr = trajectory(p, u0, periods=4, samples_per_period=1024, settings=settings, transient=100)
    return float(tr.state[:, 0].min())


def test_unsearched_stage_measures_what_a_hand_built_sweep_gives(tmp_path, monkeypatch):
    """``gearsim calibrate --stage forms --no-search`` (``evaluate_unsearched``) on a short w
    window around the first grazing and the jump, against a sweep and landmark rules built
    here: the grazing as the root of min x - b of the steady non-impacting orbit (bisection of
    direct integrations), the jump as the first DC step on a 0.002 sweep, DC after the jump, and
    the backlash threshold (the scale) as the b where back contact (x_min < -b) appears."""
    import json
    from dataclasses import replace

    import gearsim.calibration.form_search as fs
    import gearsim.calibration.forms as ff
    from gearsim.cli.main import main

    st = replace(ff.FINAL, w_min=0.55, w_max=0.80, dw=0.01)
    grid = st.grid()
    monkeypatch.setattr(fs, "FINAL", st)
    monkeypatch.setattr(ff, "B_GRID", grid)  # the scale's bisection on the same short window
    assert main(["calibrate", "--stage", "forms", "--no-search", "--forms", "single_dof",
                 "--forms-dir", str(tmp_path)]) == 0
    rec = json.loads((tmp_path / "single_dof.json").read_text())
    m = rec["measured"]
    # the same parameters, written out here (the search scale: Fm 0.1, b 1; the start shape)
    p = Study.load().parameters().model.with_(model="1dof", Fm=0.1, Fe=0.17854, eps=0.3175,
                                         phi_e=math.radians(-41.59), xi=0.0609, friction=0.0,
                                         b=1.0)
    assert rec["best"] == {"Fe_over_Fm": 1.7854, "eps": 0.3175, "phi_e_deg": -41.59,
                           "xi": 0.0609, "friction": 0.0}
    settings = st.integration()
    rows = _hand_sweep(p, grid, settings)
    xmin = np.array([r["x_min"] for r in rows])
    dc = np.array([r["dc"] for r in rows])
    # the test's rules on the 0.01 grid: grazing = first cell whose motion leaves the contact
    # (x_min < b); jump = first DC step above 0.15
    ig = int(np.argmax(xmin < p.b))
    ij = int(np.argmax(np.diff(dc) > 0.15)) + 1
    assert 0 < ig < ij < len(grid) - 1
    assert m["landmark_source"]["grazing_1"] == "exact" and m["landmark_source"]["jump"] == "exact"
    g_exact, j_exact = m["landmarks"]["grazing_1"], m["landmarks"]["jump"]
    assert grid[ig - 1] < g_exact < grid[ig]
    assert grid[ij - 1] < j_exact < grid[ij]
    # grazing: min x = b of the non-impacting orbit, bisected in w by direct integrations
    lo, hi = float(grid[ig - 1]), float(grid[ig])
    for _ in range(12):  # 0.01 / 2^12 = 2.4e-6
        mid = 0.5 * (lo + hi)
        if _min_x(p.with_(w=mid), rows[ig - 1]["final_state"], settings) > p.b:
            lo = mid
        else:
            hi = mid
    assert abs(g_exact - 0.5 * (lo + hi)) < 2e-5
    # jump: the fold lies between the last low-branch cell and the first jumped cell of a
    # 0.002 continuation sweep from the cell before the jump
    fine = np.arange(grid[ij - 1], grid[ij] + 1e-9, 0.002)
    before = rows[ij - 1]
    fdc = np.array([r["dc"] for r in _hand_sweep(p, fine[1:], settings, before["final_state"],
                                                  before["final_period"])])
    fdc = np.concatenate([[dc[ij - 1]], fdc])
    i1 = int(np.argmax(fdc - dc[ij - 1] > 0.15))
    assert i1 > 0
    assert fine[i1 - 1] < j_exact <= fine[i1]
    # DC after the jump: the first cell after the jump on the window's grid
    assert m["dc_jump"] == pytest.approx(dc[ij], abs=1e-9)
    # the scale: back contact somewhere on the window just below b*, nowhere just above it
    b_star = rec["b_star_bisection"]
    assert 0 < b_star < p.b
    assert m["Fm_derived"] == pytest.approx(p.Fm * 0.4125 / b_star)

    def back_contact(b):
        return any(r["x_min"] < -b for r in _hand_sweep(p.with_(b=b), grid, settings))

    assert back_contact(b_star - 0.002) and not back_contact(b_star + 0.002)


def test_unfinished_form_stream_log_and_tradeoff_evidence(tmp_path):
    """forms-table's helpers on hand-written logs: an unfinished form's row is its best logged
    evaluation (exact before coarse) with the counts; the stream log gives load and wall time;
    the evidence names, for a target hit within tolerance, the landmarks missing there."""
    import json

    from gearsim.calibration.evidence import best_per_target
    from gearsim.calibration.form_search import partial_record, stream_runs
    from gearsim.calibration.forms import FORMS
    from gearsim.calibration.tables import form_summary_lines, landmarks_within

    logs = tmp_path / "logs"
    logs.mkdir()
    good = perfect()
    bad = perfect()
    bad.landmarks["grazing_1"] = 0.569 + 0.1  # 5 tolerances late; every other target exact
    hit = perfect()
    hit.landmarks["period_one"] = 1.864 - 0.05  # first grazing exact, 2>1 misses
    hit.landmarks["jump"] = None

    def line(x, m):
        return json.dumps({"x": x, "J": score(m)[0], "measured": m.to_dict()}) + "\n"

    x0 = [f.start for f in FORMS["single_dof"].free]
    (logs / "single_dof-coarse.11.jsonl").write_text(line(x0, good) + json.dumps(
        {"x": x0, "J": 1e3, "error": "boom"}) + "\n")
    (logs / "single_dof-exact.11.jsonl").write_text(line(x0, bad) + line(x0, hit))
    rec = partial_record(FORMS["single_dof"], logs)
    assert rec["unfinished"] == {"n_coarse": 2, "n_exact": 2, "level": "exact"}
    assert rec["J"] == pytest.approx(score(bad)[0])  # the exact level wins over a better coarse
    assert landmarks_within(rec["measured"]) == 11
    assert partial_record(FORMS["te_rate"], logs) is None
    (tmp_path / "streamA.log").write_text(
        "=== single_dof start 2026-11-30T02:39:00Z load 0.32 1.43 1.80 code f3f7786\n"
        "[single_dof] start J (coarse) = 2.3\n321.56 s wall 249.23 s user\n"
        "=== single_dof end 2026-11-30T02:44:22Z rc 0\n")
    runs = stream_runs(tmp_path)
    assert runs["single_dof"] == {"stream": "streamA", "start": "2026-11-30T02:39:00Z",
                             "load": "0.32 1.43 1.80", "code": "f3f7786", "wall_s": 321.56,
                             "user_s": 249.23, "end": "2026-11-30T02:44:22Z"}
    rec["run"] = runs["single_dof"]
    row = form_summary_lines({"single_dof": rec})[2]
    assert "11 of 12" in row and "0 + 2" not in row and "2 + 2 (unfinished)" in row
    assert "| 322 | 0.32 1.43 1.80 | f3f7786 |" in row
    best = best_per_target(logs)
    g = best["grazing_1"]
    assert g["n"] == 3 and g["n_hit"] == 2 and g["error"] == pytest.approx(0.0)
    # of the two evaluations that hit the first grazing, the lower J is `good` (nothing misses)
    assert g["hit_J"] == 0.0 and g["hit_misses"] == {}
    p1 = best["period_one"]
    assert p1["n_hit"] == 2 and p1["hit_J"] == 0.0
    # with `hit` alone: hitting the first grazing, the jump (lost) and 2>1 miss, both named
    logs2 = tmp_path / "logs2"
    logs2.mkdir()
    (logs2 / "single_dof-exact.12.jsonl").write_text(line(x0, hit))
    g2 = best_per_target(logs2)["grazing_1"]
    assert g2["hit_misses"].keys() == {"jump", "period_one"}
    assert g2["hit_misses"]["jump"] is None
    assert g2["hit_misses"]["period_one"] == pytest.approx(-0.05)
