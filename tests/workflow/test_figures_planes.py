"""Any plane fully drawn: a (w, eps) plane of a tiny real pipeline run gets its pattern, DC and
Kmax maps, the paper's plane figures drawn for it say "not applicable" for the paper comparison,
and the report says "not applicable" where the paper has nothing to compare."""

from __future__ import annotations

import json
import sqlite3

import pandas as pd
import pytest
from tiny_study import CONFIGS, tiny_study
from workflow_helpers import make_workdir, smk

from gearsim.cli.main import main
from gearsim.presentation.report import analyse
from gearsim.presentation.report_inputs import load_plane
from gearsim.presentation.report_markdown import to_markdown
from gearsim.results.catalogue import CatalogueError


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    return tiny_study(tmp_path_factory.getbasetemp())


def test_maps_of_a_w_eps_plane(study, tmp_path, monkeypatch):
    monkeypatch.chdir(study)
    cells = study / "results/weps/cells.parquet"
    out = tmp_path / "figs"
    assert main(["figures", "--maps", "--plane", f"weps={cells}", "--configfile", *CONFIGS,
                 "--outdir", str(out), "--index"]) == 0
    for kind in ("pattern", "dc", "kmax"):
        rec = json.loads((out / "planes" / f"weps-{kind}.json").read_text())
        assert rec["axes"] == ["w", "eps"] and rec["plane"] == "weps"
        assert "(ω, ε)" in rec["caption"]
        assert (out / "planes" / f"weps-{kind}.png").stat().st_size > 20_000
    pattern = json.loads((out / "planes" / "weps-pattern.json").read_text())
    assert any("not applicable" in n for n in pattern["notes"])
    assert "grid 6 x 4 cells" in pattern["notes"] and not any("paper 400" in n for n in
                                                                pattern["notes"])
    index = (out / "README.md").read_text()
    assert "## Plane weps" in index and "weps-kmax.png" in index


def test_paper_plane_figure_for_another_plane(study, tmp_path, monkeypatch):
    """`gearsim figures --fig 7 --plane weps=...` draws the (w, eps) plane (was KeyError 'b')."""
    monkeypatch.chdir(study)
    cells = study / "results/weps/cells.parquet"
    assert main(["figures", "--fig", "7", "12", "13", "--plane", f"weps={cells}",
                 "--configfile", *CONFIGS, "--outdir", str(tmp_path)]) == 0
    rec = json.loads((tmp_path / "fig07.json").read_text())
    assert rec["inputs"] == ["weps/cells"]
    assert "(ω, ε)" in rec["caption"]
    assert any("not applicable" in d for d in rec["differences"])
    assert any("Drawn for the plane 'weps'" in d for d in rec["differences"])
    for n in (12, 13):
        assert (tmp_path / f"fig{n}.png").is_file()


def test_report_not_applicable_for_a_study_of_ones_own(study):
    weps = pd.read_parquet(study / "results/weps/cells.parquet")
    rep = analyse({}, {"weps": weps}, plane_axes={"weps": ("w", "eps")}, configured_sweeps=[])
    md = to_markdown(rep)
    assert rep.compared == 0 and not rep.misses
    assert "nothing beyond the tolerances" not in md
    # a report about the study itself: no scorecard, no paper sections
    assert md.startswith("# Study report") and "nothing is compared with the paper" in md
    assert "Scorecard" not in md and "standard sweep" not in md
    assert f"| weps | (w, eps) | {len(weps)} (6 x 4) |" in md
    # the paper's own plane is still compared, and says how many comparisons were made
    wb = pd.read_parquet(study / "results/wb/cells.parquet")
    rep2 = analyse({}, {"wb": wb, "weps": weps},
                   plane_axes={"wb": ("w", "b"), "weps": ("w", "eps")}, configured_sweeps=[])
    assert rep2.compared == 1 and rep2.b_threshold is not None
    assert "plane wb" in rep2.b_threshold.note


def test_report_cli_planes_from_config(study, tmp_path, monkeypatch):
    monkeypatch.chdir(study)
    out = tmp_path / "report.md"
    assert main(["report", "--configfile", *CONFIGS, "--catalogue", str(tmp_path / "none"),
                 "--calibration", str(tmp_path / "none.json"), "--out", str(out)]) == 0
    md = out.read_text()
    assert "| weps | (w, eps) |" in md and "| wxi | (w, xi) | not computed |" in md
    assert "| wb | (w, b) |" in md


def test_report_rule_declares_what_it_reads(tmp_path):
    wd = make_workdir(tmp_path)
    r = smk(wd, "-n", "-p", "results/report.md", "--configfile", "config/tiny.yaml")
    block = r.stdout[r.stdout.index("rule report:"):]
    block = block[:block.index("\n\n")]
    inputs = block.split("input:", 1)[1].split("\n", 1)[0]
    for f in ("results/catalogue.d/build.sqlite", "results/sweeps/b015.parquet",
              "results/wb/audit.parquet", "results/wxi/audit.parquet",
              "results/wb/cells.parquet", "docs/calibration.json",
              ".snakemake/gearsim/default/config.json"):  # the resolved config the jobs read
        assert f in inputs, (f, inputs)
    assert "--configfile" in r.stdout


def test_report_reads_planes_from_the_real_catalogue(study, tmp_path):
    """The catalogue's cells (axes stored as x / y, impact as ``impact``) give the report the
    same plane as cells.parquet; a file that is not a catalogue is a one-line error."""
    cat = study / "results/catalogue.sqlite"
    got = load_plane("wb", catalogue=cat, results=tmp_path)
    want = pd.read_parquet(study / "results/wb/cells.parquet")
    assert len(got) == len(want) and "I" in got.columns
    assert sorted(got["label"]) == sorted(want["label"])
    assert load_plane("wxi", catalogue=cat, results=tmp_path) is None  # not in this catalogue
    a = analyse({}, {"wb": got}, plane_axes={"wb": ("w", "b")}, configured_sweeps=[])
    b = analyse({}, {"wb": want}, plane_axes={"wb": ("w", "b")}, configured_sweeps=[])
    assert (a.b_threshold.last_with, a.b_threshold.first_without) == (
        b.b_threshold.last_with, b.b_threshold.first_without)
    bogus = tmp_path / "bogus.sqlite"
    sqlite3.connect(bogus).execute("create table cells (x int)").connection.commit()
    with pytest.raises(CatalogueError):
        load_plane("wb", catalogue=bogus, results=tmp_path)
