"""FFT spectra of the mesh displacement (Fig 6).

The trajectory is sampled on exactly uniform times (:func:`gearsim.cell.simulate.trajectory` lands
on
every output time), over a whole number of motion periods, so the lines of a periodic motion sit
on FFT bins. The mesh frequency ``w`` and its sub-harmonics ``w/2, w/4, w/8`` are marked.
"""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.lines import Line2D

from gearsim.analysis.paper import PAPER_FIG6
from gearsim.presentation.figures.data import PointMotion, spectrum

SUBHARMONICS = (1, 2, 4, 8)
_SUB_COLOURS = {1: "#d62728", 2: "#ff7f0e", 4: "#2ca02c", 8: "#9467bd"}


def draw_spectrum(ax, pm: PointMotion, *, fmax_factor: float = 3.3) -> None:
    f, a = spectrum(pm)
    w = pm.params.w
    keep = f <= fmax_factor * w
    ax.plot(f[keep], a[keep], color="#1f4fd6", lw=0.8)
    top = float(a[keep][1:].max()) if keep.sum() > 1 else 1.0
    for d in SUBHARMONICS:
        ax.axvline(w / d, color=_SUB_COLOURS[d], lw=0.7, ls="--", alpha=0.9, zorder=0)
    ax.set_xlim(0, fmax_factor * w)
    ax.set_ylim(0, 1.12 * top if top > 0 else 1)
    ax.set_xlabel(r"angular frequency (units of $\omega_n$)")
    ax.set_ylabel(r"amplitude of $x$")


def figure6(points: Sequence[PointMotion], *, paper: dict[float, str] | None = None):
    """Fig 6: FFT spectra, one panel per point, ``w`` and sub-harmonics marked."""
    paper = PAPER_FIG6 if paper is None else paper
    n = len(points)
    ncols = max(1, min(2, n))
    nrows = int(np.ceil(n / ncols))
    fig, axes = plt.subplots(nrows, ncols, figsize=(10.0, 3.2 * nrows + 0.4), squeeze=False)
    for k, (ax, pm) in enumerate(zip(axes.ravel(), points, strict=False)):
        draw_spectrum(ax, pm)
        ref = next((v for kk, v in paper.items() if abs(kk - pm.params.w) < 1e-9), "?")
        ax.set_title(f"({chr(97 + k)}) $\\omega$ = {pm.params.w:g}: paper {ref}; ours "
                     f"{pm.label}", fontsize=8.5, loc="left")
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    handles = [Line2D([], [], color="#1f4fd6", lw=0.8, label="|FFT of x|")] + [
        Line2D([], [], color=_SUB_COLOURS[d], lw=0.8, ls="--",
               label=r"$\omega$" if d == 1 else rf"$\omega/{d}$")
        for d in SUBHARMONICS
    ]
    if n:
        axes.ravel()[0].legend(handles=handles, fontsize=7, loc="upper right", framealpha=0.85)
    fig.tight_layout()
    return fig
