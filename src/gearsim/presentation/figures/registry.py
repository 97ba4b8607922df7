"""Every figure of the study, in one table: :data:`FIGURES` holds one :class:`FigureSpec` per
figure (number, the paper's caption, the tables it reads, the builder, the figures built with
it). The CLI (``gearsim figures``), the Snakemake figure rules
(:mod:`gearsim.presentation.figures.rules`) and
the index (:mod:`gearsim.presentation.figures.index`) all read this table and nothing else.

Adding a figure (e.g. Fig 18 of a new analysis) is one call in the module that draws it::

    from gearsim.presentation.figures.registry import FigureSpec, Inputs, register

    register(FigureSpec(18, "Basins of attraction in the (w, b) plane.",
                        Inputs(planes=("wb",)), build_fig18))

(and the module listed in :data:`EXTENSIONS` so it is imported). ``build_fig18(ctx)`` returns a
list of :class:`Built`. Maps drawn for *every* plane of a study (pattern, DC, Kmax, ...) are
:class:`MapSpec` entries of :data:`PLANE_MAPS` (:func:`register_map`).

:func:`build` turns a :class:`Context` (tables read by the CLI, the parameters and integration
settings of the pipeline config) into matplotlib figures plus a record (our caption, where we
differ from the paper and why) that the CLI writes next to the image as ``figNN.json`` and
:mod:`gearsim.presentation.figures.index` collects into ``results/figures/README.md``.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from gearsim.analysis.paper import (
    COEXIST_POINT,
    PAPER_B_THRESHOLD,
    PAPER_FIG5,
    PAPER_FIG6,
    PAPER_FIG9_11,
    PAPER_JUMP_DC,
    PAPER_JUMP_KMAX,
    PAPER_SEQUENCE_TEXT,
    PAPER_XI_THRESHOLD,
)
from gearsim.cell.motion import double_sided
from gearsim.cell.simulate import IntegrationSettings
from gearsim.dynamics.parameters import ModelParameters
from gearsim.errors import UsageError


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
    # continuation tables (docs/orbits.md): "standard" (branches of the standard sweep's set),
    # "standard_points", "<plane>_curves" (two-parameter bifurcation curves)
    orbits: dict[str, pd.DataFrame] = field(default_factory=dict)


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
    paper = " (paper 400 x 400)" if _axes(df) in (("w", "b"), ("w", "xi")) else ""
    return f"grid {nx} x {ny} cells{paper}"


# ------------------------------------------------------------------------------ builders
def _fig1(ctx: Context) -> list[Built]:
    from gearsim.presentation.figures.schematic import figure1

    return [Built(1, figure1(), "Schematic of the 6-DOF bending-torsional model: non-circular "
                  "driver p and curve-face gear g on bearings (spring + damper in Y and Z, "
                  "radial clearance), mesh spring K(t) and damper C_n with backlash 2B and "
                  "transmission error e(t) along the line of action.",
                  ["Redrawn from the model description (the paper's image is not in our copy); "
                   "the gear shapes are illustrative (pitch curve of order 2, face of order "
                   "4)."])]


def _fig2(ctx: Context) -> list[Built]:
    from gearsim.presentation.figures.phase import compute_fig2, figure2

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


def _fig4(ctx: Context) -> list[Built]:
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
                     f"jump); Kmax at the jump in the paper {PAPER_JUMP_KMAX}; our Kmax reading "
                     "is the default "
                     "catalogue column 'kmax'.")
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


def _point_motions(ctx: Context, name: str, ws_default):
    from gearsim.presentation.figures.data import points_from_table
    from gearsim.presentation.figures.phase import compute_points

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
    from gearsim.presentation.figures.phase import figure5

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
    from gearsim.presentation.figures.spectra import figure6

    pts, inputs, how = _point_motions(ctx, "fig6", list(PAPER_FIG6))
    diffs = _label_diffs(pts, PAPER_FIG6) or ["every panel has the paper's pattern"]
    if "points/fig6" not in inputs:
        diffs.append(_POINT_NOTE)
    return [Built(6, figure6(pts), "One-sided FFT amplitude spectra of x(τ) on exactly "
                  "uniform samples over a whole number of motion periods (Hann window), with "
                  f"ω and ω/2, ω/4, ω/8 marked; motions {how}.", diffs, inputs)]


def _axes(df: pd.DataFrame) -> tuple[str, str]:
    from gearsim.presentation.figures.data import plane_axes

    return plane_axes(df)


def axes_text(df: pd.DataFrame) -> str:
    """``(ω, b)``: the plane's two axes, as the paper writes them."""
    sym = {"b": "b", "xi": "ξ", "w": "ω", "eps": "ε"}
    x, y = _axes(df)
    return f"({sym.get(x, x)}, {sym.get(y, y)})"


