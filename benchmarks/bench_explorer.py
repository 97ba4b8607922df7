"""The explorer page: its size and its load time in headless chromium (benchmarks/CHANGELOG.md,
"Explorer page").

    python benchmarks/bench_explorer.py page --results results --configfile config/config.yaml
        the page of a finished run (default: the default run's results/)
    python benchmarks/bench_explorer.py stand-in --source RESULTS --plane wb --n 400
        a stand-in for the default run when it has not been computed: each of the default
        planes (wb, wxi) as an n x n plane made from the source run's plane of that name (e.g.
        the quick run's 40 x 40 planes), else from --plane (its
        regions, labels, chaotic cells and section points; values interpolated between its
        cells with cell-to-cell scatter, section points jittered so that no two cells share
        them), plus the source run's sweeps; --all-chaotic: the worst case for the page size,
        every cell chaotic with 16 distinct random section points (the page's point budget
        then caps the points per cell)

    python benchmarks/bench_explorer.py compare PAGE_A PAGE_B
        two pages side by side in one run (e.g. the default run's page of a baseline clone and
        the page built from the same catalogue with this checkout): bytes and load times,
        alternating loads; writes benchmarks/results/explorer_compare.json

    python benchmarks/bench_explorer.py readout PAGE --catalogue CAT --cells 20
        hovers CELLS random cells of every plane of a page in headless chromium (a mouse
        event at each cell's centre) and compares the readout's DC, Kmax and lambda with the
        catalogue's values to the digits shown; writes benchmarks/results/explorer_readout.json

Load time: from navigation start to the page's "ready" mark (the data inflated and every map
and diagram drawn; ``performance.now()``), median of 5 loads in a fresh headless chromium
(1500 x 1100), and the wall time of ``driver.get`` + ready as selenium sees it. Writes
``benchmarks/results/explorer.json`` (``explorer_worst.json`` for --all-chaotic).
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, loadavg  # noqa: E402

FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--window-size=1500,1100")


def load_times(path: Path, repeats: int = 5) -> dict:
    """Median load time of the page (ms to the ready mark, and wall seconds)."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    ready, wall = [], []
    for _ in range(repeats):
        profile = tempfile.mkdtemp(prefix="bench-explorer-")
        opts = webdriver.ChromeOptions()
        opts.binary_location = shutil.which("chromium")
        for flag in (*FLAGS, f"--user-data-dir={profile}"):
            opts.add_argument(flag)
        opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
        driver = webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=opts)
        try:
            t0 = time.perf_counter()
            driver.get(path.resolve().as_uri())
            while driver.execute_script("return document.body.dataset.ready") != "1":
                time.sleep(0.01)
            wall.append(time.perf_counter() - t0)
            ready.append(driver.execute_script("return window.GEARSIM.readyAt"))
            errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
            if errors:
                raise RuntimeError(f"console errors: {errors}")
        finally:
            driver.quit()
            shutil.rmtree(profile, ignore_errors=True)
    return {"ready_ms_median": statistics.median(ready), "ready_ms": ready,
            "wall_s_median": statistics.median(wall), "wall_s": wall}


