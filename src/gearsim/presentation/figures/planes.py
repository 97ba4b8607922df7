"""Two-parameter plane figures: 3-D bifurcation and pattern maps (Figs 7, 14), DC cloud and
I:DC maps (Figs 12, 16), Kmax cloud and maps (Figs 13, 17), and the co-simulation grid (Fig 3).

Input is a cells table (``results/<plane>/cells.parquet``, see
:mod:`gearsim.presentation.figures.data`).
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.patches import Patch, Rectangle

from gearsim.cell.motion import DEFAULT_KMAX
from gearsim.presentation.figures import style
from gearsim.presentation.figures.data import cell_edges, plane_centres, plane_grid

# ------------------------------------------------------------------------------ pattern maps


def category_grid(df: pd.DataFrame) -> tuple[np.ndarray, list[str]]:
    """(ny, nx) integer grid of pattern categories and the category keys present (in order)."""
    cats = style.pattern_categories(df)
    present = [k for k in style.PATTERN_KEYS if k in set(cats)]
    index = {k: n for n, k in enumerate(present)}
    tmp = df.assign(_cat=[index[c] for c in cats])
    return plane_grid(tmp, "_cat", fill=-1), present


def draw_pattern_map(ax, df: pd.DataFrame, *, legend: bool = True, legend_kw=None):
    """Categorical map of the I/nT patterns over the plane; returns the keys drawn."""
    xname, xs, yname, ys = plane_centres(df)
    grid, present = category_grid(df)
    if not present:
        return present
    cmap = ListedColormap([style.PATTERN_COLOURS[k] for k in present])
    norm = BoundaryNorm(np.arange(-0.5, len(present) + 0.5), cmap.N)
    masked = np.ma.masked_less(grid, 0)
    ax.pcolormesh(cell_edges(xs), cell_edges(ys), masked, cmap=cmap, norm=norm,
                  shading="flat", rasterized=True)
    _boundaries(ax, xs, ys, grid)
    style.plane_axes(ax, xname, yname)
    if legend:
        counts = pd.Series(style.pattern_categories(df)).value_counts()
        handles = [Patch(facecolor=style.PATTERN_COLOURS[k], edgecolor="#555555", lw=0.4,
                         label=f"{style.PATTERN_LABELS[k]} ({counts.get(k, 0)})")
                   for k in present]
        kw = {"loc": "upper left", "bbox_to_anchor": (1.01, 1.0), "fontsize": 7,
              "title": "pattern I/nT (cells)", "title_fontsize": 7, "frameon": False}
        kw.update(legend_kw or {})
        ax.legend(handles=handles, **kw)
    return present


def draw_bifurcation3d(ax, df: pd.DataFrame, *, max_rows: int = 40, max_points: int = 32,
                       point_size: float | None = None) -> None:
    """3-D bifurcation diagram: (x parameter, y parameter, Poincare x) coloured by I.

    At most ``max_rows`` plane rows (evenly spaced in ``j``) and ``max_points`` section points
    per cell are drawn, enough to show the structure without drowning it.
    """
    xname, _xs, yname, ys = plane_centres(df)
    ny = len(ys)
    rows = np.unique(np.linspace(0, ny - 1, min(max_rows, ny)).round().astype(int))
    sub = df[df["j"].isin(rows) & (df["status"] != "diverged")]
    X, Y, Z, C = [], [], [], []
    for xv, yv, px, I in zip(sub[xname], sub[yname], sub["poincare_x"], sub["I"], strict=True):
        px = np.asarray(px, dtype=float)[-max_points:]
        X.append(np.full(len(px), xv))
        Y.append(np.full(len(px), yv))
        Z.append(px)
        C.extend([style.impact_colour(I)] * len(px))
    if X:
        Zc = np.concatenate(Z)
        # unsettled cells far off the attractors would squash the axis: clip to a robust range
        lo, hi = np.percentile(Zc, [5, 95])
        pad = 1.0 * (hi - lo + 1e-12)
        keep = (Zc >= lo - pad) & (Zc <= hi + pad)
        if point_size is None:
            point_size = float(np.clip(6000.0 / max(len(sub), 1), 0.3, 4.0))
        ax.scatter(np.concatenate(X)[keep], np.concatenate(Y)[keep], Zc[keep], s=point_size,
                   c=list(np.asarray(C, dtype=object)[keep]), marker="o", linewidths=0,
                   depthshade=False, rasterized=True)
    ax.set_xlabel(style.param_symbol(xname), labelpad=2)
    ax.set_ylabel(style.param_symbol(yname), labelpad=2)
    ax.set_zlabel(r"mesh displacement $x$", labelpad=2)
    ax.tick_params(labelsize=7, pad=0)
    ax.view_init(elev=22, azim=-60)
    from gearsim.presentation.figures.bifurcation import impact_legend

    impact_legend(ax, df["I"].to_numpy(dtype=int), loc="upper left")


def _map_panel(fig, draw, df: pd.DataFrame, label: str, title: str | None,
               margins: tuple[float, float, float]):
    """Panel (b) of a two-panel plane figure: the map ``draw`` makes, its label, the figure's
    title and its ``(left, right, wspace)`` margins."""
    ax2 = fig.add_subplot(1, 2, 2)
    draw(ax2, df)
    ax2.set_title(label, fontsize=9, loc="left")
    if title:
        fig.suptitle(title, fontsize=10)
    left, right, wspace = margins
    fig.subplots_adjust(left=left, right=right, wspace=wspace, bottom=0.1, top=0.9)
    return fig


def figure_pattern(df: pd.DataFrame, *, title: str | None = None):
    """Figs 7 and 14: (a) 3-D bifurcation of mesh displacement, (b) pattern map."""
    fig = plt.figure(figsize=(13.0, 5.4))
    ax1 = fig.add_subplot(1, 2, 1, projection="3d")
    draw_bifurcation3d(ax1, df)
    ax1.set_title("(a) relative micro-displacement bifurcation", fontsize=9, loc="left")
    return _map_panel(fig, draw_pattern_map, df, "(b) pattern types and regions", title,
                      (0.0, 0.80, 0.28))


# ------------------------------------------------------------------------------ DC and Kmax


def robust_max(Z: np.ndarray) -> float:
    """Upper end of a colour scale: the maximum, capped at twice the 99th percentile so that a
    single runaway cell (e.g. next to a diverged one) does not flatten the whole map."""
    finite = Z[np.isfinite(Z)]
    if not len(finite):
        return 1.0
    return float(min(finite.max(), 2.0 * np.percentile(finite, 99)))


def _surface(ax, df: pd.DataFrame, column: str, zlabel: str, cmap: str = "turbo",
             max_side: int = 120, cap: float | None = None):
    xname, xs, yname, ys = plane_centres(df)
    Z = plane_grid(df, column)
    if cap is not None:
        Z = np.minimum(Z, cap)
    sx = max(1, int(np.ceil(len(xs) / max_side)))
    sy = max(1, int(np.ceil(len(ys) / max_side)))
    Xg, Yg = np.meshgrid(xs[::sx], ys[::sy])
    Zs = Z[::sy, ::sx]
    finite = np.isfinite(Zs)
    vmin = float(np.nanmin(Zs)) if finite.any() else 0.0
    vmax = float(np.nanmax(Zs)) if finite.any() else 1.0
    surf = ax.plot_surface(Xg, Yg, np.where(finite, Zs, np.nan), cmap=cmap, vmin=vmin,
                           vmax=vmax, linewidth=0, antialiased=False, rstride=1, cstride=1,
                           rasterized=True)
    ax.set_xlabel(style.param_symbol(xname), labelpad=2)
    ax.set_ylabel(style.param_symbol(yname), labelpad=2)
    ax.set_zlabel(zlabel, labelpad=0)
    ax.tick_params(labelsize=7, pad=0)
    ax.view_init(elev=28, azim=-60)
    return surf


def dc_category(I: int, dc: float) -> str:
    band = style.dc_band(dc)
    return "no data" if band == "n/a" else f"{int(I)}:{band}"


# ten shades per impact state, one per DC band of 0.1 (light = small DC, dark = large DC);
# steps are wide enough that neighbouring bands stay apart
_DC_SHADES = {
    1: ["#fff7bc", "#fee391", "#fec44f", "#fe9929", "#ec7014", "#cc4c02", "#993404",
        "#662506", "#3d1503", "#1a0900"],
    2: ["#deebf7", "#c6dbef", "#9ecae1", "#6baed6", "#4292c6", "#2171b5", "#08519c",
        "#08306b", "#041a3d", "#020d1f"],
    -1: ["#e5f5e0", "#c7e9c0", "#a1d99b", "#74c476", "#41ab5d", "#238b45", "#006d2c",
         "#00441b", "#002910", "#001408"],
    -2: ["#f2f0f7", "#dadaeb", "#bcbddc", "#9e9ac8", "#807dba", "#6a51a3", "#54278f",
         "#3f007d", "#2a0054", "#15002a"],
}


def _dc_colour(I: int, band: str) -> str:
    """Colour of an ``I:band`` category: red for ``0:0.0``, a shade of the I family else."""
    if band == "n/a":
        return "#ffffff"
    if int(I) == 0:
        return "#e41a1c"
    k = 0 if band == "0.0" else int(round(float(band.split("\u2013")[1]) * 10)) - 1
    return _DC_SHADES.get(int(I), ["#bbbbbb"] * 10)[min(max(k, 0), 9)]


def _boundaries(ax, xs, ys, grid) -> None:
    """Thin lines between cells of different categories (keeps similar colours apart)."""
    xe, ye = cell_edges(xs), cell_edges(ys)
    segs = []
    for j in range(grid.shape[0]):
        for i in range(grid.shape[1] - 1):
            if grid[j, i] != grid[j, i + 1]:
                segs.append([(xe[i + 1], ye[j]), (xe[i + 1], ye[j + 1])])
    for j in range(grid.shape[0] - 1):
        for i in range(grid.shape[1]):
            if grid[j, i] != grid[j + 1, i]:
                segs.append([(xe[i], ye[j + 1]), (xe[i + 1], ye[j + 1])])
    if segs:
        from matplotlib.collections import LineCollection

        ax.add_collection(LineCollection(segs, colors="k", linewidths=0.25, alpha=0.7))


def draw_dc_map(ax, df: pd.DataFrame, *, legend: bool = True):
    """I:DC plane distribution: categories ``I:band`` (bands of 0.1, ``0.0`` for exactly 0)."""
    xname, xs, yname, ys = plane_centres(df)
    keys = [dc_category(i, d) for i, d in zip(df["I"], df["dc"], strict=True)]

    def order(k):
        if k == "no data":
            return (9, 0.0)
        i, band = k.split(":")
        lo = -1.0 if band == "0.0" else (9.0 if band == "n/a" else float(band.split("\u2013")[0]))
        return ({0: 0, 1: 1, 2: 2, -1: 3, -2: 4}.get(int(i), 5), lo)

    present = sorted(set(keys), key=order)
    index = {k: n for n, k in enumerate(present)}
    grid = plane_grid(df.assign(_cat=[index[k] for k in keys]), "_cat", fill=-1)
    colours = ["#ffffff" if k == "no data" else _dc_colour(int(k.split(":")[0]), k.split(":")[1])
               for k in present]
    cmap = ListedColormap(colours)
    norm = BoundaryNorm(np.arange(-0.5, len(present) + 0.5), cmap.N)
    ax.pcolormesh(cell_edges(xs), cell_edges(ys), np.ma.masked_less(grid, 0), cmap=cmap,
                  norm=norm, shading="flat", rasterized=True)
    _boundaries(ax, xs, ys, grid)
    style.plane_axes(ax, xname, yname)
    if legend:
        handles = [Patch(facecolor=c, edgecolor="#555555", lw=0.4, label=k)
                   for k, c in zip(present, colours, strict=True)]
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7,
                  title="I : DC", title_fontsize=7, frameon=False,
                  ncol=1 if len(handles) <= 22 else 2)
    return present


def figure_dc(df: pd.DataFrame, *, title: str | None = None):
    """Figs 12 and 16: (a) DC cloud diagram, (b) I:DC plane distribution."""
    fig = plt.figure(figsize=(13.0, 5.4))
    ax1 = fig.add_subplot(1, 2, 1, projection="3d")
    surf = _surface(ax1, df, "dc", "DC")
    fig.colorbar(surf, ax=ax1, shrink=0.6, pad=0.12, label=style.DC_LABEL)
    ax1.set_title("(a) DC cloud diagram", fontsize=9, loc="left")
    return _map_panel(fig, draw_dc_map, df, "(b) I:DC plane distribution", title,
                      (0.02, 0.82, 0.15))


def figure_kmax(df: pd.DataFrame, *, column: str | None = None, title: str | None = None):
    """Figs 13 and 17: (a) Kmax cloud diagram, (b) plane distribution (filled contours)."""
    column = column or ("kmax" if "kmax" in df.columns else DEFAULT_KMAX)
    label = style.kmax_label(None if column == "kmax" else column)
    fig = plt.figure(figsize=(13.0, 5.4))
    ax1 = fig.add_subplot(1, 2, 1, projection="3d")
    Zall = plane_grid(df, column)
    cap = robust_max(Zall)
    n_over = int(np.sum(Zall[np.isfinite(Zall)] > cap))
    surf = _surface(ax1, df, column, r"$K_{\max}$", cap=cap)
    fig.colorbar(surf, ax=ax1, shrink=0.6, pad=0.12, label=label,
                 extend="max" if n_over else "neither")
    ax1.set_title(r"(a) $K_{\max}$ cloud diagram", fontsize=9, loc="left")
    ax2 = fig.add_subplot(1, 2, 2)
    xname, xs, yname, ys = plane_centres(df)
    Z = np.minimum(Zall, cap)
    finite = np.isfinite(Z)
    vmin = float(np.nanmin(Z)) if finite.any() else 0.0
    vmax = float(np.nanmax(Z)) if finite.any() else 1.0
    from matplotlib.ticker import MaxNLocator

    levels = MaxNLocator(20).tick_values(vmin, vmax if vmax > vmin else vmin + 1e-9)
    if len(xs) > 1 and len(ys) > 1:
        cs = ax2.contourf(xs, ys, Z, levels=levels, cmap="turbo")
        ax2.contour(xs, ys, Z, levels=levels[::2], colors="k", linewidths=0.3)
    else:
        cs = ax2.pcolormesh(cell_edges(xs), cell_edges(ys), Z, cmap="turbo")
    fig.colorbar(cs, ax=ax2, label=label, extend="max" if n_over else "neither")
    if n_over:
        style.note_box(ax2, f"{n_over} cell(s) above {cap:.2f} (max {np.nanmax(Zall):.2f}) "
                       "drawn at the top colour", loc="upper right", fontsize=6.5)
    style.plane_axes(ax2, xname, yname)
    ax2.set_title(r"(b) $K_{\max}$ plane distribution", fontsize=9, loc="left")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.subplots_adjust(left=0.02, right=0.95, wspace=0.12, bottom=0.1, top=0.9)
    return fig


# ------------------------------------------------------------------------------ Fig 3


def coarse_cells(df: pd.DataFrame, nx: int = 12, ny: int = 8) -> pd.DataFrame:
    """A coarse view of a plane: the cell nearest the centre of each of ``nx x ny`` blocks."""
    NX = int(df["i"].max()) + 1
    NY = int(df["j"].max()) + 1
    nx, ny = min(nx, NX), min(ny, NY)
    ii = ((np.arange(nx) + 0.5) * NX / nx).astype(int)
    jj = ((np.arange(ny) + 0.5) * NY / ny).astype(int)
    sub = df[df["i"].isin(ii) & df["j"].isin(jj)].copy()
    sub["i"] = sub["i"].map({v: k for k, v in enumerate(ii)})
    sub["j"] = sub["j"].map({v: k for k, v in enumerate(jj)})
    return sub


def figure3(df: pd.DataFrame, *, nx: int = 12, ny: int = 8, title: str | None = None):
    """Fig 3: the (u, v) plane cut into cells, a(i, j) at the cell centres, coloured by the
    pattern a real (coarse) plane computed there.

    The coarse grid takes, for each of ``nx x ny`` blocks of the computed plane, the cell
    nearest the block centre; its cell edges are drawn at the block boundaries.
    """
    sub = coarse_cells(df, nx, ny)
    xname, _, yname, _ = plane_centres(df)
    NX = int(df["i"].max()) + 1
    NY = int(df["j"].max()) + 1
    _, fxs, _, fys = plane_centres(df)
    xe_full, ye_full = cell_edges(fxs), cell_edges(fys)
    nxc, nyc = int(sub["i"].max()) + 1, int(sub["j"].max()) + 1
    xe = np.linspace(xe_full[0], xe_full[-1], nxc + 1)
    ye = np.linspace(ye_full[0], ye_full[-1], nyc + 1)
    xc, yc = 0.5 * (xe[:-1] + xe[1:]), 0.5 * (ye[:-1] + ye[1:])
    fig, ax = plt.subplots(figsize=(9.5, 5.8))
    cats = style.pattern_categories(sub)
    for (i, j), c in zip(zip(sub["i"], sub["j"], strict=True), cats, strict=True):
        ax.add_patch(Rectangle((xe[i], ye[j]), xe[i + 1] - xe[i], ye[j + 1] - ye[j],
                               facecolor=style.PATTERN_COLOURS[c], alpha=0.75,
                               edgecolor="#333333", lw=0.6))
    X, Y = np.meshgrid(xc, yc)
    ax.plot(X.ravel(), Y.ravel(), "o", ms=2.5, color="k", label=r"cell centre $a(i, j)$")
    # annotate one interior cell
    ia, ja = min(2, nxc - 1), min(2, nyc - 1)
    ax.add_patch(Rectangle((xe[ia], ye[ja]), xe[ia + 1] - xe[ia], ye[ja + 1] - ye[ja],
                           fill=False, edgecolor="#d62728", lw=2.0, zorder=5))
    ax.annotate(r"$a(i, j)$", xy=(xc[ia], yc[ja]), xytext=(xc[ia] + 0.45 * (xe[1] - xe[0]) * 3,
                yc[ja] + 0.6 * (ye[1] - ye[0])), fontsize=10, color="#d62728",
                arrowprops={"arrowstyle": "->", "color": "#d62728"}, zorder=6)
    ax.annotate("", xy=(xe[ia], ye[ja] - 0.15 * (ye[1] - ye[0])),
                xytext=(xe[ia + 1], ye[ja] - 0.15 * (ye[1] - ye[0])),
                arrowprops={"arrowstyle": "<->", "color": "#d62728", "lw": 0.8}, zorder=6)
    ax.text(xc[ia], ye[ja] - 0.2 * (ye[1] - ye[0]), r"$\Delta u$", ha="center", va="top",
            color="#d62728", fontsize=8, zorder=6)
    ax.set_xlim(xe[0], xe[-1])
    ax.set_ylim(ye[0], ye[-1])
    ax.set_xlabel(f"u = {style.param_label(xname)}")
    ax.set_ylabel(f"v = {style.param_label(yname)}")
    present = [k for k in style.PATTERN_KEYS if k in set(cats)]
    handles = [Patch(facecolor=style.PATTERN_COLOURS[k], alpha=0.75, edgecolor="#333333",
                     label=style.PATTERN_LABELS[k]) for k in present]
    handles.append(ax.get_lines()[0])
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7,
              frameon=False, title="state of the cell", title_fontsize=7)
    ax.set_title(f"{nxc} x {nyc} cells shown (one per block of the computed "
                 f"{NX} x {NY} plane; the study uses 400 x 400)", fontsize=8)
    style.finish(fig, title)
    return fig
