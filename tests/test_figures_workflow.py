"""figures.smk: the figure rules plan one job per figure (9-11 together) plus the index with the
right CLI arguments, and a config without a plane leaves that plane's figures out (dry run only,
seconds)."""

from __future__ import annotations

import re

from workflow_helpers import make_workdir, smk

from gearsim.figures import rules as gfr


def _jobs(stdout: str) -> dict[str, int]:
    table = stdout[stdout.index("Job stats:"):]
    return {m.group(1): int(m.group(2)) for m in re.finditer(r"^(\w+)\s+(\d+)$", table, re.M)}


def test_dry_run_plans_every_figure(tmp_path):
    wd = make_workdir(tmp_path)
    r = smk(wd, "-n", "-p", "results/figures/README.md", "--configfile", "config/tiny.yaml")
    jobs = _jobs(r.stdout)
    assert jobs["figure"] == len(gfr.FIGURE_INPUTS) == 14
    assert jobs["figures_double_sided"] == 1 and jobs["figures_index"] == 1
    assert "gearsim figures --fig 04 --sweep standard=results/sweeps/standard.parquet" in r.stdout
    assert "--plane wb=results/wb/cells.parquet" in r.stdout


def test_unconfigured_plane_drops_its_figures():
    sweeps = ["standard", "b015", "b025", "b035", "xi005", "xi009", "xi015"]
    built = gfr.built_figures(sweeps, ["wb"], ["fig5", "fig6", "fig9_11"])
    assert 14 not in built and 16 not in built and 17 not in built
    assert {1, 2, 3, 4, 7, 9, 10, 11, 12, 13, 15} <= set(built)
    assert gfr.built_figures([], [], []) == [1]
