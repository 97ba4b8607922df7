"""The builders of the paper's figures 1-17 (the table that names them:
:mod:`gearsim.presentation.figures.registry`). Each takes a :class:`~.context.Context` and returns
a list of :class:`~.context.Built`."""

from __future__ import annotations

import numpy as np
import pandas as pd

from gearsim.analysis.paper import (
    PAPER_FIG5,
    PAPER_FIG6,
    PAPER_FIG9_11,
    PAPER_JUMP_DC,
    PAPER_JUMP_KMAX,
    PAPER_SEQUENCE_TEXT,
)
from gearsim.cell.motion import DEFAULT_KMAX, KMAX_DEFINITION
from gearsim.presentation.figures.context import (
    _POINT_NOTE,
    Built,
    Context,
    _grid_note,
    _need,
    _plane,
    _sweep_note,
    axes_text,
    paper_comparison,
    sweep_title,
)


# ------------------------------------------------------------------------------ builders
def fig1(ctx: Context) -> list[Built]:
    from gearsim.presentation.figures.schematic import figure1

    return [Built(1, figure1(), "Schematic of the 6-DOF bending-torsional model: non-circular "
                  "driver p and curve-face gear g on bearings (spring + damper in Y and Z, "
                  "radial clearance), mesh spring K(t) and damper C_n with backlash 2B and "
                  "transmission error e(t) along the line of action.",
                  ["Redrawn from the model description (the paper's image is not in our copy); "
                   "the gear shapes are illustrative (pitch curve of order 2, face of order "
                   "4)."])]


def fig2(ctx: Context) -> list[Built]:
    from gearsim.presentation.figures.data import figure_data
    from gearsim.presentation.figures.phase import fig2_data, figure2

    df, stated = figure_data(ctx, "fig2")
    data = fig2_data(df, stated, ctx.params)
    b = data.b
    ws = ", ".join(f"I = {I}: ω = {pm.params.w:.3f} ({pm.npq})" for I, pm in
                   data.motions.items())
    diffs = ["The paper's sketch is schematic; ours shows simulated steady trajectories of "
             f"I = 0, 1 and 2 at b = {b:g} ({ws})."]
    diffs += data.notes
    diffs.append(_POINT_NOTE)
    return [Built(2, figure2(data), f"Phase plane split by x = +b and x = -b (b = {b:g}) into "
                  "tooth-face contact, separation and tooth-back contact, with simulated steady "
                  "trajectories of impact states I = 0, 1 and 2.", diffs, ["sweeps/b015"])]


def fig3(ctx: Context) -> list[Built]:
    from gearsim.presentation.figures.planes import figure3

    df = _plane(ctx, "wb")
    ax = axes_text(df)
    return [Built(3, figure3(df), f"Two-parameter co-simulation: the (u, v) = {ax} plane cut "
                  "into cells with centres a(i, j); each cell coloured by the pattern computed "
                  f"at its centre (a coarse view of the {ax} plane).",
                  [f"A coarse 12 x 8 view taken from our computed plane ({_grid_note(df)}) "
                   "instead of a blank schematic grid."], ["wb/cells"])]


def _landmark_diffs(df: pd.DataFrame) -> list[str]:
    """Paper landmarks beside ours, matched among the landmarks drawn (brief excursions out)."""
    from gearsim.analysis.landmarks import match_paper
    from gearsim.presentation.figures.bifurcation import landmarks_of

    if len(df) < 2:
        return []
    m = match_paper(landmarks_of(df))
    out = []
    for _, r in m.iterrows():
        ours = f"{r['ours']:.3f}" if r["found"] else "not found"
        out.append(f"{r['text']}: paper ω = {r['paper']:g}, ours {ours}")
    return out


