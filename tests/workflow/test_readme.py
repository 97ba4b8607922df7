"""The README's examples run as written and print what the pipeline computes for the same cells."""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[2]


def _python_blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def _gearsim(*args, cwd):
    env = dict(os.environ)
    env.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".numba_cache"))
    r = subprocess.run([sys.executable, "-m", "gearsim", *args], capture_output=True, text=True,
                       cwd=cwd, env=env)
    assert r.returncode == 0, r.stderr
    return r


@pytest.fixture(scope="module")
def readme_run():
    """Run the README's first Python example from the checkout, as a reader would."""
    code = _python_blocks((ROOT / "README.md").read_text())[0]
    namespace: dict = {}
    out = io.StringIO()
    cwd = os.getcwd()
    try:
        os.chdir(ROOT)
        with contextlib.redirect_stdout(out):
            exec(compile(code, "README.md", "exec"), namespace)  # noqa: S102 - our own README
    finally:
        os.chdir(cwd)
    return namespace, out.getvalue()


def test_readme_cell_is_the_cli_point(readme_run, tmp_path):
    ns, printed = readme_run
    c = ns["cell"].classification
    lines = printed.splitlines()
    assert lines[0].endswith("standard_parameters.yaml")  # where xi came from
    assert lines[1].split()[:2] == ["0/1T", "1-0-0"]
    cli = json.loads(_gearsim("point", "--omega", "0.48", "--json", cwd=tmp_path).stdout)
    assert (cli["label"], cli["label_npq"], cli["status"]) == (c.label, c.label_npq, c.status)
    assert cli["dc"] == pytest.approx(c.dc, abs=1e-12)
    assert cli["kmax"] == pytest.approx(c.kmax, rel=1e-12)


def test_readme_sweep_is_the_pipeline_sweep(readme_run, tmp_path):
    """The README's sweep equals the pipeline's b015 sweep of config/quick.yaml, cell by cell."""
    ns, printed = readme_run
    sweep = ns["sweep"]
    out = tmp_path / "b015.parquet"
    _gearsim("sweep", "--name", "b015", "--configfile", str(ROOT / "config/quick.yaml"),
             "--out", str(out), cwd=tmp_path)
    pipe = pd.read_parquet(out)
    assert len(pipe) == len(sweep) == 121
    np.testing.assert_allclose(sweep["value"], pipe["value"], rtol=0, atol=1e-15)
    assert list(sweep["label"]) == list(pipe["label"])
    assert list(sweep["label_npq"]) == list(pipe["label_npq"])
    np.testing.assert_allclose(sweep["dc"], pipe["dc"], atol=1e-9)
    np.testing.assert_allclose(sweep["kmax"], pipe["kmax"], rtol=1e-6)
    assert "label_npq" in printed and len(printed.splitlines()) > 3


def _bash_lines(text: str) -> list[str]:
    """Every line of the README's bash blocks, continuation lines joined."""
    out = []
    for block in re.findall(r"```bash\n(.*?)```", text, flags=re.S):
        for line in block.replace("\\\n", " ").splitlines():
            if line.strip() and not line.lstrip().startswith("#"):
                out.append(line)
    return out


# commands that run for more than a few minutes on 2 cores, or may, with their arguments
LONG = re.compile(r"^\s*(make (reproduce|test)\b|(\S+=\S+ )*snakemake\b(?!.*(-n\b|--unlock))|"
                  r"gearsim (refine-orbits|bifurcation-curves|basins|continue)\b)")
COST = re.compile(r"#.*~\d+ (s|min)\b")


def test_readme_long_commands_say_their_cost():
    lines = [ln for ln in _bash_lines((ROOT / "README.md").read_text()) if LONG.match(ln)]
    assert len(lines) >= 10, lines
    assert [ln for ln in lines if not COST.search(ln)] == []
    # the plane's refinement as printed: bounded by --limit, written outside results/
    from gearsim.cli.main import build_parser

    refine = next(ln for ln in lines if "refine-orbits" in ln)
    args = build_parser().parse_args(refine.split("#")[0].split()[1:])
    assert args.limit is not None and not args.out.startswith("results/")


def test_readme_point_output_is_what_point_prints(tmp_path):
    text = (ROOT / "README.md").read_text()
    block = re.search(r"`gearsim point --omega 0.48` prints.*?```\n(.*?)```", text, flags=re.S)
    shown = block.group(1).splitlines()
    printed = _gearsim("point", "--omega", "0.48", cwd=tmp_path).stdout.splitlines()
    assert len(printed) == len(shown) == 3
    for s, p in zip(shown, printed, strict=True):
        assert p.startswith(s.removesuffix("...").rstrip()), (s, p)
    # the definition printed beside Kmax is the one the README states
    from gearsim.cell.motion import KMAX_DEFINITION

    assert f"Kmax = {KMAX_DEFINITION};" in printed[2]


def test_readme_fast_look_and_own_study_say_where_they_write():
    text = (ROOT / "README.md").read_text()
    quick = next(ln for ln in _bash_lines(text) if "config/quick.yaml" in ln)
    assert "into studies/quick/" in quick
    import yaml

    assert yaml.safe_load((ROOT / "config/quick.yaml").read_text())["folder"] == "quick"
    for words in ("results/.configuration.json", "--config replace_results=true",
                  "`folder: NAME`", "`studies/quick/results/`", "make clean-results"):
        assert words in text, words
    # the README's own study: its tile_rows is explained, its torque sweep is the telling one
    study = re.search(r"```yaml\n(study: weps.*?)```", text, flags=re.S).group(1)
    cfg = yaml.safe_load(study)
    assert cfg["sweeps"]["torque"]["fixed"] == {"speed_rpm": 12000}
    assert "tile_rows: 15       # plane rows per job" in study
