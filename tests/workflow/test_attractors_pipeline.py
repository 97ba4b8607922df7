"""Multistability in the pipeline: attractor tiles -> catalogue `attractors` and n_attractors.

Runs the workflow on config/tiny.yaml with `multistability` on for plane wb only (8 x 8 cells,
6 starts each), then answers the questions of docs/multistability.md with SQL.
"""

import pandas as pd
import pytest
from workflow_helpers import make_workdir, smk

from gearsim.results.catalogue import open_catalogue


@pytest.fixture(scope="module")
def ms_run(tmp_path_factory):
    wd = make_workdir(tmp_path_factory.mktemp("ms"))
    # wb: every cell; wxi keeps the default configuration's every 3rd cell per axis
    (wd / "config/ms.yaml").write_text(
        "planes:\n  wb:\n    multistability: {starts: 6, seed: 3, every: 1}\n"
    )
    cfg = ("--configfile", "config/tiny.yaml", "config/ms.yaml")
    smk(wd, "results/catalogue.d/build.sqlite", "results/figures/planes/wb-coexistence.png",
        "--cores", "2", *cfg)
    return wd, cfg

def test_attractor_tiles_and_catalogue(ms_run):
    wd, _ = ms_run
    tiles = sorted((wd / "results/wb/attractors").glob("*.parquet"))
    assert len(tiles) == 2 and len(list((wd / "results/wxi/attractors").glob("*"))) == 2
    df = pd.concat([pd.read_parquet(f) for f in tiles])
    assert df.groupby(["i", "j"]).ngroups == 64
    # basin fractions of a cell add up to the share of starts that did not diverge
    per_cell = df.groupby(["i", "j"]).agg(s=("basin_fraction", "sum"),
                                          d=("diverged_fraction", "first"))
    assert ((per_cell.s + per_cell.d - 1.0).abs() < 1e-12).all()
    # the forward-continuation state found an attractor in every non-diverged cell
    assert (df.groupby(["i", "j"])["found_by"].apply(lambda s: s.str.contains("forward").any())
            | (per_cell.d == 1.0)).all()
    con = open_catalogue(wd / "results/catalogue.sqlite")
    n_att = con.execute(
        "SELECT COUNT(*) FROM attractors a JOIN plane_cells c ON c.id = a.cell_id "
        "WHERE c.plane = 'wb'"
    ).fetchone()[0]
    assert n_att == int((df.attractor >= 0).sum())
    rows = con.execute(
        "SELECT p.name, COUNT(c.n_attractors) FROM cells c JOIN planes p ON p.id = c.plane_id "
        "GROUP BY p.name ORDER BY p.name"
    ).fetchall()
    assert rows == [("wb", 64), ("wxi", 9)]  # wxi: i, j in (0, 3, 6); NULL elsewhere
    # n_attractors counts the real attractors (an 'unsettled' bucket is not one)
    bad = con.execute(
        "SELECT COUNT(*) FROM cells c WHERE c.n_attractors IS NOT NULL AND c.n_attractors != "
        "(SELECT COUNT(*) FROM attractors a WHERE a.cell_id = c.id AND a.motion != 'unsettled')"
    ).fetchone()[0]
    assert bad == 0
    # the SQL of docs/multistability.md runs
    con.execute(
        "SELECT c.x, c.y FROM plane_cells c WHERE c.plane = 'wb' AND EXISTS (SELECT 1 FROM "
        "attractors a WHERE a.cell_id = c.id AND a.label = '1/1T') AND EXISTS (SELECT 1 FROM "
        "attractors a WHERE a.cell_id = c.id AND a.label = '2/1T')"
    ).fetchall()
    assert con.execute("PRAGMA foreign_key_check").fetchall() == []
    doc = con.execute(
        "SELECT COUNT(*) FROM column_dictionary WHERE table_name = 'attractors'"
    ).fetchone()[0]
    assert doc == 21  # with status, mu_max, critical
    con.close()

def test_rerun_is_incremental(ms_run):
    wd, cfg = ms_run
    r = smk(wd, "results/catalogue.d/build.sqlite", "--cores", "2", "-n", *cfg)
    assert "attractor_tile" not in r.stdout

def test_bad_multistability_rejected(tmp_path):
    wd = make_workdir(tmp_path)
    (wd / "config/bad.yaml").write_text("planes:\n  wb:\n    multistability: {starts: 0}\n")
    r = smk(wd, "-n", "--configfile", "config/tiny.yaml", "config/bad.yaml", check=False)
    assert r.returncode != 0
    assert "multistability" in (r.stdout + r.stderr)


def test_maps_written(ms_run):
    wd, _ = ms_run
    for kind in ("coexistence", "forward-basin"):
        assert (wd / f"results/figures/planes/wb-{kind}.png").stat().st_size > 10_000


def test_every_thins_the_attractor_grid():
    from gearsim.study.attractor_tiles import task_specs
    from gearsim.study.config import Study, load_config

    cfg = load_config(["config/config.yaml", "config/tiny.yaml"],
                      {"planes": {"wb": {"multistability": {"starts": 4, "every": 2}}}})
    cells = [c for s in task_specs(Study.of(cfg), "wb", 0, None) for c in s.cells]
    # tile 0 = rows j 0..3 of the 8 x 8 plane: rows 0 and 2, columns 0, 2, 4, 6
    assert sorted((c[0], c[1]) for c in cells) == [(i, j) for i in (0, 2, 4, 6) for j in (0, 2)]
    assert all(c[4] is None for c in cells)  # no tile file: no forward states
