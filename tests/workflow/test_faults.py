"""Faults of the machine and of the files, made real: a tmpfs that fills up, a read-only bind
mount, random bytes in place of a catalogue or a table, catalogues of older and newer schema
versions. Each gives one line naming the file and the cause and exit 2 (or a repaired result),
and the previous good outputs stay as they were."""

from __future__ import annotations

import gzip
import os
import shutil
import sqlite3
import subprocess
import time
from pathlib import Path

import pytest
import yaml
from synthetic_tiles import write_tile

from gearsim.cli.commands.catalogue import plane_record
from gearsim.results import catalogue as gc
from gearsim.study import config as gcfg
from gearsim.study import grid as ggrid

ROOT = next(p for p in Path(__file__).resolve().parents if (p / "pyproject.toml").is_file())
#: a catalogue built by the previous release (schema version 2, gearsim 06d135c) from the
#: synthetic 4 x 4 wb plane of tests/synthetic_tiles.py
V2_CATALOGUE = ROOT / "tests/data/catalogue_v2.sqlite.gz"


@pytest.fixture()
def gearsim(capsys, monkeypatch):
    """Run the CLI in-process from ``cwd``; returns ``(exit status, stderr)``."""
    from gearsim.cli.main import main

    def run(args, cwd):
        monkeypatch.chdir(cwd)
        capsys.readouterr()
        code = main([str(a) for a in args])
        return code, capsys.readouterr().err

    return run


def one_line(code, err, *words):
    assert code == 2, (code, err[-2000:])
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, (w, err)


def _can_mount() -> bool:
    return os.geteuid() == 0 and shutil.which("mount") is not None


needs_root = pytest.mark.skipif(not _can_mount(), reason="needs root to mount a tmpfs / bind")


@pytest.fixture()
def mounts():
    """Mount helper; every mount is undone at the end."""
    done: list[Path] = []

    def mount(*args: str, target: Path) -> Path:
        target.mkdir(parents=True, exist_ok=True)
        r = subprocess.run(["mount", *args, str(target)], capture_output=True, text=True)
        if r.returncode != 0:
            pytest.skip(f"cannot mount here: {r.stderr.strip()}")
        done.append(target)
        return target

    yield mount
    for t in reversed(done):
        subprocess.run(["umount", "-l", str(t)], capture_output=True)


def tmpfs(mounts, target: Path, size: str) -> Path:
    return mounts("-t", "tmpfs", "-o", f"size={size}", "tmpfs", target=target)


def read_only(mounts, source: Path, target: Path) -> Path:
    source.mkdir(parents=True, exist_ok=True)
    mounts("--bind", "-o", "ro", str(source), target=target)
    try:  # older mount(8) ignores ro on the first bind: remount
        (target / ".w").write_text("")
    except OSError:
        return target
    (target / ".w").unlink()
    subprocess.run(["mount", "-o", "remount,bind,ro", str(target)], check=True)
    return target


def fill(folder: Path, leave: int) -> None:
    """Fill the file system of ``folder`` until about ``leave`` bytes are free."""
    st = os.statvfs(folder)
    free = st.f_bavail * st.f_frsize
    with open(folder / "filler", "wb") as f:
        try:
            f.write(b"\0" * max(free - leave, 0))
        except OSError:
            pass


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """A 4 x 4 wb plane in 2 synthetic tiles, its cells.parquet and a catalogue."""
    d = tmp_path_factory.mktemp("faults")
    over = {"tile_rows": 2, "planes": {"wb": {
        "x": {"name": "w", "min": 0.1, "max": 2.5, "n": 4},
        "y": {"name": "b", "min": 0.0, "max": 1.0, "n": 4}, "fixed": {}}}}
    (d / "study.yaml").write_text(yaml.safe_dump(over))
    files = [ROOT / "config/config.yaml", ROOT / "config/tiny.yaml", d / "study.yaml"]
    cfg = gcfg.load_config(files, root=ROOT)
    tiles = [write_tile(cfg, "wb", t, d / f"{t}.parquet") for t in ggrid.tile_ids(cfg, "wb")]
    cells = gc.combine_tiles(tiles, d / "cells.parquet", plane_record(gcfg.Study.of(cfg), "wb"))
    cat = d / "catalogue.sqlite"
    gc.build_catalogue(cat, [cells])
    return {"dir": d, "cfg": cfg, "files": files, "tiles": tiles, "cells": cells, "cat": cat}


