"""Several planes' tiles in one call of the chain driver (``gearsim simulate-tile --plane wb
--plane wxi``: on a GPU, both planes' chains in one launch) give each tile's frame as its own
call does: the chains are independent lanes, so sharing a lanes object changes no value."""

from __future__ import annotations

import copy
import subprocess
import sys

import pandas as pd
import pytest

from gearsim.study import config as gcfg
from gearsim.study import tiles as gt

DEFAULT = gcfg.study_root() / "config" / "config.yaml"
TINY = gcfg.study_root() / "config" / "tiny.yaml"
RK4 = {"integration": {"method": "rk4", "steps_per_period": 64}}


@pytest.fixture(scope="module")
def rk4_study():
    cfg = copy.deepcopy(gcfg.load_config([DEFAULT, TINY]))
    cfg["integration"].update(RK4["integration"])
    return gcfg.Study.of(cfg)


def _same(a: pd.DataFrame, b: pd.DataFrame) -> None:
    # every column but the wall clock's
    cols = [c for c in a.columns if c != "elapsed_s"]
    assert list(a.columns) == list(b.columns)
    pd.testing.assert_frame_equal(a[cols], b[cols], check_exact=True)


def test_both_planes_in_one_call_equal_their_own_tiles(rk4_study):
    seen = []
    together = gt.run_tiles(rk4_study, [("wb", 1), ("wxi", 0)],
                            progress=lambda d, t, s: seen.append((d, t)))
    alone = [gt.run_tile(rk4_study, "wb", 1), gt.run_tile(rk4_study, "wxi", 0)]
    for a, b in zip(alone, together, strict=True):
        _same(a, b)
    assert len(set(together[0]["label"])) > 2  # not vacuous: several motions
    assert seen and seen[-1] == (64, 64)


def test_the_command_writes_one_file_per_plane(tmp_path):
    cmd = [sys.executable, "-m", "gearsim.cli.main", "simulate-tile", "--plane", "wb",
           "--plane", "wxi", "--tile", "1", "--configfile", str(TINY), "--config-json",
           '{"integration": {"method": "rk4", "steps_per_period": 64}}']
    one = subprocess.run(cmd + ["--out", str(tmp_path / "a.parquet")], capture_output=True,
                         text=True)
    assert one.returncode == 2 and one.stderr.count("\n") == 1 and "--out" in one.stderr
    assert not list(tmp_path.iterdir())  # nothing written
    out = [tmp_path / "wb.parquet", tmp_path / "wxi.parquet"]
    run = subprocess.run(cmd + ["--out", str(out[0]), "--out", str(out[1])],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    frames = [pd.read_parquet(p) for p in out]
    assert [set(f["plane"]) for f in frames] == [{"wb"}, {"wxi"}]
    assert [len(f) for f in frames] == [32, 32]
