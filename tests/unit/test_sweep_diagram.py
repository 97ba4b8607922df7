"""Every sweep's bifurcation diagram, in the sweep's own units (gearsim figures
--sweep-diagrams): section points, DC and Kmax against the swept value."""

from __future__ import annotations

import json

import matplotlib
import numpy as np
import pytest
from sweep_tables import synthetic_sweep

from gearsim.cli.main import main
from gearsim.presentation.figures.sweeps import figure_sweep_diagram
from gearsim.results import catalogue

matplotlib.use("Agg")

#: a torque sweep as the pipeline stores it: Fm values, the physical axis kept beside them
SPEC = {"name": "Fm", "min": 0.1, "max": 2.5, "n": 24,
        "physical": {"name": "torque_Nm", "unit": "N m", "min": 4.0, "max": 100.0}}


def _torque_sweep():
    return synthetic_sweep().assign(parameter="Fm")


def test_diagram_axis_in_the_sweeps_unit():
    """The swept axis is in N m: Fm times 40 (100 N m / 2.5); the three panels hold the section
    points, DC and Kmax of every point."""
    df = _torque_sweep()
    fig, caption = figure_sweep_diagram(df, name="torque", spec=SPEC)
    ax_x, ax_dc, ax_k = fig.axes[:3]
    assert ax_k.get_xlabel() == "torque_Nm [N m]"
    xs = np.concatenate([c.get_offsets()[:, 0] for c in ax_x.collections])
    assert xs.min() == pytest.approx(0.1 * 40) and xs.max() == pytest.approx(2.5 * 40)
    n_points = sum(len(p) for p in df["poincare_x"])
    assert sum(len(c.get_offsets()) for c in ax_x.collections) == n_points
    dc_line = ax_dc.get_lines()[0]
    assert np.allclose(dc_line.get_xdata(), df["value"] * 40)
    assert np.allclose(dc_line.get_ydata(), df["dc"])
    assert np.allclose(ax_k.get_lines()[0].get_ydata(), df["kmax"])
    assert "torque_Nm [N m]" in caption and "24 points" in caption


def test_dimensionless_sweep_keeps_its_parameter():
    fig, _ = figure_sweep_diagram(synthetic_sweep(), name="standard", spec={"name": "w"})
    assert "omega" in fig.axes[2].get_xlabel() or "w" in fig.axes[2].get_xlabel()
    xs = fig.axes[1].get_lines()[0].get_xdata()
    assert xs.min() == pytest.approx(0.1) and xs.max() == pytest.approx(2.5)


def test_cli_writes_the_diagram_and_indexes_it(tmp_path):
    """The units come from the table's provenance when the config has no such sweep."""
    path = tmp_path / "torque.parquet"
    catalogue.write_parquet(_torque_sweep(), path,
                            {catalogue.PROVENANCE_KEY: {"subtree": {"sweep": SPEC}}})
    out = tmp_path / "figs"
    assert main(["figures", "--sweep-diagrams", "--sweep", f"torque={path}", "--outdir",
                 str(out), "--index"]) == 0
    for ext in ("png", "pdf"):
        assert (out / "sweeps" / f"torque.{ext}").stat().st_size > 1000
    rec = json.loads((out / "sweeps" / "torque.json").read_text())
    assert "torque_Nm [N m]" in rec["caption"]
    index = (out / "README.md").read_text()
    assert "# Bifurcation diagrams of every sweep" in index and "sweeps/torque.png" in index
    assert "## Fig" not in index  # no paper figure was drawn


def test_cli_needs_a_sweep(capsys):
    assert main(["figures", "--sweep-diagrams"]) == 2
    assert "--sweep" in capsys.readouterr().err


def test_a_dimensionless_sweep_on_a_gear_gets_a_top_axis_in_rpm():
    fig, caption = figure_sweep_diagram(
        synthetic_sweep(), name="standard", spec={"name": "w"},
        physical={"name": "speed_rpm", "unit": "rpm", "k": 20000.0})
    top = fig.axes[0].child_axes
    assert len(top) == 1 and top[0].get_xlabel() == "speed_rpm [rpm]"
    # the secondary axis maps w to k w: the panel's w limits become rpm limits
    lo, hi = fig.axes[0].get_xlim()
    assert top[0].get_xlim() == pytest.approx((20000.0 * lo, 20000.0 * hi))
    assert "Top axis: speed_rpm [rpm]" in caption


def test_plane_maps_of_a_gear_study_have_physical_axes(tmp_path):
    """With a gear file the maps get axes in rpm (w) and um (b) beside the dimensionless ones,
    and their records say so."""
    from test_figures import synthetic_plane

    from gearsim.study.config import project_root

    cells = tmp_path / "wb.parquet"
    synthetic_plane("b").to_parquet(cells)
    study = tmp_path / "gear.yaml"
    study.write_text(f"gear: {project_root() / 'config/gears/standard.yaml'}\n")
    out = tmp_path / "figs"
    assert main(["figures", "--maps", "--plane", f"wb={cells}", "--map", "pattern",
                 "--configfile", str(study), "--outdir", str(out)]) == 0
    rec = json.loads((out / "planes" / "wb-pattern.json").read_text())
    assert any("speed_rpm [rpm]" in n and "half_backlash_um [um]" in n for n in rec["notes"])
