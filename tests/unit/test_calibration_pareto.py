"""The landmark trade-off read from evaluation logs: group errors by hand, the front against a
brute-force dominance check, the Figs 9-11 tally."""

from __future__ import annotations

import json
import math

import numpy as np

from gearsim.analysis.paper import PAPER_LANDMARKS
from gearsim.calibration.pareto import (
    LOWER,
    UPPER,
    coexist_tally,
    front,
    group_error,
    pareto_points,
)
from gearsim.calibration.targets import CAP

PAPER = {pl.key: pl.w for pl in PAPER_LANDMARKS}


def test_group_error_is_the_capped_rms_in_tolerances():
    e = {"grazing_1": 0.04, "jump": -0.02, "pd_1_2": math.nan}
    # 2 and 1 tolerances, the missing landmark the cap
    assert group_error(e, LOWER) == math.sqrt((4 + 1 + CAP**2) / 3)
    assert group_error({k: 1.0 for k in UPPER}, UPPER) == CAP


def test_front_keeps_exactly_the_undominated_points():
    rng = np.random.default_rng(4)
    pts = [{"lower": float(a), "upper": float(b)} for a, b in rng.random((300, 2))]
    got = {(p["lower"], p["upper"]) for p in front(pts)}
    brute = {(p["lower"], p["upper"]) for p in pts
             if not any(q["lower"] <= p["lower"] and q["upper"] <= p["upper"] and q is not p
                        for q in pts)}
    assert got == brute


def test_points_and_tally_from_logs(tmp_path):
    lm = dict(PAPER)
    lm["grazing_1"] += 0.04  # lower: 2 tolerances on one of three
    lm["period_one"] = None  # upper: the cap on one of four
    rec = {"x": [1.0], "J": 3.0, "measured": {"landmarks": lm, "coexist": ["1-1-1", "2-2-1"]}}
    other = {"x": [2.0], "J": 1e3, "error": "RuntimeError()"}  # a failed evaluation
    (tmp_path / "single_dof-lanes.s1.jsonl").write_text(json.dumps(rec) + "\n"
                                                        + json.dumps(other) + "\n")
    pts = pareto_points(tmp_path)
    assert len(pts) == 1 and pts[0]["form"] == "single_dof" and pts[0]["level"] == "lanes"
    assert np.isclose(pts[0]["lower"], math.sqrt(4 / 3))
    assert np.isclose(pts[0]["upper"], math.sqrt(CAP**2 / 4))
    t = coexist_tally(tmp_path)
    assert t["n_sets"] == 1 and t["motions_found"] == {"1-1-1": 1, "2-2-1": 1}
    assert t["most_of_the_paper_motions"] == 2


def test_collect_fit_spread_and_the_report_rows(tmp_path):
    from gearsim.calibration.lane_fit import collect_fit
    from gearsim.calibration.tables import fit_report_lines
    from gearsim.presentation.report import Report
    from gearsim.presentation.report_markdown import _appendix_lines

    for seed, J in ((1, 2.0), (2, 2.05), (3, 2.1)):
        rec = {"seed": seed, "search": "cma-es", "nfev": 100 * seed, "stopped_by": "flat",
               "runs": [], "J_lanes": J, "best": {"xi": 0.06}, "cpu_s_search": 10.0,
               "wall_s_search": 20.0, "curve": [[8, J + 1], [100 * seed, J]]}
        (tmp_path / f"single_dof.s{seed}.json").write_text(json.dumps(rec))
    fit = collect_fit(["single_dof", "te_rate"], tmp_path)
    f = fit["forms"]["single_dof"]
    assert "te_rate" not in fit["forms"]  # no record: no row
    assert (f["evaluations"], f["n_seeds"], f["cpu_s"]) == (600, 3, 30.0)
    assert np.isclose(f["spread"], 0.05)  # (2.1 - 2.0) / 2.0
    row = [line for line in fit_report_lines(fit) if line.startswith("| single_dof")]
    assert row == ["| single_dof | 600 | 3 | 2.000, 2.050, 2.100 | flat, flat, flat | 5.0% | "
                   "30 | 60 |"]
    app = _appendix_lines(Report(calibration={"fit": fit}))
    assert app[0].startswith("## Appendix") and "\n### CMA-ES fits in lanes" in "\n".join(app)


def test_collect_fit_takes_an_unfinished_seed_from_its_log(tmp_path):
    from gearsim.calibration.lane_fit import collect_fit

    (tmp_path / "logs").mkdir()
    lines = [json.dumps({"x": [0.0], "J": J, "measured": None}) for J in (5.0, 4.0, 4.5, 3.0)]
    (tmp_path / "logs" / "te_rate-lanes.s2.jsonl").write_text("\n".join(lines) + "\n")
    s = collect_fit(["te_rate"], tmp_path)["forms"]["te_rate"]["seeds"]["2"]
    assert (s["nfev"], s["stopped_by"], s["J_lanes"]) == (4, "unfinished", 3.0)
    assert s["curve"] == [[1, 5.0], [3, 4.0], [4, 3.0]]  # where the best J changes, and the end