def _cells(db: Path) -> list[tuple]:
    con = sqlite3.connect(db)
    try:
        return con.execute("SELECT i, j, x, y, label, impact, dc, kmax FROM cells "
                           "ORDER BY j, i").fetchall()
    finally:
        con.close()


# ------------------------------------------------------------------ schema versions
def _v2(tmp_path: Path) -> Path:
    db = tmp_path / "catalogue.sqlite"
    db.write_bytes(gzip.decompress(V2_CATALOGUE.read_bytes()))
    return db


def test_previous_release_catalogue_is_refused_then_migrated(tmp_path, gearsim, study):
    db = _v2(tmp_path)
    before = _cells(db)
    assert len(before) == 16
    code, err = gearsim(["query", "--catalogue", db, "SELECT COUNT(*) FROM cells"], tmp_path)
    one_line(code, err, str(db), "schema version 2", "reads version 4",
             f"gearsim catalogue migrate {db}")
    code, err = gearsim(["catalogue", "migrate", db], tmp_path)
    assert code == 0, err
    assert "migrated from version 2 to schema version 4" in err
    con = gc.open_catalogue(db)
    try:
        assert con.execute("PRAGMA user_version").fetchone()[0] == gc.SCHEMA_VERSION == 4
        assert {s for (s,) in con.execute("SELECT status FROM runs")} == {"ok"}
        info = dict(con.execute("SELECT key, value FROM catalogue_info"))
        assert info["schema_version"] == "4"
        doc = con.execute("SELECT unit FROM column_dictionary WHERE table_name = 'runs' "
                          "AND column_name = 'status'").fetchall()
        assert len(doc) == 1
    finally:
        con.close()
    # the data are those of the release, and the same as a fresh build of the same tiles
    assert _cells(db) == before == _cells(study["cat"])
    # the plane's view, as a build makes it
    con = gc.open_catalogue(db)
    try:
        assert con.execute("SELECT COUNT(*), MIN(w), MAX(b) FROM wb").fetchone() == \
            gc.open_catalogue(study["cat"]).execute(
                "SELECT COUNT(*), MIN(w), MAX(b) FROM wb").fetchone()
    finally:
        con.close()
    # a second migration has nothing to do; the file is unchanged
    data = db.read_bytes()
    code, err = gearsim(["catalogue", "migrate", db], tmp_path)
    assert code == 0 and "already at schema version 4" in err
    assert db.read_bytes() == data


def test_older_version_2_without_orbit_tables_is_migrated(tmp_path, gearsim):
    """Early version-2 catalogues had no attractor and orbit tables and no n_attractors."""
    db = _v2(tmp_path)
    con = sqlite3.connect(db)
    for t in ("attractors", "bifurcation_points", "bifurcation_curves", "cell_orbits"):
        con.execute(f"DROP TABLE {t}")
    con.execute("DROP VIEW plane_cells")  # c.* of a view is fixed when it is created
    con.execute("ALTER TABLE cells DROP COLUMN n_attractors")
    con.execute("CREATE VIEW plane_cells AS SELECT p.name AS plane, p.x_name, p.y_name, c.* "
                "FROM cells c JOIN planes p ON p.id = c.plane_id")
    con.commit()
    con.close()
    code, err = gearsim(["catalogue", "migrate", db], tmp_path)
    assert code == 0, err
    con = gc.open_catalogue(db)
    try:
        names = {r[0] for r in con.execute("SELECT name FROM sqlite_master")}
        assert gc.REQUIRED <= names
        assert con.execute("SELECT COUNT(*) FROM cells WHERE n_attractors IS NULL"
                           ).fetchone()[0] == 16
        assert con.execute("SELECT COUNT(*) FROM plane_cells").fetchone()[0] == 16
    finally:
        con.close()


