"""The published catalogue is a Snakemake target: `snakemake results/catalogue.sqlite`."""

from __future__ import annotations

import shutil
import subprocess

import pytest

from gearsim.study.config import project_root


@pytest.mark.skipif(shutil.which("snakemake") is None, reason="snakemake not installed")
def test_snakemake_plans_the_published_catalogue():
    """A dry run for results/catalogue.sqlite plans the catalogue build and the publishing job,
    whose output is flagged update (never deleted before the job)."""
    r = subprocess.run(
        ["snakemake", "-n", "--nolock", "results/catalogue.sqlite", "--configfile",
         "config/tiny.yaml"],
        cwd=project_root(), capture_output=True, text=True, timeout=600)
    out = r.stdout + r.stderr
    assert r.returncode == 0, out[-2000:]
    assert "No rule to produce" not in out
    assert "results/catalogue.sqlite (update)" in out
    assert "rule catalogue:" in out and "rule published_catalogue:" in out
