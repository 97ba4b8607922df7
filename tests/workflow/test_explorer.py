"""The explorer page in a real headless browser (Debian's chromium + chromium-driver through
selenium), on the tables of a tiny real pipeline run: the page loads with no console error;
every layer of every plane draws the cell colours of its values; a hover over a known cell shows
that cell's values from cells.parquet; a click draws its Poincare points, lists its coexisting
attractors from the catalogue and picks the nearest sweep. A screenshot of each plane is kept
under the test's tmp dir (path printed)."""

from __future__ import annotations

import json
import os
import re
import shutil
import time

import numpy as np
import pandas as pd
import pytest
from tiny_study import CATALOGUE, CONFIGS, tiny_study

from gearsim.cli.main import main
from gearsim.presentation import explorer
from gearsim.presentation.explorer import (
    MAX_POINTS,
    MISSING,
    NO_VALUE,
    Block,
    array_of,
    decode_block,
    digits_of,
    json_of,
    plane_from_cells,
    plane_payload,
    quantised_of,
    values_of,
)
from gearsim.presentation.figures import style
from gearsim.presentation.orbit_plots import CURVE_STYLE
from gearsim.results.catalogue import open_catalogue

CHROMIUM = shutil.which("chromium")
DRIVER = shutil.which("chromedriver")
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--window-size=1600,1200")


@pytest.fixture(scope="module")
def monkeypatch_module():
    mp = pytest.MonkeyPatch()
    yield mp
    mp.undo()


@pytest.fixture(scope="module")
def page(tmp_path_factory, monkeypatch_module):
    wd = tiny_study(tmp_path_factory.getbasetemp())
    monkeypatch_module.chdir(wd)
    out = wd / "results" / "explorer" / "index.html"
    assert main(["explorer", "--configfile", *CONFIGS, "--plane", "wb", "weps",
                 "--sweep", "standard", "--catalogue", str(wd / CATALOGUE),
                 "--out", str(out)]) == 0
    return wd, out


def _expected_points(cell: pd.Series) -> tuple[np.ndarray, np.ndarray]:
    px, pv = np.asarray(cell["poincare_x"], float), np.asarray(cell["poincare_v"], float)
    keep = MAX_POINTS
    if cell["motion"] == "periodic" and cell["n"] > 0:
        keep = min(MAX_POINTS, int(cell["n"]))
    return px[-keep:], pv[-keep:]


def test_block_round_trips_within_half_a_step():
    """The 16-bit coding of the page: every value back within half a step of its range, NaN
    kept as missing."""
    rng = np.random.default_rng(1)
    v = rng.normal(size=1000) * 3.7 + 1.0
    v[::97] = np.nan
    block = Block()
    enc = block.quantised(v)
    raw = decode_block(block.encoded())
    got = values_of(raw, enc)
    ok = np.isfinite(v)
    assert np.array_equal(np.isfinite(got), ok)
    assert np.max(np.abs(got[ok] - v[ok])) <= 0.5 * enc["step"] * (1 + 1e-9)
    assert enc["step"] == pytest.approx(np.ptp(v[ok]) / (MISSING - 1))
    q = quantised_of(raw, enc)
    assert q.max() == MISSING and np.array_equal(q == MISSING, ~ok)


def test_attractor_lines_round_trip_in_the_block():
    """The attractor lines of the searched cells travel as JSON text inside the compressed
    block (not beside it): the same lines back, and gzip packs them to a fraction."""
    lines = {str(k): [f"#0 1/1T (1-1-0), basin {k % 100}.0 %, DC 0.{k:04d}",
                      "#1 2/2T (2-2-1), basin 37.5 %, λ -0.01234"] for k in range(3000)}
    block = Block()
    enc = block.add_json(lines)
    assert set(enc) == {"json"}
    encoded = block.encoded()
    assert json_of(decode_block(encoded), enc) == lines
    text = len(json.dumps(lines, ensure_ascii=False).encode())
    assert len(encoded) < text / 4  # base64 of gzip: a quarter of the text or less


