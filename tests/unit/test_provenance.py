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
        ("analysis/attractors/api.py", ("tiles",), ("analysis", "catalogue", "presentation")),
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
    for scope, layers in gprov.CODE_SCOPES.items():
        files = {f.relative_to(PKG).as_posix() for f in gprov.code_files(scope)}
        expected = {r for r in every if "/" not in r or r.split("/", 1)[0] in layers}
        assert files == expected
    tiles = {f.relative_to(PKG).as_posix() for f in gprov.code_files("tiles")}
    assert {"study/tiles.py", "cell/chains.py", "numerics/batch.py", "errors.py"} <= tiles
    assert not any(r.startswith(("presentation/", "calibration/", "cli/")) for r in tiles)


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
