"""Nothing a run made is replaced unasked: a command by hand stops before writing over a file of a
recorded results folder (one line: the file, the option that writes elsewhere, the one that
replaces); a tile in place that no run of the folder computed is found before any job, named
with the settings it differs in and the command that repairs it, and nothing is removed."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from synthetic_tiles import write_tile

from gearsim.errors import UsageError
from gearsim.results import in_place as ip
from gearsim.study.config import Study

ROOT = Path(__file__).resolve().parents[2]
TINY = ROOT / "config/tiny.yaml"


def _record(tmp_path: Path, *files: Path) -> dict:
    return ip.run_record(Study.load(list(files), root=ROOT), ["config/config.yaml", *files])


def test_hand_command_stops_before_a_file_of_a_recorded_run(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    results = tmp_path / "results"
    fig = results / "figures" / "fig04.png"
    fig.parent.mkdir(parents=True)
    fig.write_bytes(b"png")
    new = results / "figures" / "fig99.png"
    # no record: not a run's folder, nothing to protect
    ip.check_hand_outputs([fig, new], replace=False, elsewhere="--outdir DIR")
    ip.write_record(_record(tmp_path, TINY), results)
    with pytest.raises(UsageError) as err:
        ip.check_hand_outputs([new, fig], replace=False, elsewhere="--outdir DIR")
    line = str(err.value)
    assert "\n" not in line
    assert line.startswith(f"{fig}: made by the workflow (a file of the results of a run in "
                           "results/)")
    assert "give --outdir DIR to write elsewhere, or --replace to replace it" in line
    assert fig.read_bytes() == b"png"
    ip.check_hand_outputs([fig], replace=True, elsewhere="--outdir DIR")  # asked: it may
    ip.check_hand_outputs([new], replace=False, elsewhere="--outdir DIR")  # a new file: fine
    ip.check_hand_outputs([tmp_path / "elsewhere.png"], replace=False, elsewhere="--out")


def test_a_tile_of_another_configuration_is_named_with_its_repair(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    study = Study.load([TINY], root=ROOT)
    record = _record(tmp_path, TINY)
    results = tmp_path / "results"
    tile = results / "wb" / "tiles" / "0.parquet"
    write_tile(study.config, "wb", 0, tile)
    ip.write_record(record, results)
    ip.check_tiles_in_place(record, results)  # the run's own tile passes
    # a tile of another grid, written by hand over the run's
    own = tmp_path / "mine.yaml"
    own.write_text("planes:\n  wb:\n    x: {name: w, min: 0.1, max: 2.5, n: 10}\n")
    other = Study.load([TINY, own], root=ROOT)
    write_tile(other.config, "wb", 0, tile)
    before = sorted(p.name for p in results.rglob("*"))
    with pytest.raises(UsageError) as err:
        ip.check_tiles_in_place(record, results)
    line = str(err.value)
    assert line.startswith("results/wb/tiles/0.parquet: a tile of another configuration")
    assert "x.n 10 -> 8" in line and "`rm results/wb/tiles/0.parquet`" in line
    assert "nothing was removed" in line and "\n" not in line
    assert sorted(p.name for p in results.rglob("*")) == before
    # this run's configuration is the tile's (the study was edited to it): it passes
    ip.check_tiles_in_place(_record(tmp_path, TINY, own), results)


def test_the_record_keeps_every_hash_a_run_had(tmp_path):
    """A run of an edited study records its hashes beside the earlier ones: tiles of either,
    left by a run interrupted after the edit, pass (Snakemake recomputes them)."""
    first = _record(tmp_path, TINY)
    own = tmp_path / "edit.yaml"
    own.write_text("planes:\n  wb:\n    fixed: {xi: 0.07}\n")
    second = _record(tmp_path, TINY, own)
    ip.write_record(first, tmp_path)
    ip.write_record(second, tmp_path)
    history = json.loads((tmp_path / ip.RECORD.name).read_text())["history"]
    assert history["plane wb"] == sorted({first["items"]["plane wb"],
                                          second["items"]["plane wb"]})
    assert history["plane wxi"] == [first["items"]["plane wxi"]]


def test_partial_kept_says_what_an_interrupted_run_keeps(tmp_path):
    import pandas as pd

    partial = tmp_path / "wb_orbits.parquet.partial"
    assert ip.partial_kept(partial, "cells refined").startswith("no cells refined were kept")
    pd.DataFrame({"i": range(7)}).to_parquet(partial)
    assert ip.partial_kept(partial, "cells refined") == \
        f"the 7 cells refined so far are kept in {partial}"
