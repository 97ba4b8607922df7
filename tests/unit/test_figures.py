"""Figures: every figure function runs on tiny synthetic inputs and draws something readable.

Checks on the matplotlib Figure objects: every visible axes has axis labels (3-D: also z) and
non-empty artists; figures that have a legend in the paper (bifurcation colours, pattern maps,
I:DC maps, phase portraits, spectra) have one. The data are synthetic (a few rows built here) or
a couple of tiny simulations, so the whole module runs in seconds.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402
from reference import reference_settings
from sweep_tables import synthetic_sweep

from gearsim.cell.classify import Classification  # noqa: E402
from gearsim.cli.main import main  # noqa: E402
from gearsim.dynamics.parameters import ModelParameters  # noqa: E402
from gearsim.presentation.figures import bifurcation, phase, planes, schematic, spectra, style  # noqa: E402
from gearsim.presentation.figures.context import Context, sweep_title  # noqa: E402
from gearsim.presentation.figures.data import (  # noqa: E402
    PointMotion,
    Recorded,
    Track,
    plane_axes,
    spectrum,
)
from gearsim.presentation.figures.registry import FIGURES, build  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
TINY = reference_settings(rtol=1e-7, atol=1e-10, transient=20, transient_continuation=8,
                           chunk=8, max_periods=16, n_max=4)


# ------------------------------------------------------------------------------ synthetic data
def synthetic_plane(yname: str = "b", nx: int = 10, ny: int = 6) -> pd.DataFrame:
    sweep = synthetic_sweep(nx)
    rows = []
    ys = np.linspace(0.05, 0.95, ny) if yname == "b" else np.linspace(0.045, 0.155, ny)
    for j, y in enumerate(ys):
        for i, r in sweep.iterrows():
            row = r.to_dict()
            row.update(i=i, j=j, w=r["value"], **{yname: float(y)}, x=r["value"], y=float(y))
            if j == 0 and i == 3:
                row.update(dc=float("nan"), status="diverged", motion="diverged",
                           label="diverged", poincare_x=[], poincare_v=[])
            rows.append(row)
    df = pd.DataFrame(rows).drop(columns=["parameter", "value", "direction"])
    return df


def synthetic_point(w: float = 0.8, n: int = 2, I: int = 2, spp: int = 64,
                    periods: int = 16) -> PointMotion:
    p = ModelParameters(w=w, b=0.15)
    T = p.mesh_period
    tau = np.arange(periods * spp + 1) * T / spp
    x = 0.5 * np.cos(w * tau) + 0.2 * np.cos(w * tau / n) + 0.1
    v = np.gradient(x, tau)
    state = np.c_[x, v]
    sec = state[::spp][:-1]
    force = np.where(x > p.b, x - p.b, np.where(x < -p.b, x + p.b, 0.0)) + 0.1 * v
    tr = Track(tau, state, force, sec)
    cls = Classification(
        motion="periodic", status="ok", I=I, n=n, p=n, q=1, label=f"{I}/{n}T",
        label_npq=f"{n}-{n}-1", dc=0.2, kmax_peak_mean=3.0, kmax_peak_static=1.5,
        kmax_section_mean=1.0, kmax_section_static=0.5, kmin_peak_mean=-1.0, lyapunov=-0.1,
        x_min=float(x.min()), x_max=float(x.max()), converged=True, window_periods=32,
    )
    return PointMotion(p, Recorded(cls), tr, spp)


# ------------------------------------------------------------------------------ checks
def _is_3d(ax) -> bool:
    return hasattr(ax, "get_zlabel")


def _data_axes(fig):
    """Axes that carry data (not colour bars, not switched off)."""
    out = []
    for ax in fig.axes:
        if not ax.axison and not _is_3d(ax):
            continue
        if ax.get_label() == "<colorbar>":
            continue
        out.append(ax)
    return out


def check_figure(fig, *, legend: bool, min_axes: int = 1) -> None:
    axes = _data_axes(fig)
    assert len(axes) >= min_axes
    for ax in axes:
        # panels stacked on a shared x axis carry the label once, on the bottom panel
        siblings = ax.get_shared_x_axes().get_siblings(ax)
        assert any(a.get_xlabel().strip() for a in siblings), f"missing x label in {ax}"
        assert ax.get_ylabel().strip(), f"missing y label in {ax}"
        if _is_3d(ax):
            assert ax.get_zlabel().strip()
        artists = ax.collections + ax.lines + ax.patches + ax.images
        assert artists, "axes without artists"
        sizes = []
        for a in ax.collections:
            if hasattr(a, "get_offsets") and len(a.get_offsets()):
                sizes.append(len(a.get_offsets()))
            elif hasattr(a, "get_array") and a.get_array() is not None:
                sizes.append(np.size(a.get_array()))
            elif hasattr(a, "get_paths"):
                sizes.append(len(a.get_paths()))
        sizes += [len(line.get_xdata()) for line in ax.lines]
        sizes += [1 for _ in ax.patches]
        assert sum(sizes) > 0, "artists are empty"
    if legend:
        assert any(ax.get_legend() is not None for ax in fig.axes), "legend missing"
    plt.close(fig)


# ------------------------------------------------------------------------------ tests
def test_style_categories_and_bands():
    assert style.pattern_category("periodic", 0, 1) == "0/1T"
    assert style.pattern_category("periodic", 1, 1) == "1/1T"
    assert style.pattern_category("periodic", 1, 8) == "1/8T"
    assert style.pattern_category("periodic", 1, 6) == "1/nT"
    assert style.pattern_category("periodic", 2, 4) == "2/4T"
    assert style.pattern_category("chaos", 2, 0) == "chaos2"
    assert style.pattern_category("chaos", 1, 0) == "chaos1"
    assert style.pattern_category("diverged", 0, 0) == "other"
    assert style.PATTERN_COLOURS["0/1T"].lower() in ("#e41a1c",)  # red
    assert style.PATTERN_COLOURS["1/1T"].lower() == "#ffd92f"  # yellow
    assert style.IMPACT_COLOURS[0] == "#d62728" and style.IMPACT_COLOURS[1] == "#000000"
    # dark grey for double-sided chaos, light grey for face-impact chaos
    dark = int(style.PATTERN_COLOURS["chaos2"][1:3], 16)
    light = int(style.PATTERN_COLOURS["chaos1"][1:3], 16)
    assert dark < light
    assert style.dc_band(0.0) == "0.0"
    assert style.dc_band(0.05) == "0.0\u20130.1"
    assert style.dc_band(0.66) == "0.6\u20130.7"
    assert style.dc_band(1.0) == "0.9\u20131.0"
    assert style.dc_band(float("nan")) == "n/a"


def test_fig1_schematic():
    fig = schematic.figure1()
    ax = fig.axes[0]
    texts = " ".join(t.get_text() for t in ax.texts)
    for sym in ("K_{py}", "C_{gz}", "K(t)", "C_n", "2B", "y_p", "theta_g", "T_p"):
        assert sym in texts, sym
    assert len(ax.patches) > 5 and len(ax.lines) > 20
    plt.close(fig)


def test_fig4_bifurcation_dc_kmax():
    df = synthetic_sweep()
    fig = bifurcation.figure4(df)
    check_figure(fig, legend=True, min_axes=3)
    lm = bifurcation.landmarks_of(df)
    assert {"grazing", "period_doubling"} <= set(lm["kind"])


def test_bifurcation_colours_follow_impact_state():
    df = synthetic_sweep()
    fig, ax = plt.subplots()
    bifurcation.draw_bifurcation(ax, df, annotate=False)
    colours = {tuple(np.round(c, 3)) for c in ax.collections[0].get_facecolors()}
    assert (0.839, 0.153, 0.157, 1.0) in colours  # red I = 0
    assert (0.0, 0.0, 0.0, 1.0) in colours  # black I = 1
    plt.close(fig)


@pytest.mark.parametrize("number", [8, 15])
def test_sweep_panels(number):
    names = ("b015", "b025", "b035") if number == 8 else ("xi005", "xi009", "xi015")
    ctx = Context(sweeps={n: synthetic_sweep() for n in names})
    (b,) = build([number], ctx)
    check_figure(b.figure, legend=True, min_axes=3)
    assert len(b.differences) == 4


@pytest.mark.parametrize("yname", ["b", "xi"])
def test_plane_figures(yname):
    df = synthetic_plane(yname)
    assert plane_axes(df) == ("w", yname)
    check_figure(planes.figure_pattern(df), legend=True, min_axes=2)
    check_figure(planes.figure_dc(df), legend=True, min_axes=2)
    check_figure(planes.figure_kmax(df), legend=False, min_axes=2)
    check_figure(planes.figure3(df, nx=5, ny=3), legend=True)


def test_dc_map_categories():
    df = synthetic_plane("b")
    fig, ax = plt.subplots()
    present = planes.draw_dc_map(ax, df)
    assert "0:0.0" in present and "1:0.5\u20130.6" in present and "no data" in present
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == present
    plt.close(fig)


def test_fig2_phase_plane():
    pms = {0: synthetic_point(n=1, I=0), 1: synthetic_point(n=1, I=1), 2: synthetic_point()}
    fig = phase.figure2(phase.Fig2Data(0.15, pms))
    check_figure(fig, legend=True)


def test_fig5_and_fig6_from_points():
    pts = [synthetic_point(w=w) for w in (0.48, 1.02, 1.37, 1.53)]
    check_figure(phase.figure5(pts), legend=True, min_axes=4)
    check_figure(spectra.figure6(pts), legend=True, min_axes=4)


def test_spectrum_lines_on_bins():
    pm = synthetic_point(w=0.8, n=2, periods=16)
    f, a = spectrum(pm)
    k = int(np.argmax(a))
    assert math.isclose(f[k], 0.8, rel_tol=1e-9)
    assert math.isclose(a[k], 0.5, rel_tol=0.02)  # amplitude of the w line
    sub = int(np.argmin(np.abs(f - 0.4)))
    assert math.isclose(a[sub], 0.2, rel_tol=0.02)


def test_fig9_11_panels_and_missing_note():
    pm = synthetic_point()
    fig = phase.figure_double_sided(pm, target="2-2-1", note="2-2-1 reached from 1 of 1")
    check_figure(fig, legend=True, min_axes=3)
    fig = phase.figure_double_sided(None, target="4-4-2", note="4-4-2 NOT found")
    assert any("NOT found" in t.get_text() for ax in fig.axes for t in ax.texts)
    plt.close(fig)


def test_choose_motion_reports_missing_targets():
    p = ModelParameters(w=0.82, b=0.15)
    found = {"1-1-1": phase.Attractor("1-1-1", "2/1T", synthetic_point(n=1), 5)}
    search = phase.AttractorSearch(p, 5, found)
    pm, note = phase.choose_motion(search, "1-1-1")
    assert pm is found["1-1-1"].motion and "5 of 5" in note
    pm, note = phase.choose_motion(search, "4-4-2", used=["1-1-1"])
    assert pm is not None and "NOT found" in note and "Shown instead" in note


def test_simulated_points_tiny_read_back_as_simulated():
    """The study-side simulations on real (tiny) runs: Fig 5 points and the attractor search;
    the search written as its figure-data table reads back as the figures' search, motion for
    motion (keys, hits, labels, trajectories, section points)."""
    from gearsim.study import figure_data as fd

    p = ModelParameters()
    pts = fd.compute_points(p, [0.3], settings=TINY, min_periods=4, samples_per_period=16)
    assert pts[0].traj.state.shape[0] >= 4 * 16
    search = fd.search_attractors(p.with_(w=0.82, b=0.15), settings=TINY, grid=(2, 1),
                                  min_periods=4, backward_from=0.02, backward_step=0.01)
    assert search.tried == 5 and search.found
    rows = [(k, "found", hits, m) for k, (m, hits) in search.found.items()]
    df = fd._motion_rows(rows)
    read = phase.search_from_table(df, {"params": search.params.to_dict(),
                                        "tried": search.tried, "unconfirmed": {}}, p)
    assert read.params == search.params and read.tried == search.tried
    assert list(read.found) == list(search.found)
    for k, (m, hits) in search.found.items():
        a = read.found[k]
        assert a.hits == hits and a.npq == k and a.label == m.result.classification.label
        assert a.motion.samples_per_period == m.samples_per_period and a.motion.seed == m.seed
        assert np.array_equal(a.motion.traj.state, m.traj.state[:, :2])
        assert np.array_equal(a.motion.traj.section, m.traj.section[:, :2])
        assert np.array_equal(a.motion.traj.mesh_force, m.traj.mesh_force)
        assert a.motion.result.classification.n == m.result.classification.n


def test_sweep_title():
    assert sweep_title("b015") == "b = 0.15"
    assert sweep_title("xi009") == "ξ = 0.09"
    assert sweep_title("x", {"b": 0.25}) == "b = 0.25"


def test_cli_fig1_and_index(tmp_path, monkeypatch):
    monkeypatch.chdir(ROOT)
    assert main(["figures", "--fig", "1", "--outdir", str(tmp_path), "--index"]) == 0
    for ext in ("png", "pdf", "json"):
        assert (tmp_path / f"fig01.{ext}").stat().st_size > 1000 or ext == "json"
    rec = json.loads((tmp_path / "fig01.json").read_text())
    assert rec["paper_caption"] == FIGURES[1].paper_caption and rec["differences"]
    index = (tmp_path / "README.md").read_text()
    # only what was drawn: Fig 1, not the figures of this study that were not drawn
    assert "## Fig 1\n" in index and "## Fig 17" not in index and "Not built" not in index


def test_cli_sweep_figure(tmp_path, monkeypatch):
    monkeypatch.chdir(ROOT)
    path = tmp_path / "standard.parquet"
    synthetic_sweep().to_parquet(path)
    out = tmp_path / "figs"
    assert main(["figures", "--fig", "4", "--sweep", f"standard={path}",
                 "--outdir", str(out)]) == 0
    assert (out / "fig04.png").is_file() and (out / "fig04.pdf").is_file()
    rec = json.loads((out / "fig04.json").read_text())
    assert any("grazing" in d for d in rec["differences"])


def test_cli_errors(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(ROOT)
    assert main(["figures", "--fig", "4", "--outdir", str(tmp_path)]) == 2
    assert "needs the sweep 'standard'" in capsys.readouterr().err
    assert main(["figures", "--fig", "99", "--outdir", str(tmp_path)]) == 2
    assert main(["figures", "--outdir", str(tmp_path)]) == 2
    assert main(["figures", "--fig", "4", "--sweep", "nofile"]) == 2
    assert main(["figures", "--map", "dc", "--outdir", str(tmp_path)]) == 2
    assert "--map KIND needs --maps" in capsys.readouterr().err
    assert main(["figures", "--maps", "--outdir", str(tmp_path)]) == 2
    assert "--maps needs at least one --plane" in capsys.readouterr().err
    plane = tmp_path / "p.parquet"
    synthetic_plane("eps").to_parquet(plane)
    assert main(["figures", "--maps", "--map", "nope", "--plane", f"p={plane}",
                 "--outdir", str(tmp_path / "m")]) == 2
    assert "unknown plane map 'nope'; allowed: pattern, dc, kmax" in capsys.readouterr().err
    assert not (tmp_path / "m").exists()  # nothing partial


def test_kmax_colour_scale_ignores_a_runaway_cell():
    Z = np.ones((10, 10))
    Z[3, 3] = 50.0
    assert planes.robust_max(Z) < 3.0
    assert planes.robust_max(np.linspace(0, 2, 100).reshape(10, 10)) == pytest.approx(2.0)
    df = synthetic_plane("b")
    df.loc[df.index[5], "kmax"] = 100.0
    fig = planes.figure_kmax(df)
    assert any("above" in t.get_text() for ax in fig.axes for t in ax.texts)
    plt.close(fig)


def test_fig4_landmark_labels_are_staggered_not_stacked():
    """Labels of marks closer than a line of text (Fig 4's 1.565 / 1.585 / 1.619) are spread
    to at least the minimum separation; an isolated mark's label does not move."""
    fig, ax = plt.subplots(figsize=(7.5, 3.0))
    ax.set_xlim(0.1, 2.5)
    xs = [0.645, 1.565, 1.585, 1.619, 2.2]
    dx = bifurcation.label_shifts(ax, xs, min_sep_pt=7.5)
    width = ax.get_window_extent().width * 72.0 / fig.dpi
    at = [(x - 0.1) / 2.4 * width + d for x, d in zip(xs, dx, strict=True)]
    assert dx[0] == 0.0 and dx[-1] == 0.0
    assert all(b - a >= 7.5 - 1e-9 for a, b in zip(at, at[1:], strict=False))
    assert any(d != 0.0 for d in dx[1:4])
    assert abs(np.mean(dx[1:4])) < 1e-6  # the crowded run stays centred on its marks
    plt.close(fig)
