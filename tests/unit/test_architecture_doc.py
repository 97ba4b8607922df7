"""docs/architecture.md against the package: every module of ``src/gearsim`` has its row, and
every module, file and name the page writes in backticks exists (read from the source, nothing
imported)."""

from __future__ import annotations

import ast
import re
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "src" / "gearsim"
DOC = ROOT / "docs" / "architecture.md"
#: the top folders of the repository a path in the page may start with (else it is in the package)
REPO_DIRS = ("src/", "tests/", "workflow/", "config/", "benchmarks/", "docs/", "profiles/", ".ci/")
SUBPACKAGES = tuple(p.name for p in PACKAGE.iterdir() if (p / "__init__.py").is_file())
PATH = re.compile(r"^[\w.*/-]+\.(py|smk|yaml|html)$")
DOTTED = re.compile(r"^(gearsim\.)?([a-z_]+(?:\.[A-Za-z_]\w*)+)(\(.*\))?$")


def _tokens() -> list[str]:
    return re.findall(r"`([^`\n]+)`", DOC.read_text(encoding="utf-8"))


def _modules() -> list[str]:
    return sorted(p.relative_to(PACKAGE).as_posix() for p in PACKAGE.rglob("*.py")
                  if p.name != "__init__.py")


@cache
def _top_names(path: Path) -> frozenset[str]:
    """Names a module defines at its top level (functions, classes, assignments, imports)."""
    names: set[str] = set()
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            names.add(node.name)
        elif isinstance(node, ast.Assign):
            names.update(t.id for t in node.targets if isinstance(t, ast.Name))
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
        elif isinstance(node, ast.Import | ast.ImportFrom):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
    return frozenset(names)


def _missing_name(dotted: str) -> str | None:
    """Why ``dotted`` (``cell.simulate.simulate_cell``, ``study.config.Study.load``) does not
    resolve in the package; None when it does."""
    parts = dotted.split(".")
    where = PACKAGE
    for i, part in enumerate(parts):
        if (where / part).is_dir() and (where / part / "__init__.py").is_file():
            where = where / part
            continue
        if (where / f"{part}.py").is_file():
            module = where / f"{part}.py"
            rest = parts[i + 1:]
            if rest and rest[0] not in _top_names(module):
                return f"{module.relative_to(ROOT)} defines no {rest[0]!r}"
            return None
        if i and part in _top_names(where / "__init__.py"):
            return None
        return f"no module {'.'.join(parts[:i + 1])!r} under src/gearsim"
    return None


def test_every_module_of_the_package_has_its_row():
    named = set(_tokens())
    absent = [m for m in _modules() if m not in named]
    assert not absent, (f"docs/architecture.md names no {absent}: add each module's row "
                        "(`path` | its one job) to its layer's table in \"Modules\"")


def test_every_path_the_page_names_exists():
    gone = []
    for token in _tokens():
        if not PATH.match(token):
            continue
        base = ROOT if token.startswith(REPO_DIRS) else PACKAGE
        if not list(base.glob(token)):
            gone.append(token)
    assert not gone, f"docs/architecture.md names files that do not exist: {gone}"


def test_every_package_name_the_page_writes_resolves():
    wrong = []
    for token in _tokens():
        m = DOTTED.match(token)
        if not m or m.group(2).split(".")[0] not in SUBPACKAGES:
            continue
        why = _missing_name(m.group(2))
        if why:
            wrong.append(f"`{token}`: {why}")
    assert not wrong, "docs/architecture.md: " + "; ".join(wrong)


def test_the_checks_can_fail():
    # the three checks above would catch a module without a row and a name that is gone
    assert "cell/simulate.py" in _modules()
    assert _missing_name("cell.simulate.simulate_cell") is None
    assert _missing_name("cell.simulate.no_such_function") is not None
    assert _missing_name("cell.no_such_module") is not None
    assert not list(PACKAGE.glob("cell/no_such_module.py"))
