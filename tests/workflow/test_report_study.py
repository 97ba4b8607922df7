"""The reports the pipeline writes, read as a user reads them: a study of one's own (the README's
(w, eps) plane and torque sweep in N m, small) gets a report about itself with the sweep's
diagram in N m and a figure index of what it drew; the paper's tiny study gets the scorecard on
its first screen. No generated file mentions how the work was organised."""

from __future__ import annotations

import shutil

import pytest
import yaml
from tiny_study import CONFIGS, tiny_study
from workflow_helpers import ROOT, make_workdir, smk_in

from gearsim.cli.main import main

STUDY = {
    "study": "wepsmall",
    "gear": "config/gears/standard.yaml",
    "planes": {"weps": {"x": {"name": "w", "min": 0.1, "max": 2.5, "n": 6},
                        "y": {"name": "eps", "min": 0.05, "max": 0.6, "n": 4},
                        "fixed": {"b": 0.3}}},
    "sweeps": {"torque": {"name": "torque_Nm", "min": 4, "max": 40, "n": 7,
                          "fixed": {"speed_rpm": 6000}}},
    "points": {},
    "tile_rows": 4,
    "integration": {"method": "rk4", "steps_per_period": 64, "transient": 30,
                    "transient_continuation": 10, "chunk": 16, "max_periods": 32, "n_max": 8},
    "audit": {"fraction": 0.1, "threshold": 0.0},
    "orbits": {"continuation": False, "curves": False},
}
OUT = "studies/wepsmall/results"


def _generated_text(results):
    for f in results.rglob("*"):
        if f.is_file() and f.suffix in (".md", ".json", ".html", ".csv", ".txt"):
            yield f, f.read_text(errors="replace")


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    wd = make_workdir(tmp_path_factory.mktemp("report_study"))
    shutil.copytree(ROOT / "config/gears", wd / "config/gears")
    (wd / "config/wepsmall.yaml").write_text(yaml.safe_dump(STUDY))
    # a study runs from the project directory; its targets are named inside its folder
    smk_in(wd, "results/report.md", "results/figures/README.md", "results/explorer/index.html",
        "--cores", "2", "--configfile", "config/wepsmall.yaml", timeout=1800)
    return wd


def test_a_study_of_ones_own_reports_itself(study):
    res = study / OUT
    md = (res / "report.md").read_text()
    lines = md.splitlines()
    assert lines[0] == "# Study report: wepsmall"
    assert "Scorecard" not in md and "Landmarks" not in md
    assert lines.index("## Planes") < lines.index("## Sweeps")
    assert "| weps | (w, eps) | 24 (6 x 4) |" in md
    assert "**torque**: torque_Nm [N m], 7 points." in md
    assert "- torque_Nm [N m] 4 to 40: " in md
    assert "![bifurcation diagram of sweep torque](figures/sweeps/torque.png)" in md
    assert (res / "figures/sweeps/torque.png").stat().st_size > 10_000
    rec = yaml.safe_load((res / "figures/sweeps/torque.json").read_text())
    assert "torque_Nm [N m]" in rec["caption"]
    index = (res / "figures/README.md").read_text()
    assert "Not built" not in index and "sweeps/torque.png" in index
    drawn = {f"## Fig {int(p.stem[3:])}" for p in (res / "figures").glob("fig[0-9][0-9].json")}
    listed = {line for line in index.splitlines() if line.startswith("## Fig ")}
    assert listed == drawn
    for f, text in _generated_text(res):
        assert "issue" not in text.lower(), f


def test_the_papers_study_leads_with_the_scorecard(tmp_path_factory, tmp_path, monkeypatch):
    wd = tiny_study(tmp_path_factory.getbasetemp())
    monkeypatch.chdir(wd)
    out = tmp_path / "report.md"
    assert main(["report", "--configfile", *CONFIGS, "--catalogue", "results/catalogue.sqlite",
                 "--calibration", str(ROOT / "docs/calibration.json"), "-o", str(out)]) == 0
    head = out.read_text().splitlines()[:40]
    assert head[0] == "# Reproduction report" and "## Scorecard" in head
    assert sum(line.startswith("| w: ") for line in head) == 12
    assert any(line.startswith("| b above which no double-sided impact occurs | 0.4125 |")
               for line in head)
    text = out.read_text()
    assert "## Appendix: calibration and model forms" in text
    assert text.index("## Appendix") > text.index("## Details of the paper comparison")
    assert "issue" not in text.lower()
