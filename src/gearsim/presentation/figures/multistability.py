"""Figures of coexisting attractors (beyond the paper): basin pictures, coexistence maps,
basin-fraction maps of the continuation attractor.

Inputs: a basin grid (:mod:`gearsim.analysis.basins`, one row per start) with its attractor table,
or a
plane's cells table with ``n_attractors`` and its ``attractors`` table (catalogue, one row per
attractor of a cell: ``i``, ``j``, ``attractor``, ``label``, ``motion``, ``I``, ``n``,
``basin_fraction``, ``found_by``).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from gearsim.analysis.paper import PAPER_COEXIST
from gearsim.presentation.figures import style

# distinct colours for attractor indices of one cell (basin pictures)
_ATTRACTOR_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b",
                      "#e377c2", "#bcbd22", "#17becf", "#7f7f7f"]  # fmt: skip
_DIVERGED = "#000000"


def _pattern_text(row) -> str:
    npq = row.get("label_npq") or ""
    return f"{row['label']} ({npq})" if npq else str(row["label"])


def figure_basins(starts: pd.DataFrame, attractors: pd.DataFrame, *, title: str | None = None):
    """Basin picture: the start grid in ``(x, x')`` coloured by the attractor reached, with the
    attractors' section points drawn on top; legend with pattern and basin fraction."""
    # matplotlib here, not at the top: the workflow reads this module's figure table on every
    # parse, without drawing
    import matplotlib.pyplot as plt
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.patches import Patch

    nx = int(starts["ix"].max()) + 1
    nv = int(starts["iv"].max()) + 1
    grid = np.full((nv, nx), -1, dtype=int)
    grid[starts["iv"].to_numpy(), starts["ix"].to_numpy()] = starts["attractor"].to_numpy()
    xs = np.sort(starts["x0"].unique())
    vs = np.sort(starts["v0"].unique())
    k = max(len(attractors), 1)
    colours = [_DIVERGED] + [_ATTRACTOR_COLOURS[i % len(_ATTRACTOR_COLOURS)] for i in range(k)]
    cmap = ListedColormap(colours)
    norm = BoundaryNorm(np.arange(-1.5, k + 0.5), cmap.N)
    fig, ax = plt.subplots(figsize=(7.8, 5.2))
    dx = (xs[-1] - xs[0]) / max(len(xs) - 1, 1)
    dv = (vs[-1] - vs[0]) / max(len(vs) - 1, 1)
    extent = (xs[0] - dx / 2, xs[-1] + dx / 2, vs[0] - dv / 2, vs[-1] + dv / 2)
    ax.imshow(grid, origin="lower", extent=extent, aspect="auto", cmap=cmap, norm=norm,
              interpolation="nearest", rasterized=True)  # fmt: skip
    handles = []
    markers = "osD^vP*X"
    for _, a in attractors.iterrows():
        idx = int(a["attractor"])
        c = colours[idx + 1]
        mk = markers[idx % len(markers)]
        px, pv = np.asarray(a["poincare_x"]), np.asarray(a["poincare_v"])
        ax.scatter(px, pv, s=22 if len(px) < 20 else 4, marker=mk, c=c, edgecolors="white",
                   linewidths=0.8, zorder=5)  # fmt: skip
        handles.append(plt.Line2D([], [], marker=mk, ls="", mfc=c, mec="white", ms=9,
                                  label=f"{_pattern_text(a)}: basin {a['basin_fraction']:.3f}"))
    nd = int(np.sum(grid < 0))
    if nd:
        handles.append(Patch(facecolor=_DIVERGED, label=f"diverged: {nd / grid.size:.3f}"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7.5,
              frameon=False, title=f"attractor: basin fraction ({nx} x {nv} starts);\n"
              "markers: its Poincare points", title_fontsize=8)  # fmt: skip
    ax.set_xlabel("start " + style.X_LABEL)
    ax.set_ylabel("start " + style.V_LABEL)
    if title:
        ax.set_title(title, fontsize=9)
    fig.tight_layout()
    return fig


# ------------------------------------------------------------------------------ hysteresis
def figure_hysteresis(sweeps: pd.DataFrame, *, title: str | None = None):
    """Forward and backward sweeps side by side: (a) Poincare x, (b) DC; the band shaded."""
    import matplotlib.pyplot as plt

    from gearsim.analysis.hysteresis import hysteresis

    h = hysteresis(sweeps)
    fig, axes = plt.subplots(2, 1, figsize=(7.5, 6.4), sharex=True)
    styles = {"forward": dict(c="#1f4fd6", marker=".", s=10, label="increasing w (forward)"),
              "backward": dict(c="#d62728", marker="o", s=7, facecolors="none", linewidths=0.5,
                               label="decreasing w (backward)")}  # fmt: skip
    for d, kw in styles.items():
        part = sweeps[sweeps["direction"] == d]
        xs = np.concatenate([[v] * len(p) for v, p in zip(part["value"], part["poincare_x"],
                                                           strict=True)])  # fmt: skip
        ys = np.concatenate([np.asarray(p, dtype=float) for p in part["poincare_x"]])
        kw = dict(kw)
        if kw.get("facecolors") == "none":
            ax_kw = {k: v for k, v in kw.items() if k != "c"}
            axes[0].scatter(xs, ys, edgecolors=kw["c"], rasterized=True, **ax_kw)
            axes[1].plot(part["value"], part["dc"], "o", mfc="none", mec=kw["c"], ms=3,
                         mew=0.5, label=kw["label"])  # fmt: skip
        else:
            axes[0].scatter(xs, ys, rasterized=True, **kw)
            axes[1].plot(part["value"], part["dc"], ".", c=kw["c"], ms=3, label=kw["label"])
    if h.band is not None:
        for ax in axes:
            ax.axvspan(*h.band, color="#ffd92f", alpha=0.35, lw=0, label="hysteresis band",
                       zorder=0)
    axes[0].set_ylabel("Poincaré " + style.X_LABEL)
    axes[1].set_ylabel(style.DC_LABEL)
    axes[1].set_xlabel(style.param_label(h.parameter))
    axes[1].legend(fontsize=7.5, loc="best")
    axes[0].set_title("(a) bifurcation diagram, both sweep directions", fontsize=9, loc="left")
    axes[1].set_title("(b) disengagement duty cycle", fontsize=9, loc="left")
    style.finish(fig, title)
    return fig, h


# ------------------------------------------------------------------------------ registry


def fig18(ctx):
    from gearsim.presentation.figures.context import Built, _need

    df = _need(ctx.sweeps, "hysteresis", "sweep")
    fig, h = figure_hysteresis(df)
    lines = [s.lstrip("- ") for s in h.lines()]
    return [Built(18, fig, "Hysteresis of the softening fold: the sweep in increasing w (blue) "
                  "and in decreasing w (red, open) over the same grid; shaded: the band between "
                  "the two jumps, where both motions coexist. " + " ".join(lines),
                  ["Not in the paper (its sweeps run forward only). Fig 4 is the forward "
                   "sweep of the standard set; this figure adds the backward branch."],
                  ["sweeps/hysteresis"])]


def _basins(ctx, name: str):
    """``(params, n, starts, attractors, stated)`` of a basin picture's figure-data table."""
    from gearsim.presentation.figures.data import figure_data

    starts, stated = figure_data(ctx, name)
    att = pd.DataFrame.from_records(stated["attractors"])
    return ctx.params.with_(**stated["params"]), int(stated["n"]), starts, att, stated


def fig19(ctx):
    from gearsim.presentation.figures.context import Built

    p, n, starts, att, _ = _basins(ctx, "fig19")
    fig = figure_basins(starts, att, title=f"Basins of attraction at w = {p.w:g}, "
                        f"b = {p.b:g} (Figs 9-11's point)")  # fmt: skip
    found = {r["label_npq"]: r["basin_fraction"] for _, r in att.iterrows()}
    which = "; ".join(
        f"{t}: " + (f"basin {found[t]:.3f}" if t in found else "not found") for t in PAPER_COEXIST
    )
    return [Built(19, fig, f"Basins of attraction at the point of Figs 9-11 (w = {p.w:g}, "
                  f"b = {p.b:g}): {n} x {n} starts in (x, x') (the finder's start "
                  "box widened to hold the attractors), bearings at rest, "
                  "coloured by the attractor reached. The paper's three motions in our model: "
                  f"{which}.",
                  [f"The paper shows {', '.join(PAPER_COEXIST)} at this point; {len(att)} "
                   "attractor(s) found over the picture's box."],
                  [])]


def fig20(ctx):
    from gearsim.presentation.figures.context import Built

    p, n, starts, att, stated = _basins(ctx, "fig20")
    w = stated["w"]
    fig = figure_basins(starts, att, title=f"Basins of attraction at w = {w:g}, "
                        f"b = {p.b:g} (inside the fold's hysteresis band)")  # fmt: skip
    parts = ", ".join(f"{_pattern_text(r)} {r['basin_fraction']:.3f}" for _, r in att.iterrows())
    return [Built(20, fig, f"Basins of attraction inside the hysteresis band of the fold (w = "
                  f"{w:g}, standard parameters): {n} x {n} starts; basin "
                  f"fractions: {parts}.", [stated["note"], "Not in the paper."],
                  ["sweeps/hysteresis"])]




# ------------------------------------------------------------------------------ plane maps
def _grid(att: pd.DataFrame, column: str, fill=np.nan):
    """``(xs, ys, Z)``: cell centres of the computed cells and ``Z[j, i]`` of one row per cell."""
    xs = np.sort(att["x"].unique())
    ys = np.sort(att["y"].unique())
    ix = {v: k for k, v in enumerate(xs)}
    iy = {v: k for k, v in enumerate(ys)}
    Z = np.full((len(ys), len(xs)), fill, dtype=float)
    for x, y, v in zip(att["x"], att["y"], att[column], strict=True):
        Z[iy[y], ix[x]] = v
    return xs, ys, Z


def _edges(c: np.ndarray, lim: tuple[float, float] | None = None) -> np.ndarray:
    """Cell edges around centres ``c`` (midpoints), clipped to the plane's axis range."""
    if len(c) == 1:
        e = np.array([c[0] - 0.5, c[0] + 0.5])
    else:
        mid = 0.5 * (c[1:] + c[:-1])
        e = np.concatenate([[2 * c[0] - mid[0]], mid, [2 * c[-1] - mid[-1]]])
    if lim is not None:
        e = np.clip(e, lim[0], lim[1])
    return e


def figure_coexistence(att: pd.DataFrame, x_name: str, y_name: str, *, title: str | None = None,
                       xlim=None, ylim=None):
    """(a) number of attractors per cell; (b) the dominant pattern (most starts), hatched where
    another attractor coexists. ``att``: attractor-tile rows (one per attractor of a cell)."""
    # matplotlib here, not at the top: the workflow reads this module's figure table on every
    # parse, without drawing
    import matplotlib.pyplot as plt
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.patches import Patch

    real = att[(att["attractor"] >= 0) & (att["motion"] != "unsettled")]
    cells = att.drop_duplicates(["i", "j"])[["i", "j", "x", "y", "n_attractors"]]
    xs, ys, N = _grid(cells, "n_attractors")
    dom = real.sort_values("attractor").drop_duplicates(["i", "j"])
    cats = style.pattern_categories(dom.assign(n=dom["n"].fillna(0)))
    present = [k for k in style.PATTERN_KEYS if k in set(cats)]
    index = {k: n for n, k in enumerate(present)}
    _, _, P = _grid(dom.assign(_c=[index[c] for c in cats]), "_c")
    fig, axes = plt.subplots(1, 2, figsize=(13.5, 5.2))
    nmax = int(np.nanmax(N)) if np.isfinite(N).any() else 1
    cmap = plt.get_cmap("viridis", nmax + 1)
    ex, ey = _edges(xs, xlim), _edges(ys, ylim)
    m = axes[0].pcolormesh(ex, ey, np.ma.masked_invalid(N), cmap=cmap,
                           vmin=-0.5, vmax=nmax + 0.5, shading="flat", rasterized=True)
    cb = fig.colorbar(m, ax=axes[0], ticks=range(nmax + 1))
    cb.set_label("number of coexisting attractors")
    axes[0].set_title("(a) attractors per cell", fontsize=9, loc="left")
    if present:
        pc = ListedColormap([style.PATTERN_COLOURS[k] for k in present])
        norm = BoundaryNorm(np.arange(-0.5, len(present) + 0.5), pc.N)
        axes[1].pcolormesh(ex, ey, np.ma.masked_invalid(P), cmap=pc, norm=norm,
                           shading="flat", rasterized=True)  # fmt: skip
        jj, ii = np.nonzero(np.nan_to_num(N) >= 2)
        if len(ii):
            from matplotlib.collections import PatchCollection
            from matplotlib.patches import Rectangle

            rects = [Rectangle((ex[i], ey[j]), ex[i + 1] - ex[i], ey[j + 1] - ey[j])
                     for i, j in zip(ii, jj, strict=True)]  # fmt: skip
            axes[1].add_collection(PatchCollection(rects, facecolor="none", edgecolor="black",
                                                   hatch="////", lw=0.0))  # fmt: skip
        handles = [Patch(facecolor=style.PATTERN_COLOURS[k], edgecolor="#555555", lw=0.4,
                         label=style.PATTERN_LABELS[k]) for k in present]
        handles.append(Patch(facecolor="white", edgecolor="black", hatch="////",
                             label="another attractor coexists"))
        if np.any(np.nan_to_num(N, nan=1) == 0):
            handles.append(Patch(facecolor="white", edgecolor="#555555", lw=0.4,
                                 label="no settled attractor (all starts unsettled/diverged)"))
        axes[1].legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                       fontsize=7, frameon=False, title="dominant pattern (most starts)",
                       title_fontsize=7)  # fmt: skip
    axes[1].set_title("(b) dominant pattern, hatched where multistable", fontsize=9, loc="left")
    for ax in axes:
        style.plane_axes(ax, x_name, y_name)
    style.finish(fig, title)
    return fig


def figure_forward_basin(att: pd.DataFrame, x_name: str, y_name: str, *,
                         title: str | None = None, xlim=None, ylim=None):
    """Basin fraction of the attractor the forward continuation chain reaches (the plane's
    own cell label), per cell; grey where it was reached by no sampled start (fraction 0)."""
    import matplotlib.pyplot as plt

    fw = att[att["found_by"].fillna("").str.contains("forward")]
    cells = att.drop_duplicates(["i", "j"])[["i", "j", "x", "y"]]
    merged = cells.merge(fw[["i", "j", "basin_fraction"]], on=["i", "j"], how="left")
    xs, ys, B = _grid(merged, "basin_fraction")
    fig, ax = plt.subplots(figsize=(7.8, 5.2))
    cmap = plt.get_cmap("magma").copy()
    cmap.set_bad("#bdbdbd")
    m = ax.pcolormesh(_edges(xs, xlim), _edges(ys, ylim), np.ma.masked_invalid(B), cmap=cmap,
                      vmin=0, vmax=1, shading="flat", rasterized=True)  # fmt: skip
    cb = fig.colorbar(m, ax=ax)
    cb.set_label("basin fraction of the forward-continuation attractor")
    style.plane_axes(ax, x_name, y_name)
    low = float(np.nanmean(B < 0.1)) if np.isfinite(B).any() else float("nan")
    ax.set_title(f"share of cells below 0.1: {low:.3f} (grey: no continuation state)",
                 fontsize=8, loc="left")  # fmt: skip
    style.finish(fig, title)
    return fig


def figure_floquet_margin(cells: pd.DataFrame, x_name: str, y_name: str, *,
                          title: str | None = None, xlim=None, ylim=None):
    """Floquet margin of a plane: ``1 - |mu|max`` of each periodic cell's orbit per motion period
    (log scale; the bifurcation curves are where it reaches 0), black where the status is
    ``bifurcation`` (within 1e-3 of the unit circle), light grey where a periodic cell has no
    margin (a run with ``floquet: slow`` margins only its refined cells; variable-ratio and
    DP5 cells have none), white where the cell has no periodic orbit (chaos, quasi-periodic,
    unsettled, diverged). The top leaves room for a figure title (``suptitle``).
    ``cells``: a plane's cell rows (``x``, ``y``, ``motion``, ``status``, ``mu_max``, and
    ``refined`` if present)."""
    import matplotlib.pyplot as plt  # here, not at the top: the workflow reads this module's
    from matplotlib.colors import (  # figure table on every parse
        BoundaryNorm,
        ListedColormap,
        LogNorm,
    )
    from matplotlib.patches import Patch

    df = cells[["x", "y"]].copy()
    mu = pd.to_numeric(cells["mu_max"], errors="coerce").to_numpy(dtype=float)
    status = cells["status"].astype(str).to_numpy()
    periodic = cells["motion"].astype(str).to_numpy() == "periodic"
    margin = np.where(np.isfinite(mu), np.clip(1.0 - mu, 1e-4, 1.0), np.nan)
    df["margin"] = np.where(status == "bifurcation", np.nan, margin)
    df["kind"] = np.select([status == "bifurcation", np.isfinite(df["margin"]), periodic],
                           [2.0, np.nan, 1.0], default=0.0)  # fmt: skip
    xs, ys, M = _grid(df, "margin")
    _, _, K = _grid(df, "kind", fill=0.0)
    ex, ey = _edges(xs, xlim), _edges(ys, ylim)
    fig, ax = plt.subplots(figsize=(8.4, 5.2))
    under = ListedColormap(["#ffffff", "#d9d9d9", "#000000"])
    ax.pcolormesh(ex, ey, np.ma.masked_invalid(K), cmap=under,
                  norm=BoundaryNorm([-0.5, 0.5, 1.5, 2.5], 3), shading="flat",
                  rasterized=True)  # fmt: skip
    m = ax.pcolormesh(ex, ey, np.ma.masked_invalid(M), cmap="viridis",
                      norm=LogNorm(vmin=1e-4, vmax=1.0), shading="flat", rasterized=True)
    cb = fig.colorbar(m, ax=ax)
    cb.set_label("Floquet margin 1 - |mu|max per motion period")
    n_mu = int(np.isfinite(margin).sum())
    n_ref = (int(cells["refined"].fillna(False).astype(bool).sum())
             if "refined" in cells.columns else None)
    handles = [
        Patch(facecolor="#000000", label=f"bifurcation ({int((status == 'bifurcation').sum())} "
              "cells: 1 - |mu|max < 1e-3)"),
        Patch(facecolor="#d9d9d9", edgecolor="#555555", lw=0.4,
              label="periodic, no margin computed"),
        Patch(facecolor="#ffffff", edgecolor="#555555", lw=0.4, label="no periodic orbit"),
    ]  # fmt: skip
    which = f"{n_mu} of {len(df)} cells with a margin"
    which += f" ({n_ref} refined by Newton)" if n_ref is not None else ""
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.0, -0.13), ncol=3,
              fontsize=7, frameon=False, title=which, title_fontsize=7)  # fmt: skip
    style.plane_axes(ax, x_name, y_name)
    style.finish(fig, title, rect=(0.0, 0.0, 1.0, 0.94))  # the top strip: the figure title
    return fig


def map_floquet(df: pd.DataFrame):
    """The Floquet-margin map of a plane's cells table (:data:`maps.PLANE_MAPS` entry)."""
    from gearsim.presentation.figures.data import plane_axes

    xn, yn = plane_axes(df)
    cells = df.assign(x=df[xn], y=df[yn])
    n_mu = int(pd.to_numeric(cells["mu_max"], errors="coerce").notna().sum())
    n_bif = int((cells["status"].astype(str) == "bifurcation").sum())
    fig = figure_floquet_margin(cells, xn, yn)
    return (fig, f"Floquet margin 1 - |mu|max of every periodic cell's orbit per motion period "
            f"({n_mu} of {len(cells)} cells), black at a bifurcation ({n_bif} cells within "
            "1e-3 of |mu| = 1); the bifurcation curves are where the margin reaches 0.",
            ["The margin is that of the cell's own RK4 map (docs/model.md, 'Settled motions'; "
             "its accuracy against the flow's by w: docs/decisions.md, 'Floquet margin of "
             "every cell'). Light grey: periodic cells without a margin (a run with "
             "floquet: slow, variable-ratio or DP5 cells)."])

