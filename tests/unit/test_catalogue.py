"""Parquet provenance, combining tiles and the SQLite catalogue (gearsim.results.catalogue)."""

from __future__ import annotations

import copy
import json
import shutil
import sqlite3
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from gearsim.cell.simulate import CellResult
from gearsim.results import catalogue as gc
from gearsim.results import schema as gsch
from gearsim.study import config as gcfg
from gearsim.study import grid as ggrid
from gearsim.study import provenance as gprov
from gearsim.study import tiles as gt
from gearsim.study.audit import audit_frame
from gearsim.study.config import Study
from gearsim.study.provenance import plane_record

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """A 3 x 4 wb plane (2 tiles) simulated in-process with tiny budgets, plus one sweep."""
    d = tmp_path_factory.mktemp("cat")
    cfg = gcfg.load_config([ROOT / "config/config.yaml", ROOT / "config/tiny.yaml"])
    cfg = copy.deepcopy(cfg)
    cfg["planes"]["wb"]["x"]["n"] = 3
    cfg["planes"]["wb"]["y"]["n"] = 4
    cfg["tile_rows"] = 2
    files = []
    for t in ggrid.tile_ids(cfg, "wb"):
        df = gt.run_tile(Study.of(cfg), "wb", t)
        study = Study.of(cfg)
        prov = gprov.provenance(gprov.plane_subtree(study, "wb"), kind="tile", name="wb",
                                study=study, tile=t, started=gc.now_iso(),
                                finished=gc.now_iso(), wall_s=1.0, cells=len(df),
                                workers="in-process")
        files.append(gc.write_parquet(df, d / f"tiles/{t}.parquet", {gc.PROVENANCE_KEY: prov}))
    cells = gc.combine_tiles(files, d / "cells.parquet", plane_record(Study.of(cfg), "wb"))
    from gearsim.dynamics.parameters import ModelParameters
    from gearsim.study.sweeps import sweep_frame

    sw = sweep_frame(ModelParameters(b=0.15), "w", np.array([0.5, 1.0, 1.5]), "forward",
                     gcfg.integration_settings(cfg))
    sprov = gprov.provenance(gprov.sweep_subtree(Study.of(cfg), "b015"), kind="sweep", name="b015",
                             study=Study.of(cfg))
    sweep = gc.write_parquet(sw, d / "sweeps/b015.parquet", {gc.PROVENANCE_KEY: sprov})
    cfg["audit"]["fraction"] = 0.25
    aud = audit_frame(Study.of(cfg), "wb", pd.read_parquet(cells))
    aprov = gprov.provenance(gprov.plane_subtree(Study.of(cfg), "wb"), kind="audit", name="wb",
                             study=Study.of(cfg), audit_seed=1)
    audit = gc.write_parquet(aud, d / "audit.parquet", {gc.PROVENANCE_KEY: aprov})
    db = d / "catalogue.sqlite"
    counts = gc.build_catalogue(db, [cells], [sweep], [audit])
    return {"dir": d, "cfg": cfg, "tiles": files, "cells": cells, "sweep": sweep, "db": db,
            "counts": counts, "audit": aud}


def test_tile_provenance(small):
    prov = gc.read_metadata(small["tiles"][1])
    for key in ("config_hash", "code_version", "package_versions", "tangent_seed",
                "parameters_source", "started", "finished"):
        assert key in prov, key
    subtree = gprov.plane_subtree(Study.of(small["cfg"]), "wb")
    assert prov["config_hash"] == gprov.config_hash(subtree)
    assert prov["code_version"] == gprov.code_version()
    assert {"numpy", "numba", "dask", "pyarrow"} <= set(prov["package_versions"])
    assert prov["tile"] == 1
    # no temporary files left behind by the atomic writes
    assert not [p for p in small["dir"].rglob(".*tmp*")]


def test_cells_parquet(small):
    df = pd.read_parquet(small["cells"])
    assert len(df) == 12 and df[["j", "i"]].drop_duplicates().shape[0] == 12
    assert list(df["j"]) == sorted(df["j"])
    row_cols = set(CellResult.__dataclass_fields__) - {"params"}
    assert {"poincare_x", "poincare_v", "final_state"} <= set(df.columns)
    assert "kmax_peak_static" in df and "kmax_section_mean" in df and row_cols
    assert isinstance(df["poincare_x"].iloc[0], (list, np.ndarray))
    schema = pq.read_schema(small["cells"])
    assert str(schema.field("poincare_x").type).startswith("list")
    rec = gc.read_metadata(small["cells"], gc.PLANE_KEY)
    assert rec["x"]["name"] == "w" and rec["y"]["name"] == "b"
    assert len(gc.read_metadata(small["cells"], gc.TILES_KEY)) == 2


