"""The rule files include in any order: each names its own outputs and reads the others' through
input functions, and no list is appended to in include order. A Snakefile that includes them in
the reverse order (common.smk first: the configuration) plans the same jobs, with the same
outputs and shell commands, as the project's (dry runs only, seconds)."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

from workflow_helpers import ROOT, make_workdir, smk

INCLUDE = re.compile(r'^include: "(workflow/rules/[a-z_]+\.smk)"$', re.M)


def _plan(stdout: str) -> list[str]:
    """Every job of a dry run as its rule, outputs and shell command (sorted)."""
    jobs = []
    for block in re.split(r"\n(?=(?:local)?rule \w+:)", stdout):
        m = re.match(r"(?:local)?rule (\w+):", block)
        if not m:
            continue
        out = re.search(r"^\s+output: (.*)$", block, re.M)
        shell = [ln.strip() for ln in block.splitlines() if ln.strip().startswith("gearsim ")]
        jobs.append(f"{m.group(1)} | {out.group(1) if out else ''} | {' '.join(shell)}")
    return sorted(jobs)


def _reordered(tmp: Path) -> Path:
    """A copy of the project's Snakefile and workflow/ whose rule files include in reverse."""
    text = (ROOT / "Snakefile").read_text()
    files = INCLUDE.findall(text)
    assert files[0] == "workflow/rules/common.smk" and len(files) >= 9
    order = [files[0], *reversed(files[1:])]
    assert order != files
    lines = iter(f'include: "{f}"' for f in order)
    text = INCLUDE.sub(lambda m: next(lines), text)
    proj = tmp / "project"
    shutil.copytree(ROOT / "workflow", proj / "workflow")
    if (ROOT / "docs/calibration.json").is_file():  # the report reads it beside the Snakefile
        (proj / "docs").mkdir()
        shutil.copy(ROOT / "docs/calibration.json", proj / "docs/calibration.json")
    (proj / "Snakefile").write_text(text)
    return proj / "Snakefile"


def test_the_rule_files_include_in_any_order(tmp_path):
    wd = make_workdir(tmp_path / "work")
    args = ("-n", "-p", "--configfile", "config/tiny.yaml")
    ours = smk(wd, *args)
    theirs = smk(wd, "-s", str(_reordered(tmp_path)), *args)
    plan = _plan(ours.stdout)
    assert len(plan) > 40 and any(p.startswith("figure_09_10_11 |") for p in plan)
    assert _plan(theirs.stdout) == plan