@pytest.mark.parametrize("version, words", [
    (1, ["schema version 1", "too old to migrate", "rebuild"]),
    (5, ["schema version 5", "newer gearsim"]),
])
def test_other_versions_are_refused_in_one_line(tmp_path, gearsim, study, version, words):
    db = tmp_path / "catalogue.sqlite"
    shutil.copyfile(study["cat"], db)
    con = sqlite3.connect(db)
    con.execute(f"PRAGMA user_version = {version}")
    con.commit()
    con.close()
    data = db.read_bytes()
    one_line(*gearsim(["catalogue", "migrate", db], tmp_path), str(db), *words)
    one_line(*gearsim(["query", "--catalogue", db, "SELECT 1"], tmp_path), str(db),
             f"schema version {version}")
    assert db.read_bytes() == data


# ------------------------------------------------------------------ damaged catalogues
def _damage_pages(db: Path) -> None:
    """Random bytes over pages in the middle of a valid catalogue (header intact)."""
    n = db.stat().st_size
    with open(db, "r+b") as f:
        f.seek((n // 2) // 4096 * 4096)
        f.write(os.urandom(3 * 4096))


@pytest.mark.parametrize("how", ["random-file", "damaged-pages"])
@pytest.mark.parametrize("command", ["query", "export"])
def test_damaged_catalogue_is_refused_by_readers(tmp_path, gearsim, study, how, command):
    db = tmp_path / "catalogue.sqlite"
    if how == "random-file":
        db.write_bytes(os.urandom(200_000))
    else:
        shutil.copyfile(study["cat"], db)
        _damage_pages(db)
    data = db.read_bytes()
    args = (["query", "--catalogue", db, "SELECT COUNT(*) FROM cells"] if command == "query"
            else ["export", "--catalogue", db, "--plane", "wb", "--format", "csv",
                  "--out", tmp_path / "wb.csv"])
    one_line(*gearsim(args, tmp_path), str(db), "damaged")
    assert db.read_bytes() == data
    assert not (tmp_path / "wb.csv").exists()


def test_report_refuses_a_damaged_catalogue(tmp_path, study):
    """No silent fallback to the Parquet cells: the report stops on a damaged catalogue."""
    from gearsim.presentation.report_inputs import load_plane

    db = tmp_path / "catalogue.sqlite"
    db.write_bytes(os.urandom(100_000))
    (tmp_path / "wb").mkdir()
    shutil.copyfile(study["cells"], tmp_path / "wb/cells.parquet")
    with pytest.raises(gc.CatalogueError, match="damaged"):
        load_plane("wb", catalogue=db, results=tmp_path)


def test_workflow_sets_a_damaged_catalogue_aside(tmp_path, study):
    """What the workflow does at start (workflow/rules/common.smk): a damaged published
    catalogue makes the catalogue rule's output go aside (kept), so the rule rebuilds it."""
    built = tmp_path / "results/catalogue.d/build.sqlite"
    pub = tmp_path / "results/catalogue.sqlite"
    built.parent.mkdir(parents=True)
    shutil.copyfile(study["cat"], built)
    os.link(built, pub)
    assert gc.set_aside_damaged(pub, built) == []
    good = built.read_bytes()
    with open(pub, "r+b") as f:  # overwritten in place: the hard link shares the damage
        f.write(os.urandom(len(good)))
    lines = gc.set_aside_damaged(pub, built, dry_run=True)
    assert len(lines) == 1 and "damaged" in lines[0] and "next run rebuilds" in lines[0]
    assert built.exists()
    lines = gc.set_aside_damaged(pub, built)
    assert not built.exists()
    kept = list((built.parent / "damaged").iterdir())
    assert len(kept) == 1 and kept[0].stat().st_size == len(good)
    assert str(kept[0]) in lines[-1]


# ------------------------------------------------------------------ the disk fills up
@needs_root
def test_full_disk_during_catalogue_build_keeps_the_old_one(tmp_path, gearsim, study, mounts):
    disk = tmpfs(mounts, tmp_path / "disk", "2m")
    pub = disk / "catalogue.sqlite"
    shutil.copyfile(study["cat"], pub)
    old = pub.read_bytes()
    # room for the pre-flight's lower bound (the input's size), not for the catalogue: the
    # disk fills up during the build
    fill(disk, 100_000)
    code, err = gearsim(["catalogue", "build", "--cells", study["cells"], "--out",
                         disk / "catalogue.d/build.sqlite", "--publish", pub], tmp_path)
    one_line(code, err, "catalogue.d/build.sqlite", "full")
    assert "SQL" not in err and "INSERT" not in err and "CREATE" not in err
    assert pub.read_bytes() == old
    assert not [p for p in disk.rglob("*") if ".tmp-" in p.name]


@needs_root
def test_full_disk_before_writing_a_table_keeps_the_old_file(tmp_path, gearsim, study, mounts):
    """Less room than the tiles take: refused before the tiles are combined."""
    disk = tmpfs(mounts, tmp_path / "disk", "1m")
    out = disk / "cells.parquet"
    out.write_bytes(b"previous")
    fill(disk, 12_000)
    code, err = gearsim(["catalogue", "cells", "--plane", "wb", "--tiles", *study["tiles"],
                         "--configfile", *study["files"][1:], "--out", out], tmp_path)
    one_line(code, err, str(out), "free", "needed")
    assert out.read_bytes() == b"previous"
    assert not [p for p in disk.iterdir() if ".tmp-" in p.name]


@needs_root
def test_tile_on_a_tiny_disk_is_refused_before_simulating(tmp_path, gearsim, mounts,
                                                          monkeypatch):
    from gearsim.study import tiles

    def no_simulation(*a, **k):
        raise AssertionError("simulated although the output cannot be written")

    monkeypatch.setattr(tiles, "run_tile", no_simulation)
    disk = tmpfs(mounts, tmp_path / "disk", "64k")
    code, err = gearsim(["simulate-tile", "--plane", "wb", "--tile", "0", "--configfile",
                         ROOT / "config/tiny.yaml", "--out", disk / "0.parquet"], tmp_path)
    one_line(code, err, str(disk / "0.parquet"), "free", "needed")


# ------------------------------------------------------------------ read-only folders
@needs_root
@pytest.mark.parametrize("command", ["simulate-tile", "table1", "export", "catalogue-build",
                                     "catalogue-audit", "refine-orbits", "figures"])
def test_read_only_folder_is_one_line_before_any_work(tmp_path, gearsim, study, mounts,
                                                     monkeypatch, command):
    from gearsim.study import tiles

    monkeypatch.setattr(tiles, "run_tile", lambda *a, **k: pytest.fail("simulated"))
    ro = read_only(mounts, tmp_path / "src", tmp_path / "ro")
    args = {
        "simulate-tile": ["simulate-tile", "--plane", "wb", "--tile", "0", "--configfile",
                          ROOT / "config/tiny.yaml", "--out", ro / "tiles/0.parquet"],
        "table1": ["table1", "--params", ROOT / "config/standard_parameters.yaml",
                   "--md", ro / "table1.md", "--csv", tmp_path / "table1.csv"],
        "export": ["export", "--catalogue", study["cat"], "--plane", "wb", "--format", "csv",
                   "--out", ro / "wb.csv"],
        "catalogue-build": ["catalogue", "build", "--cells", study["cells"],
                            "--out", ro / "build.sqlite"],
        "catalogue-audit": ["catalogue", "audit", "--plane", "wb", "--cells", study["cells"],
                            "--configfile", *study["files"][1:], "--out", ro / "audit.parquet"],
        "refine-orbits": ["refine-orbits", "--plane", "wb", "--cells", study["cells"],
                          "--configfile", *study["files"][1:], "--out", ro / "orbits.parquet"],
        "figures": ["figures", "--fig", "4", "--sweep", f"standard={study['cells']}",
                    "--outdir", ro / "figures"],
    }[command]
    code, err = gearsim(args, tmp_path)
    one_line(code, err, str(ro), "read-only")
    assert list((tmp_path / "src").iterdir()) == []
    assert not (tmp_path / "table1.csv").exists()


@needs_root
def test_missing_permission_is_one_line(tmp_path, study):
    """As an unprivileged user (root passes permission checks): a folder of mode 0555."""
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    tmp_path.chmod(0o755)
    for p in tmp_path.parents:
        if p == Path("/"):
            break
        p.chmod(p.stat().st_mode | 0o005)
    cache = tmp_path / "numba"  # the unprivileged user's own (table1 compiles nothing)
    cache.mkdir(mode=0o777)
    cache.chmod(0o777)
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "NUMBA_CACHE_DIR": str(cache)}
    cmd = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", "python3", "-m",
           "gearsim.cli.main", "table1", "--params",
           str(ROOT / "config/standard_parameters.yaml"),
           "--md", str(locked / "t.md"), "--csv", str(locked / "t.csv")]
    if shutil.which("setpriv") is None:
        pytest.skip("no setpriv")
    import sys

    cmd[cmd.index("python3")] = sys.executable
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120)
    one_line(r.returncode, r.stderr, str(locked), "permission denied")
    assert list(locked.iterdir()) == []


