"""Phase portraits with Poincare points, time histories and dynamic load (Figs 2, 5, 9-11).

Everything drawn here was simulated by a study-side job (:mod:`gearsim.study.figure_data`,
the point sets of :mod:`gearsim.study.sweeps`); the readers here turn its tables into what the
``figure*`` functions draw, so tests can feed tiny inputs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from gearsim.analysis.paper import PAPER_FIG5
from gearsim.dynamics.parameters import ModelParameters
from gearsim.presentation.figures import style
from gearsim.presentation.figures.data import PointMotion, motions_from_table


def _paper_label(w: float, table: dict[float, str]) -> str:
    for k, v in table.items():
        if abs(k - w) < 1e-9:
            return v
    return "?"


# ------------------------------------------------------------------------------ drawing helpers
def draw_phase(ax, pm: PointMotion, *, periods: int | None = None, colour: str = "#1f77b4",
               show_b: bool = True, label: str | None = None, lw: float = 0.6,
               poincare: bool = True) -> None:
    """Phase trajectory ``(x, x')`` over the last ``periods`` mesh periods, with the section
    points on top."""
    spp = pm.samples_per_period
    st = pm.traj.state
    if periods is not None:
        st = st[-(periods * spp + 1):]
    ax.plot(st[:, 0], st[:, 1], color=colour, lw=lw, alpha=0.85, label=label)
    if poincare:
        sec = pm.traj.section
        ax.plot(sec[:, 0], sec[:, 1], "o", ms=3.5, mfc="#d62728", mec="k", mew=0.4,
                zorder=5, label=None)
    if show_b:
        lo, hi = ax.get_xlim()
        for s in (1, -1):
            if lo <= s * pm.params.b <= hi:
                ax.axvline(s * pm.params.b, color="#555555", lw=0.6, ls="--")
        ax.set_xlim(lo, hi)
    ax.set_xlabel(style.X_LABEL)
    ax.set_ylabel(style.V_LABEL)


def phase_legend(ax, b: float, loc="best", fontsize=6.5, extra=()):
    handles = [Line2D([], [], color="#1f77b4", lw=0.8, label="trajectory"),
               Line2D([], [], ls="", marker="o", ms=3.5, mfc="#d62728", mec="k", mew=0.4,
                      label="Poincaré points"),
               Line2D([], [], color="#555555", lw=0.6, ls="--", label=rf"$x = \pm b$ ({b:g})"),
               *extra]
    ax.legend(handles=handles, loc=loc, fontsize=fontsize, framealpha=0.8)


# ------------------------------------------------------------------------------ Fig 2
@dataclass
class Fig2Data:
    b: float
    motions: dict[int, PointMotion]  # impact state -> motion
    notes: list[str] = field(default_factory=list)


def fig2_data(df: pd.DataFrame, stated: dict, params: ModelParameters) -> Fig2Data:
    """Fig 2's motions from its figure-data table (one row per impact state)."""
    motions = {int(key): pm for key, _, _, pm in motions_from_table(df, params)}
    return Fig2Data(float(stated["b"]), motions, list(stated.get("notes") or []))


def figure2(data: Fig2Data):
    """Fig 2: the phase plane split by ``x = +b`` and ``x = -b``, with real trajectories."""
    fig, ax = plt.subplots(figsize=(8.0, 5.6))
    b = data.b
    xs = np.concatenate([pm.traj.state[:, 0] for pm in data.motions.values()] or [np.zeros(1)])
    vs = np.concatenate([pm.traj.state[:, 1] for pm in data.motions.values()] or [np.zeros(1)])
    span = max(xs.max() - xs.min(), 4 * b, 1e-3)
    xlo, xhi = min(xs.min(), -b) - 0.12 * span, max(xs.max(), b) + 0.12 * span
    vspan = max(vs.max() - vs.min(), 1e-3)
    vlo, vhi = vs.min() - 0.15 * vspan, vs.max() + 0.15 * vspan
    regions = [
        (b, xhi, "#fde0dd", r"$x > b$: tooth-face contact (meshing)"),
        (-b, b, "#f0f0f0", r"$|x| \leq b$: separation (inside the backlash)"),
        (xlo, -b, "#deebf7", r"$x < -b$: tooth-back contact"),
    ]
    handles = []
    for lo, hi, colour, text in regions:
        ax.axvspan(lo, hi, color=colour, zorder=0)
        handles.append(Patch(facecolor=colour, edgecolor="#999999", label=text))
    for s, name in ((1, "+b"), (-1, "-b")):
        ax.axvline(s * b, color="k", lw=1.0)
        ax.annotate(f"x = {name}", xy=(s * b, 1.0), xycoords=("data", "axes fraction"),
                    xytext=(2, -10), textcoords="offset points", fontsize=8)
    for I, pm in data.motions.items():
        c = pm.result.classification
        colour = style.impact_colour(I)
        n = max(c.n, 1)
        draw_phase(ax, pm, periods=n if c.n > 0 else 16, colour=colour, show_b=False, lw=1.1,
                   poincare=False)
        handles.append(Line2D([], [], color=colour, lw=1.2,
                              label=f"I = {I}: {c.label} ({c.label_npq}), "
                                    rf"$\omega$ = {pm.params.w:.3f}"))
    ax.set_xlim(xlo, xhi)
    ax.set_ylim(vlo, vhi)
    ax.set_xlabel(style.X_LABEL)
    ax.set_ylabel(style.V_LABEL)
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7.5,
              frameon=False)
    ax.set_title(f"phase plane at b = {b:g}: regions and simulated steady trajectories",
                 fontsize=9)
    if data.notes:
        style.note_box(ax, "\n".join(data.notes), loc="lower left")
    fig.tight_layout()
    return fig


