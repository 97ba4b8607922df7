"""figures.smk: the figure rules plan one job per figure (9-11 together) plus the index with the
right CLI arguments, and a config without a plane leaves that plane's figures out (dry run only,
seconds)."""

from __future__ import annotations

import re

import pytest
from workflow_helpers import make_workdir, smk

from gearsim.presentation.figures import registry
from gearsim.presentation.figures import rules as gfr


def _jobs(stdout: str) -> dict[str, int]:
    table = stdout[stdout.index("Job stats:"):]
    return {m.group(1): int(m.group(2)) for m in re.finditer(r"^(\w+)\s+(\d+)$", table, re.M)}


def test_dry_run_plans_every_figure(tmp_path):
    wd = make_workdir(tmp_path)
    r = smk(wd, "-n", "-p", "results/figures/README.md", "--configfile", "config/tiny.yaml")
    jobs = _jobs(r.stdout)
    singles = [f"figure_{n:02d}" for n in (1, 2, 3, 4, 5, 6, 7, 8, 12, 13, 14, 15, 16, 17)]
    assert all(jobs[name] == 1 for name in singles), jobs
    assert jobs["figure_09_10_11"] == 1 and jobs["figures_index"] == 1
    assert jobs["plane_maps"] == 2  # wb and wxi
    assert "gearsim figures --fig 4 --sweep standard=results/sweeps/standard.parquet" in r.stdout
    # what a figure draws that is simulated is a figure-data job's table; the figure reads it
    assert "--fig 9 10 11 --figure-data fig9_11=results/figure_data/fig9_11.parquet" in r.stdout
    assert "--fig 2 --figure-data fig2=results/figure_data/fig2.parquet" in r.stdout
    assert ("gearsim figure-data --name fig9_11 --sweep b015=results/sweeps/b015.parquet"
            in r.stdout)
    assert jobs["figure_data"] >= 2
    assert "--fig 5 --points fig5=results/points/fig5.parquet" in r.stdout
    assert "--fig 7 --plane wb=results/wb/cells.parquet" in r.stdout
    assert "gearsim figures --maps --plane wb=results/wb/cells.parquet" in r.stdout


def _files(sweeps=(), planes=(), points=(), orbits=(), figure_data=()):
    """Table name -> path, as figures.smk gives them (stand-in paths that name the table)."""
    return {"sweeps": {s: f"s/{s}.pq" for s in sweeps}, "planes": {p: f"p/{p}.pq" for p in planes},
            "points": {q: f"q/{q}.pq" for q in points}, "orbits": {o: f"o/{o}.pq" for o in orbits},
            "figure_data": {f: f"f/{f}.pq" for f in figure_data}}


def test_one_table_drives_rules_cli_and_index():
    """The rules' inputs and CLI arguments are those of the figure table, for every figure."""
    files = _files(["standard", "b015", "b025", "b035", "xi005", "xi009", "xi015"],
                   ["wb", "wxi"], ["fig5", "fig6", "fig9_11"], ["standard", "wb_curves"],
                   ["fig2", "fig9_11"])
    groups = gfr.groups(files)
    # a figure of simulated motions is drawn where its figure-data table is made
    assert {2, 9, 10, 11} <= set(gfr.built_figures(files))
    assert 19 not in gfr.built_figures(files) and 20 not in gfr.built_figures(files)
    assert 21 in gfr.built_figures(files) and 22 not in gfr.built_figures(files)  # wxi_curves
    for spec in groups:
        paths = gfr.input_paths(spec, files)
        args = gfr.cli_args(spec, files)
        for kind, option in gfr.KINDS.items():
            for path in paths[kind]:
                name = path.split("/")[1].removesuffix(".pq")
                assert files[kind][name] == path and f"--{option} {name}={path}" in args
        for name in spec.inputs.sweeps:
            assert files["sweeps"][name] in paths["sweeps"]
        assert gfr.outputs(spec)["png"] == [f"results/figures/fig{n:02d}.png"
                                            for n in spec.members]
    # Figs 5 and 6 read their recorded points; Fig 4 the continuation when it is made
    assert gfr.input_paths(registry.FIGURES[5], files)["points"] == ["q/fig5.pq"]
    assert gfr.input_paths(registry.FIGURES[9], files)["figure_data"] == ["f/fig9_11.pq"]
    assert gfr.input_paths(registry.FIGURES[9], files)["sweeps"] == []
    assert gfr.input_paths(registry.FIGURES[4], files)["orbits"] == ["o/standard.pq"]
    assert gfr.input_paths(registry.FIGURES[4], _files(["standard"]))["orbits"] == []


def test_a_new_figure_registers_in_one_place():
    def build_new(ctx):
        return []

    n = max(registry.figures()) + 1
    spec = registry.register(registry.FigureSpec(
        n, "Basins in the (w, b) plane.", registry.Inputs(planes=("wb",)), build_new,
        in_paper=False))
    try:
        assert n in gfr.built_figures(_files(planes=["wb"]))
        assert n not in gfr.built_figures(_files(planes=["wxi"]))
        assert gfr.cli_args(spec, _files(planes=["wb"])) == f"--fig {n} --plane wb=p/wb.pq"
        assert gfr.rule_name(spec) == f"figure_{n:02d}"
        assert gfr.caption_params(spec)["in_paper"] is False
        assert gfr.caption_params(registry.FIGURES[7])["in_paper"] is True
        with pytest.raises(ValueError, match="registered twice"):
            registry.register(registry.FigureSpec(n, "x", registry.Inputs(), lambda c: []))
    finally:
        registry.FIGURES.pop(n)