def fig4(ctx: Context) -> list[Built]:
    from gearsim.presentation.figures.bifurcation import figure4, landmarks_of, sequence_text

    df = _need(ctx.sweeps, "standard", "sweep")
    diffs = [_sweep_note(df), f"Our sequence: {sequence_text(df)}."]
    flick = landmarks_of(df).attrs.get("flickers", 0)
    if flick:
        diffs.append(f"{flick} brief excursions (A → B → A with B shorter than 3 swept values) "
                     "are not marked as landmarks on the diagram.")
    jump = df[df["dc"] == df["dc"].max()]
    diffs += _landmark_diffs(df)
    if len(jump):
        diffs.append(f"Largest DC {float(df['dc'].max()):.3f} (paper {PAPER_JUMP_DC} after the "
                     f"jump); Kmax at the jump in the paper {PAPER_JUMP_KMAX}; our Kmax = "
                     f"{KMAX_DEFINITION} (the catalogue's kmax).")
    fig = figure4(df)
    inputs = ["sweeps/standard"]
    exact = ""
    if "standard" in ctx.orbits:  # the continuation of the same set (docs/orbits.md)
        from gearsim.presentation.orbit_plots import overlay_standard

        diffs += overlay_standard(fig, ctx, df)
        inputs.append("orbits/standard")
        exact = (" Dashed: unstable periodic orbits (continuation); diamonds on the axis: the "
                 "exact bifurcation points of the landmarks.")
    return [Built(4, fig, "(a) Bifurcation diagram of the mesh displacement x at the "
                  "Poincaré section versus ω (red I = 0, black I = 1, blue I = 2) with the "
                  "landmarks found in the same data (G Bif grazing, PD Bif period doubling, "
                  "Jump, Chaos onset); (b) I:DC diagram (DC coloured by I, runs labelled "
                  "I:DC band); (c) Kmax versus ω." + exact, diffs, inputs)]


def _point_motions(ctx: Context, name: str):
    from gearsim.presentation.figures.data import points_from_table

    pts = points_from_table(_need(ctx.points, name, "points"), ctx.params)
    return pts, [f"points/{name}"], "recorded by the pipeline (forward ramp in ω)"


def _label_diffs(pts, paper: dict[float, str]) -> list[str]:
    out = []
    for pm in pts:
        ref = next((v for k, v in paper.items() if abs(k - pm.params.w) < 1e-9), None)
        ours = pm.npq
        if ref is None:
            continue
        same = ref == ours or (ref == "chaotic" and ours == "chaos")
        if not same:
            out.append(f"ω = {pm.params.w:g}: paper {ref}, ours {ours}")
    return out


def fig5(ctx: Context) -> list[Built]:
    from gearsim.presentation.figures.phase import figure5

    pts, inputs, how = _point_motions(ctx, "fig5")
    diffs = _label_diffs(pts, PAPER_FIG5) or ["every panel has the paper's pattern"]
    diffs.append("Paper panels (b) and (e) are the grazing points themselves; ours shows "
                 "whatever our model does at that ω (grazing of ours lies elsewhere, Fig 4).")
    return [Built(5, figure5(pts), "Phase trajectories (x, x') with the Poincaré points at "
                  f"each of the paper's ω; motions {how}; each panel names the paper's "
                  "pattern and ours.", diffs, inputs)]


def fig6(ctx: Context) -> list[Built]:
    from gearsim.presentation.figures.spectra import figure6

    pts, inputs, how = _point_motions(ctx, "fig6")
    diffs = _label_diffs(pts, PAPER_FIG6) or ["every panel has the paper's pattern"]
    return [Built(6, figure6(pts), "One-sided FFT amplitude spectra of x(τ) on exactly "
                  "uniform samples over a whole number of motion periods (Hann window), with "
                  f"ω and ω/2, ω/4, ω/8 marked; motions {how}.", diffs, inputs)]


def fig_pattern(number: int, plane: str):
    def build(ctx: Context) -> list[Built]:
        from gearsim.presentation.figures.planes import figure_pattern

        df = _plane(ctx, plane)
        diffs = [_grid_note(df), paper_comparison(df)]
        diffs.append("Categories: quasi-periodic cells get a lighter grey than chaotic ones "
                     "(the paper greys both); high periods other than 1, 2, 4, 8 are grouped.")
        return [Built(number, figure_pattern(df), f"Motion in the {axes_text(df)} plane: (a) "
                      "3-D bifurcation diagram of the Poincaré points of x over the plane "
                      "(at most 40 rows, coloured by I); (b) pattern I/nT of every cell "
                      "(red 0/1T, yellow 1/1T, colours for sub-harmonics and double-sided "
                      "patterns, dark grey double-sided chaos, light grey face-impact chaos).",
                      diffs, [f"{plane}/cells"])]
    return build