def _threshold_b(df: pd.DataFrame) -> str:
    two = df[double_sided(df["I"], df.get("q"))]
    if not len(two):
        return "no double-sided cells (back impacts) in our (ω, b) plane"
    return (f"double-sided cells (back impacts) up to b = {float(two['b'].max()):.4f} in ours "
            f"(paper: only for b < {PAPER_B_THRESHOLD})")


def _threshold_xi(df: pd.DataFrame) -> str:
    other = df[~df["label"].isin(["0/1T", "1/1T"])]
    if not len(other):
        return "only 0/1T and 1/1T in our (ω, ξ) plane"
    return (f"patterns other than 0/1T and 1/1T up to ξ = {float(other['xi'].max()):.4f} in "
            f"ours (paper: only 0/1T and 1/1T for ξ > {PAPER_XI_THRESHOLD})")


def paper_comparison(df: pd.DataFrame) -> str:
    """The paper's threshold for a plane of these axes beside ours, or "not applicable" when
    the paper has no plane of these axes."""
    axes = _axes(df)
    if axes == ("w", "b"):
        return _threshold_b(df)
    if axes == ("w", "xi"):
        return _threshold_xi(df)
    return (f"Paper comparison not applicable: the paper has no {axes_text(df)} plane (it "
            "maps (ω, b) and (ω, ξ) only).")


def _plane(ctx: Context, plane: str) -> pd.DataFrame:
    return _need(ctx.planes, plane, "plane")


def _fig_pattern(number: int, plane: str):
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


def _fig_sweeps(number: int, names: tuple[str, ...]):
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


def _fig_dc(number: int, plane: str):
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


def _fig_kmax(number: int, plane: str):
    def build(ctx: Context) -> list[Built]:
        from gearsim.cell.classify import DEFAULT_KMAX, KMAX_READINGS
        from gearsim.presentation.figures.data import plane_grid
        from gearsim.presentation.figures.planes import figure_kmax, robust_max

        df = _plane(ctx, plane)
        axis = axes_text(df)
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
    from gearsim.presentation.figures.phase import (
        choose_motion,
        figure_double_sided,
        search_attractors,
    )

    spec = ctx.point_specs.get("fig9_11", COEXIST_POINT)
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


# ------------------------------------------------------------------------------ the table
@dataclass(frozen=True)
class Inputs:
    """The tables a figure reads, by their config names (``config/config.yaml``).

    ``sweeps``, ``planes`` and ``points`` are tables (``results/sweeps/NAME.parquet``,
    ``results/NAME/cells.parquet``, ``results/points/NAME.parquet``) that the pipeline passes to
    the CLI and declares as rule inputs. ``config_points`` are entries of the config's
    ``points:`` that the figure reads from the config only (no table), e.g. Figs 9-11's
    ``fig9_11: {b, w}``: the figure is drawn only where they are configured.
    """

    sweeps: tuple[str, ...] = ()
    planes: tuple[str, ...] = ()
    points: tuple[str, ...] = ()
    config_points: tuple[str, ...] = ()
    # continuation tables ``results/orbits/NAME.parquet`` (workflow/rules/orbits.smk):
    # "standard" (its located points are read from standard_points.parquet beside it) and
    # "<plane>_curves" (one per plane); ``optional_orbits`` are passed when the pipeline makes
    # them (config ``orbits:``), the figure is drawn without them otherwise
    orbits: tuple[str, ...] = ()
    optional_orbits: tuple[str, ...] = ()

    def tables(self) -> dict[str, tuple[str, ...]]:
        """``{"sweeps": names, "planes": names, "points": names, "orbits": names}``."""
        return {"sweeps": self.sweeps, "planes": self.planes, "points": self.points,
                "orbits": self.orbits}


def orbit_available(name: str, sweeps, planes, orbits=None) -> bool:
    """Whether the pipeline makes the continuation table ``name``: listed in ``orbits``
    (:func:`gearsim.analysis.bifcurves.pipeline_orbit_tables`), or when that is not given, its
    sweep or
    plane is configured."""
    if orbits is not None:
        return name in orbits
    if name.endswith("_curves"):
        return name[: -len("_curves")] in planes
    return name in sweeps


