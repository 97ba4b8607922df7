"""Figures of periodic-orbit branches and two-parameter bifurcation curves (matplotlib).

Branch diagram: section displacement ``x`` (dimensionless, units of ``b_c``) against the
continuation parameter, stable parts solid, unstable parts dashed, located events marked
(fold, period doubling, Neimark-Sacker, grazing); below it the largest Floquet multiplier
modulus with the unit circle's radius as a reference line.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from gearsim.presentation.figures.style import param_label

EVENT_STYLE = {
    "fold": ("s", "#2ca02c", "fold (LP)"),
    "period_doubling": ("o", "#d62728", "period doubling (PD)"),
    "neimark_sacker": ("D", "#9467bd", "Neimark-Sacker (NS)"),
    "grazing": ("^", "#ff7f0e", "grazing (G)"),
}
PERIOD_COLOURS = ("#000000", "#1f4fd6", "#17becf", "#8c564b", "#e377c2")


def _segments(values: np.ndarray, flags: np.ndarray):
    """Split a polyline into runs of equal stability (adjacent runs share their end point)."""
    start = 0
    for k in range(1, len(values) + 1):
        if k == len(values) or flags[k] != flags[start]:
            yield slice(start, min(k + 1, len(values))), bool(flags[start])
            start = k


def draw_branches(ax, df: pd.DataFrame, column: str = "x") -> None:
    """Draw every branch of a :func:`gearsim.analysis.continuation.continue_orbit` table on
    ``ax``."""
    periods_seen: set[int] = set()
    for _, br in df.groupby("branch", sort=True):
        br = br.sort_index()
        n = int(br["period"].iloc[0])
        colour = PERIOD_COLOURS[min(int(np.log2(max(n, 1))), len(PERIOD_COLOURS) - 1)]
        vals = br["value"].to_numpy()
        ys = br[column].to_numpy()
        stab = br["stable"].to_numpy()
        for sl, st in _segments(vals, stab):
            label = None
            if n not in periods_seen and st:
                label = f"period {n} (stable solid, unstable dashed)"
                periods_seen.add(n)
            ax.plot(vals[sl], ys[sl], color=colour, lw=1.3 if st else 1.0,
                    ls="-" if st else "--", label=label)
    seen: set[str] = set()
    ev = df[df["event"] != ""]
    for _, r in ev.iterrows():
        marker, colour, text = EVENT_STYLE[r["event"]]
        ax.plot(r["value"], r[column], marker=marker, color=colour, ms=6, ls="none",
                mfc="none" if r["event"] == "grazing" else colour,
                label=None if r["event"] in seen else text)
        seen.add(r["event"])


def figure_branches(df: pd.DataFrame, *, title: str | None = None):
    """Branch diagram (section ``x``) and the largest multiplier modulus, two stacked panels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    name = str(df["name"].iloc[0]) if len(df) else "w"
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(7.0, 6.2), sharex=True,
                                 gridspec_kw={"height_ratios": [3, 2]})
    draw_branches(a1, df, "x")
    a1.set_ylabel(r"section displacement $x(\tau = kT)$ (units of $b_c$)")
    a1.legend(fontsize=7, loc="best")
    for _, br in df.groupby("branch", sort=True):
        n = int(br["period"].iloc[0])
        colour = PERIOD_COLOURS[min(int(np.log2(max(n, 1))), len(PERIOD_COLOURS) - 1)]
        a2.plot(br["value"], br["mu_max"], color=colour, lw=1.0, label=f"period {n}")
    a2.axhline(1.0, color="grey", lw=0.8, ls=":")
    a2.set_yscale("log")
    a2.set_ylabel(r"largest Floquet multiplier $|\mu|_{max}$")
    a2.set_xlabel(param_label(name))
    a2.legend(fontsize=7, loc="best")
    if title:
        a1.set_title(title, fontsize=9)
    fig.tight_layout()
    return fig


CURVE_STYLE = {
    "period_doubling": ("-", "#d62728", "period doubling"),
    "fold": ("-.", "#2ca02c", "fold (hysteresis edge)"),
    "grazing": (":", "#ff7f0e", "grazing"),
    "neimark_sacker": ("--", "#9467bd", "Neimark-Sacker"),
}
#: the line of each kind of curve in Figs 21 and 22 (the grazing by its flank): dash pattern and
#: the words of the caption; the colour is the orbit's period (:data:`CURVE_PERIOD_COLOURS`)
CURVE_LINES = {
    ("period_doubling", ""): ("-", "period doubling n -> 2n"),
    ("fold", ""): ((0, (5, 1.5, 1, 1.5, 1, 1.5)), "fold"),
    ("grazing", "face"): ((0, (1, 1.2)), "grazing of the tooth face (x = +b)"),
    ("grazing", "back"): ((0, (3, 1.5)), "grazing of the tooth back (x = -b)"),
    ("grazing", "bearing"): ((0, (3, 1, 1, 1, 1, 1)), "grazing of a bearing clearance"),
    ("neimark_sacker", ""): ((0, (5, 3)), "Neimark-Sacker"),
}
#: colour of a curve by the period of its orbit (1, 2, 4, 8, 16, more)
CURVE_PERIOD_COLOURS = ("#111111", "#1f4fd6", "#e7298a", "#6a3d9a", "#b15928", "#17becf")
#: marker of each kind of codimension-2 point (docs/orbits.md, the atlas's tables)
CODIM2_MARKERS = {
    "pd_grazing": ("*", "doubling meets grazing"),
    "fold_grazing": ("D", "fold meets grazing"),
    "cusp": ("^", "cusp (two folds meet)"),
    "double_grazing": ("s", "both flanks graze"),
    "pd_pd": ("p", "two doublings meet"),
    "grazing_grazing": ("X", "two turning points graze"),
}


