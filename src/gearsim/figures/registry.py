"""Every figure of the study: the paper's caption, the inputs, and how ours is built.

:func:`build` turns a :class:`Context` (tables read by the CLI, the parameters and integration
settings of the pipeline config) into matplotlib figures plus a record (our caption, where we
differ from the paper and why) that the CLI writes next to the image as ``figNN.json`` and
:mod:`gearsim.figures.index` collects into ``results/figures/README.md``.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from ..parameters import ModelParameters
from ..simulate import IntegrationSettings

PAPER_CAPTIONS: dict[int, str] = {
    1: "Dynamic model of curve-face gear transmission system.",
    2: "Distribution of the system's phase trajectories on the plane.",
    3: "(Caption lost in our copy; the text: schematic diagram of two-parameter co-simulation, "
       "the (u, v) plane divided into grids with the cell centres a(i, j).)",
    4: "(a) Bifurcation diagram of mesh displacement; (b) I: DC diagram; (c) Kmax diagram.",
    5: "Superpositions of the phase diagram and Poincaré mapping of the gear pair: (a) ω = 0.48 "
       "1-0-0, (b) ω = 0.569 grazing, (c) ω = 0.86 1-1-0, (d) ω = 1.02 2-2-0, (e) ω = 1.072 "
       "grazing, (f) ω = 1.25 2-1-0, (g) ω = 1.37 4-3-0, (h) ω = 1.384 8-6-0, (i) ω = 1.53 "
       "chaotic, (j) ω = 1.7 4-3-0, (k) ω = 1.81 2-2-0, (l) ω = 2.24 1-1-0.",
    6: "FFT spectrum: (a) ω = 0.48 1-0-0, (b) ω = 1.02 2-2-0, (c) ω = 1.37 4-3-0, (d) ω = 1.53 "
       "chaotic.",
    7: "Meshing motion law diagram of the system in the (ω, b) parameter plane: (a) relative "
       "micro-displacement bifurcation diagram of gear pair, (b) pattern types and distribution "
       "regions of periodic motions.",
    8: "Single-parameter bifurcation diagrams of mesh displacement under different dimensionless "
       "backlash b: (a) b = 0.15, (b) b = 0.25, (c) b = 0.35.",
    9: "1-1-1 double-sided impact motion, when b = 0.15, ω = 0.82: (a) superposition of phase "
       "diagram and Poincaré map, (b) time history diagram, (c) dynamic load coefficient diagram.",
    10: "2-2-1 double-sided impact motion, when b = 0.15, ω = 0.82: (a) superposition of phase "
        "diagram and Poincaré map, (b) time history diagram, (c) dynamic load coefficient "
        "diagram.",
    11: "4-4-2 double-sided impact motion, when b = 0.15, ω = 0.82: (a) superposition of phase "
        "diagram and Poincaré map, (b) time history diagram, (c) dynamic load coefficient "
        "diagram.",
    12: "Impact states: disengagement duty cycle (I: DC) diagram in the (ω, b) parameter plane: "
        "(a) DC cloud diagram, (b) I: DC plane distribution diagram.",
    13: "Maximum dynamic load coefficient in the (ω, b) parameter plane: (a) cloud diagram, "
        "(b) plane distribution diagram.",
    14: "Meshing motion law diagram of the system in the (ω, ξ) parameter plane: (a) relative "
        "micro-displacement bifurcation diagram of gear pair, (b) pattern types and distribution "
        "regions of periodic motions.",
    15: "Single-parameter bifurcation diagrams of mesh displacement under different meshing "
        "damping ratios ξ: (a) ξ = 0.05, (b) ξ = 0.09, (c) ξ = 0.15.",
    16: "Impact states: disengagement duty cycle (I: DC) diagram in the (ω, ξ) parameter plane: "
        "(a) DC cloud diagram, (b) I: DC plane distribution diagram.",
    17: "Maximum dynamic load coefficient in the (ω, ξ) parameter plane: (a) cloud diagram, "
        "(b) plane distribution diagram.",
}

# the paper's pattern sequences along the sweeps of Figs 8 and 15 (Sect 3.2, 3.3)
PAPER_SEQUENCES: dict[str, str] = {
    "b015": "0/1T → 1/1T → 2/1T → 2/2T → 1/2T → 1/1T",
    "b025": "0/1T … double-sided interval with period 4 and 8 … face impacts",
    "b035": "0/1T … double-sided 2/4T and 2/2T … face impacts",
    "xi005": "0/1T → 1/1T → 1/2T → 1/4T → … chaos … → 1/8T → 1/4T → 1/2T → 1/1T",
    "xi009": "0/1T → 1/1T → 1/2T → 1/4T → 1/2T → 1/1T",
    "xi015": "0/1T → 1/1T",
}

# which inputs each figure reads: sweeps, planes, point sets (names as in config/config.yaml)
INPUTS: dict[int, dict[str, list[str]]] = {
    1: {},
    2: {"sweeps": ["b015"]},
    3: {"planes": ["wb"]},
    4: {"sweeps": ["standard"]},
    5: {"sweeps": ["standard"], "points": ["fig5"]},
    6: {"sweeps": ["standard"], "points": ["fig6"]},
    7: {"planes": ["wb"]},
    8: {"sweeps": ["b015", "b025", "b035"]},
    9: {"sweeps": ["b015"], "points": ["fig9_11"]},
    12: {"planes": ["wb"]},
    13: {"planes": ["wb"]},
    14: {"planes": ["wxi"]},
    15: {"sweeps": ["xi005", "xi009", "xi015"]},
    16: {"planes": ["wxi"]},
    17: {"planes": ["wxi"]},
}
INPUTS[10] = INPUTS[11] = INPUTS[9]
GROUPS = {9: (9, 10, 11), 10: (9, 10, 11), 11: (9, 10, 11)}
ALL = tuple(range(1, 18))


@dataclass
class Context:
    """What the figures read. Tables are looked up by their config names."""

    params: ModelParameters = field(default_factory=ModelParameters)
    settings: IntegrationSettings = field(default_factory=IntegrationSettings)
    sweeps: dict[str, pd.DataFrame] = field(default_factory=dict)
    planes: dict[str, pd.DataFrame] = field(default_factory=dict)
    points: dict[str, pd.DataFrame] = field(default_factory=dict)  # pipeline point tables
    point_specs: dict[str, Any] = field(default_factory=dict)  # config `points:`
    sweep_fixed: dict[str, dict[str, float]] = field(default_factory=dict)  # config `sweeps:`


@dataclass
class Built:
    number: int
    figure: Any  # matplotlib Figure
    caption: str  # ours
    differences: list[str]
    inputs: list[str] = field(default_factory=list)


def sweep_title(name: str, fixed: dict[str, float] | None = None) -> str:
    """``b = 0.15`` from a sweep's fixed parameters, or from a name like ``b015`` / ``xi005``."""
    sym = {"b": "b", "xi": "ξ", "w": "ω", "eps": "ε"}
    if fixed:
        return ", ".join(f"{sym.get(k, k)} = {v:g}" for k, v in fixed.items())
    m = re.fullmatch(r"([a-z]+)0(\d+)", name)
    if m:
        return f"{sym.get(m.group(1), m.group(1))} = 0.{m.group(2)}"
    return name


