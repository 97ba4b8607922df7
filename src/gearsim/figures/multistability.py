"""Figures of coexisting attractors (beyond the paper): basin pictures, coexistence maps,
basin-fraction maps of the continuation attractor.

Inputs: a basin grid (:mod:`gearsim.basins`, one row per start) with its attractor table, or a
plane's cells table with ``n_attractors`` and its ``attractors`` table (catalogue, one row per
attractor of a cell: ``i``, ``j``, ``attractor``, ``label``, ``motion``, ``I``, ``n``,
``basin_fraction``, ``found_by``).
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.patches import Patch

from . import style

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