def curve_flank(row) -> str:
    """``face``, ``back``, ``bearing`` for a grazing curve (its ``flank`` column, else read
    from its ``boundary``), ``""`` for the other kinds."""
    if str(row.get("kind", "")) != "grazing":
        return ""
    flank = str(row.get("flank", "") or "")
    if flank:
        return flank
    b = str(row.get("boundary", "") or "").replace(" ", "")
    return "face" if b.startswith("x=+") else "back" if b.startswith("x=-") else "bearing"


def _period_colour(n: int) -> str:
    k = int(np.log2(max(n, 1))) if n & (n - 1) == 0 else len(CURVE_PERIOD_COLOURS) - 1
    return CURVE_PERIOD_COLOURS[min(k, len(CURVE_PERIOD_COLOURS) - 1)]


def _curve_text(kind: str, flank: str, n: int) -> str:
    if kind == "period_doubling":
        return f"period doubling {n}T -> {2 * n}T"
    if kind == "grazing":
        return f"grazing {dict(face='x=+b', back='x=-b').get(flank, 'bearing')}, {n}T"
    return f"{kind.replace('_', ' ')}, {n}T"


def curve_look(row) -> dict[str, Any]:
    """How a curve is drawn in Figs 21 and 22 and in the explorer: ``colour`` (its period),
    ``dash`` (its kind and flank, in units of the line width; empty: solid) and the legend's
    ``text``."""
    kind, n = str(row.get("kind", "")), int(row.get("period", 1))
    flank = curve_flank(row)
    ls, _ = CURVE_LINES.get((kind, flank), ("-", kind))
    dash = [] if isinstance(ls, str) else list(ls[1])
    return {"colour": _period_colour(n), "dash": dash, "text": _curve_text(kind, flank, n),
            "flank": flank}


def draw_curves(ax, curves: pd.DataFrame, *, swap: bool = False, labels: bool = True,
                codim2: pd.DataFrame | None = None) -> list:
    """Draw two-parameter bifurcation curves (``value`` on x, ``value2`` on y): the dash
    pattern by kind (a grazing by its flank), the colour by the orbit's period, a white halo
    under each line; the codimension-2 points as black markers by kind. Returns the legend
    handles: one per kind and period drawn, then one per kind of codimension-2 point."""
    from matplotlib import patheffects
    from matplotlib.lines import Line2D

    halo = [patheffects.withStroke(linewidth=3.2, foreground="white", alpha=0.8)]
    keys: dict[tuple[str, str, int], Line2D] = {}
    for _, c in curves.groupby("curve", sort=True):
        r = c.iloc[0]
        kind, n = str(r["kind"]), int(r["period"])
        flank = curve_flank(r)
        ls, _text = CURVE_LINES.get((kind, flank), ("-", kind))
        colour = _period_colour(n)
        xs, ys = c["value"].to_numpy(), c["value2"].to_numpy()
        if swap:
            xs, ys = ys, xs
        ax.plot(xs, ys, ls=ls, color=colour, lw=1.5, path_effects=halo, zorder=3)
        if len(xs) == 1:
            ax.plot(xs, ys, marker=".", color=colour, ms=4, zorder=3)
        keys.setdefault((kind, flank, n), Line2D([], [], ls=ls, color=colour, lw=1.5,
                                                 label=_curve_text(kind, flank, n)))
    order = {k: i for i, k in enumerate(("period_doubling", "grazing", "fold"))}
    handles = [keys[k] for k in sorted(keys, key=lambda k: (order.get(k[0], 9), k[1], k[2]))]
    if codim2 is not None and len(codim2):
        # a point whose Newton solve did not converge is not located: grey, said in the legend
        located = (codim2["converged"].astype(bool) if "converged" in codim2
                   else pd.Series(True, index=codim2.index))
        for (kind, ok), g in codim2.groupby([codim2["kind"], located], sort=True):
            marker, text = CODIM2_MARKERS.get(str(kind), ("o", str(kind)))
            edge = "black" if ok else "0.55"
            xs, ys = g["value"].to_numpy(), g["value2"].to_numpy()
            if swap:
                xs, ys = ys, xs
            ax.plot(xs, ys, ls="none", marker=marker, ms=7, mfc="white", mec=edge,
                    mew=1.1, zorder=5)
            label = f"{text} ({len(g)})" if ok else f"{text}, not converged ({len(g)})"
            handles.append(Line2D([], [], ls="none", marker=marker, ms=7, mfc="white",
                                  mec=edge, mew=1.1, label=label))
    return handles if labels else []


