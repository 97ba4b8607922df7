"""Bifurcation diagrams of the mesh displacement (Figs 4, 8, 15).

Poincare points of every swept value, coloured by the impact state of that value (red I = 0,
black I = 1, blue I = 2); landmarks (grazing ``G Bif``, period doubling ``PD Bif``, ``Jump``,
chaos onset) come from :func:`gearsim.analysis.landmarks.find_landmarks` on the same table and are
marked with their parameter value. Fig 4 adds the I:DC and Kmax panels.
"""

from __future__ import annotations

from collections.abc import Mapping

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.lines import Line2D

from gearsim.analysis.landmarks import find_landmarks
from gearsim.cell.motion import DEFAULT_KMAX
from gearsim.presentation.figures import style
from gearsim.presentation.figures.data import explode_poincare, sweep_axis

# the landmark kinds marked on the diagrams and their line colours
MARKED = {
    "grazing": ("G Bif", "#8c564b"),
    "period_doubling": ("PD Bif", "#2ca02c"),
    "inverse_period_doubling": ("PD Bif", "#2ca02c"),
    "period_one": ("PD Bif", "#2ca02c"),
    "jump": ("Jump", "#ff7f0e"),
    "chaos_onset": ("Chaos", "#9467bd"),
}


def landmarks_of(df: pd.DataFrame, *, min_run: int = 3) -> pd.DataFrame:
    """Landmarks of a sweep table worth marking (empty table when there are too few rows).

    Excursions ``A -> B -> A`` where ``B`` lasts fewer than ``min_run`` swept values (a cell or
    two classified differently next to a bifurcation, or a brief switch of branch) are not
    marked; jumps are always kept. The table's ``attrs["flickers"]`` counts the pairs dropped.
    """
    if len(df) < 2:
        out = pd.DataFrame(columns=["kind", "value", "annotation"])
        out.attrs["flickers"] = 0
        return out
    lm = find_landmarks(df).reset_index(drop=True)
    changes = lm[lm["kind"] != "jump"].index.tolist()
    drop: set[int] = set()
    for a, b in zip(changes[:-1], changes[1:], strict=True):
        if a in drop:
            continue
        ra, rb = lm.loc[a], lm.loc[b]
        run = int(rb["i_lo"]) - int(ra["i_hi"]) + 1
        if run < min_run and ra["from_npq"] == rb["to_npq"]:
            drop.update((a, b))
    out = lm.drop(index=sorted(drop)).reset_index(drop=True)
    out.attrs["flickers"] = len(drop) // 2
    return out


def impact_legend(ax, Is, loc="upper left", **kw):
    """Legend with one marker per impact state present."""
    present = [i for i in (0, 1, 2, -1, -2) if i in set(int(v) for v in Is)]
    handles = [
        Line2D([], [], ls="", marker="o", ms=4, color=style.impact_colour(i),
               label=style.IMPACT_NAMES[i])
        for i in present
    ]
    if handles:
        ax.legend(handles=handles, loc=loc, fontsize=7, framealpha=0.85, **kw)


def draw_bifurcation(ax, df: pd.DataFrame, *, landmarks: pd.DataFrame | None = None,
                     legend: bool = True, point_size: float | None = None, max_points: int = 128,
                     annotate: bool = True) -> pd.DataFrame:
    """Poincare points of a sweep coloured by impact state; returns the landmarks drawn."""
    name, _ = sweep_axis(df)
    v, x, I, _rows = explode_poincare(df, max_points=max_points)
    colours = np.array([style.impact_colour(i) for i in I], dtype=object)
    if point_size is None:  # fewer swept values -> bigger dots
        point_size = float(np.clip(2400.0 / max(len(df), 1), 0.8, 6.0))
    # draw black first and red/blue on top so the rare states stay visible
    order = np.argsort([{1: 0, 0: 1, 2: 2}.get(int(i), 3) for i in I], kind="stable")
    ax.scatter(v[order], x[order], s=point_size, c=list(colours[order]), marker="o",
               linewidths=0, rasterized=True)
    ax.set_xlabel(style.param_label(name))
    ax.set_ylabel(r"mesh displacement $x$ (Poincaré points)")
    if len(v):
        ax.set_xlim(float(np.min(df["value"])), float(np.max(df["value"])))
    if legend:
        impact_legend(ax, I, loc="lower left")
    lm = landmarks_of(df) if landmarks is None else landmarks
    if annotate:
        mark_landmarks(ax, lm)
    return lm


