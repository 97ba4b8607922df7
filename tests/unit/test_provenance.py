"""The code version covers every module that decides a result (gearsim.study.provenance)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

import gearsim
from gearsim.study import provenance as gprov

PKG = Path(gearsim.__file__).resolve().parent


@pytest.fixture(scope="module")
def copy_of_package(tmp_path_factory):
    dst = tmp_path_factory.mktemp("pkg") / "gearsim"
    shutil.copytree(PKG, dst, ignore=shutil.ignore_patterns("__pycache__"))
    return dst


def _flip_one_byte(path: Path) -> bytes:
    data = path.read_bytes()
    k = len(data) // 2
    path.write_bytes(data[:k] + bytes([data[k] ^ 0x01]) + data[k + 1 :])
    return data


def test_copy_has_the_same_version(copy_of_package):
    for scope in gprov.CODE_SCOPES:
        assert gprov.code_version(scope, copy_of_package) == gprov.code_version(scope)
        assert len(gprov.code_version(scope)) == 16


@pytest.mark.parametrize(
    "rel",
    [
        "study/tiles.py",
        "study/grid.py",
        "study/config.py",
        "dynamics/model.py",
        "numerics/batch.py",
        "cell/chains.py",
        "cell/classify.py",
        "physical/units.py",
        "errors.py",
    ],
)
def test_one_byte_in_a_deciding_module_changes_every_version(copy_of_package, rel):
    before = {s: gprov.code_version(s, copy_of_package) for s in gprov.CODE_SCOPES}
    original = _flip_one_byte(copy_of_package / rel)
    try:
        for scope in gprov.CODE_SCOPES:
            assert gprov.code_version(scope, copy_of_package) != before[scope]
    finally:
        (copy_of_package / rel).write_bytes(original)
    assert {s: gprov.code_version(s, copy_of_package) for s in gprov.CODE_SCOPES} == before


@pytest.mark.parametrize(
    ("rel", "unchanged", "changed"),
    [
        ("presentation/figures/style.py", ("tiles", "analysis", "catalogue"), ("presentation",)),
        ("presentation/report.py", ("tiles", "analysis", "catalogue"), ("presentation",)),
        ("calibration/fidelity.py", ("tiles", "analysis", "catalogue"),
         ("calibration", "presentation")),
        ("cli/commands/figures.py", tuple(gprov.CODE_SCOPES), ()),
        ("analysis/attractors/api.py", ("tiles",),
         ("attractors", "analysis", "catalogue", "presentation")),
        ("analysis/attractors/pool.py", ("tiles",), ("attractors", "analysis")),
        ("analysis/bifcurves.py", ("tiles", "attractors"), ("analysis", "presentation")),
        ("results/catalogue.py", ("tiles", "analysis"), ("catalogue", "presentation")),
    ],
)
def test_a_layer_edit_changes_only_the_scopes_that_name_it(copy_of_package, rel, unchanged,
                                                            changed):
    before = {s: gprov.code_version(s, copy_of_package) for s in gprov.CODE_SCOPES}
    original = _flip_one_byte(copy_of_package / rel)
    try:
        for scope in unchanged:
            assert gprov.code_version(scope, copy_of_package) == before[scope]
        for scope in changed:
            assert gprov.code_version(scope, copy_of_package) != before[scope]
    finally:
        (copy_of_package / rel).write_bytes(original)


def test_every_module_of_a_scope_is_hashed():
    """code_files of a scope are exactly the .py files of its layers and of the package root."""
    every = {f.relative_to(PKG).as_posix() for f in PKG.rglob("*.py")
             if "__pycache__" not in f.parts}
    for scope, entries in gprov.CODE_SCOPES.items():
        files = {f.relative_to(PKG).as_posix() for f in gprov.code_files(scope)}
        inner = [e for e in entries if "/" in e]
        expected = {r for r in every if "/" not in r or r.split("/", 1)[0] in entries
                    or any(r == f"{e}.py" or r.startswith(f"{e}/") for e in inner)
                    or any(r == f"{e.split('/')[0]}/__init__.py" for e in inner)}
        assert files == expected
    tiles = {f.relative_to(PKG).as_posix() for f in gprov.code_files("tiles")}
    assert {"study/tiles.py", "cell/chains.py", "numerics/batch.py", "errors.py"} <= tiles
    assert not any(r.startswith(("presentation/", "calibration/", "cli/")) for r in tiles)


def test_a_scope_that_loses_its_modules_is_refused(copy_of_package, monkeypatch):
    """A renamed module must not drop out of the jobs' code versions unseen; one of a scope's
    modules may go while another of them is there."""
    monkeypatch.setitem(gprov.CODE_SCOPES, "probe", (*gprov.SIMULATION, "analysis/gone"))
    with pytest.raises(ValueError, match="analysis/gone"):
        gprov.code_version("probe", copy_of_package)
    monkeypatch.setitem(gprov.CODE_SCOPES, "probe",
                        (*gprov.SIMULATION, "analysis/gone", "analysis/basins"))
    files = {f.relative_to(copy_of_package).as_posix()
             for f in gprov.code_files("probe", copy_of_package)}
    assert {"analysis/basins.py", "analysis/__init__.py"} <= files
    assert not any(f.startswith("analysis/") and f not in ("analysis/basins.py",
                   "analysis/__init__.py") for f in files)
    monkeypatch.setitem(gprov.CODE_SCOPES, "probe", ("nolayer",))
    with pytest.raises(ValueError, match="nolayer"):
        gprov.code_version("probe", copy_of_package)


def test_an_unknown_scope_is_refused():
    with pytest.raises(ValueError, match="code scope"):
        gprov.code_version("everything")


def test_a_new_module_and_a_rename_change_the_version(copy_of_package):
    before = gprov.code_version("tiles", copy_of_package)
    new = copy_of_package / "dynamics" / "nonlinearity.py"
    new.write_text("GAIN = 1.0\n")
    try:
        assert gprov.code_version("tiles", copy_of_package) != before
    finally:
        new.unlink()
    src, dst = copy_of_package / "study" / "grid.py", copy_of_package / "study" / "grids.py"
    src.rename(dst)
    try:
        assert gprov.code_version("tiles", copy_of_package) != before
    finally:
        dst.rename(src)
    assert gprov.code_version("tiles", copy_of_package) == before