@needs_root
def test_workflow_in_a_read_only_results_folder_is_one_line(tmp_path, mounts):
    """A fresh run whose results/ is a read-only mount stops before any job, in one line."""
    from workflow_helpers import make_workdir, smk

    wd = make_workdir(tmp_path / "wd")
    read_only(mounts, tmp_path / "src", wd / "results")
    r = smk(wd, "--cores", "1", "--configfile", "config/tiny.yaml", check=False,
            timeout=600)
    assert r.returncode == 2, r.stderr[-3000:]
    last = r.stderr.strip().splitlines()[-1]
    assert last == f"gearsim: error: output folder {wd / 'results'}: cannot write in it " \
                   "(read-only file system)", r.stderr[-3000:]
    assert "Traceback" not in r.stderr and "File " not in r.stderr
    assert not (wd / "logs").exists() or not any((wd / "logs").iterdir())


# ------------------------------------------------------------------ files not what they say
def test_files_that_are_not_what_their_name_says(tmp_path, gearsim):
    junk = tmp_path / "junk.parquet"
    junk.write_bytes(os.urandom(5000))
    one_line(*gearsim(["figures", "--fig", "4", "--sweep", f"standard={junk}", "--outdir",
                       tmp_path / "figs"], tmp_path), str(junk), "not a readable Parquet")
    params = tmp_path / "params.yaml"
    params.write_text("dimensionless: [1, 2]\n")
    one_line(*gearsim(["table1", "--params", params, "--md", tmp_path / "t.md", "--csv",
                       tmp_path / "t.csv"], tmp_path), str(params), "'dimensionless'",
             "mapping")
    params.write_bytes(os.urandom(3000))
    code, err = gearsim(["table1", "--params", params, "--md", tmp_path / "t.md", "--csv",
                         tmp_path / "t.csv"], tmp_path)
    one_line(code, err, str(params))
    assert not (tmp_path / "t.md").exists()


