"""Every gearsim command of the README is accepted by the command line as written."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def bash_gearsim_lines(text: str) -> list[list[str]]:
    """Every `gearsim ...` command of the README's bash blocks, as argument lists (comments and
    optional `[...]` parts left out)."""
    out = []
    for block in re.findall(r"```bash\n(.*?)```", text, flags=re.S):
        for line in block.splitlines():
            line = re.sub(r"\s+#.*$", "", line).strip()
            if line.startswith("gearsim "):
                out.append(shlex.split(re.sub(r"\[[^]]*\]", "", line))[1:])
    return out


def test_readme_commands_parse():
    from gearsim.cli.main import build_parser

    lines = bash_gearsim_lines((ROOT / "README.md").read_text())
    assert len(lines) > 15
    for argv in lines:
        try:
            build_parser(argv[0]).parse_args(argv)
        except SystemExit as exc:  # argparse's exit: a README line the CLI rejects
            raise AssertionError(f"gearsim {' '.join(argv)}: rejected ({exc})") from None