# ------------------------------------------------------------------------------ Fig 5
def figure5(points: Sequence[PointMotion], *, paper: dict[float, str] | None = None,
            ncols: int = 4):
    """Fig 5: phase diagrams with Poincare points, one panel per ``w``."""
    paper = PAPER_FIG5 if paper is None else paper
    n = len(points)
    ncols = max(1, min(ncols, n))
    nrows = int(np.ceil(n / ncols))
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.3 * ncols, 2.9 * nrows + 0.3),
                             squeeze=False)
    for k, (ax, pm) in enumerate(zip(axes.ravel(), points, strict=False)):
        c = pm.result.classification
        periods = max(c.n, 1) * 2 if c.n > 0 else 96
        draw_phase(ax, pm, periods=periods)
        ref = _paper_label(pm.params.w, paper)
        ax.set_title(f"({chr(97 + k)}) $\\omega$ = {pm.params.w:g}\npaper {ref}; ours "
                     f"{pm.label}", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.xaxis.label.set_size(7)
        ax.yaxis.label.set_size(7)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    if n:
        phase_legend(axes.ravel()[0], points[0].params.b, loc="best")
    fig.tight_layout()
    return fig


# ------------------------------------------------------------------------------ Figs 9-11
@dataclass
class Attractor:
    npq: str
    label: str
    motion: PointMotion
    hits: int  # initial conditions that reached it


@dataclass
class AttractorSearch:
    params: ModelParameters
    tried: int
    found: dict[str, Attractor]  # npq (or motion name) -> attractor
    elsewhere: dict[str, PointMotion] = field(default_factory=dict)  # npq -> other-w motion
    # targets the sweep lists at other w that did not persist when re-simulated there
    unconfirmed: dict[str, list[str]] = field(default_factory=dict)

    def summary(self) -> str:
        parts = [f"{a.motion.label} x{a.hits}" for a in
                 sorted(self.found.values(), key=lambda a: -a.hits)]
        return ", ".join(parts) if parts else "nothing"


def search_from_table(df: pd.DataFrame, stated: dict, params: ModelParameters
                      ) -> AttractorSearch:
    """Figs 9-11's attractor search from its figure-data table (rows ``found`` with the
    initial conditions that reached each motion, and ``elsewhere``)."""
    p = params.with_(**stated["params"])
    search = AttractorSearch(p, int(stated["tried"]), {},
                             unconfirmed={k: list(v) for k, v in
                                          (stated.get("unconfirmed") or {}).items()})
    for key, role, hits, pm in motions_from_table(df, params):
        if role == "found":
            search.found[key] = Attractor(key, pm.result.classification.label, pm, hits)
        else:
            search.elsewhere[key] = pm
    return search


def choose_motion(search: AttractorSearch, target: str,
                  used: Sequence[str] = ()) -> tuple[PointMotion | None, str]:
    """The motion to draw for ``target`` and a note saying what it is when not the target."""
    p = search.params
    where = f"b = {p.b:g}, \u03c9 = {p.w:g}"
    if target in search.found:
        a = search.found[target]
        return a.motion, (f"{target} reached from {a.hits} of {search.tried} initial conditions "
                          f"at {where}")
    lead = (f"{target} NOT found at {where} from {search.tried} initial conditions "
            f"(found: {search.summary()}).")
    if target in search.elsewhere:
        pm = search.elsewhere[target]
        return pm, f"{lead} Shown: {target} at \u03c9 = {pm.params.w:.4g} from the b sweep."
    if target in search.unconfirmed:
        lead += (f" The b sweep lists {target} elsewhere, but it did not persist when "
                 f"re-simulated from the sweep state (\u03c9 -> found: "
                 f"{'; '.join(search.unconfirmed[target])}).")
    others = [a for a in search.found.values() if a.npq not in used]
    others = others or list(search.found.values())
    if not others:
        return None, lead
    n_t = int(target.split("-")[0])
    best = min(others, key=lambda a: (a.motion.result.classification.I != 2,
                                      abs(a.motion.result.classification.n - n_t), -a.hits))
    return best.motion, f"{lead} Shown instead: {best.motion.label} at {where}."


TAU_SHIFTED = r"dimensionless time $\tau - \tau_0$ ($\tau_0$: a Poincaré section time)"


def _headroom(ax, frac: float = 0.28) -> None:
    lo, hi = ax.get_ylim()
    ax.set_ylim(lo, hi + frac * (hi - lo))


def figure_double_sided(pm: PointMotion | None, *, target: str, note: str,
                        time_periods: int | None = None):
    """Figs 9-11: (a) phase + Poincare, (b) time history, (c) dynamic load coefficient."""
    fig, axes = plt.subplots(1, 3, figsize=(13.5, 4.2))
    if pm is None:
        for ax in axes:
            ax.axis("off")
        style.note_box(axes[1], note, loc="upper left", fontsize=9)
        return fig
    c = pm.result.classification
    n = max(c.n, 1)
    periods = time_periods or (max(4, 2 * n) if c.n > 0 else 16)
    draw_phase(axes[0], pm, periods=n * 2 if c.n > 0 else 64)
    _headroom(axes[0])
    phase_legend(axes[0], pm.params.b, loc="upper right")
    spp = pm.samples_per_period
    m = periods * spp + 1
    tau_abs = pm.traj.tau[-m:]
    T = pm.params.mesh_period
    tau0 = np.ceil(tau_abs[0] / T - 1e-9) * T  # a section time, shown as 0
    tau = tau_abs - tau0
    x = pm.traj.state[-m:, 0]
    axes[1].plot(tau, x, color="#1f77b4", lw=0.9, label=r"$x(\tau)$")
    for s in (1, -1):
        axes[1].axhline(s * pm.params.b, color="#555555", lw=0.6, ls="--",
                        label=r"$x = \pm b$" if s == 1 else None)
    tsec = np.arange(0.0, tau[-1] / T + 1e-9) * T
    xsec = np.interp(tsec, tau, x)
    axes[1].plot(tsec, xsec, "o", ms=3.5, mfc="#d62728", mec="k", mew=0.4,
                 label="Poincaré points (every T)")
    axes[1].set_xlabel(TAU_SHIFTED)
    axes[1].set_ylabel(style.X_LABEL)
    _headroom(axes[1])
    axes[1].legend(fontsize=6.5, loc="upper right", framealpha=0.8, ncol=3)
    load = pm.traj.mesh_force[-m:] / pm.params.Fm
    axes[2].plot(tau, load, color="#2ca02c", lw=0.9, label=r"$F_n/F_m$")
    axes[2].axhline(0.0, color="k", lw=0.6)
    axes[2].axhline(1.0, color="#555555", lw=0.6, ls=":", label="static load (1)")
    axes[2].set_xlabel(TAU_SHIFTED)
    axes[2].set_ylabel(style.LOAD_LABEL)
    _headroom(axes[2])
    axes[2].legend(fontsize=6.5, loc="upper right", framealpha=0.8, ncol=2)
    for ax, tag in zip(axes, "abc", strict=True):
        ax.set_title(f"({tag})", fontsize=9, loc="left")
    fig.suptitle(f"paper: {target} double-sided impact motion; ours: {pm.label} "
                 f"at b = {pm.params.b:g}, \u03c9 = {pm.params.w:.4g}", fontsize=10)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    fig.text(0.01, 0.01, note, fontsize=7.5, ha="left", va="bottom", wrap=True,
             bbox={"boxstyle": "round,pad=0.3", "fc": "#fff8dc", "ec": "#b8860b"})
    return fig
