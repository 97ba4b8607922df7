"""``gearsim export``: a catalogue plane as an xarray Dataset on its grid, with
units, long names and provenance; every format re-opened equals the catalogue's cells."""

from __future__ import annotations

import json
import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr
from synthetic_tiles import tile_frame, write_tile

from gearsim.cli.main import main
from gearsim.results import catalogue as gc
from gearsim.results.export import VARIABLES
from gearsim.study import config as gcfg
from gearsim.study import grid as ggrid
from gearsim.study import provenance as gprov
from gearsim.study import tiles as gt
from gearsim.study.config import Study
from gearsim.study.provenance import plane_record

ROOT = Path(__file__).resolve().parents[2]
NX, NY = 5, 4
CHAOS = {(1, 0), (4, 3)}  # cells without a period: p, q NULL, dc NULL


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    d = tmp_path_factory.mktemp("export")
    cfg = gcfg.load_config([ROOT / "config/config.yaml", ROOT / "config/tiny.yaml"], root=ROOT)
    cfg["tile_rows"] = 2
    cfg["planes"]["wb"]["x"]["n"], cfg["planes"]["wb"]["y"]["n"] = NX, NY
    tiles = []
    for t in ggrid.tile_ids(cfg, "wb"):
        df = tile_frame(cfg, "wb", t)
        for i, j in CHAOS:
            k = df.index[(df["i"] == i) & (df["j"] == j)]
            df.loc[k, ["p", "q"]] = pd.NA
            df.loc[k, ["label", "label_npq", "motion"]] = ["chaos", "", "chaos"]
            df.loc[k, "lyapunov"] = 0.05
            df.loc[k, "dc"] = np.nan
        tiles.append(write_tile(cfg, "wb", t, d / f"{t}.parquet", df=df))
    cells = gc.combine_tiles(tiles, d / "cells.parquet", plane_record(Study.of(cfg), "wb"))
    out = d / "catalogue.sqlite"
    gc.build_catalogue(out, [cells])
    return out


def _catalogue_cells(db: Path) -> pd.DataFrame:
    con = sqlite3.connect(db)
    df = pd.read_sql("SELECT * FROM cells ORDER BY j, i", con)
    con.close()
    return df


def _assert_equals_catalogue(ds: xr.Dataset, db: Path, nx=NX, ny=NY, chaos=True) -> None:
    cells = _catalogue_cells(db)
    assert len(cells) == nx * ny
    assert ds["label"].dims == ("b", "w") and ds.sizes == {"b": ny, "w": nx}
    np.testing.assert_array_equal(ds["w"].values, cells[cells.j == 0].sort_values("i")["x"])
    np.testing.assert_array_equal(ds["b"].values, cells[cells.i == 0].sort_values("j")["y"])
    i, j = cells["i"].to_numpy(), cells["j"].to_numpy()
    for c in VARIABLES:
        got = ds[c].values[j, i]
        want = cells[c].to_numpy()
        if c in ("motion", "status", "label", "label_npq", "critical"):
            assert [str(v) for v in got] == [str(v) for v in want], c
        else:
            np.testing.assert_array_equal(np.asarray(got, float), np.asarray(want, float), c)
    if chaos:
        assert np.isnan(ds["p"].values[0, 1]) and ds["label"].values[0, 1] == "chaos"


def test_dataset_attributes(db):
    from gearsim.results.export import plane_dataset

    ds = plane_dataset(db, "wb")
    for name, var in {**ds.coords, **ds.data_vars}.items():
        assert var.attrs["units"] and var.attrs["long_name"], name
    assert ds["lyapunov"].attrs["units"] == "1/tau"
    assert ds["w"].attrs["units"].startswith("1 (w_h / w_n)")
    con = sqlite3.connect(db)
    sql = "SELECT config_hash, code_version, integration FROM planes"
    h, code, integ = con.execute(sql).fetchone()
    con.close()
    assert ds.attrs["config_hash"] == h and ds.attrs["code_version"] == code == gprov.code_version()
    assert json.loads(ds.attrs["integration"]) == json.loads(integ)
    assert "b" not in json.loads(ds.attrs["parameters"])


