"""One Kmax: for one cell of the tiny study's (w, b) plane, `gearsim point`, the catalogue's
`kmax`, the Kmax map, the explorer page and the scorecard show the same number under the name
Kmax with its definition beside it, and the column dictionary says which column is Kmax."""

from __future__ import annotations

import html
import json
import re
import sqlite3

import numpy as np
import pandas as pd
import pytest
from tiny_study import CATALOGUE, CONFIGS, tiny_study

from gearsim.cell.motion import DEFAULT_KMAX, KMAX_DEFINITION, KMAX_READINGS
from gearsim.cli.main import main
from gearsim.presentation.explorer import decode_block, digits_of

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def cell(tmp_path_factory):
    """The study, and a cell that starts its row from rest (as `point` does) with readings that
    differ from each other (so a wrong reading cannot pass for Kmax)."""
    wd = tiny_study(tmp_path_factory.getbasetemp())
    cells = pd.read_parquet(wd / "results/wb/cells.parquet")
    first = cells[(cells["i"] == 0) & (cells["status"] == "ok")].copy()
    spread = first[list(KMAX_READINGS)].max(axis=1) - first[list(KMAX_READINGS)].min(axis=1)
    c = first.loc[spread.idxmax()]
    assert spread.max() > 0.05
    return wd, c


def test_one_kmax_in_point_catalogue_maps_explorer_and_scorecard(cell, capsys, monkeypatch):
    wd, c = cell
    monkeypatch.chdir(wd)
    # the catalogue's kmax, and the column dictionary naming it
    con = sqlite3.connect(f"file:{wd / CATALOGUE}?mode=ro", uri=True)
    (kmax,) = con.execute("SELECT kmax FROM wb WHERE i = ? AND j = ?",
                          (int(c["i"]), int(c["j"]))).fetchone()
    meaning = dict(con.execute("SELECT column_name, meaning FROM column_dictionary "
                               "WHERE table_name = 'cells'").fetchall())
    con.close()
    assert kmax == c[DEFAULT_KMAX] == c["kmax"]
    assert meaning["kmax"].startswith(f"Kmax, the maximum dynamic load coefficient: "
                                      f"{KMAX_DEFINITION}")
    assert [k for k in KMAX_READINGS if "not Kmax" in meaning[k]] == [
        k for k in KMAX_READINGS if k != DEFAULT_KMAX]

    # point: the same cell from rest, under the study's settings
    args = ["point", "--omega", repr(float(c["w"])), "--set", f"b={float(c['b'])!r}",
            "--configfile", *CONFIGS]
    assert main(args) == 0
    out = capsys.readouterr().out.splitlines()
    shown = float(re.search(r"\bKmax=([0-9.]+)", out[1]).group(1))
    assert shown == pytest.approx(kmax, abs=5e-5)
    assert out[2].startswith(f"Kmax = {KMAX_DEFINITION}; other readings: ")
    assert "Kmax" not in out[2].split(";", 1)[1]  # the other readings keep their own names
    assert main([*args, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["kmax"] == pytest.approx(kmax, rel=1e-9)

    # the map: the plane's kmax column under the Kmax label, its definition in the notes
    from gearsim.presentation.figures.data import plane_grid
    from gearsim.presentation.figures.maps import _map_kmax

    cells = pd.read_parquet(wd / "results/wb/cells.parquet")
    fig, _, notes = _map_kmax(cells)
    labels = [a.get_ylabel() for a in fig.axes]
    assert any(lab.startswith(r"$K_{\max}$ (peak") for lab in labels), labels
    assert f"Kmax = {KMAX_DEFINITION} (the catalogue's kmax)." in notes
    assert plane_grid(cells, "kmax")[int(c["j"]), int(c["i"])] == kmax

    # the explorer page: the cell's Kmax to the digits it shows, the definition on the page
    page = wd / "kmax_explorer.html"
    assert main(["explorer", "--configfile", *CONFIGS, "--plane", "wb", "--sweep", "standard",
                 "--catalogue", str(wd / CATALOGUE), "--out", str(page)]) == 0
    text = page.read_text()
    assert f"K<sub>max</sub> = {html.escape(KMAX_DEFINITION)})" in text
    data = json.loads(re.search(r'id="gearsim-data">(.*?)</script>', text, re.S).group(1))
    raw = decode_block(re.search(r'id="gearsim-block">(.*?)</script>', text, re.S).group(1))
    wb = next(p for p in data["planes"] if p["name"] == "wb")
    layer = wb["layers"]["kmax"]
    assert layer["title"] == f"Kmax ({KMAX_DEFINITION})"  # the layer's title
    got = digits_of(raw, layer["values"])[int(c["j"]) * wb["nx"] + int(c["i"])]
    assert got == float(f"{kmax:.4f}")

    # the scorecard: given this cell as the one after the jump, it shows its Kmax, not the
    # reading closest to the paper's
    from gearsim.presentation.report import build_report
    from gearsim.presentation.scorecard import scorecard

    rep, _ = build_report(sweeps_dir=wd / "results/sweeps", catalogue=wd / CATALOGUE,
                          results=wd / "results", calibration=None, planes=("wb",),
                          sweeps=["standard"])
    rep.jump = {"w_lo": float(c["w"]), "w_hi": float(c["w"]), "dc_before": 0.0,
                "dc_after": float(c["dc"]), "kmax_before": {},
                "kmax_after": {k: float(c[k]) for k in KMAX_READINGS}}
    rows = [r for r in scorecard(rep) if r.item.startswith("Kmax")]
    assert [(r.item, r.ours) for r in rows] == [
        (f"Kmax after the jump ({KMAX_DEFINITION})", f"{kmax:.3f}")]
    assert np.isfinite(kmax)