def test_os_error_line_names_file_and_cause():
    import errno

    from gearsim.cli.main import os_error_line

    line = os_error_line(OSError(errno.ENOSPC, "No space left on device", "/x/tile.parquet"))
    assert line == "/x/tile.parquet: the disk is full"
    line = os_error_line(OSError(errno.EROFS, "Read-only file system", "results/.compiled"))
    assert "results/.compiled" in line and "read-only" in line
    assert time  # noqa: B018 - keeps the import for the kill tests below


# ------------------------------------------------------------------ messages
def test_axis_message_names_the_key_and_value_written(tmp_path):
    f = tmp_path / "big.yaml"
    f.write_text("planes:\n  wb:\n    x: {name: w, min: 0.1, max: 2.5, n: 8}\n"
                 "    y: {name: b, min: 0.0, max: 1.0e8, n: 8}\n    fixed: {}\n")
    with pytest.raises(gcfg.ConfigError) as e:
        gcfg.load_config([ROOT / "config/config.yaml", ROOT / "config/tiny.yaml", f],
                         root=ROOT)
    msg = str(e.value)
    assert "'planes.wb.y.max': 1.0e8" in msg and "[0, 1000]" in msg
    assert "6250000" not in msg and "100000000.0" not in msg


# ------------------------------------------------------------------ bounded jobs
def _point(params):
    """A located period-doubling row as bifurcation_points gives it (values irrelevant: the
    budget is spent before the first relocation)."""
    return {"kind": "period_doubling", "period": 1, "boundary": "", "name": "w", "value": 1.0,
            "x": 0.1, "v": 0.0, "mu_max": 1.0, "mu_re": [-1.0], "mu_im": [0.0],
            "stable": True}


