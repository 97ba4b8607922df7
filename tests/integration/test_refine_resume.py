"""`gearsim refine-orbits` on a whole (small) plane: it shows the time left, writes the cells
refined so far every N cells, and a run killed halfway and started again finishes with the same
table as an uninterrupted run; progress lines are rewritten in place on a terminal and spaced in
a log."""

from __future__ import annotations

import io
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from gearsim.cell.simulate import simulate_cell
from gearsim.cli.commands._progress import Progress, duration_text
from gearsim.cli.main import main
from gearsim.study.config import Study

ROOT = Path(__file__).resolve().parents[2]
TINY = str(ROOT / "config/tiny.yaml")


@pytest.fixture(scope="module")
def plane(tmp_path_factory):
    """A 10 x 3 piece of the tiny study's (w, b) plane, each cell simulated from rest."""
    study = Study.load([TINY], root=ROOT)
    rows = []
    for j, b in enumerate((0.3, 0.5, 0.7)):
        for i, w in enumerate(np.linspace(0.3, 1.25, 10)):
            p = study.parameters(plane="wb", changes={"w": w, "b": b}).model
            res = simulate_cell(p, settings=study.settings)
            c = res.classification
            rows.append({"plane": "wb", "i": i, "j": j, "x": w, "y": b, "n": c.n,
                         "status": c.status, "label": c.label,
                         "final_state": res.final_state.tolist()})
    path = tmp_path_factory.mktemp("refine") / "cells.parquet"
    pd.DataFrame(rows).to_parquet(path)
    return path


def _args(cells: Path, out: Path, *extra: str) -> list[str]:
    return ["refine-orbits", "--plane", "wb", "--cells", str(cells), "--configfile", TINY,
            "--out", str(out), *extra]


def test_killed_run_resumes_to_the_same_table(plane, tmp_path, capsys):
    whole = tmp_path / "whole.parquet"
    assert main(_args(plane, whole)) == 0
    err = capsys.readouterr().err
    assert "left" in err and f"wrote {whole}" in err
    ref = pd.read_parquet(whole)
    periodic = pd.read_parquet(plane).query("n >= 1 and status != 'diverged'")
    assert len(ref) == len(periodic) >= 20
    assert not (tmp_path / "whole.parquet.partial").exists()

    out = tmp_path / "killed.parquet"
    partial = tmp_path / "killed.parquet.partial"
    env = {**os.environ, "NUMBA_CACHE_DIR": os.environ.get("NUMBA_CACHE_DIR",
                                                           str(ROOT / ".numba_cache"))}
    proc = subprocess.Popen([sys.executable, "-m", "gearsim", *_args(plane, out, "--every", "3")],
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None and not partial.exists():
        time.sleep(0.005)
    assert proc.poll() is None, "the run ended before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    kept = pd.read_parquet(partial)
    assert 3 <= len(kept) < len(ref) and not out.exists()

    assert main(_args(plane, out, "--every", "3")) == 0
    err = capsys.readouterr().err
    assert f"resuming from {partial} ({len(kept)} of {len(ref)} cells" in err
    again = pd.read_parquet(out)
    pd.testing.assert_frame_equal(again.drop(columns="orbit_ms"), ref.drop(columns="orbit_ms"))
    assert not partial.exists()

    # a partial table of other inputs is not resumed
    partial.write_bytes(b"not parquet")
    assert main(_args(plane, out, "--limit", "4")) == 0
    assert "starting afresh" in capsys.readouterr().err
    assert len(pd.read_parquet(out)) == 4


def test_progress_in_place_on_a_terminal_and_spaced_in_a_log():
    class Tty(io.StringIO):
        def isatty(self):
            return True

    tty = Tty()
    p = Progress("job", 100, stream=tty, interval=0)
    for k in range(1, 101):
        p(k, 100, k * 0.5)
    p.close()
    text = tty.getvalue()
    assert text.count("\n") == 1 and text.count("\r") == 100
    assert "100/100 cells (100%), 2.00 cells/s, 50 s so far, 0 s left" in text
    log = io.StringIO()
    p = Progress("job", 100, stream=log, start=40)  # 40 done before: rate of this run's 60
    for k in range(41, 101):
        p(k, 100, (k - 40) * 2.0)
    lines = log.getvalue().splitlines()
    assert len(lines) == 2  # the first and the last: the calls came faster than LOG_INTERVAL
    # no rate from one cell (its time may be a compile's): the time left is not guessed
    assert "41/100 cells (41%), 2 s so far, time left: measuring the rate" in lines[0]
    assert "100/100 cells (100%), 0.50 cells/s, 2 min 00 s so far, 0 s left" in lines[1]
    assert (duration_text(59.6), duration_text(200), duration_text(7500)) == (
        "1 min 00 s", "3 min 20 s", "2 h 05 min")


def test_time_left_waits_for_a_measured_rate():
    """A first cell that took a minute (the kernels compiled before it) and then 2 cells/s: no
    time left until MEASURE_CELLS cells and MEASURE_SECONDS seconds after the first cell, then
    the time left at the rate measured from the first cell on (not the first minute's)."""
    log = io.StringIO()
    p = Progress("job", 1000, stream=log, interval=0)
    p(1, 1000, 60.0)
    p(2, 1000, 60.5)
    p(9, 1000, 64.0)  # 8 cells in 4 s: not yet MEASURE_SECONDS
    p(13, 1000, 66.0)  # 12 cells in 6 s: 2 cells/s, 987 cells left: 8 min 14 s
    lines = log.getvalue().splitlines()
    assert all("time left: measuring the rate" in line for line in lines[:3]), lines
    assert "13/1000 cells (1%), 2.00 cells/s, 1 min 06 s so far, 8 min 14 s left" in lines[3]
