"""The explorer page in a real headless browser (Debian's chromium + chromium-driver through
selenium), on the tables of a tiny real pipeline run: the page loads with no console error, a
hover over a known cell shows that cell's values from cells.parquet, a click draws its Poincare
points. A screenshot is kept under the test's tmp dir (path printed)."""

from __future__ import annotations

import base64
import json
import os
import shutil
import time

import numpy as np
import pandas as pd
import pytest
from tiny_study import CATALOGUE, CONFIGS, tiny_study

from gearsim.cli.main import main
from gearsim.presentation.explorer import (
    MAX_POINTS,
    dequantise,
    plane_from_cells,
    plane_payload,
    plotly_js,
)
from gearsim.results.catalogue import open_catalogue

CHROMIUM = shutil.which("chromium")
DRIVER = shutil.which("chromedriver")
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--window-size=1600,1200")


@pytest.fixture(scope="module")
def page(tmp_path_factory, monkeypatch_module):
    wd = tiny_study(tmp_path_factory.getbasetemp())
    monkeypatch_module.chdir(wd)
    out = wd / "results" / "explorer" / "index.html"
    assert main(["explorer", "--configfile", *CONFIGS, "--plane", "wb", "weps",
                 "--sweep", "standard", "--catalogue", str(wd / CATALOGUE),
                 "--out", str(out)]) == 0
    return wd, out


@pytest.fixture(scope="module")
def monkeypatch_module():
    mp = pytest.MonkeyPatch()
    yield mp
    mp.undo()


def _known_cell(cells: pd.DataFrame) -> pd.Series:
    """A cell away from the edges, periodic when the tiny plane has one (fewest points)."""
    inner = cells[(cells["i"].between(1, cells["i"].max() - 1))
                  & (cells["j"].between(1, cells["j"].max() - 1))]
    periodic = inner[inner["motion"] == "periodic"]
    return (periodic if len(periodic) else inner).iloc[0]


def _expected_points(cell: pd.Series) -> tuple[np.ndarray, np.ndarray]:
    px, pv = np.asarray(cell["poincare_x"], float), np.asarray(cell["poincare_v"], float)
    keep = MAX_POINTS
    if cell["motion"] == "periodic" and cell["n"] > 0:
        keep = min(MAX_POINTS, int(cell["n"]))
    return px[-keep:], pv[-keep:]


def test_page_is_static_and_compact(page):
    wd, out = page
    html = out.read_text()
    assert "<script src=" not in html and "http://" not in html.split("<script>", 1)[0]
    assert plotly_js()[:200] in html  # the library is inline
    cells = pd.read_parquet(wd / "results/wb/cells.parquet")
    payload = plane_payload(plane_from_cells("wb", cells, ("w", "b")))
    points = int(np.frombuffer(base64.b64decode(payload["offsets"]["b64"]), "<u4")[-1])
    size = len(json.dumps(payload))
    # typed arrays: about 36 bytes per cell (base64 of 27) plus 5.3 per section point
    print(f"wb payload {size} bytes for {len(cells)} cells and {points} points")
    assert size < 1500 + 40 * len(cells) + 6 * points
    # the int16 section coding round-trips within half a step
    allx = np.concatenate([np.asarray(v, float) for v in cells["poincare_x"]])
    got = dequantise(payload["px"])
    assert len(got) == points and payload["px"]["step"] < 1e-4 * (np.ptp(allx) + 1e-300) * 2
    assert got.min() >= allx.min() - 1e-12 and got.max() <= allx.max() + 1e-12


def _hover(driver, div: str, x: float, y: float, expect: str) -> None:
    """Move the real mouse over the data point (x, y) of a map; wait for the panel."""
    from selenium.webdriver.common.action_chains import ActionChains

    heat = driver.find_element("id", div)
    driver.execute_script("arguments[0].scrollIntoView({block: 'center'});", heat)
    px, py, w, h = driver.execute_script(
        "const gd = arguments[0], xa = gd._fullLayout.xaxis, ya = gd._fullLayout.yaxis;"
        "return [xa._offset + xa.l2p(arguments[1]), ya._offset + ya.l2p(arguments[2]),"
        " gd.clientWidth, gd.clientHeight];", heat, x, y)
    ActionChains(driver).move_to_element_with_offset(
        heat, int(round(px - w / 2)), int(round(py - h / 2))).perform()
    panel = driver.find_element("id", "cell")
    deadline = time.monotonic() + 10
    while panel.get_attribute("data-cell") != expect:
        assert time.monotonic() < deadline, f"hover shows {panel.text!r}, not {expect}"
        time.sleep(0.1)