def test_payload_of_a_plane(page):
    """A plane's arrays hold exactly its cells: pattern categories, labels, DC and Kmax within
    half a step, the section points of each cell (the last n of a period-n motion)."""
    wd, out = page
    cells = pd.read_parquet(wd / "results/wb/cells.parquet")
    block = Block()
    p = plane_payload(plane_from_cells("wb", cells, ("w", "b")), block)
    raw = decode_block(block.encoded())
    nx = p["nx"]
    k = cells["j"].to_numpy() * nx + cells["i"].to_numpy()
    cats = array_of(raw, p["cat"])[k]
    assert [p["cat_keys"][c] for c in cats] == list(style.pattern_categories(cells))
    labels = np.array(p["labels"])[array_of(raw, p["label"])[k]]
    assert list(labels) == list(cells["label"].fillna(""))
    for col, digits in (("dc", 4), ("kmax", 4), ("lyapunov", 5)):
        got = digits_of(raw, p["layers"][col]["values"])[k]
        want = [float(f"{v:.{digits}f}") if np.isfinite(v) else np.nan for v in cells[col]]
        np.testing.assert_array_equal(got, want)
    counts = array_of(raw, p["counts"]).astype(int)
    offsets = np.concatenate([[0], np.cumsum(counts)])
    px = values_of(raw, p["px"])
    for _, cell in cells.iloc[::7].iterrows():
        kk = int(cell["j"]) * nx + int(cell["i"])
        ex, _ = _expected_points(cell)
        np.testing.assert_allclose(px[offsets[kk]:offsets[kk + 1]], ex, rtol=0,
                                   atol=0.51 * p["px"]["step"])


def test_floquet_margin_is_a_layer_when_the_cells_carry_it(page):
    wd, _ = page
    cells = pd.read_parquet(wd / "results/wb/cells.parquet")
    block = Block()
    plain = cells.drop(columns=["mu_max", "floquet_margin"], errors="ignore")  # no margin
    assert "floquet" not in plane_payload(plane_from_cells("wb", plain, ("w", "b")),
                                          block)["layers"]
    margin = np.linspace(0.1, 0.99, len(cells))
    p = plane_payload(plane_from_cells("wb", cells.assign(floquet_margin=margin),
                                       ("w", "b")), block)
    enc = p["layers"]["floquet"]["values"]
    raw = decode_block(block.encoded())
    k = cells["j"].to_numpy() * p["nx"] + cells["i"].to_numpy()
    got = digits_of(raw, enc)[k]
    np.testing.assert_array_equal(got, [float(f"{v:.5f}") for v in margin])


def test_layers_carry_the_shown_digits_whatever_the_range():
    """A layer's values travel as the digits the readout shows, exactly as Python prints them
    (ties to even included), whatever the other cells hold: a runaway value of 1e6 beside
    values near 1 leaves their last digit intact (16-bit steps over that range were ~16
    wide), NaN stays missing, values beyond 32 bits come back exact."""
    rng = np.random.default_rng(7)
    v = rng.uniform(0.18, 6.6, 5000)
    v[:4] = [1.048804e6, 0.03125, 0.09375, -2.5e-5]  # 1/32, 3/32: exact ties at 4 decimals
    v[4], v[5], v[6] = np.nan, 3.1e12, -7.25e9  # no value; beyond 32 bits at 4 decimals
    block = Block()
    enc = block.digits(v, 4)
    raw = decode_block(block.encoded())
    got = digits_of(raw, enc)
    want = [float(f"{x:.4f}") if np.isfinite(x) else np.nan for x in v]
    np.testing.assert_array_equal(got[:4], [1048804.0, 0.0312, 0.0938, -0.0])  # ties to even
    np.testing.assert_array_equal(got, want)
    assert set(enc["big"]) == {"0", "5", "6"}  # 1.05e10, 3.1e16, -7.25e13 at 4 decimals
    assert NO_VALUE < 0 and np.isnan(got[4])


