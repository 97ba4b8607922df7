"""The Snakemake workflow: job planning, lint, config errors, an end-to-end run on config/tiny.yaml,
re-runs after an edit, and nothing to do on a repeated run."""

from __future__ import annotations

import re
import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from workflow_helpers import (
    ROOT,
    SNAKEMAKE,
    _env,
    job_counts,
    make_workdir,
    smk,
    smk_in,
    targets,
)

from gearsim.cell.simulate import simulate_cell
from gearsim.study import config as gcfg

PIPELINE_RULES = {"compile", "simulate_tile", "plane_cells", "audit", "sweep", "points",
                  "catalogue"}
PIPELINE_FILES = ("Snakefile", "common.smk", "planes.smk", "sweeps.smk", "points.smk")


def planned_outputs(output: str) -> set[str]:
    """Output files of the jobs a (non-quiet) dry run lists."""
    found = set()
    for m in re.finditer(r"^\s*output: (.+)$", output, flags=re.M):
        found.update(s.strip() for s in m.group(1).split(","))
    return found


def dry(workdir: Path, *configs: str, extra: tuple[str, ...] = ()):
    args = [*targets(workdir, *configs), "-n", *extra]  # targets first: options take lists
    if configs:
        args += ["--configfile", *configs]
    r = smk(workdir, *args)
    return r.stdout + r.stderr


@pytest.fixture(scope="module")
def fresh(tmp_path_factory):
    return make_workdir(tmp_path_factory.mktemp("plan"))


@pytest.mark.parametrize(
    ("configs", "tiles", "sweeps", "points"),
    [
        ((), 2 * 5, 8, 3),  # 400 rows / tile_rows 80
        (("config/quick.yaml",), 2 * 2, 8, 3),
        (("config/tiny.yaml",), 2 * 2, 8, 3),
    ],
)
def test_dry_run_plans_the_expected_jobs(fresh, configs, tiles, sweeps, points):
    if configs == ("config/quick.yaml",):
        # the fast look runs in studies/quick/ (its `folder`): from the project directory, as
        # a user runs it (--directory would override that folder and is refused)
        r = smk_in(fresh, *targets(fresh, *configs), "-n", "--quiet", "rules", "--configfile",
                   *configs)
        out = r.stdout + r.stderr
    else:
        out = dry(fresh, *configs, extra=("--quiet", "rules"))
    counts = job_counts(out)
    # attractor_tile: the default planes set `multistability` (docs/multistability.md)
    # the catalogue loads the bifurcation curves of every plane in the default config (seeded
    # from the plane's own map, not from the standard continuation); quick and tiny set
    # orbits.curves off
    orbit = {} if configs else {"bifurcation_curves": 2}
    assert counts == {"compile": 1, "simulate_tile": tiles, "plane_cells": 2, "audit": 2,
                      "sweep": sweeps, "points": points, "catalogue": 1,
                      "attractor_tile": tiles, **orbit,
                      "total": 1 + tiles + 2 + 2 + sweeps + points + 1 + tiles
                      + sum(orbit.values())}, out


def test_all_target_includes_pipeline_outputs(fresh):
    r = smk(fresh, "-n", "--quiet", "rules", "--configfile", "config/tiny.yaml", check=False)
    out = r.stdout + r.stderr
    if r.returncode != 0:  # another stage's inputs may be missing in a bare checkout
        pytest.skip(f"`all` cannot be planned here: {out.strip().splitlines()[-1]}")
    counts = job_counts(out)
    assert counts["all"] == 1 and counts["simulate_tile"] == 4 and counts["catalogue"] == 1


def test_lint_clean_for_pipeline_rules():
    r = subprocess.run([str(SNAKEMAKE), "--lint", "-s", str(ROOT / "Snakefile")], cwd=ROOT,
                       env=_env(), capture_output=True, text=True, timeout=300)
    out = r.stdout + r.stderr
    assert r.returncode == 0 and "Lints for" not in out, out  # every rule, not only ours
    for m in re.finditer(r"Lints for (rule (\w+)|snakefile (\S+)):", out):
        rule, snakefile = m.group(2), m.group(3)
        assert rule not in PIPELINE_RULES, out
        assert snakefile is None or not snakefile.endswith(PIPELINE_FILES), out


def test_slurm_profile_parses(fresh):
    r = smk(fresh, *targets(fresh, "config/tiny.yaml"), "-n", "--profile",
            str(ROOT / "profiles/slurm"), "--executor", "dryrun", "--configfile",
            "config/tiny.yaml", "--quiet", "rules")
    assert job_counts(r.stdout + r.stderr)["simulate_tile"] == 4