def test_catalogue_tables(small):
    c = small["counts"]
    assert c["cells"] == 12 and c["planes"] == 1 and c["sweeps"] == 1 and c["sweep_points"] == 3
    assert c["runs"] == 2 + 1 + 1 and c["audits"] == len(small["audit"]) == 3
    con = sqlite3.connect(small["db"])
    tables = {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")}
    assert {"runs", "planes", "cells", "sweeps", "sweep_points", "audits"} <= tables
    idx = {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='index'")}
    assert "ix_cells_plane_id_label" in idx and "ix_cells_plane_id_x_y" in idx
    ddl = con.execute("SELECT sql FROM sqlite_master WHERE name='cells'").fetchone()[0]
    assert "CONSTRAINT uq_cells_plane_id_i_j UNIQUE" in ddl
    assert "CONSTRAINT fk_cells_plane_id_planes FOREIGN KEY" in ddl
    fks = con.execute("PRAGMA foreign_key_list(cells)").fetchall()
    assert {r[2] for r in fks} == {"planes", "runs"}
    assert con.execute("PRAGMA foreign_key_check").fetchall() == []
    # cell values equal the Parquet values, every CellResult.row() column present
    df = pd.read_parquet(small["cells"]).sort_values(["j", "i"])
    sql = pd.read_sql("SELECT * FROM cells ORDER BY j, i", con)
    assert list(sql["label"]) == list(df["label"])
    assert list(sql["impact"]) == list(df["I"])
    np.testing.assert_allclose(sql["kmax_section_static"], df["kmax_section_static"])
    for col in gc.ROW_COLUMNS:
        assert ("impact" if col == "I" else col) in sql.columns
    run = con.execute("SELECT code_version, tangent_seed, started FROM runs WHERE kind='tile'")
    assert all(r[0] == gprov.code_version() and r[1] and r[2] for r in run)
    plane = con.execute("SELECT name, x_name, y_name, x_n, y_n, fixed FROM planes").fetchone()
    assert plane[:5] == ("wb", "w", "b", 3, 4)
    view = con.execute("SELECT COUNT(*) FROM plane_cells WHERE plane='wb'").fetchone()[0]
    assert view == 12
    con.close()


def test_foreign_keys_enforced(tmp_path):
    from sqlalchemy import text

    eng = gc.make_engine(f"sqlite:///{tmp_path / 'x.sqlite'}")
    gc.Base.metadata.create_all(eng)
    with eng.connect() as con:
        assert con.execute(text("PRAGMA foreign_keys")).scalar() == 1
    eng.dispose()


def test_catalogue_replaced_atomically(small, tmp_path):
    out = tmp_path / "c.sqlite"
    out.write_text("old")
    with pytest.raises(gc.CatalogueError, match="missing.parquet: not found"):
        gc.build_catalogue(out, [tmp_path / "missing.parquet"])
    assert out.read_text() == "old"
    assert not list(tmp_path.glob(".c.sqlite.tmp*"))


# ------------------------------------------------------------------------- metadata (13.4)
def test_schema_version_and_application_id(small):
    con = sqlite3.connect(small["db"])
    assert con.execute("PRAGMA user_version").fetchone()[0] == gc.SCHEMA_VERSION == 4
    assert con.execute("PRAGMA application_id").fetchone()[0] == 0x47454152
    con.close()
    gc.open_catalogue(small["db"]).close()


def test_column_dictionary_covers_every_column(small):
    con = sqlite3.connect(small["db"])
    docs = {(t, c): (u, m) for t, c, u, m in con.execute(
        "SELECT table_name, column_name, unit, meaning FROM column_dictionary")}
    tables = [r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")]
    # 8 + bifurcation_points, bifurcation_curves, codim2_points, cell_orbits, attractors
    assert len(tables) == 13
    for t in tables:
        for col in con.execute(f'PRAGMA table_info("{t}")'):
            assert (t, col[1]) in docs, (t, col[1])
            assert docs[(t, col[1])][1], (t, col[1])
    assert docs[("cells", "lyapunov")][0] == "1/tau"
    assert docs[("cells", "x_max")][0].startswith("1 (X_n / b_c)")
    assert ("plane_cells", "*") in docs
    con.close()


def test_catalogue_info_and_integration(small):
    import json
    import subprocess

    con = sqlite3.connect(small["db"])
    info = {k: json.loads(v) for k, v in con.execute("SELECT key, value FROM catalogue_info")}
    assert info["schema_version"] == gc.SCHEMA_VERSION == 4
    assert info["code_versions"] == [gprov.code_version()]
    want = gcfg.integration_settings(small["cfg"]).to_dict()
    assert info["integration"] == json.loads(json.dumps(want))
    (plane_int,) = con.execute("SELECT integration FROM planes").fetchone()
    assert json.loads(plane_int) == info["integration"]
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True,
                          text=True)
    if head.returncode == 0:
        assert info["git_commit"] == head.stdout.strip()
    assert info["counts"]["cells"] == 12
    con.close()


def test_sweep_parameters_are_the_values_used(small):
    """b015 runs at b = 0.15 (its `fixed`), not the standard b: the recorded set says so."""
    import json

    con = sqlite3.connect(small["db"])
    name, params, fixed = con.execute("SELECT name, parameters, fixed FROM sweeps").fetchone()
    params, fixed = json.loads(params), json.loads(fixed)
    assert name == "b015" and fixed == {"b": 0.15}
    assert params["b"] == 0.15
    assert "w" not in params  # the swept parameter is in sweep_points.value
    base = Study.of(small["cfg"]).parameters().model.to_dict()
    assert base["b"] != 0.15
    assert {k: v for k, v in params.items() if k != "b"} == {
        k: v for k, v in base.items() if k not in ("b", "w")}
    # plane parameters leave out the two axes
    pparams = json.loads(con.execute("SELECT parameters FROM planes").fetchone()[0])
    assert "w" not in pparams and "b" not in pparams and pparams["xi"] == base["xi"]
    con.close()


# ----------------------------------------------------------------- the plane atlas's tables
def _atlas_files(d):
    """A seed table, a curve and a codimension-2 point in the plane atlas's columns."""
    mu = {"mu_re": [[-1.0, 0.5]], "mu_im": [[0.0, 0.1]], "stable": [False]}
    seed = dict(point=[0], kind=["period_doubling"], period=[1], boundary=[""], name=["w"],
                value=[1.0055], x=[0.3], v=[0.1], mu_max=[1.0], branch=[0], plane=["wb"],
                name2=["b"], value2=[0.5], curve=[0], source=["map"], seed_i=[3], seed_j=[2],
                seed_i2=[4], seed_j2=[2], label_a=["1/1T"], label_b=["1/2T"], **mu)
    curve = {k: v * 2 for k, v in seed.items() if k not in ("point", "branch")}
    curve.update(value2=[0.5, 0.6], seq=[0, 1], flank=["", ""], end_first=["edge", "codim2"],
                 end_last=["codim2", "codim2"], end_first_detail=["b = 0", "b = 0"],
                 end_last_detail=["at point 0", "at point 0"], codim2_first=[-1, -1],
                 codim2_last=[0, 0], curve=[0, 0])
    c2 = dict(point=[0], plane=["wb"], kind=["pd_grazing"],
              conditions=["period_doubling; grazing x=-b"], period=[1], boundary=["x=-b"],
              name=["w"], value=[1.01], name2=["b"], value2=[0.3], curves=[[0, 1]],
              curve_kinds=[["period_doubling", "grazing"]], residual_1=[1e-10],
              residual_2=[2e-10], residual=[2e-10], step=[1e-8], iterations=[4],
              converged=[True], gap_cells=[0.2], x=[0.3], v=[0.1], mu_max=[1.0], **{
                  k: v for k, v in mu.items() if k != "stable"})
    prov = {gc.PROVENANCE_KEY: {"kind": "curves", "name": "wb"}}
    return [gc.write_parquet(pd.DataFrame(t), d / f"wb_{n}.parquet", prov)
            for n, t in (("curves_points", seed), ("curves", curve), ("codim2", c2))]


def test_the_plane_atlas_tables_are_loaded_with_their_columns(small, tmp_path):
    files = _atlas_files(tmp_path)
    db = tmp_path / "c.sqlite"
    counts = gc.build_catalogue(db, [small["cells"]], orbit_files=files)
    assert (counts["bifurcation_points"], counts["bifurcation_curves"],
            counts["codim2_points"]) == (1, 2, 1)
    con = gc.open_catalogue(db)
    try:
        assert con.execute("SELECT curve, source, seed_i, label_b FROM bifurcation_points"
                           ).fetchall() == [(0, "map", 3, "1/2T")]
        assert con.execute("SELECT seq, end_first, codim2_last FROM bifurcation_curves "
                           "ORDER BY seq").fetchall() == [(0, "edge", 0), (1, "codim2", 0)]
        kind, curves, conv, res = con.execute(
            "SELECT kind, curves, converged, residual FROM codim2_points").fetchone()
        assert (kind, json.loads(curves), conv, res) == ("pd_grazing", [0, 1], 1, 2e-10)
    finally:
        con.close()


def test_a_version_3_catalogue_gains_the_atlas_tables(small, tmp_path):
    db = tmp_path / "c.sqlite"
    shutil.copyfile(small["db"], db)
    con = sqlite3.connect(db)
    con.execute("DROP TABLE codim2_points")
    for t, cols in gsch._ATLAS_COLUMNS.items():
        for c in cols:
            con.execute(f"ALTER TABLE {t} DROP COLUMN {c}")
    con.execute("PRAGMA user_version = 3")
    con.commit()
    con.close()
    assert gc.migrate_catalogue(db) == (3, 4)
    con = gc.open_catalogue(db)
    try:
        have = {r[1] for r in con.execute("PRAGMA table_info(bifurcation_curves)")}
        assert set(gsch._ATLAS_COLUMNS["bifurcation_curves"]) <= have
        assert con.execute("SELECT COUNT(*) FROM codim2_points").fetchone()[0] == 0
    finally:
        con.close()