def test_readout_carries_status_critical_and_refined(page):
    """The cell readout's verified-motion columns: per cell its status, the kind of its
    critical multiplier and whether its label is that of the Newton orbit, decoded from the
    page's arrays exactly."""
    wd, _ = page
    cells = pd.read_parquet(wd / "results/wb/cells.parquet")
    kinds = np.array(["ok", "bifurcation", "not_converged"])[np.arange(len(cells)) % 3]
    crit = np.array(["", "fold", "period_doubling", "neimark_sacker"])[np.arange(len(cells)) % 4]
    refined = np.arange(len(cells)) % 5 == 0
    cells = cells.assign(status=kinds, critical=crit, refined=refined)
    block = Block()
    p = plane_payload(plane_from_cells("wb", cells, ("w", "b")), block)
    raw = decode_block(block.encoded())
    k = cells["j"].to_numpy() * p["nx"] + cells["i"].to_numpy()
    v = p["verified"]
    for col, truth in (("status", kinds), ("critical", crit)):
        got = np.array(v[col]["names"])[array_of(raw, v[col]["index"])[k]]
        assert list(got) == list(truth), col
    assert list(array_of(raw, v["refined"])[k].astype(bool)) == list(refined)


def test_page_is_static_and_small(page):
    wd, out = page
    html = out.read_text()
    assert "<script src=" not in html and "http://" not in html and "https://" not in html
    assert "issue" not in html.lower()
    cells = sum(len(pd.read_parquet(wd / f"results/{p}/cells.parquet")) for p in ("wb", "weps"))
    # no plotting library inside: the page is its code and style, the scorecard and the
    # plane/sweep metadata (~15 kB here) and about 60 bytes per cell
    template = len(explorer._TEMPLATE.read_text())
    assert len(html) < template + 15_000 + 60 * cells, (len(html), template)


def _driver(tmp_path):
    if CHROMIUM is None or DRIVER is None:  # pragma: no cover - CI installs both (.ci/run)
        why = ("chromium and chromium-driver are needed: apt-get install -y chromium "
               "chromium-driver (.ci/run installs them)")
        if os.environ.get("CI"):  # CI skips nothing
            pytest.fail(why)
        pytest.skip(why)
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for flag in (*FLAGS, f"--user-data-dir={tmp_path / 'profile'}"):
        opts.add_argument(flag)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service(DRIVER), options=opts)


def _load(driver, url):
    driver.get(url)
    deadline = time.monotonic() + 60
    while driver.execute_script("return document.body.dataset.ready") != "1":
        assert time.monotonic() < deadline, "the page never finished drawing"
        time.sleep(0.05)


def _move(driver, plane: str, x: float, y: float, click: bool = False) -> None:
    """Move the real mouse over the data point (x, y) of a plane's map (and click)."""
    from selenium.webdriver.common.action_chains import ActionChains

    canvas = driver.find_element("id", f"map-{plane}")
    driver.execute_script("arguments[0].scrollIntoView({block: 'center'});", canvas)
    dx, dy = driver.execute_script("return window.GEARSIM.pixelOf(arguments[0], arguments[1],"
                                   " arguments[2]);", plane, x, y)
    chain = ActionChains(driver).move_to_element_with_offset(canvas, int(round(dx)),
                                                             int(round(dy)))
    (chain.click() if click else chain).perform()


def _pixel(driver, plane: str, x: float, y: float) -> list[int]:
    """The colour the map's canvas shows at the data point (x, y)."""
    return driver.execute_script(
        "const p = window.GEARSIM.planes[arguments[0]], f = p.frame;"
        "const d = f.ctx.getImageData(Math.round(f.X(arguments[1])), Math.round(f.Y(arguments[2])),"
        " 1, 1).data; return [d[0], d[1], d[2]];", plane, x, y)


def _hex(c: str) -> list[int]:
    return [int(c[k:k + 2], 16) for k in (1, 3, 5)]


