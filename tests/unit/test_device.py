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
from gearsim.numerics.backend import CPU, select
from gearsim.numerics.batch import Lanes
from gearsim.study import provenance
from gearsim.study.config import Study

ROOT = Path(__file__).resolve().parents[2]
_, _, _simulated, WHY = device._probe()
no_gpu = pytest.mark.skipif(not WHY, reason="a CUDA device (or the simulator) is present")


def test_default_is_the_cpu_and_leaves_provenance_as_it_was():
    backend = select("cpu")
    assert backend is CPU and backend.kind == "cpu" and backend.record() is None
    assert Lanes(3, 1).backend is CPU
    for rec in (provenance.provenance({"a": 1}, kind="tile", name="x"),
                provenance.provenance({"a": 1}, kind="tile", name="x", device=backend.record())):
        assert "device" not in rec


@no_gpu
def test_cuda_without_a_gpu_is_one_line_naming_the_setting():
    with pytest.raises(device.DeviceError) as err:
        select("cuda")
    msg = str(err.value)
    assert msg.startswith("execution.device: cuda: ") and "\n" not in msg
    assert Lanes(3, 1).backend is CPU  # nothing chosen for anyone else


@no_gpu
def test_auto_falls_back_to_the_cpu_and_says_so(caplog):
    with caplog.at_level("WARNING", logger="gearsim.numerics.device"):
        backend = select("auto")
    dev = backend.device
    assert backend.kind == "cpu" and dev.asked == "auto" and dev.note.startswith("on the CPU: ")
    assert any("auto" in r.getMessage() for r in caplog.records)
    assert Lanes(3, 1, backend).backend.kind == "cpu"
    rec = provenance.provenance({"a": 1}, kind="tile", name="x", device=backend.record())
    assert rec["device"]["kind"] == "cpu" and rec["device"]["asked"] == "auto"
    assert rec["device"]["note"] == dev.note
    # outside the configuration hash: the same subtree hashes alike on either device
    assert rec["config_hash"] == provenance.config_hash({"a": 1})


def test_the_study_carries_its_device_and_the_workflow_reads_it_there():
    """The study's execution settings say where its jobs run (config/gpu.yaml: cuda, a GPU
    job); --device is folded in by with_device; no choice is kept anywhere else."""
    paper = Study.load(root=ROOT)
    gpu = Study.load([ROOT / "config/gpu.yaml"], root=ROOT)
    assert paper.execution == device.Execution("cpu") and not paper.execution.uses_gpu
    assert gpu.execution.device == "cuda" and gpu.execution.uses_gpu
    assert paper.with_device("auto").execution.device == "auto"
    assert paper.with_device(None) is paper
    assert paper.with_device("auto").settings == paper.settings  # outside the settings
    assert "STUDY.execution.uses_gpu" in (ROOT / "workflow/rules/common.smk").read_text()


def test_unknown_device_is_one_line():
    with pytest.raises(device.DeviceError, match=r"^execution.device: 'gpu' is not one of"):
        select("gpu")


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


SIMULATING = ("point", "orbit", "sweep", "attractors", "basins", "simulate-tile",
              "attractor-tile")


@pytest.mark.parametrize("command", SIMULATING)
def test_every_simulating_command_takes_the_device(command):
    """``--device`` on every command that simulates, with the study's ``execution.device`` as
    its default (``gearsim point --omega 0.8 --device auto`` runs)."""
    from gearsim.cli.main import build_parser

    sub = next(a for a in build_parser(command)._actions if a.dest == "command")
    opts = {o: a for a in sub.choices[command]._actions for o in a.option_strings}
    assert "--device" in opts and opts["--device"].default is None
    assert tuple(opts["--device"].choices) == device.DEVICES


@no_gpu
def test_point_with_device_cuda_and_no_gpu_is_one_line():
    proc = subprocess.run([sys.executable, "-m", "gearsim.cli.main", "point", "--omega", "0.8",
                           "--device", "cuda"], capture_output=True, text=True, cwd=ROOT,
                          timeout=120)  # fmt: skip
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("gearsim point: error: --device: cuda")
