"""``gearsim query``: read-only access and the documented SQL examples."""

from __future__ import annotations

import shutil
import sqlite3
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from gearsim.cli.main import main
from gearsim.results import catalogue as gc
from gearsim.results.query import EXAMPLES, execute

ROOT = Path(__file__).resolve().parents[2]

# Synthetic wb plane, 5 (w) x 8 (b) cells on b in [0, 1]: double-sided impacts (I = 2) in the
# rows b < 0.5 (j <= 3), chaos with a positive Lyapunov exponent at two cells.
NX, NY = 5, 8


def _row(label, impact, lyap):
    return {
        "motion": "chaos" if label == "chaos" else "periodic", "status": "ok", "I": impact,
        "n": 0 if label == "chaos" else 1, "p": None if label == "chaos" else 1,
        "q": None if label == "chaos" else (1 if impact == 2 else 0), "label": label,
        "label_npq": "" if label == "chaos" else "1-1-0", "dc": 0.1, "kmax": 1.5,
        "kmax_peak_mean": 2.0, "kmax_peak_static": 1.5, "kmax_section_mean": 1.8,
        "kmax_section_static": 1.2, "kmin_peak_mean": 0.0, "lyapunov": lyap, "x_min": -1.0,
        "x_max": 1.0, "converged": label != "chaos", "window_periods": 16, "periods": 100,
        "steps": 1000, "mu_max": None, "critical": "", "refined": False, "settle": None,
    }