POINT_TRANSIENT = 300  # at least this many transient periods for the figures' own simulations
POINT_TRANSIENT_CONTINUATION = 200


_POINT_NOTE = (f"The figure's own simulations use at least {POINT_TRANSIENT} transient periods "
               f"({POINT_TRANSIENT_CONTINUATION} when continued), more than the plane cells, so "
               "slowly decaying transients are not drawn as long-period motions.")


def point_settings(ctx: Context) -> IntegrationSettings:
    """Settings of the figures' own point simulations (Figs 2, 5, 6 without recorded points,
    9-11): the config's, with a transient of at least 300 periods (200 when continued), so a
    slowly decaying transient is not drawn as a long-period motion. A few points only: cheap."""
    st = ctx.settings
    return st.with_(transient=max(st.transient, POINT_TRANSIENT),
                    transient_continuation=max(st.transient_continuation,
                                               POINT_TRANSIENT_CONTINUATION))


def _need(table: dict[str, pd.DataFrame], name: str, kind: str) -> pd.DataFrame:
    if name not in table:
        from ..errors import UsageError

        raise UsageError(f"this figure needs the {kind} '{name}' (pass --{kind} {name}=PATH)")
    return table[name]


def _sweep_note(df: pd.DataFrame) -> str:
    v = df["value"].to_numpy(dtype=float)
    step = (v.max() - v.min()) / max(len(v) - 1, 1) if len(v) else float("nan")
    return (f"{len(v)} swept values of ω (step {step:.4f}; the study's config uses 1201, the "
            "paper does not state its step); landmarks are located to within one step; "
            "pattern sequences leave out runs shorter than 3 swept values")


