"""The README's commands run by hand beside a finished study, as a new user runs them (the
session's tiny run stands in for the default run):

* nothing the workflow made is replaced unasked: `simulate-tile` of another study file and the
  README's `figures --fig 4` stop in one line naming the file and the options (`--out` /
  `--outdir` elsewhere, `--replace`); a tile of another configuration put there anyway (with
  `--replace`) is found by the workflow before any job, named with the command that repairs it,
  and nothing is removed; that command repairs it;
* the GPU file runs into its own folder beside the results; a refusal names the settings that
  differ; a failed job's log is named as a path that opens from the project folder;
* Ctrl-C on `refine-orbits`: one line saying what was kept and the command that resumes, exit
  130, no traceback; the same command resumes and finishes; no time left is shown before the
  rate is measured.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from workflow_helpers import ROOT, _env, smk, smk_in

pytestmark = pytest.mark.slow

# a study file of one's own with another grid and no `folder:` (the config/mine2.yaml)
MINE = "planes:\n  wb:\n    x: {name: w, min: 0.1, max: 2.5, n: 10}\n"


def _files(wd: Path) -> dict[str, str]:
    return {p.relative_to(wd).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted((wd / "results").rglob("*")) if p.is_file()}


def _gearsim(wd: Path, *args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "gearsim", *args], cwd=wd,
                          env=env or _env(), capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def beside(tiny_run, tmp_path_factory):
    """A copy of the session's finished tiny run (results, record, Snakemake's records) with the
    README's Fig 4 drawn by the workflow."""
    wd = tmp_path_factory.mktemp("beside") / "run"
    shutil.copytree(tiny_run[0], wd, ignore=shutil.ignore_patterns("locks"))
    (wd / "config" / "mine2.yaml").write_text(MINE)
    smk(wd, "results/figures/fig04.png", "--cores", "2", "--configfile", "config/tiny.yaml")
    return wd