def _plane(tmp: Path, name: str, yname: str, lo: float, hi: float) -> Path:
    ys = lo + (np.arange(NY) + 0.5) * (hi - lo) / NY
    xs = 0.1 + (np.arange(NX) + 0.5) * 2.4 / NX
    recs = []
    for j, y in enumerate(ys):
        for i, x in enumerate(xs):
            if name == "wb" and (i, j) in ((2, 1), (3, 6)):
                r = _row("chaos", 2 if j <= 3 else 1, 0.05 + 0.01 * i)
            elif name == "wb" and j <= 3:
                r = _row("2/1T", 2, -0.1)
            else:
                r = _row("1/1T", 1, -0.1)
            recs.append({"plane": name, "tile": j // 4, "i": i, "j": j, "x": x, "y": y,
                         "w": x, yname: y, **r, "poincare_x": [0.1], "poincare_v": [0.2],
                         "elapsed_s": 0.01})
    df = pd.DataFrame(recs)
    df["p"] = df["p"].astype("Int64")
    df["q"] = df["q"].astype("Int64")
    tiles = [{"kind": "tile", "name": name, "tile": t, "config_hash": "h", "code_version": "c",
              "package_versions": {}, "tangent_seed": 1, "cells": NX * NY // 2} for t in (0, 1)]
    rec = {"name": name, "x": {"name": "w", "min": 0.1, "max": 2.5, "n": NX},
           "y": {"name": yname, "min": lo, "max": hi, "n": NY}, "fixed": {}, "parameters": {},
           "config_hash": "h", "code_version": "c"}
    return gc.write_parquet(df, tmp / f"{name}.parquet", {gc.PLANE_KEY: rec, gc.TILES_KEY: tiles})


def _sweep(tmp: Path, name: str = "standard", n: int = 6) -> Path:
    """A w sweep of n points: 1/1T then 2/1T, as `gearsim sweep` writes it."""
    ws = np.linspace(0.1, 2.5, n)
    df = pd.DataFrame([{"parameter": "w", "value": w, "direction": "forward",
                        **_row("1/1T" if k < n // 2 else "2/1T", 1 if k < n // 2 else 2, -0.1),
                        "poincare_x": [0.1], "poincare_v": [0.2]} for k, w in enumerate(ws)])
    df["p"] = df["p"].astype("Int64")
    df["q"] = df["q"].astype("Int64")
    prov = {"kind": "sweep", "name": name, "cells": n, "config_hash": "h", "code_version": "c",
            "subtree": {"sweep": {"name": "w", "min": 0.1, "max": 2.5, "n": n, "fixed": {}}}}
    return gc.write_parquet(df, tmp / f"{name}.parquet", {gc.PROVENANCE_KEY: prov})


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    d = tmp_path_factory.mktemp("q")
    files = [_plane(d, "wb", "b", 0.0, 1.0), _plane(d, "wxi", "xi", 0.04, 0.16)]
    out = d / "catalogue.sqlite"
    gc.build_catalogue(out, files, [_sweep(d)])
    return out


def test_example_patterns(db):
    cols, rows = execute(db, EXAMPLES["patterns"])
    assert cols == ["plane", "label", "cells"]
    got = {(p, lab): n for p, lab, n in rows}
    assert got == {("wb", "2/1T"): 19, ("wb", "1/1T"): 19, ("wb", "chaos"): 2,
                   ("wxi", "1/1T"): 40}


def test_example_b_threshold(db):
    cols, rows = execute(db, EXAMPLES["b-threshold"])
    assert cols == ["last_b_with_I2", "b_threshold"]
    last, threshold = rows[0]
    assert last == pytest.approx(0.4375) and threshold == pytest.approx(0.5)


def test_example_chaos(db):
    cols, rows = execute(db, EXAMPLES["chaos"])
    assert [(r[0], r[1], r[2]) for r in rows] == [("wb", 3, 6), ("wb", 2, 1)]
    assert all(r[cols.index("lyapunov")] > 0 for r in rows)


@pytest.mark.skipif(shutil.which("sqlite3") is None, reason="sqlite3 shell not installed")
@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_examples_run_in_plain_sqlite3(db, name):
    out = subprocess.run(["sqlite3", "-readonly", str(db), EXAMPLES[name]], capture_output=True,
                         text=True, check=True)
    assert out.stdout.strip() and not out.stderr
    _, rows = execute(db, EXAMPLES[name])
    assert len(out.stdout.strip().splitlines()) == len(rows)


def test_examples_are_documented():
    doc = (ROOT / "docs/pipeline.md").read_text()
    for name, sql in EXAMPLES.items():
        assert sql in doc, name


@pytest.mark.parametrize(
    "sql",
    [
        "DELETE FROM cells",
        "INSERT INTO planes(name) VALUES ('x')",
        "DROP TABLE cells",
        "PRAGMA writable_schema=ON",
        "WITH x AS (SELECT 1) DELETE FROM cells",
        "SELECT 1; DELETE FROM cells",
        "ATTACH DATABASE ':memory:' AS m",
        "SELECT * FROM cells WHERE",
    ],
)
def test_rejects_anything_but_one_select(db, sql, capsys):
    before = sqlite3.connect(db).execute("SELECT COUNT(*) FROM cells").fetchone()[0]
    assert main(["query", "--db", str(db), sql]) == 2
    err = capsys.readouterr().err
    assert err.startswith("gearsim query: error:") and err.count("\n") == 1
    assert sqlite3.connect(db).execute("SELECT COUNT(*) FROM cells").fetchone()[0] == before


def test_query_prints_a_table(db, capsys):
    assert main(["query", "--db", str(db), "SELECT name, x_n, y_n FROM planes ORDER BY name"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split() == ["name", "x_n", "y_n"] and out[2].split() == ["wb", "5", "8"]
    assert out[-1] == "(2 rows)"
    assert main(["query", "--db", str(db), "--example", "chaos", "--format", "csv"]) == 0
    assert "plane,i,j,x,y,label,lyapunov" in capsys.readouterr().out


def test_missing_catalogue(tmp_path, capsys):
    assert main(["query", "--db", str(tmp_path / "none.sqlite"), "SELECT 1"]) == 2
    assert "catalogue not found" in capsys.readouterr().err


def test_with_select_is_allowed(db):
    sql = "WITH t AS (SELECT label FROM plane_cells) SELECT COUNT(*) AS n FROM t"
    cols, rows = execute(db, sql)
    assert cols == ["n"] and rows == [(NX * NY * 2,)]


# --------------------------------------------------------------- limits and guards (14.2, 13.6)
COUNT = "SELECT i, j, label FROM plane_cells ORDER BY plane, j, i"
ENDLESS = "WITH RECURSIVE n(k) AS (SELECT 1 UNION ALL SELECT k + 1 FROM n) SELECT k FROM n"


def _gen(n):
    return f"WITH RECURSIVE n(k) AS (SELECT 1 UNION ALL SELECT k + 1 FROM n WHERE k < {n}) " \
           "SELECT k FROM n"


@pytest.mark.parametrize(
    "fmt, max_rows, sql, lines, cut",
    [
        ("csv", ["--max-rows", "-1"], COUNT, 1 + 2 * NX * NY, False),  # -1 drops no row
        ("csv", [], _gen(2500), 2501, False),  # file formats stream every row by default
        ("json", [], _gen(2500), 2 + 2500, False),
        ("csv", ["--max-rows", "10"], _gen(2500), 11, True),
        ("csv", ["--max-rows", "80"], COUNT, 81, False),  # exactly the limit: nothing cut
        ("table", [], _gen(2500), 2 + 1000 + 1, True),  # the table shows 1000 by default
        ("table", ["--max-rows", "-1"], _gen(2500), 2 + 2500 + 1, False),
        ("table", [], ENDLESS, 2 + 1000 + 1, True),  # endless CTE: the fetch is bounded
    ],
)
def test_row_limit(db, capsys, fmt, max_rows, sql, lines, cut):
    assert main(["query", "--db", str(db), "--format", fmt, *max_rows, sql]) == 0
    out, err = capsys.readouterr()
    assert len(out.splitlines()) == lines
    if cut:
        assert "output cut at" in err and err.count("\n") == 1
        if fmt == "table":
            assert out.splitlines()[-1] == "(1000 rows, more not shown)"
    else:
        assert err == ""
    if fmt == "json":
        import json

        assert [r["k"] for r in json.loads(out)] == list(range(1, 2501))


def test_max_rows_minus_one_returns_every_row(db):
    cols, rows = execute(db, COUNT)
    assert len(rows) == 2 * NX * NY == 80


@pytest.mark.parametrize(
    "args, words",
    [
        (["--format", "csv", "--max-rows", "-1", "--timeout", "1", ENDLESS], ["stopped after 1 s"]),
        (["--timeout", "1", "SELECT COUNT(*) FROM cells a, cells b, cells c, cells d, cells e"],
         ["stopped after 1 s"]),
        (["--max-rows", "-2", "SELECT 1"], ["--max-rows", "-1"]),
        (["--timeout", "0", "SELECT 1"], ["--timeout"]),
        (["--timeout", "nan", "SELECT 1"], ["--timeout"]),
        (["SELECT fts3_tokenizer('simple')"], ["only reading"]),
        (["SELECT load_extension('x')"], ["only reading"]),
        (["SELECT length(randomblob(1000000000))"], ["only reading"]),
        (["SELECT zeroblob(10)"], ["only reading"]),
        (["SELECT * FROM pragma_table_info('cells')"], ["only reading"]),
        (["SELECT writefile('x', 'y')"], ["writefile"]),
        (["-- only a comment"], ["only SELECT"]),
    ],
)
@pytest.mark.timeout(60)  # refused before SQLite runs anything: a run would take minutes
def test_refused_with_one_line(db, capsys, args, words):
    assert main(["query", "--db", str(db), *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("gearsim query: error:") and err.count("\n") == 1, err
    for w in words:
        assert w in err, (w, err)


@pytest.mark.parametrize(
    "sql, want",
    [
        ("-- how many cells\nSELECT COUNT(*) AS n FROM cells", [(80,)]),
        ("/* block */ SELECT COUNT(*) AS n FROM cells -- trailing", [(80,)]),
        ("SELECT round(abs(-1.26), 1) AS v", [(1.3,)]),
        ("SELECT json_extract(fixed, '$') AS v FROM planes WHERE name = 'wb'", [("{}",)]),
        ("SELECT group_concat(DISTINCT label) AS v FROM cells WHERE impact = 2 AND label = '2/1T'",
         [("2/1T",)]),
        ("SELECT COUNT(*) FROM (SELECT row_number() OVER (ORDER BY id) FROM cells)", [(80,)]),
        ("SELECT unit FROM column_dictionary WHERE table_name = 'cells' AND column_name = 'x_max'",
         [("1 (X_n / b_c)",)]),
    ],
)
def test_allowed_reads(db, sql, want):
    assert execute(db, sql)[1] == want


def test_blob_and_non_finite_values_in_json_and_csv(db, capsys):
    import json

    sql = "SELECT x'00ff10' AS b, 1e999 AS big, 'text' AS t"
    assert main(["query", "--db", str(db), "--format", "json", sql]) == 0
    assert json.loads(capsys.readouterr().out) == [{"b": "AP8Q", "big": None, "t": "text"}]
    assert main(["query", "--db", str(db), "--format", "csv", sql]) == 0
    assert capsys.readouterr().out.splitlines() == ["b,big,t", "AP8Q,,text"]
    assert main(["query", "--db", str(db), sql]) == 0
    assert "<3 bytes>" in capsys.readouterr().out


@pytest.mark.parametrize("fmt", ["table", "csv", "json"])
def test_closed_pipe_is_quiet(db, fmt):
    """`gearsim query ... | head -1`: the reader leaves early; no traceback, no error."""
    import os
    import sys

    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    proc = subprocess.Popen(
        [sys.executable, "-m", "gearsim", "query", "--db", str(db), "--format", fmt,
         "--max-rows", "-1", _gen(200_000)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    proc.stdout.readline()
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 0
    assert err == "", err


def test_plane_and_sweep_views_speak_the_study_names(tmp_path):
    """A view per plane named after it with its axis names as columns, holding exactly the
    plane's cells; a view per sweep with the swept parameter's name; both in the column
    dictionary; an axis given in physical units gets its physical column."""
    d = tmp_path
    files = [_plane(d, "wb", "b", 0.0, 1.0), _plane(d, "wxi", "xi", 0.04, 0.16)]
    out = d / "catalogue.sqlite"
    gc.build_catalogue(out, files)
    con = sqlite3.connect(out)
    got = con.execute("select w, b, label from wb where w between 0.3 and 0.6 and b > 0.5 "
                      "order by b").fetchall()
    ref = con.execute("select c.x, c.y, c.label from cells c join planes p on p.id = "
                      "c.plane_id where p.name = 'wb' and c.x between 0.3 and 0.6 and c.y > 0.5 "
                      "order by c.y").fetchall()
    assert got == ref and len(got) == 4  # i = 1 (w = 0.58), rows j = 4..7
    assert con.execute("select count(*) from wxi").fetchone()[0] == NX * NY
    assert con.execute("select min(xi), max(xi) from wxi").fetchone() == pytest.approx(
        (0.04 + 0.5 * 0.12 / NY, 0.16 - 0.5 * 0.12 / NY))
    docs = dict(con.execute("select column_name, unit from column_dictionary "
                            "where table_name = 'wb'").fetchall())
    assert docs["b"] == "1 (B / b_c)" and docs["label"] == "" and "*" in docs
    con.close()
    assert main(["query", "select w, b, label from wb where w between 0.3 and 0.6 and b > 0.5",
                 "--catalogue", str(out)]) == 0


def test_view_names_never_shadow_a_table(tmp_path):
    """A plane named like a table or view of the catalogue gets the prefix plane_ (again, while
    the name is taken)."""
    g = _plane(tmp_path, "cells", "b", 0.0, 1.0)
    out = tmp_path / "c.sqlite"
    gc.build_catalogue(out, [g])
    con = sqlite3.connect(out)
    names = {r[0] for r in con.execute("select name from sqlite_master where type = 'view'")}
    assert "plane_cells" in names  # the existing joined view keeps its name
    assert con.execute("select count(*), min(b) >= 0 from plane_plane_cells").fetchone() == (
        NX * NY, 1)
    con.close()


def test_readme_view_query_runs(tmp_path, capsys):
    """The README's query by the plane's own names runs on a catalogue of a (w, b) plane and
    returns exactly the cells of that window."""
    import sqlite3

    from test_readme_commands import bash_gearsim_lines

    out = tmp_path / "catalogue.sqlite"
    gc.build_catalogue(out, [_plane(tmp_path, "wb", "b", 0.0, 1.0)])
    sql = next(a[1] for a in bash_gearsim_lines((ROOT / "README.md").read_text())
               if a[0] == "query" and "from wb" in a[1])
    assert main(["query", sql.replace("between 1.0 and 1.01", "between 0.8 and 0.9"),
                 "--catalogue", str(out), "--format", "csv"]) == 0
    rows = capsys.readouterr().out.strip().splitlines()
    con = sqlite3.connect(out)
    want = con.execute("select count(*) from cells where x between 0.8 and 0.9 and y > 0.9"
                       ).fetchone()[0]
    con.close()
    assert rows[0] == "w,b,label" and len(rows) - 1 == want > 0


def test_plane_view_has_physical_columns_with_a_gear(tmp_path):
    """A plane record with the gear's factors (a study with a gear file) gives the view the
    physical column of each axis with a physical meaning: speed_rpm = k * w."""
    from gearsim.physical.units import load_gear, physical_factors

    gear = load_gear(ROOT / "config/gears/standard.yaml")
    f = _plane(tmp_path, "wb", "b", 0.0, 1.0)
    rec = gc.read_metadata(f, gc.PLANE_KEY)
    rec["physical"] = physical_factors(gear, ["w", "b"])
    g = gc.write_parquet(pd.read_parquet(f), tmp_path / "wb_gear.parquet",
                         {gc.PLANE_KEY: rec, gc.TILES_KEY: gc.read_metadata(f, gc.TILES_KEY)})
    out = tmp_path / "c.sqlite"
    gc.build_catalogue(out, [g])
    con = sqlite3.connect(out)
    rows = con.execute("select w, speed_rpm, b, half_backlash_um from wb").fetchall()
    units = dict(con.execute("select column_name, unit from column_dictionary "
                             "where table_name = 'wb'").fetchall())
    con.close()
    # the standard gear: w = 1 at its speed_rpm, b = 1 at 10 um (b_c)
    for w, rpm, b, um in rows:
        assert rpm == pytest.approx(w * gear.speed_rpm, rel=1e-9)
        assert um == pytest.approx(b * gear.nominal_length_um, rel=1e-9)
    assert units["speed_rpm"] == "rpm" and units["half_backlash_um"] == "um"


def test_example_sweep_view(db):
    """The sweep's view: its points in order with the swept parameter's name."""
    cols, rows = execute(db, EXAMPLES["sweep-view"])
    assert cols[:2] == ["w", "label"]
    assert [r[0] for r in rows] == pytest.approx(list(np.linspace(0.1, 2.5, 6)))
    assert [r[1] for r in rows] == ["1/1T"] * 3 + ["2/1T"] * 3
