"""The code version covers every module that decides a result (gearsim.provenance)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

import gearsim
from gearsim import provenance as gprov

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
    assert gprov.code_version(copy_of_package) == gprov.code_version()
    assert len(gprov.code_version()) == 16


@pytest.mark.parametrize(
    "rel",
    [
        "commands/catalogue.py",  # the audit (was missed by the hand-kept module list)
        "commands/sweep.py",  # sweeps and named points (was missed)
        "commands/simulate_tile.py",
        "tiles.py",
        "grid.py",
        "config.py",
        "model.py",
        "batch.py",
        "catalogue.py",
    ],
)
def test_one_byte_in_a_deciding_module_changes_the_version(copy_of_package, rel):
    before = gprov.code_version(copy_of_package)
    original = _flip_one_byte(copy_of_package / rel)
    try:
        assert gprov.code_version(copy_of_package) != before
    finally:
        (copy_of_package / rel).write_bytes(original)
    assert gprov.code_version(copy_of_package) == before


def test_every_deciding_module_is_hashed():
    """Every .py file outside the presentation-only list is in code_files, commands/ included."""
    files = {f.relative_to(PKG).as_posix() for f in gprov.code_files()}
    every = {
        f.relative_to(PKG).as_posix() for f in PKG.rglob("*.py") if "__pycache__" not in f.parts
    }
    presentation = {
        r
        for r in every
        if any(r == ex or (ex.endswith("/") and r.startswith(ex)) for ex in gprov.PRESENTATION_ONLY)
    }
    assert files == every - presentation
    assert {"commands/catalogue.py", "commands/sweep.py", "cli.py", "tiles.py"} <= files
    assert not any(r.startswith("figures/") for r in files)


def test_a_new_module_and_a_rename_change_the_version(copy_of_package):
    before = gprov.code_version(copy_of_package)
    new = copy_of_package / "nonlinearity.py"
    new.write_text("GAIN = 1.0\n")
    try:
        assert gprov.code_version(copy_of_package) != before
    finally:
        new.unlink()
    src, dst = copy_of_package / "grid.py", copy_of_package / "grids.py"
    src.rename(dst)
    try:
        assert gprov.code_version(copy_of_package) != before
    finally:
        dst.rename(src)
    assert gprov.code_version(copy_of_package) == before


def test_presentation_module_does_not_change_the_version(copy_of_package):
    before = gprov.code_version(copy_of_package)
    target = copy_of_package / "figures" / "style.py"
    original = _flip_one_byte(target)
    try:
        assert gprov.code_version(copy_of_package) == before
    finally:
        target.write_bytes(original)