def _grid_note(df: pd.DataFrame) -> str:
    nx, ny = int(df["i"].max()) + 1, int(df["j"].max()) + 1
    return f"grid {nx} x {ny} cells (paper 400 x 400)"


# ------------------------------------------------------------------------------ builders
def _fig1(ctx: Context) -> list[Built]:
    from .schematic import figure1

    return [Built(1, figure1(), "Schematic of the 6-DOF bending-torsional model: non-circular "
                  "driver p and curve-face gear g on bearings (spring + damper in Y and Z, "
                  "radial clearance), mesh spring K(t) and damper C_n with backlash 2B and "
                  "transmission error e(t) along the line of action.",
                  ["Redrawn from the model description (the paper's image is not in our copy); "
                   "the gear shapes are illustrative (pitch curve of order 2, face of order "
                   "4)."])]


def _fig2(ctx: Context) -> list[Built]:
    from .phase import compute_fig2, figure2

    sweep = ctx.sweeps.get("b015")
    b = ctx.sweep_fixed.get("b015", {}).get("b", 0.15)
    data = compute_fig2(ctx.params, settings=point_settings(ctx), sweep=sweep, b=b)
    ws = ", ".join(f"I = {I}: ω = {pm.params.w:.3f} ({pm.npq})" for I, pm in
                   data.motions.items())
    diffs = ["The paper's sketch is schematic; ours shows simulated steady trajectories of "
             f"I = 0, 1 and 2 at b = {b:g} ({ws})."]
    diffs += data.notes
    diffs.append(_POINT_NOTE)
    return [Built(2, figure2(data), f"Phase plane split by x = +b and x = -b (b = {b:g}) into "
                  "tooth-face contact, separation and tooth-back contact, with simulated steady "
                  "trajectories of impact states I = 0, 1 and 2.", diffs,
                  ["sweeps/b015"] if sweep is not None else [])]


def _fig3(ctx: Context) -> list[Built]:
    from .planes import figure3

    df = _need(ctx.planes, "wb", "plane")
    return [Built(3, figure3(df), "Two-parameter co-simulation: the (u, v) = (ω, b) plane cut "
                  "into cells with centres a(i, j); each cell coloured by the pattern computed "
                  "at its centre (a coarse view of the (ω, b) plane).",
                  [f"A coarse 12 x 8 view taken from our computed plane ({_grid_note(df)}) "
                   "instead of a blank schematic grid."], ["wb/cells"])]


def _landmark_diffs(df: pd.DataFrame) -> list[str]:
    """Paper landmarks beside ours, matched among the landmarks drawn (brief excursions out)."""
    from ..landmarks import match_paper
    from .bifurcation import landmarks_of

    if len(df) < 2:
        return []
    m = match_paper(landmarks_of(df))
    out = []
    for _, r in m.iterrows():
        ours = f"{r['ours']:.3f}" if r["found"] else "not found"
        out.append(f"{r['text']}: paper ω = {r['paper']:g}, ours {ours}")
    return out


def _fig4(ctx: Context) -> list[Built]:
    from .bifurcation import figure4, landmarks_of, sequence_text

    df = _need(ctx.sweeps, "standard", "sweep")
    diffs = [_sweep_note(df), f"Our sequence: {sequence_text(df)}."]
    flick = landmarks_of(df).attrs.get("flickers", 0)
    if flick:
        diffs.append(f"{flick} brief excursions (A → B → A with B shorter than 3 swept values) "
                     "are not marked as landmarks on the diagram.")
    jump = df[df["dc"] == df["dc"].max()]
    diffs += _landmark_diffs(df)
    if len(jump):
        diffs.append(f"Largest DC {float(df['dc'].max()):.3f} (paper 0.66 after the jump); "
                     f"Kmax at the jump in the paper 1.311; our Kmax reading is the default "
                     "catalogue column 'kmax'.")
    return [Built(4, figure4(df), "(a) Bifurcation diagram of the mesh displacement x at the "
                  "Poincaré section versus ω (red I = 0, black I = 1, blue I = 2) with the "
                  "landmarks found in the same data (G Bif grazing, PD Bif period doubling, "
                  "Jump, Chaos onset); (b) I:DC diagram (DC coloured by I, runs labelled "
                  "I:DC band); (c) Kmax versus ω.", diffs, ["sweeps/standard"])]