def mark_landmarks(ax, lm: pd.DataFrame, *, text: bool = True):
    """Vertical lines at the landmarks with their short names (G Bif, PD Bif, Jump, Chaos)."""
    if lm is None or len(lm) == 0:
        return
    marks = [(float(r["value"]), *MARKED[str(r["kind"])]) for _, r in lm.iterrows()
             if str(r["kind"]) in MARKED]
    for w, _name, colour in marks:
        ax.axvline(w, color=colour, lw=0.7, ls="--", alpha=0.8, zorder=0)
    if not text or not marks:
        return
    lo, hi = ax.get_xlim()
    gap = (hi - lo) / 300  # marks this close share a label; the rest are staggered
    groups: list[list[tuple[float, str, str]]] = [[marks[0]]]
    for m in marks[1:]:
        if m[0] - groups[-1][-1][0] < gap:
            groups[-1].append(m)
        else:
            groups.append([m])
    centres = [float(np.mean([m[0] for m in g])) for g in groups]
    shifts = label_shifts(ax, centres)
    for g, c, dx in zip(groups, centres, shifts, strict=True):
        names = list(dict.fromkeys(m[1] for m in g))
        if len(names) > 1:  # several kinds close together: short names
            short = {"G Bif": "G", "PD Bif": "PD", "Jump": "Jump", "Chaos": "Chaos"}
            names = ["/".join(short[n] for n in names)]
        ws = [m[0] for m in g]
        where = f"{ws[0]:.3f}" if len(ws) == 1 else f"{min(ws):.3f}–{max(ws):.3f}"
        ax.annotate(f"{'/'.join(names)} {where}", xy=(c, 1.0),
                    xycoords=("data", "axes fraction"), xytext=(dx, 2 if dx == 0 else 6),
                    textcoords="offset points", fontsize=5.5, color=g[0][2], va="bottom",
                    ha="center", rotation=90,
                    arrowprops=None if dx == 0 else dict(arrowstyle="-", lw=0.4,
                                                         color=g[0][2], shrinkA=0, shrinkB=0))


def label_shifts(ax, xs: list[float], min_sep_pt: float = 7.5) -> list[float]:
    """Horizontal offsets (points) that keep rotated labels at ``xs`` (data, increasing) at
    least ``min_sep_pt`` apart (one line of 5.5-pt text): labels are pushed right where they
    crowd, then each crowded run is centred on its marks (not past its left neighbour); a
    label that moves gets a leader line to its mark (Fig 4's 1.565-1.619 cluster)."""
    if not xs:
        return []
    lo, hi = ax.get_xlim()
    width = ax.get_window_extent().width * 72.0 / ax.figure.dpi
    pos = [(x - lo) / (hi - lo) * width for x in xs]
    out = list(pos)
    runs: list[list[int]] = [[0]]
    for t in range(1, len(out)):
        if pos[t] < out[t - 1] + min_sep_pt:
            out[t] = out[t - 1] + min_sep_pt
            runs[-1].append(t)
        else:
            runs.append([t])
    prev_end = -np.inf
    for run in runs:
        back = float(np.mean([out[t] - pos[t] for t in run]))
        back = min(back, out[run[0]] - (prev_end + min_sep_pt))
        for t in run:
            out[t] -= back
        prev_end = out[run[-1]]
    return [0.0 if abs(o - p_) < 1e-6 else float(o - p_) for o, p_ in zip(out, pos, strict=True)]


def draw_dc(ax, df: pd.DataFrame, *, band_labels: bool = True) -> None:
    """I:DC diagram along the sweep: DC coloured by I, runs of equal ``I:band`` labelled."""
    name, v = sweep_axis(df)
    dc = df["dc"].to_numpy(dtype=float)
    Is = df["I"].to_numpy(dtype=int)
    ax.plot(v, dc, color="#999999", lw=0.5, zorder=1)
    ax.scatter(v, dc, s=5, c=[style.impact_colour(i) for i in Is], zorder=2, linewidths=0)
    ax.set_ylabel(style.DC_LABEL)
    ax.set_xlabel(style.param_label(name))
    ax.set_ylim(-0.03, 1.0)
    if len(v):
        ax.set_xlim(float(v.min()), float(v.max()))
    impact_legend(ax, Is, loc="upper right")
    if not band_labels or len(v) == 0:
        return
    keys = [f"{i}:{style.dc_band(d)}" for i, d in zip(Is, dc, strict=True)]
    span = v.max() - v.min() if len(v) > 1 else 1.0
    start = 0
    for k in range(1, len(keys) + 1):
        if k == len(keys) or keys[k] != keys[start]:
            a, b = v[start], v[k - 1]
            if (b - a) >= span / 40 or k - start >= 3:
                ymid = float(np.nanmean(dc[start:k]))
                ax.annotate(keys[start], xy=(0.5 * (a + b), min(ymid + 0.06, 0.93)),
                            fontsize=5.5, ha="center", va="bottom", rotation=90,
                            color=style.impact_colour(Is[start]))
            start = k


