"""Basin grids: every start's attractor equals its full-length run; files and CLI."""

import numpy as np
import pytest
from reference import reference_settings

from gearsim.analysis.attractors import FinderOptions
from gearsim.analysis.basins import basin_grid, read_basin_grid, write_basin_grid
from gearsim.cli.main import main
from gearsim.dynamics.parameters import ModelParameters, ParameterError

REFERENCE = dict(Fm=0.1, Fe=0.1724, eps=0.371, xi=0.05, phi_e=-0.7853981633974483, friction=0.0)
GEAR = reference_settings(method="rk4")


def test_basin_grid_equals_full_length_runs_and_round_trips(tmp_path):
    p = ModelParameters(w=1.1, b=0.15, **REFERENCE)
    fast = basin_grid(p, n=10, settings=GEAR)
    full = basin_grid(p, n=10, settings=GEAR, options=FinderOptions(early=False))
    assert fast.labels.shape == (10, 10)
    assert len(fast.cell.attractors) == len(full.cell.attractors) >= 2
    assert np.array_equal(fast.labels, full.labels)
    assert fast.early.sum() > 50
    assert fast.periods.sum() < full.periods.sum()
    # the grid spans the box at cell centres, rows = velocity, columns = displacement
    assert np.all(np.diff(fast.x) > 0) and np.all(np.diff(fast.v) > 0)
    path = write_basin_grid(fast, tmp_path / "g.parquet")
    starts, att, params = read_basin_grid(path)
    assert len(starts) == 100 and params["w"] == 1.1
    assert att["basin_fraction"].sum() == pytest.approx(1.0)
    sel = starts[(starts.ix == 3) & (starts.iv == 7)].iloc[0]
    assert sel.attractor == fast.labels[7, 3]
    assert sel.x0 == fast.x[3] and sel.v0 == fast.v[7]


def test_bad_grid_rejected():
    with pytest.raises(ParameterError, match="'n'"):
        basin_grid(ModelParameters(), n=1)
    with pytest.raises(ParameterError, match="'box'"):
        basin_grid(ModelParameters(), n=4, box=(1.0, 0.0, -1.0, 1.0))


def test_cli_attractors_and_basins(tmp_path, capsys):
    args = ["--omega", "1.1", "--set", "b=0.15", "--params", "none.yaml"]
    assert main(["attractors", *args, "--starts", "4"]) == 2  # missing parameter file
    assert main(["attractors", "--omega", "1.1", "--set", "b=0.15", "--starts", "0"]) == 2
    err = capsys.readouterr().err
    assert "--starts" in err
    assert main(["attractors", "--omega", "1.1", "--set", "b=0.15", "--starts", "8"]) == 0
    out = capsys.readouterr().out
    assert "basin=" in out and "diverged:" in out
    out_file = tmp_path / "b.parquet"
    rc = main(["basins", "--omega", "1.1", "--set", "b=0.15", "--n", "6", "-o", str(out_file)])
    assert rc == 0
    assert out_file.exists() and out_file.with_suffix(".png").exists()
