"""The fidelity objective on hand-built inputs with known answers; the DE harness on a toy."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from gearsim.fidelity import (
    CAP,
    PAPER_COEXIST,
    PAPER_SEQUENCES,
    TARGETS,
    Measured,
    backlash_from_sweep,
    score,
    sequence_distance,
    target_errors,
)
from gearsim.fidelity_fit import refine, run_de, sobol_population
from gearsim.landmarks import PAPER_LANDMARKS


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
    # Fig 15c against round 1's sweep at xi = 0.15 (a period-2 window remains)
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
    from gearsim.fidelity import form_report_lines, form_table_lines

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
