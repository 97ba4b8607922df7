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


def test_readme_lists_the_model_forms():
    """The README's table of model forms names every option with its range and default (the
    parameters' own), and the single-DOF model."""
    from gearsim.dynamics.parameters import MODELS, PARAMETERS, ModelParameters, interval_text

    text = (ROOT / "README.md").read_text()
    assert "--set model=1dof" in text and set(MODELS) == {"6dof", "1dof"}
    defaults = ModelParameters()
    for name in ("te_damping", "mesh_damping_contact", "friction_arm_var"):
        row = next((ln for ln in text.splitlines() if ln.startswith(f"| `{name}`")), None)
        assert row is not None, name
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert cells[1] == interval_text(PARAMETERS[name]), (name, cells)
        assert float(cells[2]) == getattr(defaults, name), (name, cells)


def test_readme_study_file_example_is_a_valid_study_file(tmp_path):
    """The README's study file (`my.yaml`) merges over config/config.yaml and changes what it
    says."""
    import yaml

    from gearsim.study.config import Study

    text = (ROOT / "README.md").read_text()
    block = re.search(r"e\.g\. `my\.yaml`:\n\n```yaml\n(.*?)```", text, flags=re.S).group(1)
    (tmp_path / "my.yaml").write_text(block)
    study = Study.load([tmp_path / "my.yaml"], root=ROOT)
    doc = yaml.safe_load(block)
    model = study.parameters().model
    for name, value in doc["parameters"].items():
        assert getattr(model, name) == value
    for name, value in doc["integration"].items():
        assert getattr(study.settings, name) == value
