"""A tiny real study for the figure, report and explorer tests: the pipeline (Snakemake, the
`gearsim` CLI, the real tile writer) on config/tiny.yaml plus a (w, eps) plane, run once per
test session into a throw-away working directory."""

from __future__ import annotations

from pathlib import Path

from workflow_helpers import make_workdir, smk

from gearsim.cli.main import main

STUDY = """\
# tiny.yaml plus a plane of an axis pair the paper does not map, with its coexisting attractors
planes:
  weps:
    x: {name: w, min: 0.1, max: 2.5, n: 6}
    y: {name: eps, min: 0.1, max: 0.6, n: 4}
    fixed: {}
    multistability: {starts: 4, seed: 1}
"""
CONFIGS = ("config/tiny.yaml", "config/weps.yaml")
CATALOGUE = "results/catalogue.sqlite"
# tile_rows 4 (tiny.yaml): the 4 rows of the weps plane are one tile
ATTRACTORS = ("results/weps/attractors/0.parquet",)
TARGETS = ("results/wb/cells.parquet", "results/weps/cells.parquet",
           "results/sweeps/standard.parquet")


def tiny_study(base: Path) -> Path:
    """The working directory of the study under ``base`` (run on first use)."""
    wd = base / "tiny_study"
    if all((wd / t).is_file() for t in (*TARGETS, CATALOGUE)):
        return wd
    make_workdir(wd)
    (wd / "config" / "weps.yaml").write_text(STUDY)
    smk(wd, *TARGETS, *ATTRACTORS, "--cores", "2", "--configfile", *CONFIGS)
    # the catalogue of these tables, built by the pipeline's own command
    assert main(["catalogue", "build", "--cells", str(wd / TARGETS[0]), str(wd / TARGETS[1]),
                 "--sweeps", str(wd / TARGETS[2]), "--attractors",
                 *(str(wd / a) for a in ATTRACTORS), "--out", str(wd / CATALOGUE)]) == 0
    return wd