def _point_motions(ctx: Context, name: str, ws_default):
    from .data import points_from_table
    from .phase import compute_points

    if name in ctx.points:
        pts = points_from_table(ctx.points[name], ctx.params)
        return pts, [f"points/{name}"], "recorded by the pipeline (forward ramp in ω)"
    ws = ctx.point_specs.get(name, ws_default)
    sweep = ctx.sweeps.get("standard")
    pts = compute_points(ctx.params, ws, settings=point_settings(ctx), sweep=sweep,
                         min_periods=32 if name == "fig5" else 128,
                         samples_per_period=128 if name == "fig5" else 64)
    return pts, (["sweeps/standard"] if sweep is not None else []), pts[0].seed if pts else ""


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


def _fig5(ctx: Context) -> list[Built]:
    from .phase import PAPER_FIG5, figure5

    pts, inputs, how = _point_motions(ctx, "fig5", list(PAPER_FIG5))
    diffs = _label_diffs(pts, PAPER_FIG5) or ["every panel has the paper's pattern"]
    if "points/fig5" not in inputs:
        diffs.append(_POINT_NOTE)
    diffs.append("Paper panels (b) and (e) are the grazing points themselves; ours shows "
                 "whatever our model does at that ω (grazing of ours lies elsewhere, Fig 4).")
    return [Built(5, figure5(pts), "Phase trajectories (x, x') with the Poincaré points at "
                  f"each of the paper's ω; motions {how}; each panel names the paper's "
                  "pattern and ours.", diffs, inputs)]


def _fig6(ctx: Context) -> list[Built]:
    from .spectra import PAPER_FIG6, figure6

    pts, inputs, how = _point_motions(ctx, "fig6", list(PAPER_FIG6))
    diffs = _label_diffs(pts, PAPER_FIG6) or ["every panel has the paper's pattern"]
    if "points/fig6" not in inputs:
        diffs.append(_POINT_NOTE)
    return [Built(6, figure6(pts), "One-sided FFT amplitude spectra of x(τ) on exactly "
                  "uniform samples over a whole number of motion periods (Hann window), with "
                  f"ω and ω/2, ω/4, ω/8 marked; motions {how}.", diffs, inputs)]


def _threshold_b(df: pd.DataFrame) -> str:
    two = df[df["I"] == 2]
    if not len(two):
        return "no double-sided (I = 2) cells in our (ω, b) plane"
    return (f"double-sided (I = 2) cells up to b = {float(two['b'].max()):.4f} in ours "
            "(paper: only for b < 0.4125)")


def _threshold_xi(df: pd.DataFrame) -> str:
    other = df[~df["label"].isin(["0/1T", "1/1T"])]
    if not len(other):
        return "only 0/1T and 1/1T in our (ω, ξ) plane"
    return (f"patterns other than 0/1T and 1/1T up to ξ = {float(other['xi'].max()):.4f} in "
            "ours (paper: only 0/1T and 1/1T for ξ > 0.1436)")


def _fig_pattern(number: int, plane: str):
    def build(ctx: Context) -> list[Built]:
        from .planes import figure_pattern

        df = _need(ctx.planes, plane, "plane")
        axis = "(ω, b)" if plane == "wb" else "(ω, ξ)"
        diffs = [_grid_note(df)]
        diffs.append(_threshold_b(df) if plane == "wb" else _threshold_xi(df))
        diffs.append("Categories: quasi-periodic cells get a lighter grey than chaotic ones "
                     "(the paper greys both); high periods other than 1, 2, 4, 8 are grouped.")
        return [Built(number, figure_pattern(df), f"Motion in the {axis} plane: (a) 3-D "
                      "bifurcation diagram of the Poincaré points of x over the plane "
                      "(at most 40 rows, coloured by I); (b) pattern I/nT of every cell "
                      "(red 0/1T, yellow 1/1T, colours for sub-harmonics and double-sided "
                      "patterns, dark grey double-sided chaos, light grey face-impact chaos).",
                      diffs, [f"{plane}/cells"])]
    return build