def test_page_in_chromium(page, tmp_path):
    if CHROMIUM is None or DRIVER is None:  # pragma: no cover - CI installs both (.ci/run)
        why = ("chromium and chromium-driver are needed: apt-get install -y chromium "
               "chromium-driver (.ci/run installs them)")
        if os.environ.get("CI"):  # CI skips nothing
            pytest.fail(why)
        pytest.skip(why)
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.action_chains import ActionChains

    wd, out = page
    cells = pd.read_parquet(wd / "results/wb/cells.parquet")
    cell = _known_cell(cells)
    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for flag in (*FLAGS, f"--user-data-dir={tmp_path / 'profile'}"):
        opts.add_argument(flag)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(DRIVER), options=opts)
    try:
        driver.get(out.as_uri())
        deadline = time.monotonic() + 60
        while driver.execute_script("return document.body.dataset.ready") != "1":
            assert time.monotonic() < deadline, "the page never finished drawing"
            time.sleep(0.1)
        errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
        assert not errors, errors
        _hover(driver, "map-wb-pattern", float(cell["w"]), float(cell["b"]),
               f"wb:{cell['i']}:{cell['j']}")
        text = driver.find_element("id", "cell").text
        f32 = lambda v: float(np.float32(v))  # noqa: E731 (the page stores float32)
        assert f"label: {cell['label']}" in text
        assert f"n-p-q: {cell['label_npq'] or '—'}" in text
        assert f"impact state I: {int(cell['I'])}, period n: {int(cell['n'])}" in text
        assert f"DC: {f32(cell['dc']):.4f}" in text
        assert f"Kmax: {f32(cell['kmax']):.4f}" in text
        assert f"Lyapunov exponent: {f32(cell['lyapunov']):.5f}" in text
        assert "coexisting attractors" not in text  # multistability is off for wb
        ActionChains(driver).click().perform()
        deadline = time.monotonic() + 10
        while driver.execute_script("return document.getElementById('poincare').dataset.cell"
                                    ) != f"wb:{cell['i']}:{cell['j']}":
            assert time.monotonic() < deadline, "the click drew no Poincare points"
            time.sleep(0.1)
        drawn = driver.execute_script("const d = document.getElementById('poincare').data[0];"
                                      "return [Array.from(d.x), Array.from(d.y)];")
        ex, ev = _expected_points(cell)
        assert len(drawn[0]) == len(ex) > 0
        # int16 over the plane's range: within half a step of the stored float64 values
        payload = plane_payload(plane_from_cells("wb", cells, ("w", "b")))
        np.testing.assert_allclose(drawn[0], ex, rtol=0, atol=0.51 * payload["px"]["step"])
        np.testing.assert_allclose(drawn[1], ev, rtol=0, atol=0.51 * payload["pv"]["step"])
        # every plane's three maps and the sweep are drawn
        for div in ("map-wb-pattern", "map-wb-dc", "map-wb-kmax", "map-weps-pattern",
                    "map-weps-dc", "map-weps-kmax", "sweep-standard"):
            assert driver.execute_script(f"return document.getElementById('{div}').data.length"
                                         ) >= 1, div
        # a (w, eps) cell with its coexisting attractors from the catalogue's attractors table
        con = open_catalogue(wd / CATALOGUE)
        att = pd.read_sql_query(
            "select a.*, c.i as _i, c.j as _j from attractors a join cells c on a.cell_id = "
            "c.id join planes p on c.plane_id = p.id where p.name = 'weps' "
            "order by c.j, c.i, a.attractor", con)
        con.close()
        assert len(att), "the tiny run found no attractor"
        counts = att.groupby(["_i", "_j"]).size().sort_values(ascending=False)
        (ai, aj), n_att = counts.index[0], int(counts.iloc[0])
        weps = pd.read_parquet(wd / "results/weps/cells.parquet")
        wcell = weps[(weps["i"] == ai) & (weps["j"] == aj)].iloc[0]
        _hover(driver, "map-weps-pattern", float(wcell["w"]), float(wcell["eps"]),
               f"weps:{ai}:{aj}")
        text = driver.find_element("id", "cell").text
        assert f"coexisting attractors: {n_att}" in text, text
        first = att[(att["_i"] == ai) & (att["_j"] == aj)].iloc[0]
        assert f"#0 {first['label']}" in text
        assert f"basin {100 * first['basin_fraction']:.1f} %" in text
        shot = tmp_path / "explorer.png"
        driver.save_screenshot(str(shot))
        print(f"screenshot: {shot}")
        assert shot.stat().st_size > 10_000
        errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
        assert not errors, errors
    finally:
        driver.quit()


def test_explorer_cli_errors(page, capsys):
    wd, _ = page
    assert main(["explorer", "--configfile", *CONFIGS, "--plane", "nope"]) == 2
    assert "--plane nope: not in the config" in capsys.readouterr().err
    assert main(["explorer", "--configfile", *CONFIGS, "--results", str(wd / "none")]) == 2
    assert "missing" in capsys.readouterr().err