def draw_kmax(ax, df: pd.DataFrame, reading: str | None = None) -> None:
    name, v = sweep_axis(df)
    col = reading or ("kmax" if "kmax" in df.columns else DEFAULT_KMAX)
    k = df[col].to_numpy(dtype=float)
    Is = df["I"].to_numpy(dtype=int)
    ax.plot(v, k, color="#999999", lw=0.5, zorder=1)
    ax.scatter(v, k, s=5, c=[style.impact_colour(i) for i in Is], zorder=2, linewidths=0)
    ax.set_ylabel(style.kmax_label(None if col == "kmax" else col))
    ax.set_xlabel(style.param_label(name))
    if len(v):
        ax.set_xlim(float(v.min()), float(v.max()))
    impact_legend(ax, Is, loc="upper right")


def figure4(df: pd.DataFrame, *, title: str | None = None):
    """Fig 4: (a) bifurcation of mesh displacement, (b) I:DC, (c) Kmax versus w."""
    fig, axes = plt.subplots(3, 1, figsize=(7.5, 9.0), sharex=True,
                             gridspec_kw={"height_ratios": [1.6, 1.0, 1.0]})
    lm = draw_bifurcation(axes[0], df)
    draw_dc(axes[1], df)
    mark_landmarks(axes[1], lm, text=False)
    draw_kmax(axes[2], df)
    mark_landmarks(axes[2], lm, text=False)
    for ax, tag in zip(axes, "abc", strict=True):
        ax.text(0.005, 0.99, f"({tag})", transform=ax.transAxes, fontsize=10,
                fontweight="bold", va="top", ha="left")
    for ax in axes[:2]:
        ax.set_xlabel("")
        ax.tick_params(labelbottom=False)
    style.finish(fig, title)
    return fig


def figure_sweeps(sweeps: Mapping[str, pd.DataFrame], *, title: str | None = None,
                  notes: Mapping[str, str] | None = None):
    """Figs 8 and 15: one bifurcation panel per sweep, e.g. ``{"b = 0.15": df, ...}``."""
    n = len(sweeps)
    fig, axes = plt.subplots(n, 1, figsize=(7.5, 3.6 * n + 0.4), squeeze=False)
    for ax, (tag, (label, df)) in zip(axes[:, 0], enumerate(sweeps.items()), strict=True):
        draw_bifurcation(ax, df)
        ax.text(0.005, 0.99, f"({chr(97 + tag)}) {label}", transform=ax.transAxes, fontsize=9,
                fontweight="bold", va="top", ha="left")
        if notes and notes.get(label):
            style.note_box(ax, notes[label], loc="lower right", fontsize=6)
    style.finish(fig, title)
    return fig


def sequence_text(df: pd.DataFrame, min_run: int = 3) -> str:
    """Our pattern sequence along a sweep, ``0/1T -> 1/1T -> ...`` (for captions and notes).

    Runs shorter than ``min_run`` swept values (brief excursions next to bifurcations) are left
    out and equal neighbours merged, as on the diagrams' landmark marks.
    """
    labels = [str(lab) if m == "periodic" else str(m)
              for lab, m in zip(df["label"], df["motion"], strict=True)]
    runs: list[list] = []
    for lab in labels:
        if runs and runs[-1][0] == lab:
            runs[-1][1] += 1
        else:
            runs.append([lab, 1])
    kept = [r for k, r in enumerate(runs) if r[1] >= min_run or k in (0, len(runs) - 1)]
    seq: list[str] = []
    for lab, _ in kept:
        if not seq or seq[-1] != lab:
            seq.append(lab)
    return " \u2192 ".join(seq)