@pytest.mark.parametrize("fmt", ["netcdf", "zarr", "csv", "parquet"])
def test_export_round_trip(db, tmp_path, capsys, fmt):
    out = tmp_path / {"netcdf": "wb.nc", "zarr": "wb.zarr", "csv": "wb.csv",
                      "parquet": "wb.parquet"}[fmt]
    assert main(["export", "--catalogue", str(db), "--plane", "wb", "--format", fmt,
                 "--out", str(out)]) == 0
    assert "export wb: b 4 x w 5 cells" in capsys.readouterr().err
    if fmt == "netcdf":
        with xr.open_dataset(out, engine="h5netcdf") as ds:
            _assert_equals_catalogue(ds.load(), db)
            assert ds["kmax"].attrs["units"] == "1" and ds.attrs["plane"] == "wb"
    elif fmt == "zarr":
        with xr.open_zarr(out) as ds:
            _assert_equals_catalogue(ds.load(), db)
    else:
        df = pd.read_csv(out, keep_default_na=False, na_values=[""]) if fmt == "csv" \
            else pd.read_parquet(out)
        for c in ("label_npq", "critical"):  # text columns that may be empty
            df[c] = df[c].astype(object).fillna("")
        ds = df.set_index(["b", "w"]).drop(columns=["i", "j"]).to_xarray()
        _assert_equals_catalogue(ds, db)
        meta = (json.loads(Path(str(out) + ".json").read_text()) if fmt == "csv"
                else gc.read_metadata(out, b"gearsim.results.export"))
        assert meta["columns"]["lyapunov"]["units"] == "1/tau"
        assert meta["attrs"]["config_hash"]
    assert not [p for p in tmp_path.iterdir() if ".tmp-" in p.name]


def test_zarr_export_replaces_a_previous_store(db, tmp_path):
    out = tmp_path / "wb.zarr"
    for _ in range(2):
        assert main(["export", "--catalogue", str(db), "--plane", "wb", "--format", "zarr",
                     "--out", str(out)]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["wb.zarr"]


def _run(args, cwd):
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    return subprocess.run([sys.executable, "-m", "gearsim", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=60)


BAD = [
    ("unknown-plane", lambda d: ["--plane", "nope", "--out", d / "x.nc"],
     ["no plane 'nope'", "wb"]),
    ("missing-dir", lambda d: ["--plane", "wb", "--out", d / "no/such/x.nc"], ["does not exist"]),
    ("out-is-dir", lambda d: ["--plane", "wb", "--out", d], ["is a directory"]),
    ("zarr-onto-file", lambda d: ["--plane", "wb", "--format", "zarr", "--out",
                                  (d / "f").write_text("x") and d / "f"], ["is a file"]),
    ("bad-format", lambda d: ["--plane", "wb", "--format", "hdf4", "--out", d / "x"], ["hdf4"]),
]


@pytest.mark.parametrize("case", BAD, ids=[c[0] for c in BAD])
def test_bad_export_is_one_line(db, tmp_path, case):
    _, make, words = case
    before = sorted(p.name for p in tmp_path.iterdir())
    args = make(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    r = _run(["export", "--catalogue", db, *args], tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "Traceback" not in r.stderr
    for w in words:
        assert w in r.stderr, (w, r.stderr)
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_exported_variables_are_the_catalogue_cell_columns():
    assert [c for c in VARIABLES if c != "elapsed_s"] == [
        "impact" if c == "I" else c for c in gc.ROW_COLUMNS]


def test_simulated_plane_round_trips_through_netcdf(tmp_path):
    """A real (simulated) 3 x 4 plane: the NetCDF export re-opened equals the catalogue."""
    cfg = gcfg.load_config([ROOT / "config/config.yaml", ROOT / "config/tiny.yaml"], root=ROOT)
    cfg["tile_rows"] = 2
    cfg["planes"]["wb"]["x"]["n"], cfg["planes"]["wb"]["y"]["n"] = 3, 4
    tiles = []
    for t in ggrid.tile_ids(cfg, "wb"):
        df = gt.run_tile(Study.of(cfg), "wb", t)
        rows = ggrid.tile_rows(cfg, "wb", t)
        prov = gprov.provenance(gprov.plane_subtree(Study.of(cfg), "wb"), kind="tile", name="wb",
                                study=Study.of(cfg), tile=t, rows=[rows.start, rows.stop],
                                cells=len(df))
        tiles.append(gc.write_parquet(df, tmp_path / f"{t}.parquet", {gc.PROVENANCE_KEY: prov}))
    cells = gc.combine_tiles(tiles, tmp_path / "cells.parquet", plane_record(Study.of(cfg), "wb"))
    db = tmp_path / "catalogue.sqlite"
    gc.build_catalogue(db, [cells])
    assert main(["export", "--catalogue", str(db), "--plane", "wb", "--out",
                 str(tmp_path / "wb.nc")]) == 0
    with xr.open_dataset(tmp_path / "wb.nc", engine="h5netcdf") as ds:
        _assert_equals_catalogue(ds.load(), db, nx=3, ny=4, chaos=False)