def test_spent_budget_stops_curve_and_continuation_before_any_work(monkeypatch):
    from gearsim.analysis import bifcurves, continuation
    from gearsim.analysis.continuation_options import Continuation
    from gearsim.dynamics.parameters import ModelParameters

    params = ModelParameters()
    spent = Continuation(deadline=time.monotonic() - 1.0)

    def no_work(*a, **k):
        raise AssertionError("worked past the budget")

    monkeypatch.setattr(bifcurves, "relocate_window", no_work)
    monkeypatch.setattr(bifcurves, "relocate_secant", no_work)
    c = bifcurves.follow_curve(params, _point(params), "b", 0.9, step2=0.1, config=spent)
    assert len(c) == 1 and c.attrs["status"] == "budget"
    assert c.attrs["reason"].startswith("budget: wall-clock budget spent at b = ")
    curves = bifcurves.follow_curves(params, __import__("pandas").DataFrame([_point(params)]),
                                     "b", (0.0, 0.9), step2=0.1, config=spent)
    assert curves.attrs["status"] == "budget"
    assert all("budget" in r for r in curves.attrs["reasons"])
    # the continuation: its first branch job is not started
    from gearsim.analysis.orbits import find_periodic_orbit

    orbit = find_periodic_orbit(params.with_(w=1.2), 1, None, grazing=False)
    monkeypatch.setattr(continuation, "_run_branch", no_work)
    df = continuation.continue_orbit(params, "w", 1.2, 1.5, orbit, config=spent)
    assert df.attrs["status"] == "budget" and len(df) == 0
    assert df.attrs["reasons"][0].startswith("budget: wall-clock budget spent")


def _diverged_cells(study, d: Path) -> Path:
    import pyarrow.parquet as pq

    t = pq.read_table(study["cells"])
    df = t.to_pandas()
    df["status"] = "diverged"
    df.loc[0, "status"] = "ok"  # 15 of 16 diverged
    out = d / "cells.parquet"
    gc.write_parquet(df, out, {k: v for k, v in (t.schema.metadata or {}).items()
                               if k != b"pandas"})
    return out


def test_plane_of_diverged_cells_skips_its_curves(tmp_path, gearsim, study):
    cells = _diverged_cells(study, tmp_path)
    out = tmp_path / "orbits/wb_curves.parquet"
    code, err = gearsim(["bifurcation-curves", "--plane", "wb", "--cells", cells,
                         "--configfile", *study["files"][1:], "--out", out], tmp_path)
    assert code == 0, err
    assert "curves skipped: 15 of 16 cells diverged" in err
    prov = gc.read_metadata(out)
    assert prov["status"] == "skipped" and "15 of 16" in prov["reasons"][0]
    for f in (out, tmp_path / "orbits/wb_curves_points.parquet",
              tmp_path / "orbits/wb_curves_branches.parquet", out.with_suffix(".png")):
        assert f.is_file(), f
    # the catalogue records the skipped job, the report says it
    db = tmp_path / "catalogue.sqlite"
    gc.build_catalogue(db, [study["cells"]],
                       orbit_files=[tmp_path / "orbits/wb_curves_points.parquet", out])
    con = gc.open_catalogue(db)
    try:
        assert con.execute("SELECT status FROM runs WHERE kind = 'curves'").fetchall() == [
            ("skipped",), ("skipped",)]
    finally:
        con.close()
    from gearsim.presentation.report_inputs import load_curve_status

    lines = load_curve_status(tmp_path, ["wb"])
    assert lines == [f"plane wb: {prov['reasons'][0]}"]