def figure_curves(curves: pd.DataFrame, cells: pd.DataFrame | None = None, *,
                  title: str | None = None, codim2: pd.DataFrame | None = None):
    """Bifurcation curves and codimension-2 points over the plane's pattern map (if ``cells``
    is given); the legends: the patterns on the right, the curves below them."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9.6, 6.0))
    if cells is not None and len(cells):
        from gearsim.presentation.figures.planes import draw_pattern_map

        draw_pattern_map(ax, cells, legend=True, legend_kw={"fontsize": 6, "loc": "upper left",
                                                            "bbox_to_anchor": (1.01, 1.0)})
    name = str(curves["name"].iloc[0]) if len(curves) else "w"
    name2 = str(curves["name2"].iloc[0]) if len(curves) else "b"
    handles = draw_curves(ax, curves, codim2=codim2)
    if cells is not None and len(cells):
        ax.set_xlim(float(cells["x"].min()), float(cells["x"].max()))
        ax.set_ylim(float(cells["y"].min()), float(cells["y"].max()))
    if handles:
        fig.legend(handles=handles, loc="lower left", bbox_to_anchor=(0.745, 0.02),
                   fontsize=6, title="curves: kind, period (Newton-Floquet)", handlelength=4,
                   title_fontsize=6.5, ncol=1 if len(handles) <= 16 else 2, frameon=False)
    ax.set_xlabel(param_label(name))
    ax.set_ylabel(param_label(name2))
    if title:
        ax.set_title(title, fontsize=9)
    fig.subplots_adjust(left=0.07, right=0.74, bottom=0.09, top=0.93)
    return fig


def exact_marks(ctx, sweep: pd.DataFrame):
    """The exact-landmark table of the standard sweep when the continuation is available
    (``ctx``: the figures' :class:`~gearsim.presentation.figures.context.Context`)."""
    pts = ctx.orbits.get("standard_points")
    if pts is None:
        br = ctx.orbits.get("standard")
        if br is None:
            return None
        from gearsim.analysis.exact_landmarks import bifurcation_points

        pts = bifurcation_points(br)
    from gearsim.analysis.exact_landmarks import exact_landmarks

    return exact_landmarks(pts, sweep)


def overlay_standard(fig, ctx, sweep: pd.DataFrame) -> list[str]:
    """Fig 4 (a): the continuation's branches (stable solid, unstable dashed) and the exact
    landmarks (diamonds on the axis) over the sweep's Poincare points; notes for the record."""
    br = ctx.orbits.get("standard")
    if br is None or not len(br):
        return []
    ax = fig.axes[0]
    for _, b in br.groupby("branch", sort=True):
        n = int(b["period"].iloc[0])
        colour = PERIOD_COLOURS[min(int(np.log2(max(n, 1))), len(PERIOD_COLOURS) - 1)]
        b = b[b["event"] == ""]
        vals, xs, st = b["value"].to_numpy(), b["x"].to_numpy(), b["stable"].to_numpy()
        for sl, stable in _segments(vals, st):
            if not stable:  # the simulation shows the stable parts already
                ax.plot(vals[sl], xs[sl], color=colour, lw=0.8, ls=(0, (3, 2)), alpha=0.8,
                        zorder=1)
    table = exact_marks(ctx, sweep)
    notes = ["Dashed lines in (a): unstable periodic orbits from the continuation of the "
             "standard set (black period 1, blue period 2, cyan period 4; docs/orbits.md)."]
    if table is not None and len(table):
        hit = table[np.isfinite(table["exact"].to_numpy(dtype=float))]
        y0 = ax.get_ylim()[0]
        ax.plot(hit["exact"], np.full(len(hit), y0), ls="none", marker="D", ms=5,
                mfc="white", mec="#d62728", mew=1.2, zorder=5, clip_on=False,
                label="exact bifurcation (continuation)")
        ax.legend(fontsize=6, loc="lower right")
        for r in table.itertuples():
            ex = f"{r.exact:.6f}" if np.isfinite(r.exact) else "none"
            grid = f"{r.grid:.3f}" if np.isfinite(r.grid) else "not found"
            notes.append(f"{r.text}: paper ω = {r.paper:g}, grid {grid}, exact {ex}")
    return notes