def test_collect_fit_times_an_unfinished_seed_from_its_state(tmp_path):
    from gearsim.calibration.lane_fit import collect_fit, state_path

    (tmp_path / "logs").mkdir()
    lines = [json.dumps({"x": [0.0], "J": J, "measured": None}) for J in (5.0, 4.0, 4.5)]
    (tmp_path / "logs" / "te_rate-lanes.s1.jsonl").write_text("\n".join(lines) + "\n")
    (tmp_path / "logs" / "te_rate-lanes.s3.jsonl").write_text(lines[0] + "\n")
    # the state after the second generation; the log holds one evaluation more
    state = {"nfev": 2, "J_lanes": 4.0, "best": {"xi": 0.07}, "cpu_s_search": 12.5,
             "wall_s_search": 40.0, "runs": [], "curve": [[1, 5.0], [2, 4.0]],
             "start": "2026-01-01T00:00:00Z", "load": "1.00 1.00 1.00", "code": "abc"}
    state_path(tmp_path / "logs", "te_rate", 1).write_text(json.dumps(state))
    f = collect_fit(["te_rate"], tmp_path)["forms"]["te_rate"]
    s1, s3 = f["seeds"]["1"], f["seeds"]["3"]
    assert (s1["nfev"], s1["J_lanes"], s1["stopped_by"]) == (3, 4.0, "unfinished")
    assert (s1["cpu_s_search"], s1["wall_s_search"], s1["timed"]) == (12.5, 40.0, True)
    assert s1["best"] == {"xi": 0.07} and s1["load"] == "1.00 1.00 1.00"
    assert (s3["nfev"], s3["timed"], s3["cpu_s_search"]) == (1, False, 0.0)
    assert (f["evaluations"], f["cpu_s"], f["wall_s"]) == (4, 12.5, 40.0)


def test_collect_fit_reads_a_seed_resumed_past_its_record_from_its_log(tmp_path):
    from gearsim.calibration.lane_fit import collect_fit, state_path

    (tmp_path / "logs").mkdir()
    rec = {"seed": 1, "search": "cma-es", "nfev": 2, "stopped_by": "time_budget", "runs": [],
           "J_lanes": 4.0, "best": {"xi": 0.06}, "cpu_s_search": 5.0, "wall_s_search": 9.0,
           "curve": [[1, 5.0], [2, 4.0]]}
    (tmp_path / "te_rate.s1.json").write_text(json.dumps(rec))
    lines = [json.dumps({"x": [0.0], "J": J, "measured": None}) for J in (5.0, 4.0, 3.5, 3.0)]
    (tmp_path / "logs" / "te_rate-lanes.s1.jsonl").write_text("\n".join(lines) + "\n")
    state = {"nfev": 4, "J_lanes": 3.0, "best": {"xi": 0.07}, "cpu_s_search": 11.0,
             "wall_s_search": 30.0, "runs": [], "curve": [[2, 4.0], [4, 3.0]]}
    state_path(tmp_path / "logs", "te_rate", 1).write_text(json.dumps(state))
    s = collect_fit(["te_rate"], tmp_path)["forms"]["te_rate"]["seeds"]["1"]
    # the resumed search, not its older record
    assert (s["nfev"], s["J_lanes"], s["stopped_by"], s["cpu_s_search"]) == (
        4, 3.0, "unfinished", 11.0)
    # once it finishes again its record is the newer one
    (tmp_path / "te_rate.s1.json").write_text(json.dumps({**rec, "nfev": 4, "J_lanes": 3.0}))
    s = collect_fit(["te_rate"], tmp_path)["forms"]["te_rate"]["seeds"]["1"]
    assert (s["nfev"], s["stopped_by"]) == (4, "time_budget")


def test_coexist_sets_are_finished_records_first_then_checkpoints(tmp_path):
    """The Figs 9-11 scan's seed sets: a seed's record where it finished, else its checkpoint's
    best so far (marked unfinished), as where it was resumed past its record; a seed with
    neither is not scanned."""
    import json

    from gearsim.calibration.lane_fit import seed_bests

    (tmp_path / "logs").mkdir()
    (tmp_path / "f.s1.json").write_text(json.dumps({"seed": 1, "nfev": 5, "best": {"xi": 0.1}}))
    (tmp_path / "logs/f-lanes.s1.state.json").write_text(
        json.dumps({"nfev": 5, "best": {"xi": 0.2}}))
    (tmp_path / "f.s4.json").write_text(json.dumps({"seed": 4, "nfev": 5, "best": {"xi": 0.4}}))
    (tmp_path / "logs/f-lanes.s4.state.json").write_text(  # resumed past its record
        json.dumps({"nfev": 9, "best": {"xi": 0.5}}))
    (tmp_path / "logs/f-lanes.s2.state.json").write_text(json.dumps({"best": {"xi": 0.3}}))
    (tmp_path / "logs/f-lanes.s3.state.json").write_text(json.dumps({"nfev": 0}))
    (tmp_path / "g.s1.json").write_text(json.dumps({"seed": 1, "nfev": 5, "best": {"xi": 9.0}}))
    assert seed_bests(tmp_path, "f") == {"s1": ({"xi": 0.1}, True), "s2": ({"xi": 0.3}, False),
                                         "s4": ({"xi": 0.5}, False)}