def _upsample(cells: pd.DataFrame, axes: tuple[str, str], n: int, ranges, rng
              ) -> pd.DataFrame:
    """An n x n plane from a computed one (see the module docstring)."""
    from scipy.interpolate import RegularGridInterpolator

    xname, yname = axes
    nx0, ny0 = int(cells["i"].max()) + 1, int(cells["j"].max()) + 1
    src = cells.set_index(["j", "i"]).sort_index()
    ii = np.minimum((np.arange(n) + 0.5) * nx0 // n, nx0 - 1).astype(int)
    jj = np.minimum((np.arange(n) + 0.5) * ny0 // n, ny0 - 1).astype(int)
    J, I = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    rows = src.loc[list(zip(jj[J.ravel()], ii[I.ravel()], strict=True))].reset_index()
    gx = (np.arange(nx0) + 0.5) / nx0
    gy = (np.arange(ny0) + 0.5) / ny0
    fx, fy = (I.ravel() + 0.5) / n, (J.ravel() + 0.5) / n
    pts = np.column_stack([np.clip(fy, gy[0], gy[-1]), np.clip(fx, gx[0], gx[-1])])
    out = rows.copy()
    for col in ("dc", "kmax", "kmax_peak_mean", "lyapunov"):
        if col not in cells.columns:
            continue
        grid = src[col].astype(float).unstack("i").to_numpy()
        grid = np.where(np.isfinite(grid), grid, np.nanmean(grid))
        v = RegularGridInterpolator((gy, gx), grid)(pts)
        out[col] = v * (1 + 1e-3 * rng.standard_normal(len(v)))
    out["i"], out["j"] = I.ravel(), J.ravel()
    (x0, x1), (y0, y1) = ranges
    out[xname] = x0 + fx * (x1 - x0)
    out[yname] = y0 + fy * (y1 - y0)

    def jitter(a):
        a = np.asarray(a if a is not None else [], dtype=float)
        return (a * (1 + 1e-4 * rng.standard_normal(len(a)))).tolist()

    out["poincare_x"] = [jitter(a) for a in out["poincare_x"]]
    out["poincare_v"] = [jitter(a) for a in out["poincare_v"]]
    return out


def stand_in(args) -> tuple[Path, dict]:
    from gearsim.presentation.explorer import write_explorer
    from gearsim.presentation.figures.data import plane_axes

    src = Path(args.source)
    rng = np.random.default_rng(0)
    work = Path(tempfile.mkdtemp(prefix="bench-explorer-results-"))
    planes = {"wb": ("w", "b"), "wxi": ("w", "xi")}
    ranges = {"wb": ((0.1, 2.5), (0.0, 1.0)), "wxi": ((0.1, 2.5), (0.04, 0.16))}
    used, chaotic = {}, 0
    for name, ax in planes.items():
        # the source run's plane of the same name (e.g. the quick run's wb), else --plane
        source = name if (src / name / "cells.parquet").is_file() else args.plane
        used[name] = source
        cells = pd.read_parquet(src / source / "cells.parquet")
        axes = plane_axes(cells)
        df = _upsample(cells, axes, args.n, ranges[name], rng)
        if args.all_chaotic:
            df["motion"], df["label"], df["label_npq"], df["n"] = "chaos", "chaos", "", 0
            df["poincare_x"] = list(rng.uniform(-1.5, 1.5, (len(df), 16)))
            df["poincare_v"] = list(rng.uniform(-0.5, 0.5, (len(df), 16)))
        df = df.rename(columns={axes[0]: "w_src", axes[1]: "y_src"})
        df[ax[0]], df[ax[1]] = df["w_src"], df["y_src"]
        chaotic += int((df["motion"] != "periodic").sum())
        (work / name).mkdir(parents=True)
        df.drop(columns=["w_src", "y_src"]).to_parquet(work / name / "cells.parquet")
    sweeps = sorted(p.stem for p in (src / "sweeps").glob("*.parquet"))
    (work / "sweeps").mkdir()
    for s in sweeps:
        shutil.copy(src / "sweeps" / f"{s}.parquet", work / "sweeps" / f"{s}.parquet")
    out = Path(args.out)
    t0 = time.perf_counter()
    write_explorer(out, planes=planes, sweeps=sweeps, results=work, catalogue=None)
    build = time.perf_counter() - t0
    shutil.rmtree(work, ignore_errors=True)
    return out, {"kind": "stand-in" + (" (all chaotic)" if args.all_chaotic else ""),
                 "source": {k: str(src / v) for k, v in used.items()}, "n": args.n,
                 "chaotic_share": chaotic / (2 * args.n * args.n),
                 "cells": 2 * args.n * args.n, "sweeps": sweeps, "build_s": build}


def page(args) -> tuple[Path, dict]:
    from gearsim.cli.main import main

    out = Path(args.out)
    t0 = time.perf_counter()
    rc = main(["explorer", "--results", args.results, "--catalogue", args.catalogue,
               "--configfile", *args.configfile, "-o", str(out)])
    if rc:
        raise SystemExit(rc)
    return out, {"kind": "run", "results": args.results, "configfile": args.configfile,
                 "build_s": time.perf_counter() - t0}


def compare(pages: list[str], repeats: int) -> dict:
    """Bytes and load times of pages, side by side: the loads alternate (page a, page b, ...)
    so both see the same machine load."""
    runs: dict[str, list[dict]] = {p: [] for p in pages}
    for _ in range(repeats):
        for p in pages:
            runs[p].append(load_times(Path(p), 1))
    out = {}
    for p, rs in runs.items():
        ready = [r["ready_ms"][0] for r in rs]
        out[p] = {"bytes": Path(p).stat().st_size, "ready_ms": ready,
                  "ready_ms_median": statistics.median(ready)}
    return out


def readout(page_path: Path, catalogue: str, cells: int, seed: int,
            motions: tuple[str, ...] = ()) -> dict:
    """Hover ``cells`` random cells of every plane of the page; each readout value against the
    catalogue's, formatted to the digits the page shows."""
    import re

    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    from gearsim.results.catalogue import open_catalogue

    con = open_catalogue(catalogue)
    cat = pd.read_sql_query("select p.name as plane, c.i, c.j, c.x, c.y, c.motion, c.dc, "
                            "c.kmax, c.lyapunov from cells c join planes p on "
                            "c.plane_id = p.id", con)
    con.close()
    profile = tempfile.mkdtemp(prefix="bench-explorer-")
    opts = webdriver.ChromeOptions()
    opts.binary_location = shutil.which("chromium")
    for flag in (*FLAGS, f"--user-data-dir={profile}"):
        opts.add_argument(flag)
    driver = webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=opts)
    rng = np.random.default_rng(seed)
    out: dict = {}
    try:
        driver.get(page_path.resolve().as_uri())
        deadline = time.monotonic() + 120
        while driver.execute_script("return document.body.dataset.ready") != "1":
            if time.monotonic() > deadline:
                raise SystemExit("the page never finished drawing")
            time.sleep(0.1)
        for plane in driver.execute_script("return Object.keys(window.GEARSIM.planes);"):
            rows = cat[cat["plane"] == plane]
            if motions:
                rows = rows[rows["motion"].isin(motions)]
            rec = []
            for _, r in rows.iloc[rng.choice(len(rows), size=min(cells, len(rows)),
                                              replace=False)].iterrows():
                # a 400 x 400 plane's cells are about a pixel wide on the map, and mouse events
                # land on whole pixels: zoom in about the cell with the wheel (as a user does)
                # until it is several pixels wide, then move the mouse to it; a double click
                # shows the whole plane again
                driver.execute_script(
                    "const name = arguments[0], x = arguments[1], y = arguments[2];"
                    "const c = document.getElementById('map-' + name);"
                    "c.scrollIntoView({block: 'center'});"
                    "const at = (type, extra) => { const r = c.getBoundingClientRect(),"
                    " [dx, dy] = window.GEARSIM.pixelOf(name, x, y);"
                    " c.dispatchEvent(new (type === 'wheel' ? WheelEvent : MouseEvent)(type,"
                    " Object.assign({bubbles: true, cancelable: true, clientX: r.left +"
                    " r.width / 2 + dx, clientY: r.top + r.height / 2 + dy}, extra))); };"
                    "for (let k = 0; k < 12; k++) at('wheel', {deltaY: -100});"
                    "at('mousemove', {});"
                    "c.dispatchEvent(new MouseEvent('dblclick', {bubbles: true}));",
                    plane, float(r["x"]), float(r["y"]))
                hover = driver.execute_script("return window.GEARSIM.hover")
                text = driver.find_element("id", "cell").text
                shown = {k: re.search(rf"{k} = (.+?)(?:   |\n|$)", text).group(1)
                         for k in ("DC", "Kmax", "λ")}
                want = {k: (f"{r[c]:.{d}f}" if np.isfinite(r[c]) else "none")
                        for k, c, d in (("DC", "dc", 4), ("Kmax", "kmax", 4),
                                        ("λ", "lyapunov", 5))}
                same = (hover == f"{plane}:{r['i']}:{r['j']}" and all(
                    shown[k].split(" ")[0] == want[k] for k in want))
                rec.append({"i": int(r["i"]), "j": int(r["j"]), "motion": r["motion"],
                            "shown": shown, "catalogue": want, "hover": hover, "equal": same})
            out[plane] = {"cells": len(rec), "equal": sum(x["equal"] for x in rec),
                          "rows": rec}
    finally:
        driver.quit()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="what", required=True)
    c = sub.add_parser("compare", help="two pages side by side")
    c.add_argument("pages", nargs=2)
    c.add_argument("--repeats", type=int, default=5)
    a = sub.add_parser("page", help="the page of a finished run")
    a.add_argument("--results", default="results")
    a.add_argument("--catalogue", default="results/catalogue.sqlite")
    a.add_argument("--configfile", nargs="+", default=["config/config.yaml"])
    r = sub.add_parser("readout", help="random cells' readouts against the catalogue")
    r.add_argument("page")
    r.add_argument("--catalogue", default="results/catalogue.sqlite")
    r.add_argument("--cells", type=int, default=20)
    r.add_argument("--seed", type=int, default=54)
    r.add_argument("--motion", nargs="+", default=(),
                   help="sample only cells of these motions (e.g. diverged unsettled)")
    b = sub.add_parser("stand-in", help="a stand-in for the default run's two planes")
    b.add_argument("--source", required=True, help="results directory of a computed run")
    b.add_argument("--plane", required=True,
                   help="the plane of that run to upsample where it has no plane of the "
                   "default's name (wb, wxi)")
    b.add_argument("--n", type=int, default=400, help="cells per axis (the default run: 400)")
    b.add_argument("--all-chaotic", action="store_true",
                   help="every cell chaotic with 16 random section points (the size's worst case)")
    for p in (a, b):
        p.add_argument("-o", "--out", default=str(RESULTS / "explorer.html"))
        p.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    before = loadavg()
    if args.what == "readout":
        rec = {"page": args.page, "catalogue": args.catalogue, "seed": args.seed,
               "motions": list(args.motion),
               "planes": readout(Path(args.page), args.catalogue, args.cells, args.seed,
                                 tuple(args.motion))}
        RESULTS.mkdir(exist_ok=True)
        name = "explorer_readout" + ("_" + "_".join(args.motion) if args.motion else "")
        (RESULTS / f"{name}.json").write_text(json.dumps(rec, indent=1))
        for plane, r in rec["planes"].items():
            print(f"{plane}: {r['equal']} of {r['cells']} random cells show the catalogue's "
                  "DC, Kmax and lambda to the last shown digit")
        return
    if args.what == "compare":
        rec = {"pages": compare(args.pages, args.repeats), "load_before": before,
               "load_after": loadavg(), "targets": {"MB": 5.0, "load_s": 2.0}}
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / "explorer_compare.json").write_text(json.dumps(rec, indent=1))
        for p, r in rec["pages"].items():
            print(f"{p}: {r['bytes'] / 1e6:.2f} MB, ready after {r['ready_ms_median']:.0f} ms "
                  f"(median of {args.repeats})")
        print(f"load {before} -> {rec['load_after']}")
        return
    out, info = stand_in(args) if args.what == "stand-in" else page(args)
    size = out.stat().st_size
    times = load_times(out, args.repeats)
    rec = {**info, "bytes": size, "MB": round(size / 1e6, 3), **times,
           "load_before": before, "load_after": loadavg(),
           "targets": {"MB": 5.0, "load_s": 2.0}}
    RESULTS.mkdir(exist_ok=True)
    name = "explorer_worst.json" if getattr(args, "all_chaotic", False) else "explorer.json"
    (RESULTS / name).write_text(json.dumps(rec, indent=1))
    print(f"{info['kind']}: {size / 1e6:.2f} MB, ready after {times['ready_ms_median']:.0f} ms "
          f"(median of {args.repeats}; wall {times['wall_s_median']:.2f} s); load "
          f"{before} -> {rec['load_after']}")


if __name__ == "__main__":
    main()