@dataclass(frozen=True)
class FigureSpec:
    """One figure of the study.

    ``number``: the paper's figure number (new analyses: 18 and up); ``paper_caption``: the
    paper's caption, or for a figure of ours that the paper does not have, what it shows;
    ``inputs``: what the pipeline gives it; ``builder(ctx) -> list[Built]``; ``group``: every
    figure drawn by the same builder call (e.g. (9, 10, 11)), the first is the lead;
    ``tables_required``: False when the builder draws without its tables (it then simulates
    the few points it needs itself, Figs 2, 5, 6, 9-11); ``report_caption``: the caption file
    of Snakemake's HTML report (``workflow/report/``), ``figure.rst`` renders ``caption``.
    """

    number: int
    paper_caption: str
    inputs: Inputs
    builder: Callable[[Context], list[Built]]
    group: tuple[int, ...] = ()
    tables_required: bool = True
    caption: str = ""  # one line for Snakemake's HTML report
    report_caption: str = "figure.rst"
    in_paper: bool = True

    @property
    def members(self) -> tuple[int, ...]:
        return self.group or (self.number,)

    @property
    def lead(self) -> int:
        return self.members[0]

    def available(self, sweeps, planes, points, orbits=None) -> bool:
        """True when every input is configured (names of the config's sweeps, planes, points;
        ``orbits``: the continuation tables the pipeline makes)."""
        i = self.inputs
        return (all(s in sweeps for s in i.sweeps) and all(p in planes for p in i.planes)
                and all(q in points for q in (*i.points, *i.config_points))
                and all(orbit_available(o, sweeps, planes, orbits) for o in i.orbits))


FIGURES: dict[int, FigureSpec] = {}


def register(spec: FigureSpec) -> FigureSpec:
    """Add a figure to :data:`FIGURES` (every member of its group points at the same spec)."""
    for n in spec.members:
        if n in FIGURES and FIGURES[n] is not spec and FIGURES[n].builder is not spec.builder:
            raise ValueError(f"figure {n} is registered twice")
    if spec.number not in spec.members:
        raise ValueError(f"figure {spec.number} is not in its group {spec.group}")
    FIGURES[spec.number] = spec
    return spec


@dataclass(frozen=True)
class MapSpec:
    """A map drawn for every plane of a study, whatever its two axes
    (``results/figures/planes/<plane>-<kind>.png``).

    ``builder(cells) -> (figure, caption, notes)``; ``columns``: cell columns it needs (a plane
    without them, e.g. an old catalogue, is skipped with a note).
    """

    kind: str
    title: str
    builder: Callable[[pd.DataFrame], tuple[Any, str, list[str]]]
    columns: tuple[str, ...] = ()


PLANE_MAPS: dict[str, MapSpec] = {}


def register_map(spec: MapSpec) -> MapSpec:
    if spec.kind in PLANE_MAPS and PLANE_MAPS[spec.kind] is not spec:
        raise ValueError(f"plane map '{spec.kind}' is registered twice")
    PLANE_MAPS[spec.kind] = spec
    return spec


register(FigureSpec(1, "Dynamic model of curve-face gear transmission system.", Inputs(), _fig1,
                    caption="Schematic of the 6-DOF bending-torsional model (drawn)."))
register(FigureSpec(2, "Distribution of the system's phase trajectories on the plane.",
                    Inputs(sweeps=("b015",)), _fig2, tables_required=False,
                    caption="Phase plane split by x = +b and x = -b, with simulated steady "
                    "trajectories of impact states I = 0, 1 and 2."))
register(FigureSpec(3, "(Caption lost in our copy; the text: schematic diagram of two-parameter "
                    "co-simulation, the (u, v) plane divided into grids with the cell centres "
                    "a(i, j).)", Inputs(planes=("wb",)), _fig3,
                    caption="The co-simulation grid: a coarse view of the (w, b) plane."))
register(FigureSpec(4, "(a) Bifurcation diagram of mesh displacement; (b) I: DC diagram; (c) "
                    "Kmax diagram.", Inputs(sweeps=("standard",), optional_orbits=("standard",)),
                    _fig4,
                    caption="Standard forward sweep in w: Poincare points, I:DC and Kmax."))
register(FigureSpec(5, "Superpositions of the phase diagram and Poincaré mapping of the gear "
                    "pair: (a) ω = 0.48 1-0-0, (b) ω = 0.569 grazing, (c) ω = 0.86 1-1-0, (d) "
                    "ω = 1.02 2-2-0, (e) ω = 1.072 grazing, (f) ω = 1.25 2-1-0, (g) ω = 1.37 "
                    "4-3-0, (h) ω = 1.384 8-6-0, (i) ω = 1.53 chaotic, (j) ω = 1.7 4-3-0, (k) "
                    "ω = 1.81 2-2-0, (l) ω = 2.24 1-1-0.", Inputs(points=("fig5",)), _fig5,
                    tables_required=False,
                    caption="Phase trajectories with Poincare points at the paper's values of "
                    "w; every panel names the paper's pattern and ours."))
