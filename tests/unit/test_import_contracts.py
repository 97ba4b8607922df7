"""The import contracts of pyproject.toml (import-linter): the layers, the package root, and the
presentation that only reads results (indirect imports counted). `make lint` runs the same
check; this test makes the suite, and so CI, hold to it."""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
LINT_IMPORTS = Path(sys.executable).parent / "lint-imports"


def test_every_import_contract_is_kept():
    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"][
        "contracts"]
    r = subprocess.run([str(LINT_IMPORTS), "--no-cache"], cwd=ROOT, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-2000:]
    for c in contracts:  # each contract of the file was checked, not just parsed
        assert re.search(re.escape(c["name"]) + r" KEPT", r.stdout), (c["name"], r.stdout)
    assert f"{len(contracts)} kept, 0 broken" in r.stdout, r.stdout