def test_readme_commands_beside_a_finished_study(beside, tmp_path):
    wd = beside
    before = _files(wd)
    tile = "results/wb/tiles/0.parquet"

    # --- 3. hand commands replace nothing the workflow made
    r = _gearsim(wd, "simulate-tile", "--plane", "wb", "--tile", "0", "--configfile",
                 "config/tiny.yaml", "config/mine2.yaml")
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.startswith(f"gearsim simulate-tile: error: {tile}: made by the workflow")
    assert "--out PATH to write elsewhere, or --replace" in r.stderr
    r = _gearsim(wd, "figures", "--fig", "4", "--sweep",
                 "standard=results/sweeps/standard.parquet", "--configfile", "config/tiny.yaml")
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "results/figures/fig04" in r.stderr and "made by the workflow" in r.stderr
    assert "--outdir DIR to write elsewhere, or --replace" in r.stderr
    assert _files(wd) == before
    # the same by-hand figure written elsewhere, as the line says
    r = _gearsim(wd, "figures", "--fig", "4", "--sweep",
                 "standard=results/sweeps/standard.parquet", "--configfile", "config/tiny.yaml",
                 "--outdir", "mine")
    assert r.returncode == 0, r.stderr
    assert (wd / "mine/fig04.png").is_file() and _files(wd) == before

    # a tile of another grid put in place anyway: the workflow finds it before any job,
    # removes nothing and names the repair
    r = _gearsim(wd, "simulate-tile", "--plane", "wb", "--tile", "0", "--configfile",
                 "config/tiny.yaml", "config/mine2.yaml", "--replace")
    assert r.returncode == 0, r.stderr
    planted = _files(wd)
    r = smk_in(wd, "results/wb/cells.parquet", "--cores", "2", "--configfile", "config/tiny.yaml",
               check=False)
    err = [ln for ln in r.stderr.splitlines() if ln.startswith("gearsim: error:")]
    assert r.returncode == 2 and len(err) == 1, r.stdout[-2000:] + r.stderr[-2000:]
    assert f"{tile}: a tile of another configuration" in err[0] and "x.n 10 -> 8" in err[0]
    assert f"`rm {tile}`" in err[0] and "nothing was removed" in err[0]
    assert _files(wd) == planted  # results/wb/cells.parquet and the rest still there
    os.remove(wd / tile)  # the repair, as named
    smk_in(wd, "results/wb/cells.parquet", "--cores", "2", "--configfile", "config/tiny.yaml")
    assert _files(wd)[tile] != planted[tile]
    assert pd.read_parquet(wd / "results/wb/cells.parquet").shape[0] == 64

    # --- 4. the GPU file beside the results: its own folder (a dry run plans its jobs there)
    r = smk_in(wd, "-n", "--cores", "16", "--resources", "gpu=1", "--configfile",
               "config/gpu.yaml")
    assert "gearsim: error" not in r.stderr and "simulate" in r.stdout
    assert (wd / "studies/gpu").is_dir()
    # a refusal names the settings that differ
    (wd / "config/xi.yaml").write_text("planes:\n  wb:\n    fixed: {xi: 0.07}\n")
    r = smk_in(wd, "-n", "--configfile", "config/tiny.yaml", "config/xi.yaml", check=False)
    assert r.returncode == 2 and "plane wb: w 0.1..2.5 x b 0..1: 8 x 8 (fixed.xi (unset) -> " \
        "0.07)" in r.stderr, r.stderr
    # a failed job of a study of one's own: its log named from the project folder
    (wd / "config/small.yaml").write_text(
        "study: small\nplanes: {}\npoints: {}\nsweeps:\n  s: {name: w, min: 0.5, max: 1.0, "
        "n: 3, fixed: {}}\norbits: {continuation: false, curves: false}\n")
    fake = tmp_path / "bin"
    fake.mkdir()
    (fake / "gearsim").write_text("#!/bin/sh\necho 'broken on purpose' >&2\nexit 1\n")
    (fake / "gearsim").chmod(0o755)
    env = {**_env(), "PATH": f"{fake}:{_env()['PATH']}"}
    r = subprocess.run([str(Path(sys.executable).parent / "snakemake"), "-s",
                        str(ROOT / "Snakefile"), "--cores", "1", "--configfile",
                        "config/small.yaml"], cwd=wd, env=env, capture_output=True, text=True,
                       timeout=600)
    assert r.returncode != 0
    named = [ln.split(": ", 2)[2] for ln in r.stderr.splitlines()
             if ln.startswith("gearsim: log of the failed job")]
    assert named and all(n.startswith("studies/small/logs/") for n in named), r.stderr[-3000:]
    assert all((wd / n).is_file() for n in named)
    assert "broken on purpose" in (wd / named[0]).read_text()

    # --- 5. Ctrl-C on refine-orbits, then the same command resumes
    cmd = ["refine-orbits", "--plane", "wb", "--cells", "results/wb/cells.parquet",
           "--configfile", "config/tiny.yaml", "--every", "1", "--out", "wb_orbits.parquet"]
    # SIGINT as a terminal delivers it (a shell's background job would inherit it ignored)
    proc = subprocess.Popen([sys.executable, "-m", "gearsim", *cmd], cwd=wd, env=_env(),
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    lines = []
    while True:
        line = proc.stderr.readline()
        assert line, "refine-orbits ended before it showed progress: " + "".join(lines)
        lines.append(line)
        if " cells (" in line:
            break
    deadline = time.monotonic() + 120  # the first checkpoint (--every 1): a cell kept
    while not (wd / "wb_orbits.parquet.partial").exists() and time.monotonic() < deadline:
        time.sleep(0.01)
    proc.send_signal(signal.SIGINT)
    rest = proc.stderr.read()
    proc.wait(timeout=120)
    assert proc.returncode == 130, rest
    assert "Traceback" not in rest and "KeyboardInterrupt" not in rest, rest
    last = rest.strip().splitlines()[-1]
    assert last.startswith("gearsim refine-orbits: interrupted; ") and "kept in " \
        "wb_orbits.parquet.partial" in last, last
    assert last.endswith("run the same command to resume: gearsim " + " ".join(cmd)), last
    assert "time left: measuring the rate" in lines[-1]  # one cell: no guess of the time left
    r = _gearsim(wd, *cmd)
    assert r.returncode == 0 and "resuming from wb_orbits.parquet.partial" in r.stderr, r.stderr
    assert (wd / "wb_orbits.parquet").is_file()
    assert not (wd / "wb_orbits.parquet.partial").exists()
