"""Rooms meet through public names, and the figures only read.

* No module of ``src/gearsim`` imports another subpackage's underscore name
  (``from gearsim.X.m import _y`` where X is not the importer's own subpackage), nor reads one
  as an attribute of a module it imported (``m._y``, ``gearsim.X.m._y``).
* No figure of the figure table reaches the integrators: the modules its builder's module
  imports, directly or through others (function-level imports included), hold none of them.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src"
PACKAGE = SRC / "gearsim"


def _module(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _room(module: str) -> str:
    """The subpackage a module belongs to (``gearsim.results``); the root's own modules are
    the room ``gearsim``."""
    parts = module.split(".")
    return ".".join(parts[:2]) if len(parts) > 2 or (PACKAGE / parts[-1]).is_dir() else "gearsim"


def _private_imports(text: str, importer: str) -> list[str]:
    """``importer:line imports module.name`` for every underscore name that ``text`` (the
    source of the module ``importer``) imports from another room."""
    out = []
    for node in ast.walk(ast.parse(text)):
        if not isinstance(node, ast.ImportFrom) or node.level or not node.module:
            continue
        if not node.module.startswith("gearsim"):
            continue
        for alias in node.names:
            private = alias.name.startswith("_") and not alias.name.startswith("__")
            if private and _room(node.module) != _room(importer):
                out.append(f"{importer}:{node.lineno} imports {node.module}.{alias.name}")
    return out


def _is_module(dotted: str) -> bool:
    where = SRC.joinpath(*dotted.split("."))
    return where.with_suffix(".py").is_file() or (where / "__init__.py").is_file()


def _private_attributes(text: str, importer: str) -> list[str]:
    """``importer:line reads module.name`` for every underscore name that ``text`` reads as an
    attribute of a module of another room (a module bound by ``import gearsim.X.m [as n]`` or
    ``from gearsim.X import m``, or written out as ``gearsim.X.m``)."""
    tree = ast.parse(text)
    bound: dict[str, str] = {"gearsim": "gearsim"}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("gearsim.") and alias.asname:
                    bound[alias.asname] = alias.name
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            for alias in node.names:
                full = f"{node.module}.{alias.name}"
                if node.module.startswith("gearsim") and _is_module(full):
                    bound[alias.asname or alias.name] = full

    def dotted(node) -> str | None:
        if isinstance(node, ast.Name):
            return bound.get(node.id)
        if isinstance(node, ast.Attribute):
            base = dotted(node.value)
            return f"{base}.{node.attr}" if base else None
        return None

    out = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Attribute):
            continue
        if not node.attr.startswith("_") or node.attr.startswith("__"):
            continue
        base = dotted(node.value)
        if base and _is_module(base) and _room(base) != _room(importer):
            out.append((node.lineno, f"{importer}:{node.lineno} reads {base}.{node.attr}"))
    return [hit for _, hit in sorted(out)]


def test_room_finds_subpackages():
    assert _room("gearsim.results.parquet") == "gearsim.results"
    assert _room("gearsim.analysis.attractors.pool") == "gearsim.analysis"
    assert _room("gearsim.errors") == "gearsim"


def test_the_check_sees_a_private_import():
    text = ("from gearsim.results.parquet import _tmp_name\n"
            "from gearsim.presentation.context import _need, Built\n"
            "from gearsim.dynamics import model as _m\n")
    assert _private_imports(text, "gearsim.presentation.report") == [
        "gearsim.presentation.report:1 imports gearsim.results.parquet._tmp_name"]


def test_the_check_sees_a_private_attribute():
    text = ("from gearsim.presentation.figures import context\n"
            "import gearsim.numerics.kernel as k\n"
            "import gearsim.results.parquet\n"
            "from gearsim.cli.commands import _common\n"
            "a = context._axes(df)\n"
            "b = k._redo_lane\n"
            "c = gearsim.results.parquet._tmp_name(p)\n"
            "d = context.Context()._private\n"
            "e = _common.json_safe\n")
    assert _private_attributes(text, "gearsim.cli.commands.figures") == [
        "gearsim.cli.commands.figures:5 reads gearsim.presentation.figures.context._axes",
        "gearsim.cli.commands.figures:6 reads gearsim.numerics.kernel._redo_lane",
        "gearsim.cli.commands.figures:7 reads gearsim.results.parquet._tmp_name"]
    # inside its own room a module may read another's underscore names
    assert _private_attributes("from gearsim.cli.commands import _common\nx = _common._file\n",
                               "gearsim.cli.commands.point") == []


def test_no_module_reads_another_rooms_underscore_attribute():
    found = [hit for path in sorted(PACKAGE.rglob("*.py"))
             for hit in _private_attributes(path.read_text(encoding="utf-8"), _module(path))]
    assert not found, "\n".join(found)


def test_no_module_imports_another_rooms_underscore_name():
    found = [hit for path in sorted(PACKAGE.rglob("*.py"))
             for hit in _private_imports(path.read_text(encoding="utf-8"), _module(path))]
    assert not found, "\n".join(found)


#: what a figure job must never load: the integrators, one cell's and one sweep's simulation,
#: the finder, the basins and the figure-data simulations
INTEGRATORS = ("gearsim.numerics.integrate", "gearsim.numerics.kernel", "gearsim.numerics.batch",
               "gearsim.numerics.steps", "gearsim.numerics.events", "gearsim.numerics.variational",
               "gearsim.cell.simulate", "gearsim.cell.sweep", "gearsim.cell.chains",
               "gearsim.analysis.attractors", "gearsim.analysis.basins",
               "gearsim.study.figure_data")


def test_no_figure_job_reaches_the_integrators():
    grimp = pytest.importorskip("grimp")
    from gearsim.presentation.figures import registry

    graph = grimp.build_graph("gearsim")
    modules = {spec.builder.__module__ for spec in registry.figures().values()}
    assert {"gearsim.presentation.figures.builders", "gearsim.presentation.figures.multistability",
            "gearsim.presentation.figures.orbits"} <= modules
    for module in sorted(modules):
        reached = graph.find_upstream_modules(module)
        bad = sorted(m for m in reached if m.startswith(INTEGRATORS))
        assert not bad, f"{module} reaches {bad}"
    # the check can fail: the figure-data job does reach them
    assert "gearsim.cell.simulate" in graph.find_upstream_modules("gearsim.study.figure_data")


def test_the_attractor_tile_command_is_as_thin_as_the_tile_command():
    """The attractor tile's job lives in study/attractor_tiles.py beside study/tiles.py; the
    command parses, calls it and writes (at most 80 lines)."""
    commands = PACKAGE / "cli" / "commands"
    lines = len((commands / "attractor_tile.py").read_text(encoding="utf-8").splitlines())
    assert lines <= 80, lines
    text = (commands / "attractor_tile.py").read_text(encoding="utf-8")
    assert "run_tile_job" in text and "task_specs" in text and "map_unordered" not in text