def test_page_in_chromium(page, tmp_path):
    wd, out = page
    driver = _driver(tmp_path)
    try:
        _load(driver, out.as_uri())
        errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
        assert not errors, errors
        # the scorecard of the paper comparison heads the page (wb and standard are the paper's)
        score = driver.find_element("id", "scorecard-table").text
        assert "b above which no double-sided impact occurs" in score
        cells = pd.read_parquet(wd / "results/wb/cells.parquet")
        inner = cells[cells["i"].between(1, cells["i"].max() - 1)
                      & cells["j"].between(1, cells["j"].max() - 1)]
        periodic = inner[inner["motion"] == "periodic"]
        cell = (periodic if len(periodic) else inner).iloc[0]
        x, y = float(cell["w"]), float(cell["b"])
        # every layer draws this cell in the colour of its value; the legend sits beside
        cat = style.pattern_categories(cells.loc[[cell.name]])[0]
        for layer, title in (("pattern", "pattern (cells)"), ("dc", "DC"), ("kmax", "Kmax"),
                             ("lyapunov", "Lyapunov")):
            driver.find_element("id", f"layer-wb-{layer}").click()
            legend = driver.find_element("id", "legend-wb")
            assert title in legend.text, (layer, legend.text)
            m, lg = driver.find_element("id", "map-wb").rect, legend.rect
            assert lg["x"] >= m["x"] + m["width"] - 1  # beside the map, not over it
            if layer == "pattern":
                assert _pixel(driver, "wb", x, y) == _hex(style.PATTERN_COLOURS[cat])
            if layer == "dc":
                t = driver.execute_script("return DATA.turbo;")
                assert _pixel(driver, "wb", x, y) == _hex(t[round(float(cell["dc"]) * 255)])
            shot = tmp_path / f"wb-{layer}.png"
            driver.save_screenshot(str(shot))
        print(f"screenshots: {tmp_path}")
        driver.find_element("id", "layer-wb-pattern").click()
        # the wheel zooms about the mouse; the cell keeps its colour and its place under it
        full = driver.execute_script("const f = window.GEARSIM.planes.wb.frame;"
                                     " return [f.x0, f.x1, f.y0, f.y1];")
        for _ in range(4):
            driver.execute_script(
                "const c = document.getElementById('map-wb'), r = c.getBoundingClientRect(),"
                " [dx, dy] = window.GEARSIM.pixelOf('wb', arguments[0], arguments[1]);"
                "c.dispatchEvent(new WheelEvent('wheel', {deltaY: -100, bubbles: true,"
                " cancelable: true, clientX: r.left + r.width / 2 + dx,"
                " clientY: r.top + r.height / 2 + dy}));", x, y)
        zoomed = driver.execute_script("const f = window.GEARSIM.planes.wb.frame;"
                                       " return [f.x0, f.x1, f.y0, f.y1];")
        assert zoomed[1] - zoomed[0] < 0.5 * (full[1] - full[0])
        assert zoomed[0] <= x <= zoomed[1] and zoomed[2] <= y <= zoomed[3]
        assert _pixel(driver, "wb", x, y) == _hex(style.PATTERN_COLOURS[cat])
        driver.save_screenshot(str(tmp_path / "wb-zoomed.png"))
        # hover: this cell's values
        _move(driver, "wb", x, y)
        assert driver.execute_script("return window.GEARSIM.hover") == \
            f"wb:{cell['i']}:{cell['j']}"
        text = driver.find_element("id", "cell").text
        assert f"pattern: {cell['label']}" in text
        if cell["label_npq"]:
            assert f"({cell['label_npq']})" in text
        assert f"I = {int(cell['I'])}   n = {int(cell['n'])}" in text
        dc = float(re.search(r"DC = ([-0-9.]+)", text).group(1))
        assert dc == pytest.approx(float(cell["dc"]), abs=6e-5)
        kmax = float(re.search(r"Kmax = ([-0-9.]+)", text).group(1))
        assert kmax == pytest.approx(float(cell["kmax"]), abs=1e-4 + 1e-4 * abs(cell["kmax"]))
        # click: its Poincare points
        _move(driver, "wb", x, y, click=True)
        got = driver.execute_script("return window.GEARSIM.poincare")
        assert got["cell"] == f"wb:{cell['i']}:{cell['j']}"
        ex, ev = _expected_points(cell)
        assert len(got["x"]) == len(ex) > 0
        np.testing.assert_allclose(got["x"], ex, atol=1e-4 * (1 + np.ptp(ex)) + 1e-3)
        np.testing.assert_allclose(got["v"], ev, atol=1e-4 * (1 + np.ptp(ev)) + 1e-3)
        # a double click shows the whole plane again
        from selenium.webdriver.common.action_chains import ActionChains

        ActionChains(driver).double_click(driver.find_element("id", "map-wb")).perform()
        assert driver.execute_script("const f = window.GEARSIM.planes.wb.frame;"
                                     " return [f.x0, f.x1, f.y0, f.y1];") == pytest.approx(full)
        # the nearest sweep through it: the standard sweep runs along w
        assert driver.execute_script("return window.GEARSIM.near") == "standard"
        assert "attractors" in driver.find_element("id", "attractors").text  # not searched
        # a (w, eps) cell with coexisting attractors: its count (cells.n_attractors, which
        # leaves out starts that did not settle) and the rows of the attractors table
        con = open_catalogue(wd / CATALOGUE)
        att = pd.read_sql_query(
            "select a.*, c.i as _i, c.j as _j from attractors a join cells c on a.cell_id = "
            "c.id join planes p on c.plane_id = p.id where p.name = 'weps' "
            "order by c.j, c.i, a.attractor", con)
        found = pd.read_sql_query(
            "select c.i, c.j, c.n_attractors from cells c join planes p on c.plane_id = p.id "
            "where p.name = 'weps' and c.n_attractors is not null "
            "order by c.n_attractors desc, c.j, c.i", con)
        con.close()
        assert len(att) and len(found), "the tiny run found no attractor"
        ai, aj, n_att = (int(v) for v in found.iloc[0][["i", "j", "n_attractors"]])
        weps = pd.read_parquet(wd / "results/weps/cells.parquet")
        wcell = weps[(weps["i"] == ai) & (weps["j"] == aj)].iloc[0]
        driver.find_element("id", "layer-weps-attractors").click()
        colour = explorer_attractor_colour(driver, min(n_att, 4))
        assert _pixel(driver, "weps", float(wcell["w"]), float(wcell["eps"])) == colour
        _move(driver, "weps", float(wcell["w"]), float(wcell["eps"]), click=True)
        assert f"coexisting attractors: {n_att}" in driver.find_element("id", "cell").text
        listed = driver.find_element("id", "attractors").text
        first = att[(att["_i"] == ai) & (att["_j"] == aj)].iloc[0]
        assert f"#0 {first['label']}" in listed
        assert f"basin {100 * first['basin_fraction']:.1f} %" in listed
        driver.save_screenshot(str(tmp_path / "weps-attractors.png"))
        errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
        assert not errors, errors
    finally:
        driver.quit()