def _fig_sweeps(number: int, names: tuple[str, ...]):
    def build(ctx: Context) -> list[Built]:
        from .bifurcation import figure_sweeps, sequence_text

        dfs = {}
        diffs = []
        for n in names:
            df = _need(ctx.sweeps, n, "sweep")
            if not diffs:
                diffs.append(_sweep_note(df))
            title = sweep_title(n, ctx.sweep_fixed.get(n))
            dfs[title] = df
            diffs.append(f"{title}: paper {PAPER_SEQUENCES.get(n, '?')}; ours "
                         f"{sequence_text(df)}")
        what = "backlash b" if number == 8 else "mesh damping ratio ξ"
        return [Built(number, figure_sweeps(dfs), "Bifurcation diagrams of the Poincaré "
                      f"points of x versus ω at three values of the {what} (red I = 0, black "
                      "I = 1, blue I = 2; landmarks from the same data).", diffs,
                      [f"sweeps/{n}" for n in names])]
    return build


def _fig_dc(number: int, plane: str):
    def build(ctx: Context) -> list[Built]:
        from .planes import figure_dc

        df = _need(ctx.planes, plane, "plane")
        axis = "(ω, b)" if plane == "wb" else "(ω, ξ)"
        return [Built(number, figure_dc(df), f"Disengagement duty cycle in the {axis} plane: "
                      "(a) DC surface; (b) I:DC map, each cell labelled by its impact state and "
                      "DC band (0.0 exactly, then bands of 0.1).",
                      [_grid_note(df), "The paper merges some bands (0.4–0.6 in Fig 12b, "
                       "0.0–0.2 in Fig 16b); we keep uniform 0.1 bands."],
                      [f"{plane}/cells"])]
    return build


def _fig_kmax(number: int, plane: str):
    def build(ctx: Context) -> list[Built]:
        from ..classify import DEFAULT_KMAX, KMAX_READINGS
        from .data import plane_grid
        from .planes import figure_kmax, robust_max

        df = _need(ctx.planes, plane, "plane")
        axis = "(ω, b)" if plane == "wb" else "(ω, ξ)"
        diffs = [_grid_note(df), f"Kmax reading: {DEFAULT_KMAX} ({KMAX_READINGS[DEFAULT_KMAX]}); "
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


def _fig9_11(ctx: Context) -> list[Built]:
    from .phase import PAPER_FIG9_11, choose_motion, figure_double_sided, search_attractors

    spec = ctx.point_specs.get("fig9_11", {"b": 0.15, "w": 0.82})
    fixed = {k: float(v[0] if isinstance(v, list) else v) for k, v in spec.items()}
    p = ctx.params.with_(**fixed)
    sweep = ctx.sweeps.get("b015")
    search = search_attractors(p, settings=point_settings(ctx), sweep=sweep)
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
                         ["sweeps/b015"] if sweep is not None else []))
    return out


BUILDERS: dict[int, Callable[[Context], list[Built]]] = {
    1: _fig1,
    2: _fig2,
    3: _fig3,
    4: _fig4,
    5: _fig5,
    6: _fig6,
    7: _fig_pattern(7, "wb"),
    8: _fig_sweeps(8, ("b015", "b025", "b035")),
    9: _fig9_11,
    12: _fig_dc(12, "wb"),
    13: _fig_kmax(13, "wb"),
    14: _fig_pattern(14, "wxi"),
    15: _fig_sweeps(15, ("xi005", "xi009", "xi015")),
    16: _fig_dc(16, "wxi"),
    17: _fig_kmax(17, "wxi"),
}
BUILDERS[10] = BUILDERS[11] = BUILDERS[9]


def build(numbers, ctx: Context) -> list[Built]:
    """Build the figures ``numbers`` (a group such as 9-11 is built once)."""
    done: set[int] = set()
    out: list[Built] = []
    for n in numbers:
        if n in done:
            continue
        if n not in BUILDERS:
            from ..errors import UsageError

            raise UsageError(f"unknown figure {n}; allowed: 1-17")
        built = BUILDERS[n](ctx)
        for b in built:
            done.add(b.number)
        out.extend(b for b in built if b.number in numbers or GROUPS.get(n))
    return out


def record(b: Built, files: list[str], ctx: Context | None = None) -> dict[str, Any]:
    """The sidecar record of a built figure (written as ``figNN.json``), with the parameters and
    integration settings of the config it was drawn with (those of the simulated figures and,
    in the pipeline, of the input tables)."""
    rec = {
        "figure": b.number,
        "files": files,
        "paper_caption": PAPER_CAPTIONS[b.number],
        "caption": b.caption,
        "differences": b.differences,
        "inputs": b.inputs,
    }
    if ctx is not None:
        rec["parameters"] = ctx.params.to_dict()
        rec["integration"] = ctx.settings.to_dict()
    return rec