@pytest.mark.parametrize(
    ("edit", "needle"),
    [
        ({"planes": {"wb": {"x": {"min": 2.5, "max": 0.1}}}},
         "config key 'planes.wb.x': empty or reversed"),
        ({"planes": {"wb": {"y": {"name": "gap"}}}},
         "config key 'planes.wb.y.name': unknown parameter"),
        ({"tile_rows": 9}, "config key 'tile_rows': 9 is larger than the grid"),
        ({"tile_rowz": 2}, "config key 'tile_rowz': unknown key"),
        ({"planes": {"wb": {"x": {"n": "many"}}}},
         "config key 'planes.wb.x.n': 'many' is not of type"),
        ({"planes": {"wxi": {"y": {"n": 0}}}}, "config key 'planes.wxi.y.n'"),
    ],
)
def test_bad_config_stops_before_any_job(tmp_path, edit, needle):
    wd = make_workdir(tmp_path)
    (wd / "config/bad.yaml").write_text(yaml.safe_dump(edit))
    r = smk(wd, "-n", "--configfile", "config/tiny.yaml", "config/bad.yaml", check=False)
    assert r.returncode != 0
    out = r.stdout + r.stderr
    assert needle in out, out[-2000:]
    assert not (wd / "results").exists()


def test_cli_rejects_bad_config_in_one_line(tmp_path):
    wd = make_workdir(tmp_path)
    (wd / "config/bad.yaml").write_text(yaml.safe_dump({"planes": {"wb": {"y": {"min": 2}}}}))
    r = subprocess.run(
        [str(Path(sys.executable).parent / "gearsim"), "simulate-tile", "--plane", "wb", "--tile",
         "0", "--configfile", "config/config.yaml", "config/tiny.yaml", "config/bad.yaml"],
        cwd=wd, env=_env(), capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    assert r.stderr.startswith("gearsim simulate-tile: error: config key 'planes.wb.y'")
    assert r.stderr.count("\n") == 1


# ------------------------------------------------------------------------------ end to end
# tiny_run (a session fixture in conftest.py) is the end-to-end run on config/tiny.yaml,
# shared with tests/workflow/test_trust_runs.py.


@pytest.mark.slow
def test_end_to_end_tiny(tiny_run):
    wd, _, _ = tiny_run
    cfg = gcfg.load_config([wd / "config/config.yaml", wd / "config/tiny.yaml"], root=wd)
    con = sqlite3.connect(wd / "results/catalogue.sqlite")
    n_cells = con.execute("SELECT COUNT(*) FROM cells").fetchone()[0]
    grid = sum(p["x"]["n"] * p["y"]["n"] for p in cfg["planes"].values())
    assert n_cells == grid == 128
    per_plane = dict(con.execute(
        "SELECT p.name, COUNT(*) FROM cells c JOIN planes p ON p.id = c.plane_id GROUP BY p.name"))
    assert per_plane == {"wb": 64, "wxi": 64}
    # 7 one-way sweeps of 6 values and the hysteresis sweep both ways
    assert con.execute("SELECT COUNT(*) FROM sweep_points").fetchone()[0] == 7 * 6 + 2 * 6
    assert con.execute("SELECT COUNT(*) FROM runs WHERE kind='tile'").fetchone()[0] == 4
    assert con.execute("SELECT COUNT(*) FROM audits").fetchone()[0] >= 2
    src = {r[0] for r in con.execute("SELECT DISTINCT parameters_source FROM runs")}
    sp = wd / "config/standard_parameters.yaml"
    assert src == {"config/standard_parameters.yaml" if sp.exists() else "builtin-defaults"}
    con.close()
    # labels equal simulate_cell at sampled cells, started as the pipeline started them
    settings = gcfg.integration_settings(cfg)
    rng = np.random.default_rng(0)
    for plane in ("wb", "wxi"):
        df = pd.read_parquet(wd / f"results/{plane}/cells.parquet")
        assert len(df) == 64 and {"poincare_x", "poincare_v"} <= set(df.columns)
        base = gcfg.Study.of(cfg, wd).parameters(plane=plane).model
        pl = cfg["planes"][plane]
        for k in rng.choice(len(df), size=3, replace=False):
            c = df.iloc[k]
            u0, start = None, 0
            left = df[(df.j == c.j) & (df.i == c.i - 1)]
            if c.i > 0 and left.iloc[0].status != "diverged":
                left = left.iloc[0]
                u0, start = np.asarray(left.final_state), int(left.final_period)
            p = base.with_(**{pl["x"]["name"]: c.x, pl["y"]["name"]: c.y})
            r = simulate_cell(p, u0, settings=settings, start_period=start).row()
            assert (r["label"], r["label_npq"]) == (c.label, c.label_npq), (plane, c.i, c.j)
    # logs and benchmarks exist for every simulation job
    assert (wd / "logs/wb/tile_0.log").read_text().count("cells/s") >= 2
    assert (wd / "logs/benchmarks/wb/tile_1.tsv").exists()
    assert (wd / "logs/benchmarks/sweeps/standard.tsv").exists()
    pts = pd.read_parquet(wd / "results/points/fig9_11.parquet")
    assert set(pts["start"]) == {"continuation", "rest"} and len(pts["x"].iloc[0]) > 100


@pytest.mark.slow
def test_repeated_run_plans_nothing(tiny_run):
    wd, tg, _ = tiny_run
    r = smk(wd, *tg, "-n", "--configfile", "config/tiny.yaml")
    assert "Nothing to be done" in r.stdout + r.stderr, r.stdout


@pytest.mark.slow
def test_editing_one_plane_reruns_only_its_tiles(tiny_run):
    wd, tg, _ = tiny_run
    cfg_file = wd / "config/tiny.yaml"
    original = cfg_file.read_text()
    try:
        cfg = yaml.safe_load(original)
        cfg["planes"]["wxi"]["fixed"] = {"b": 0.5}
        cfg_file.write_text(yaml.safe_dump(cfg))
        out = dry(wd, "config/tiny.yaml")
        planned = planned_outputs(out)
        assert planned == {
            "results/wxi/tiles/0.parquet", "results/wxi/tiles/1.parquet",
            "results/wxi/cells.parquet", "results/wxi/audit.parquet",
            # the plane's coexisting-attractor tiles (multistability) depend on it too
            "results/wxi/attractors/0.parquet", "results/wxi/attractors/1.parquet",
            "results/catalogue.d/build.sqlite",
        }, out
        # editing one sweep re-runs that sweep (and the catalogue) only
        cfg = yaml.safe_load(original)
        cfg["sweeps"]["b025"]["fixed"] = {"b": 0.26}
        cfg_file.write_text(yaml.safe_dump(cfg))
        planned = planned_outputs(dry(wd, "config/tiny.yaml"))
        assert planned == {"results/sweeps/b025.parquet", "results/catalogue.d/build.sqlite"}
    finally:
        cfg_file.write_text(original)
    assert "Nothing to be done" in dry(wd, "config/tiny.yaml")


def _dry_with_package(wd: Path, src: Path) -> str:
    """A dry run whose Snakemake process imports gearsim from ``src`` (a copy of src/)."""
    env = {**_env(), "PYTHONPATH": str(src)}
    cmd = [str(SNAKEMAKE), "-s", str(ROOT / "Snakefile"), "-d", str(wd),
           *targets(wd, "config/tiny.yaml"), "-n", "--configfile", "config/tiny.yaml"]
    r = subprocess.run(cmd, cwd=wd, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    return r.stdout + r.stderr


@pytest.mark.slow
def test_editing_a_layer_reruns_only_the_jobs_that_depend_on_it(tiny_run, tmp_path):
    """A presentation edit re-runs no simulation (of this stage's targets); an edit of the model
    is seen by the same dry run (the code versions of gearsim.study.provenance.CODE_SCOPES;
    which scopes an edit changes: tests/unit/test_provenance.py)."""
    import shutil

    wd, _, _ = tiny_run
    # a project whose src/ is a copy (the schema and config files are the checkout's)
    src = tmp_path / "src"
    shutil.copytree(ROOT / "src", src, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    for name in ("workflow", "config", "pyproject.toml"):
        (tmp_path / name).symlink_to(ROOT / name)
    assert "Nothing to be done" in _dry_with_package(wd, src)  # the copy is the same code
    style = src / "gearsim/presentation/figures/style.py"
    style.write_text(style.read_text() + "\n# an edit of presentation only\n")
    planned = planned_outputs(_dry_with_package(wd, src))
    simulated = ("/tiles/", "/attractors/", "results/sweeps/", "results/points/", "results/orbits/",
                 "cells.parquet", "audit.parquet", "catalogue")
    assert not [p for p in planned if any(s in p for s in simulated)], planned
    # the control: the same dry run sees an edit of the equations' module (every tile, sweep
    # and point, and the kernels' compile job before them, is planned again)
    model = src / "gearsim/dynamics/model.py"
    model.write_text(model.read_text() + "\n# an edit of the equations' module\n")
    planned = planned_outputs(_dry_with_package(wd, src))
    tiles = {p for p in planned if "/tiles/" in p}
    assert tiles and all(any(f"results/{pl}/tiles/" in p for p in tiles) for pl in ("wb", "wxi"))
    assert any(p.startswith("results/sweeps/") for p in planned), planned
    assert any(p.startswith("results/.kernels/") for p in planned), planned
