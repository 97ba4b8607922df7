"""Results that a run did not ask to replace are never replaced: over a finished default run (the
session's tiny run stands in for it), the fast look runs in its own folder (studies/quick/), and
a file of one's own without `study:` or `folder:` stops in one line before any job; every result
in place stays byte for byte as it was. Other files of the same content, or
`--config replace_results=true`, run."""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import pytest
from workflow_helpers import smk, smk_in

from gearsim.results.in_place import _legacy_grids

pytestmark = pytest.mark.slow

# a file of one's own that forgot `study:` (README's example: a plane of its own, 2-row tiles)
OWN = """\
planes:
  weps:
    x: {name: w, min: 0.1, max: 2.5, n: 6}
    y: {name: eps, min: 0.05, max: 0.6, n: 4}
    fixed: {b: 0.3}
tile_rows: 2
"""


def _files(wd: Path) -> dict[str, str]:
    """sha256 of every file under results/ (Parquet tables, catalogue, figures, the record)."""
    return {p.relative_to(wd).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted((wd / "results").rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def finished(tiny_run, tmp_path_factory):
    """A copy of the session's tiny run (its results, config files and Snakemake's records)."""
    wd = tmp_path_factory.mktemp("in_place") / "run"
    shutil.copytree(tiny_run[0], wd, ignore=shutil.ignore_patterns("locks", "logs"))
    return wd


# a file of one's own that changes the grid of a plane in place
GRID = "planes:\n  wb:\n    x: {name: w, min: 0.1, max: 2.5, n: 10}\n"


# a file of one's own that changes a plane's settings, not its grid
SETTINGS = "planes:\n  wb:\n    fixed: {xi: 0.07}\n"


@pytest.mark.parametrize(("own", "says"), [
    (OWN, "added plane weps"),
    (GRID, "plane wb: w 0.1..2.5 x b 0..1: 8 x 8 -> w 0.1..2.5 x b 0..1: 10 x 8"),
    (SETTINGS, "plane wb: w 0.1..2.5 x b 0..1: 8 x 8 (fixed.xi (unset) -> 0.07)"),
])
def test_another_configuration_stops_before_any_job(finished, own, says):
    (finished / "config" / "own.yaml").write_text(own)
    before = _files(finished)
    assert "results/.configuration.json" in before  # the run recorded what made it
    r = smk(finished, "--cores", "2", "--configfile", "config/tiny.yaml", "config/own.yaml",
            check=False)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2, r.stdout[-2000:] + r.stderr[-2000:]
    err = [ln for ln in lines if ln.startswith("gearsim: error:")]
    assert len(err) == 1, lines
    assert "results/ holds the results of config/config.yaml + config/tiny.yaml" in err[0]
    assert says in err[0] and "folder: NAME" in err[0] and "replace_results=true" in err[0]
    assert "Job stats" not in r.stdout + r.stderr
    assert _files(finished) == before


def test_fast_look_runs_in_its_own_folder(finished):
    before = _files(finished)
    # the fast look plans its jobs in studies/quick/ (its `folder`), none in results/
    r = smk_in(finished, "-n", "--configfile", "config/tiny.yaml", "config/quick.yaml")
    assert "simulate_tile" in r.stdout and "gearsim: error" not in r.stderr
    # a run of a folder writes there (a cheap target of the tiny study in a folder of its own)
    smk_in(finished, "results/sweeps/b015.parquet", "--cores", "2", "--configfile",
           "config/tiny.yaml", "--config", "folder=look")
    assert (finished / "studies/look/results/sweeps/b015.parquet").is_file()
    assert (finished / "studies/look/results/.configuration.json").is_file()
    assert _files(finished) == before


def test_asked_replacement_and_same_content_run(finished):
    (finished / "config" / "own.yaml").write_text(GRID)
    # the option named in the message plans the jobs over the results in place
    r = smk(finished, "-n", "--quiet", "rules", "--configfile", "config/tiny.yaml",
            "config/own.yaml", "--config", "replace_results=true")
    assert "simulate_tile" in r.stdout + r.stderr
    # other files of the same content (a cluster file merged over the study) replace nothing
    (finished / "config" / "cluster.yaml").write_text("cluster: {scheduler_address: null}\n")
    r = smk(finished, "-n", "--configfile", "config/tiny.yaml", "config/cluster.yaml",
            "--config", "replace_results=false")
    assert "gearsim: error" not in r.stderr
    r = smk(finished, "-n", "--configfile", "config/tiny.yaml", "config/own.yaml",
            "--config", "replace_results=maybe", check=False)
    assert r.returncode != 0 and "replace_results: true or false" in r.stdout + r.stderr


def test_results_without_a_record_are_compared_by_their_grids(finished, tmp_path):
    wd = tmp_path / "legacy"
    shutil.copytree(finished, wd)
    (wd / "config" / "own.yaml").write_text(GRID)
    (wd / "results" / ".configuration.json").unlink()
    before = _files(wd)
    r = smk(wd, "-n", "--configfile", "config/tiny.yaml", "config/own.yaml", check=False)
    assert r.returncode == 2
    assert "results/ holds results of other grids" in r.stderr
    assert "plane wb: w 0.1..2.5 x b 0..1: 8 x 8 -> w 0.1..2.5 x b 0..1: 10 x 8" in r.stderr
    assert _files(wd) == before
    # the grids in place, read from the Parquet files' metadata
    grids = _legacy_grids(wd / "results")
    assert grids["sweep standard"] == "w 0.1..2.5: 6 points"
    assert grids["plane wxi"] == "w 0.1..2.5 x xi 0.04..0.16: 8 x 8"
