"""Figures of periodic-orbit branches and two-parameter bifurcation curves (matplotlib).

Branch diagram: section displacement ``x`` (dimensionless, units of ``b_c``) against the
continuation parameter, stable parts solid, unstable parts dashed, located events marked
(fold, period doubling, Neimark-Sacker, grazing); below it the largest Floquet multiplier
modulus with the unit circle's radius as a reference line.
"""

from __future__ import annotations

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


def draw_curves(ax, curves: pd.DataFrame, *, swap: bool = False, labels: bool = True) -> None:
    """Draw two-parameter bifurcation curves (``value`` on x, ``value2`` on y)."""
    seen: set[str] = set()
    for _, c in curves.groupby("curve", sort=True):
        kind = str(c["kind"].iloc[0])
        ls, colour, text = CURVE_STYLE.get(kind, ("-", "k", kind))
        n = int(c["period"].iloc[0])
        xs, ys = c["value"].to_numpy(), c["value2"].to_numpy()
        if swap:
            xs, ys = ys, xs
        ax.plot(xs, ys, ls=ls, color=colour, lw=1.8,
                label=None if (kind in seen or not labels) else text)
        seen.add(kind)
        k = len(xs) // 2
        ax.annotate(f"{n}T", (xs[k], ys[k]), fontsize=6.5, color=colour,
                    xytext=(3, 3), textcoords="offset points")


def figure_curves(curves: pd.DataFrame, cells: pd.DataFrame | None = None, *,
                  title: str | None = None):
    """Bifurcation curves over the plane's pattern map (if ``cells`` is given)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 5.2))
    if cells is not None and len(cells):
        from gearsim.presentation.figures.planes import draw_pattern_map

        draw_pattern_map(ax, cells, legend=True, legend_kw={"fontsize": 6, "loc": "upper left",
                                                            "bbox_to_anchor": (1.01, 1.0)})
    name = str(curves["name"].iloc[0]) if len(curves) else "w"
    name2 = str(curves["name2"].iloc[0]) if len(curves) else "b"
    draw_curves(ax, curves)
    if cells is not None and len(cells):
        ax.set_xlim(float(cells["x"].min()), float(cells["x"].max()))
        ax.set_ylim(float(cells["y"].min()), float(cells["y"].max()))
    handles = [h for h in ax.get_lines() if h.get_label() and not h.get_label().startswith("_")]
    if handles:
        fig.legend(handles=handles, loc="lower right", fontsize=7, title="curves (Newton)",
                   title_fontsize=7)
    ax.set_xlabel(param_label(name))
    ax.set_ylabel(param_label(name2))
    if title:
        ax.set_title(title, fontsize=9)
    fig.tight_layout()
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