register(FigureSpec(6, "FFT spectrum: (a) ω = 0.48 1-0-0, (b) ω = 1.02 2-2-0, (c) ω = 1.37 "
                    "4-3-0, (d) ω = 1.53 chaotic.", Inputs(points=("fig6",)), _fig6,
                    tables_required=False,
                    caption="FFT amplitude spectra of x, w and its sub-harmonics marked."))
register(FigureSpec(7, "Meshing motion law diagram of the system in the (ω, b) parameter plane: "
                    "(a) relative micro-displacement bifurcation diagram of gear pair, (b) "
                    "pattern types and distribution regions of periodic motions.",
                    Inputs(planes=("wb",)), _fig_pattern(7, "wb"),
                    caption="(w, b) plane: 3-D bifurcation diagram and pattern map."))
register(FigureSpec(8, "Single-parameter bifurcation diagrams of mesh displacement under "
                    "different dimensionless backlash b: (a) b = 0.15, (b) b = 0.25, (c) b = "
                    "0.35.", Inputs(sweeps=("b015", "b025", "b035")),
                    _fig_sweeps(8, ("b015", "b025", "b035")),
                    caption="Bifurcation diagrams at b = 0.15, 0.25 and 0.35."))
_DOUBLE_SIDED = {
    n: f"{npq} double-sided impact motion, when b = {COEXIST_POINT['b']}, ω = "
       f"{COEXIST_POINT['w']}: (a) superposition of phase diagram and Poincaré map, (b) time "
       "history diagram, (c) dynamic load coefficient diagram."
    for n, npq in PAPER_FIG9_11.items()}
for _n in PAPER_FIG9_11:
    register(FigureSpec(_n, _DOUBLE_SIDED[_n], Inputs(sweeps=("b015",),
                        config_points=("fig9_11",)), _fig9_11, group=(9, 10, 11),
                        tables_required=False, report_caption=f"fig{_n:02d}.rst"))
register(FigureSpec(12, "Impact states: disengagement duty cycle (I: DC) diagram in the (ω, b) "
                    "parameter plane: (a) DC cloud diagram, (b) I: DC plane distribution "
                    "diagram.", Inputs(planes=("wb",)), _fig_dc(12, "wb"),
                    caption="(w, b) plane: DC surface and I:DC map."))
register(FigureSpec(13, "Maximum dynamic load coefficient in the (ω, b) parameter plane: (a) "
                    "cloud diagram, (b) plane distribution diagram.", Inputs(planes=("wb",)),
                    _fig_kmax(13, "wb"), caption="(w, b) plane: Kmax surface and contours."))
register(FigureSpec(14, "Meshing motion law diagram of the system in the (ω, ξ) parameter "
                    "plane: (a) relative micro-displacement bifurcation diagram of gear pair, "
                    "(b) pattern types and distribution regions of periodic motions.",
                    Inputs(planes=("wxi",)), _fig_pattern(14, "wxi"),
                    caption="(w, xi) plane: 3-D bifurcation diagram and pattern map."))
register(FigureSpec(15, "Single-parameter bifurcation diagrams of mesh displacement under "
                    "different meshing damping ratios ξ: (a) ξ = 0.05, (b) ξ = 0.09, (c) ξ = "
                    "0.15.", Inputs(sweeps=("xi005", "xi009", "xi015")),
                    _fig_sweeps(15, ("xi005", "xi009", "xi015")),
                    caption="Bifurcation diagrams at xi = 0.05, 0.09 and 0.15."))
register(FigureSpec(16, "Impact states: disengagement duty cycle (I: DC) diagram in the (ω, ξ) "
                    "parameter plane: (a) DC cloud diagram, (b) I: DC plane distribution "
                    "diagram.", Inputs(planes=("wxi",)), _fig_dc(16, "wxi"),
                    caption="(w, xi) plane: DC surface and I:DC map."))
register(FigureSpec(17, "Maximum dynamic load coefficient in the (ω, ξ) parameter plane: (a) "
                    "cloud diagram, (b) plane distribution diagram.", Inputs(planes=("wxi",)),
                    _fig_kmax(17, "wxi"), caption="(w, xi) plane: Kmax surface and contours."))

