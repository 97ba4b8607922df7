"""Choosing the device (gearsim.numerics.device): cpu, cuda or auto, and what provenance says.

On a machine without numba-cuda or without a GPU (CI, this test's target), ``cuda`` is one line
and exit 2, ``auto`` runs on the CPU and says so; the default CPU run's provenance has no device
record, so its files are those of a run before the device existed.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from gearsim.numerics import device
from gearsim.numerics.batch import Lanes
from gearsim.study import provenance

ROOT = Path(__file__).resolve().parents[2]
_, _, _simulated, WHY = device._probe()
no_gpu = pytest.mark.skipif(not WHY, reason="a CUDA device (or the simulator) is present")


@pytest.fixture(autouse=True)
def back_to_cpu():
    yield
    device.select("cpu")


def test_default_is_the_cpu_and_leaves_provenance_as_it_was():
    dev = device.select("cpu")
    assert dev.kind == "cpu" and dev.record() is None
    assert Lanes(3, 1).device == "cpu"
    rec = provenance.provenance({"a": 1}, kind="tile", name="x")
    assert "device" not in rec


@no_gpu
def test_cuda_without_a_gpu_is_one_line_naming_the_setting():
    with pytest.raises(device.DeviceError) as err:
        device.select("cuda")
    msg = str(err.value)
    assert msg.startswith("execution.device: cuda: ") and "\n" not in msg
    assert device.current().kind == "cpu"  # nothing changed


@no_gpu
def test_auto_falls_back_to_the_cpu_and_says_so(caplog):
    with caplog.at_level("WARNING", logger="gearsim.numerics.device"):
        dev = device.select("auto")
    assert dev.kind == "cpu" and dev.asked == "auto" and dev.note.startswith("on the CPU: ")
    assert any("auto" in r.getMessage() for r in caplog.records)
    assert Lanes(3, 1).device == "cpu"
    rec = provenance.provenance({"a": 1}, kind="tile", name="x")
    assert rec["device"]["kind"] == "cpu" and rec["device"]["asked"] == "auto"
    assert rec["device"]["note"] == dev.note
    # outside the configuration hash: the same subtree hashes alike on either device
    assert rec["config_hash"] == provenance.config_hash({"a": 1})


def test_unknown_device_is_one_line():
    with pytest.raises(device.DeviceError, match=r"^execution.device: 'gpu' is not one of"):
        device.select("gpu")


@no_gpu
def test_simulate_tile_device_cuda_exits_2_with_one_line(tmp_path):
    out = tmp_path / "t.parquet"
    proc = subprocess.run(
        [sys.executable, "-m", "gearsim.cli.main", "simulate-tile", "--plane", "wb", "--tile",
         "0", "--configfile", str(ROOT / "config/tiny.yaml"), "--device", "cuda", "--out",
         str(out)],
        capture_output=True, text=True, cwd=ROOT, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("gearsim simulate-tile: error: --device: cuda")
    assert not out.exists()