def _readout(driver, plane: str, x: float, y: float) -> dict[str, str]:
    """Hover the data point (x, y) of a plane: the readout's DC, Kmax and λ as shown."""
    _move(driver, plane, x, y)
    text = driver.find_element("id", "cell").text
    return {k: re.search(rf"{k} = (.+?)(?:   |\n|$)", text).group(1)
            for k in ("DC", "Kmax", "λ")}


def _digits(v, d: int) -> str:
    return f"{v:.{d}f}"


def test_readout_equals_the_catalogue(page, tmp_path):
    """Hovering cells of both planes shows each cell's catalogue DC, Kmax and λ to the last
    shown digit; on a plane with diverged cells (one of the older tables whose diverged cells
    carry a runaway Kmax of ~1e6, one with none) every other cell still reads its own Kmax, the
    runaway one reads its value marked as above the drawn range (and the legend counts it), the
    one without a value says why."""
    wd, out = page
    con = open_catalogue(wd / CATALOGUE)
    cat = pd.read_sql_query("select p.name as plane, c.i, c.j, c.x, c.y, c.dc, c.kmax, "
                            "c.lyapunov from cells c join planes p on c.plane_id = p.id", con)
    con.close()
    rng = np.random.default_rng(54)
    driver = _driver(tmp_path)
    try:
        _load(driver, out.as_uri())
        for plane in ("wb", "weps"):
            rows = cat[cat["plane"] == plane]
            for _, r in rows.iloc[rng.choice(len(rows), size=min(8, len(rows)),
                                              replace=False)].iterrows():
                got = _readout(driver, plane, float(r["x"]), float(r["y"]))
                assert driver.execute_script("return window.GEARSIM.hover") == \
                    f"{plane}:{r['i']}:{r['j']}"
                for key, col, d in (("DC", "dc", 4), ("Kmax", "kmax", 4), ("λ", "lyapunov", 5)):
                    if np.isfinite(r[col]):
                        assert got[key] == _digits(r[col], d), (plane, r["i"], r["j"], key)
                    else:
                        assert got[key].startswith("none"), (plane, key, got[key])
    finally:
        driver.quit()
    # a plane with diverged cells: a runaway Kmax (older tables) and a NULL one (this code)
    cells = pd.read_parquet(wd / "results/wb/cells.parquet").reset_index(drop=True)
    big, null = 0, len(cells) - 1
    cells.loc[[big, null], ["motion", "label", "label_npq", "status"]] = [
        ["diverged", "diverged", "", "diverged"]] * 2
    cells.loc[big, "kmax"] = 1_048_804.25
    cells.loc[null, ["kmax", "dc", "lyapunov"]] = np.nan
    html = tmp_path / "diverged.html"
    html.write_text(explorer.render([plane_from_cells("wb", cells, ("w", "b"))], {}))
    driver = _driver(tmp_path)
    try:
        _load(driver, html.as_uri())
        driver.find_element("id", "layer-wb-kmax").click()
        assert "▲ 1 cell above" in driver.find_element("id", "legend-wb").text
        for k in rng.choice(np.arange(1, len(cells) - 1), size=min(8, len(cells) - 2),
                            replace=False):
            r = cells.loc[k]
            got = _readout(driver, "wb", float(r["w"]), float(r["b"]))
            assert got["Kmax"] == _digits(r["kmax"], 4), (k, got)
        got = _readout(driver, "wb", float(cells.loc[big, "w"]), float(cells.loc[big, "b"]))
        assert got["Kmax"].startswith("1048804.2500 (above the drawn range"), got
        got = _readout(driver, "wb", float(cells.loc[null, "w"]), float(cells.loc[null, "b"]))
        assert got["Kmax"] == got["DC"] == "none (diverged: no steady motion)", got
        assert not [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
    finally:
        driver.quit()


def explorer_attractor_colour(driver, n: int) -> list[int]:
    return _hex(driver.execute_script(f"return ATT_COLOURS[{n}];"))


def test_bifurcation_curves_are_drawn_on_top(page, tmp_path):
    """A plane's curve from the catalogue's bifurcation_curves is drawn over the map in its
    kind's colour (a synthetic fold line across the tiny plane)."""
    wd, _ = page
    cells = pd.read_parquet(wd / "results/wb/cells.parquet")
    plane = plane_from_cells("wb", cells, ("w", "b"))
    plane.curves = [{"curve": 0, "kind": "fold", "period": 1, "xname": "w", "yname": "b",
                     "x": [1.0, 1.0], "y": [0.0, 1.0]}]
    out = tmp_path / "curves.html"
    out.write_text(explorer.render([plane], {}))
    driver = _driver(tmp_path)
    try:
        _load(driver, out.as_uri())
        # the line is anti-aliased over its pixel column: the closest of the three around it
        # to the fold's colour in the PNGs (orbit_plots.CURVE_STYLE, one source for both)
        px = driver.execute_script(
            "const f = window.GEARSIM.planes.wb.frame, X = Math.round(f.X(1.0)),"
            " Y = Math.round(f.Y(0.5)); return Array.from(f.ctx.getImageData(X - 1, Y, 3, 1)"
            ".data);")
        fold = np.array(_hex(CURVE_STYLE["fold"][1]))
        near = min(np.abs(np.array(px[k:k + 3]) - fold).sum() for k in (0, 4, 8))
        assert near < 3 * 40, (px, fold)
        driver.find_element("id", "curves-wb").click()
        cat = style.pattern_categories(cells)
        # the cells that hold the point (two or four when it lies on a cell boundary)
        dw = np.diff(np.unique(cells["w"])).min() / 2 + 1e-9
        db = np.diff(np.unique(cells["b"])).min() / 2 + 1e-9
        near = np.flatnonzero(((cells["w"] - 1.0).abs() <= dw) & ((cells["b"] - 0.5).abs() <= db))
        assert len(near) >= 1
        assert _pixel(driver, "wb", 1.0, 0.5) in [_hex(style.PATTERN_COLOURS[cat[k]]) for k in near]
        assert not [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
    finally:
        driver.quit()


def test_explorer_cli_errors(page, capsys):
    wd, _ = page
    assert main(["explorer", "--configfile", *CONFIGS, "--plane", "nope"]) == 2
    assert "--plane nope: not in the config" in capsys.readouterr().err
    assert main(["explorer", "--configfile", *CONFIGS, "--results", str(wd / "none")]) == 2
    assert "missing" in capsys.readouterr().err


def test_points_cap_keeps_a_chaotic_page_small():
    """Few chaotic cells keep MAX_POINTS each; a page of many chaotic cells keeps fewer, so its
    section points stay within the budget (never fewer than MIN_POINTS)."""
    from gearsim.presentation.explorer import MIN_POINTS, POINTS_BUDGET, points_cap

    def plane(n_chaos, n_periodic=100):
        motion = ["chaos"] * n_chaos + ["periodic"] * n_periodic
        return explorer.PlaneData("p", "w", "b", pd.DataFrame(
            {"motion": motion, "n": [0] * n_chaos + [2] * n_periodic}))

    assert points_cap([plane(1000)]) == MAX_POINTS
    many = 50_000
    cap = points_cap([plane(many)])
    assert MIN_POINTS <= cap < MAX_POINTS and 4 * (cap * many + 200) <= POINTS_BUDGET
    assert points_cap([plane(10_000_000)]) == MIN_POINTS


def test_curves_and_codimension_2_points_look_as_in_figs_21_22(page, tmp_path):
    """A curve drawn with its look from the catalogue row (orbit_plots.curve_look: colour by
    period, dash by kind and flank) and a codimension-2 point drawn as its white marker; the
    legend names the curve by kind and period and the point by kind."""
    from gearsim.presentation.orbit_plots import curve_look

    wd, _ = page
    cells = pd.read_parquet(wd / "results/wb/cells.parquet")
    plane = plane_from_cells("wb", cells, ("w", "b"))
    look = curve_look({"kind": "period_doubling", "period": 2, "boundary": ""})
    plane.curves = [{"curve": 0, "kind": "period_doubling", "period": 2, "xname": "w",
                     "yname": "b", "x": [1.0, 1.0], "y": [0.0, 1.0], **look}]
    plane.codim2 = [{"kind": "pd_grazing", "marker": "s", "text": "doubling meets grazing",
                     "xname": "w", "yname": "b", "x": 1.6, "y": 0.5, "period": 2,
                     "converged": True, "conditions": "period_doubling; grazing x=-b"}]
    out = tmp_path / "atlas.html"
    out.write_text(explorer.render([plane], {}))
    driver = _driver(tmp_path)
    try:
        _load(driver, out.as_uri())
        px = driver.execute_script(
            "const f = window.GEARSIM.planes.wb.frame, X = Math.round(f.X(1.0)),"
            " Y = Math.round(f.Y(0.5)); return Array.from(f.ctx.getImageData(X - 1, Y, 3, 1)"
            ".data);")
        blue = np.array(_hex(look["colour"]))
        assert min(np.abs(np.array(px[k:k + 3]) - blue).sum() for k in (0, 4, 8)) < 3 * 40
        # the marker's white face at the point
        assert _pixel(driver, "wb", 1.6, 0.5) == [255, 255, 255]
        legend = driver.find_element("id", "legend-wb").text
        assert "period doubling 2T -> 4T" in legend and "doubling meets grazing (1)" in legend
        assert not [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
    finally:
        driver.quit()
