"""Scale of the catalogue path: a 2000 x 2000 plane through tiles -> cells.parquet
-> catalogue in bounded memory.

The tiles are hand-built (``tests/synthetic_tiles.py``: every column of a simulated tile,
deterministic values from (i, j)) and written through the real tile writer with the real
provenance; only the simulation is skipped (4 million cells at a tiny integration budget would
still take days on 2 cores). Each step then runs as the workflow runs it, as its own
``gearsim catalogue`` process, and the script records its wall time and peak resident memory
(``ru_maxrss`` of the child, from ``os.wait4``):

* ``gearsim catalogue cells``: check and stream the tiles into ``cells.parquet``;
* ``gearsim catalogue build --publish``: check and stream ``cells.parquet`` into the SQLite
  catalogue, build its indexes, publish it.

Target: peak RSS of each step < 2 GiB. Writes ``results/catalogue.json``.

    python benchmarks/bench_catalogue.py               # 2000 x 2000, 40-row tiles (50 tiles)
    python benchmarks/bench_catalogue.py --quick       # 400 x 400
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import loadavg, save, setup_env  # noqa: E402

GIB = 1024**3


def run_child(args: list[str], cwd: Path) -> dict:
    """Run ``gearsim ARGS`` as a child; wall time, peak RSS (bytes) and exit status."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "gearsim", *args], cwd=cwd, env=env,
                            stderr=subprocess.PIPE, text=True)
    err = proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"gearsim {' '.join(args[:2])} failed:\n{err}")
    return {
        "wall_s": round(wall, 2),
        "cpu_s": round(usage.ru_utime + usage.ru_stime, 2),
        "peak_rss_bytes": usage.ru_maxrss * 1024,
        "peak_rss_gib": round(usage.ru_maxrss * 1024 / GIB, 3),
        "stderr": err.strip().splitlines()[-1] if err.strip() else "",
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nx", type=int, default=2000)
    ap.add_argument("--ny", type=int, default=2000)
    ap.add_argument("--tile-rows", type=int, default=40)
    ap.add_argument("--quick", action="store_true", help="400 x 400")
    ap.add_argument("--workdir", default=None, help="keep the files here (default: a temp dir)")
    args = ap.parse_args(argv)
    if args.quick:
        args.nx = args.ny = 400
    setup_env()
    from synthetic_tiles import write_tile

    from gearsim.results import catalogue as gc
    from gearsim.study import config as gcfg
    from gearsim.study import grid as ggrid

    work = Path(args.workdir or tempfile.mkdtemp(prefix="bench_catalogue_"))
    work.mkdir(parents=True, exist_ok=True)
    try:
        plane = {"x": {"name": "w", "min": 0.1, "max": 2.5, "n": args.nx},
                 "y": {"name": "b", "min": 0.0, "max": 1.0, "n": args.ny}, "fixed": {}}
        cfg_file = work / "scale.yaml"
        cfg_file.write_text(yaml.safe_dump({"tile_rows": args.tile_rows,
                                            "planes": {"scale": plane}}))
        cfg = gcfg.load_config([ROOT / "config/config.yaml", cfg_file], root=ROOT)
        load0 = loadavg()
        t0 = time.perf_counter()
        tiles = [write_tile(cfg, "scale", t, work / f"tiles/{t}.parquet")
                 for t in ggrid.tile_ids(cfg, "scale")]
        write_s = time.perf_counter() - t0
        tile_bytes = sum(p.stat().st_size for p in tiles)
        print(f"{len(tiles)} tiles, {args.nx * args.ny} cells, {tile_bytes / 1e6:.0f} MB "
              f"written in {write_s:.1f} s", file=sys.stderr)
        cells = work / "cells.parquet"
        combine = run_child(["catalogue", "cells", "--plane", "scale", "--tiles",
                             *map(str, tiles), "--configfile", str(ROOT / "config/config.yaml"),
                             str(cfg_file), "--out", str(cells)], cwd=ROOT)
        print(f"catalogue cells: {combine}", file=sys.stderr)
        build, pub = work / "catalogue.d/build.sqlite", work / "catalogue.sqlite"
        catalogue = run_child(["catalogue", "build", "--cells", str(cells), "--out", str(build),
                               "--publish", str(pub)], cwd=work)
        print(f"catalogue build: {catalogue}", file=sys.stderr)
        con = gc.open_catalogue(pub)
        n, distinct = con.execute(
            "SELECT COUNT(*), COUNT(DISTINCT j * 100000 + i) FROM cells").fetchone()
        t1 = time.perf_counter()
        q = con.execute("SELECT COUNT(*) FROM cells WHERE plane_id = 1 AND label = '2/1T'")
        label_count = q.fetchone()[0]
        query_s = time.perf_counter() - t1
        con.close()
        assert n == distinct == args.nx * args.ny, (n, distinct)
        assert label_count == args.nx * args.ny // 2
        payload = {
            "plane": f"{args.nx} x {args.ny}",
            "cells": n,
            "tiles": len(tiles),
            "tile_rows": args.tile_rows,
            "tiles_mb": round(tile_bytes / 1e6, 1),
            "cells_parquet_mb": round(cells.stat().st_size / 1e6, 1),
            "catalogue_mb": round(pub.stat().st_size / 1e6, 1),
            "write_tiles_s": round(write_s, 1),
            "catalogue_cells": combine,
            "catalogue_build": catalogue,
            "indexed_label_count_s": round(query_s, 3),
            "target_peak_rss_gib": 2.0,
            "target_met": max(combine["peak_rss_gib"], catalogue["peak_rss_gib"]) < 2.0,
            "load_before": load0,
            "load_after": loadavg(),
        }
        path = save("catalogue" if not args.quick else "catalogue_quick", payload)
        print(f"-> {path}", file=sys.stderr)
    finally:
        if args.workdir is None:
            shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
