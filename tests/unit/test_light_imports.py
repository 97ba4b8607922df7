"""What a job loads before it works: the workflow's parse and the jobs that read tables start
without the compiler, the optimisers or the plotting library they do not use (each costs
0.2-0.5 s of CPU in every one of a run's ~60 processes)."""

from __future__ import annotations

import json
import subprocess
import sys

HEAVY = ("numba", "scipy.optimize", "matplotlib.pyplot", "sqlalchemy")


def _loaded(code: str) -> list[str]:
    """The HEAVY modules a fresh interpreter holds after ``code``."""
    probe = (f"{code}\nimport json, sys\n"
             f"print(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_the_workflow_parse_loads_no_kernel_optimiser_or_plotting():
    # what Snakefile and workflow/rules/*.smk import and call at parse time
    code = """
from gearsim.study import config as gcfg, grid, provenance
from gearsim.presentation.figures import rules as gfr
cfg = gcfg.load_config([gcfg.project_root() / "config/config.yaml"])
gcfg.orbit_tables(cfg)
gfr.groups({})
"""
    assert _loaded(code) == []


def test_a_figure_job_loads_no_kernel_or_optimiser():
    code = """
from gearsim.cli.main import build_parser
from gearsim.presentation.figures import registry
build_parser("figures")
registry.figures()
"""
    loaded = _loaded(code)
    assert "numba" not in loaded and "scipy.optimize" not in loaded, loaded


def test_the_kernels_are_still_loaded_where_they_run():
    # the probe can fail: simulating a cell loads Numba
    code = """
from gearsim.cell.simulate import simulate_cell
"""
    assert "numba" in _loaded(code)