def fig_sweeps(number: int, names: tuple[str, ...]):
    def build(ctx: Context) -> list[Built]:
        from gearsim.presentation.figures.bifurcation import figure_sweeps, sequence_text

        dfs = {}
        diffs = []
        for n in names:
            df = _need(ctx.sweeps, n, "sweep")
            if not diffs:
                diffs.append(_sweep_note(df))
            title = sweep_title(n, ctx.sweep_fixed.get(n))
            dfs[title] = df
            diffs.append(f"{title}: paper {PAPER_SEQUENCE_TEXT.get(n, '?')}; ours "
                         f"{sequence_text(df)}")
        what = "backlash b" if number == 8 else "mesh damping ratio ξ"
        return [Built(number, figure_sweeps(dfs), "Bifurcation diagrams of the Poincaré "
                      f"points of x versus ω at three values of the {what} (red I = 0, black "
                      "I = 1, blue I = 2; landmarks from the same data).", diffs,
                      [f"sweeps/{n}" for n in names])]
    return build


def fig_dc(number: int, plane: str):
    def build(ctx: Context) -> list[Built]:
        from gearsim.presentation.figures.planes import figure_dc

        df = _plane(ctx, plane)
        return [Built(number, figure_dc(df), "Disengagement duty cycle in the "
                      f"{axes_text(df)} plane: "
                      "(a) DC surface; (b) I:DC map, each cell labelled by its impact state and "
                      "DC band (0.0 exactly, then bands of 0.1).",
                      [_grid_note(df), "The paper merges some bands (0.4–0.6 in Fig 12b, "
                       "0.0–0.2 in Fig 16b); we keep uniform 0.1 bands."],
                      [f"{plane}/cells"])]
    return build


def fig_kmax(number: int, plane: str):
    def build(ctx: Context) -> list[Built]:
        from gearsim.presentation.figures.data import plane_grid
        from gearsim.presentation.figures.planes import figure_kmax, robust_max

        df = _plane(ctx, plane)
        axis = axes_text(df)
        diffs = [_grid_note(df), f"Kmax = {KMAX_DEFINITION} (the catalogue's kmax); "
                 "the paper's normalisation is not stated (docs/model.md)."]
        col = "kmax" if "kmax" in df.columns else DEFAULT_KMAX
        Z = plane_grid(df, col)
        cap = robust_max(Z)
        over = int(np.sum(Z[np.isfinite(Z)] > cap))
        if over:
            diffs.append(f"Colour scale capped at {cap:.2f} (twice the 99th percentile): {over} "
                         f"cell(s) reach up to {np.nanmax(Z):.2f}, drawn at the top colour.")
        return [Built(number, figure_kmax(df), f"Maximum dynamic load coefficient in the "
                      f"{axis} plane: (a) surface; (b) filled contours.", diffs,
                      [f"{plane}/cells"])]
    return build


def fig9_11(ctx: Context) -> list[Built]:
    from gearsim.presentation.figures.data import figure_data
    from gearsim.presentation.figures.phase import (
        choose_motion,
        figure_double_sided,
        search_from_table,
    )

    df, stated = figure_data(ctx, "fig9_11")
    search = search_from_table(df, stated, ctx.params)
    out = []
    used: list[str] = []
    for number, target in PAPER_FIG9_11.items():
        pm, note = choose_motion(search, target, used)
        if pm is not None:
            used.append(pm.npq)
        shown = f"{pm.npq} ({pm.result.classification.label})" if pm else "nothing"
        fig = figure_double_sided(pm, target=target, note=note)
        out.append(Built(number, fig, f"Target {target}: (a) phase trajectory with Poincaré "
                         "points, (b) time history of x with the section samples, (c) dynamic "
                         f"load coefficient F_n/F_m; shown: {shown}.", [note, _POINT_NOTE],
                         ["sweeps/b015"]))
    return out