@pytest.mark.slow
def test_curve_job_stops_at_its_budget_and_a_killed_one_leaves_nothing(tmp_path, study):
    """A budget spent before the first seed ends the atlas with status budget (exit 0, the
    tables written); the same job killed mid-run leaves the previous outputs and no temporary
    file."""
    import signal
    import sys

    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    out = tmp_path / "orbits/wb_curves.parquet"
    base = [sys.executable, "-m", "gearsim.cli.main", "bifurcation-curves", "--plane", "wb",
            "--configfile", *map(str, study["files"][1:]), "--cells", str(study["cells"]),
            "--out", str(out)]
    r = subprocess.run([*base, "--budget-s", "0.001"], capture_output=True, text=True, env=env,
                       cwd=tmp_path, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    prov = gc.read_metadata(out)
    assert prov["status"] == "budget", prov.get("reasons")
    assert "status budget" in r.stderr
    before = {p: p.read_bytes() for p in out.parent.iterdir()}
    p = subprocess.Popen(base, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env,
                         cwd=tmp_path)
    time.sleep(1)  # still starting (imports) or locating: either way mid-run
    assert p.poll() is None
    p.send_signal(signal.SIGKILL)
    p.wait(30)
    after = {q: q.read_bytes() for q in out.parent.iterdir()}
    assert after == before


def test_faults_deep_in_a_command_are_one_line(tmp_path, gearsim, monkeypatch):
    """The net under every command: an OSError or an unreadable file met anywhere."""
    import errno

    import pyarrow as pa

    from gearsim.cli.commands import table1

    args = ["table1", "--md", tmp_path / "t.md", "--csv", tmp_path / "t.csv"]

    def full(path):
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "t.md"))

    monkeypatch.setattr(table1, "table", full)
    one_line(*gearsim(args, tmp_path), f"{tmp_path / 't.md'}: the disk is full")

    def foreign(path):
        raise pa.ArrowInvalid("Parquet magic bytes not found in footer")

    monkeypatch.setattr(table1, "table", foreign)
    one_line(*gearsim(args, tmp_path), "unreadable file (ArrowInvalid: Parquet magic bytes")
    monkeypatch.setenv("GEARSIM_DEBUG", "1")  # a developer asks for the traceback
    with pytest.raises(pa.ArrowInvalid):
        gearsim(args, tmp_path)

    def bug(path):
        raise KeyError("a bug is not turned into a line")

    monkeypatch.delenv("GEARSIM_DEBUG")
    monkeypatch.setattr(table1, "table", bug)
    with pytest.raises(KeyError):
        gearsim(args, tmp_path)


def test_report_says_where_cells_come_from_without_the_catalogue(tmp_path, study):
    """No silent fallback: a report built without its catalogue says it read the Parquet cells."""
    from gearsim.presentation.report import build_report

    (tmp_path / "wb").mkdir()
    shutil.copyfile(study["cells"], tmp_path / "wb/cells.parquet")
    missing = tmp_path / "catalogue.sqlite"
    _, md = build_report(sweeps_dir=tmp_path / "none", catalogue=missing, results=tmp_path,
                         calibration=None, planes={"wb": ("w", "b")}, sweeps=[])
    assert f"catalogue {missing} not found: the cells of wb were read from" in md
    db = tmp_path / "other.sqlite"  # a catalogue without this plane
    gc.build_catalogue(db)
    _, md = build_report(sweeps_dir=tmp_path / "none", catalogue=db, results=tmp_path,
                         calibration=None, planes={"wb": ("w", "b")}, sweeps=[])
    assert f"plane wb is not in the catalogue {db}: its cells were read from" in md