def _map_pattern(df: pd.DataFrame):
    from gearsim.presentation.figures.planes import figure_pattern

    return (figure_pattern(df), f"Motion in the {axes_text(df)} plane: (a) 3-D bifurcation "
            "diagram of the Poincaré points of x (coloured by I); (b) pattern I/nT of every "
            "cell.", [_grid_note(df), paper_comparison(df)])


def _map_dc(df: pd.DataFrame):
    from gearsim.presentation.figures.planes import figure_dc

    return (figure_dc(df), f"Disengagement duty cycle in the {axes_text(df)} plane: (a) DC "
            "surface; (b) I:DC map (impact state : DC band of 0.1).", [_grid_note(df)])


def _map_kmax(df: pd.DataFrame):
    from gearsim.cell.classify import DEFAULT_KMAX, KMAX_READINGS
    from gearsim.presentation.figures.planes import figure_kmax

    return (figure_kmax(df), f"Maximum dynamic load coefficient in the {axes_text(df)} plane: "
            "(a) surface; (b) filled contours.",
            [_grid_note(df), f"Kmax reading: {DEFAULT_KMAX} ({KMAX_READINGS[DEFAULT_KMAX]})."])


register_map(MapSpec("pattern", "pattern I/nT", _map_pattern, ("I", "label", "poincare_x")))
register_map(MapSpec("dc", "disengagement duty cycle", _map_dc, ("I", "dc")))
register_map(MapSpec("kmax", "maximum dynamic load coefficient", _map_kmax, ("kmax",)))


def build_maps(plane: str, df: pd.DataFrame, kinds: Sequence[str] | None = None
               ) -> list[tuple[MapSpec, Any, str, list[str]]]:
    """Draw the maps ``kinds`` (default: every registered one) of one plane of any axes:
    ``(spec, figure, caption, notes)`` each; a map whose columns the table lacks is left out."""
    figures()  # extensions register their maps on import
    out = []
    for kind in kinds or list(PLANE_MAPS):
        if kind not in PLANE_MAPS:
            raise UsageError(f"unknown plane map '{kind}'; allowed: {', '.join(PLANE_MAPS)}")
        spec = PLANE_MAPS[kind]
        if any(c not in df.columns for c in spec.columns):
            continue
        fig, caption, notes = spec.builder(df)
        fig.suptitle(f"plane {plane}: {spec.title}", fontsize=10)
        out.append((spec, fig, caption, notes))
    return out


#: modules of other analyses that register figures numbered after 17 (imported by
#: :func:`figures`; a module missing from this checkout is skipped).
EXTENSIONS: tuple[str, ...] = ("gearsim.presentation.figures.multistability",
"gearsim.presentation.figures.orbits")


def figures() -> dict[int, FigureSpec]:
    """Every registered figure, by number (the extensions imported first)."""
    import importlib

    for mod in EXTENSIONS:
        try:
            importlib.import_module(mod)
        except ModuleNotFoundError as exc:
            if exc.name != mod:
                raise
    return dict(sorted(FIGURES.items()))


def numbers() -> tuple[int, ...]:
    return tuple(figures())


def build(numbers: Sequence[int], ctx: Context) -> list[Built]:
    """Build the figures ``numbers`` (a group such as 9-11 is built once, all its members)."""
    table = figures()
    done: set[int] = set()
    out: list[Built] = []
    for n in numbers:
        if n in done:
            continue
        if n not in table:
            raise UsageError(f"unknown figure {n}; allowed: {_ranges(tuple(table))}")
        built = table[n].builder(ctx)
        for b in built:
            done.add(b.number)
        out.extend(built)
    return out


def _ranges(ns: tuple[int, ...]) -> str:
    out, start = [], None
    for k, n in enumerate(ns):
        if start is None:
            start = n
        if k + 1 == len(ns) or ns[k + 1] != n + 1:
            out.append(f"{start}" if start == n else f"{start}-{n}")
            start = None
    return ", ".join(out)


def record(b: Built, files: list[str], ctx: Context | None = None) -> dict[str, Any]:
    """The sidecar record of a built figure (written as ``figNN.json``), with the parameters and
    integration settings of the config it was drawn with (those of the simulated figures and,
    in the pipeline, of the input tables)."""
    rec = {
        "figure": b.number,
        "files": files,
        "paper_caption": FIGURES[b.number].paper_caption,
        "caption": b.caption,
        "differences": b.differences,
        "inputs": b.inputs,
    }
    if ctx is not None:
        rec["parameters"] = ctx.params.to_dict()
        rec["integration"] = ctx.settings.to_dict()
    return rec
