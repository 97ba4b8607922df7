"""Every figure of the study, in one table: :data:`FIGURES` holds one :class:`FigureSpec` per
figure (number, the paper's caption, the tables it reads, the builder, the figures built with
it). The CLI (``gearsim figures``), the Snakemake figure rules
(:mod:`gearsim.presentation.figures.rules`) and
the index (:mod:`gearsim.presentation.figures.index`) all read this table and nothing else.

Adding a figure (e.g. Fig 24 of a new analysis) is a public builder in the module that draws
it (``fig24(ctx)`` returns a list of :class:`Built`) and one entry here::

    register(FigureSpec(24, "Basins of attraction in the (w, b) plane.",
                        Inputs(planes=("wb",)), mymodule.fig24))

The table names every builder here, so importing a figure module registers nothing. The
builders of Figs 1-17 are in :mod:`~.builders`, of Figs 18-20 in :mod:`~.multistability`, of
Figs 21-23 in :mod:`~.orbits`; what they read in :mod:`~.context`. Maps drawn for *every*
plane of a study (pattern, DC, Kmax, ...) are the :class:`~.maps.MapSpec` entries of
:data:`~.maps.PLANE_MAPS`.

:func:`build` turns a :class:`Context` (tables read by the CLI, the parameters and integration
settings of the pipeline config) into matplotlib figures plus a record (our caption, where we
differ from the paper and why) that the CLI writes next to the image as ``figNN.json`` and
:mod:`gearsim.presentation.figures.index` collects into ``results/figures/README.md``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from gearsim.analysis.paper import (
    COEXIST_POINT,
    PAPER_FIG5,
    PAPER_FIG6,
    PAPER_FIG9_11,
)
from gearsim.errors import UsageError
from gearsim.presentation.figures import builders, multistability, orbits
from gearsim.presentation.figures.context import Built, Context


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
    # what the figure draws that is simulated: figure-data tables
    # ``results/figure_data/NAME.parquet`` (gearsim.study.figure_tables.FIGURE_DATA)
    figure_data: tuple[str, ...] = ()

    def tables(self) -> dict[str, tuple[str, ...]]:
        """``{"sweeps": names, "planes": names, "points": names, "orbits": names,
        "figure_data": names}``."""
        return {"sweeps": self.sweeps, "planes": self.planes, "points": self.points,
                "orbits": self.orbits, "figure_data": self.figure_data}


def orbit_available(name: str, sweeps, planes, orbits=None) -> bool:
    """Whether the pipeline makes the continuation table ``name``: listed in ``orbits``
    (:func:`gearsim.study.config.orbit_tables`), or when that is not given, its sweep or plane
    is configured."""
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
    ``report_caption``: the caption file
    of Snakemake's HTML report (``workflow/report/``), ``figure.rst`` renders ``caption``.
    """

    number: int
    paper_caption: str
    inputs: Inputs
    builder: Callable[[Context], list[Built]]
    group: tuple[int, ...] = ()
    caption: str = ""  # one line for Snakemake's HTML report
    report_caption: str = "figure.rst"
    in_paper: bool = True

    @property
    def members(self) -> tuple[int, ...]:
        return self.group or (self.number,)

    @property
    def lead(self) -> int:
        return self.members[0]

    def available(self, sweeps, planes, points, orbits=None, figure_data=()) -> bool:
        """True when every input is configured (names of the config's sweeps, planes, points;
        ``orbits``: the continuation tables the pipeline makes; ``figure_data``: the
        figure-data tables it makes)."""
        i = self.inputs
        return (all(s in sweeps for s in i.sweeps) and all(p in planes for p in i.planes)
                and all(q in points for q in (*i.points, *i.config_points))
                and all(orbit_available(o, sweeps, planes, orbits) for o in i.orbits)
                and all(f in figure_data for f in i.figure_data))


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


def _panels(table: dict[float, str]) -> str:
    """The paper's panels of a figure of points: ``(a) ω = 0.48 1-0-0, (b) ...``."""
    return ", ".join(f"({chr(97 + k)}) ω = {w:g} {label}" for k, (w, label) in
                     enumerate(table.items()))


register(FigureSpec(1, "Dynamic model of curve-face gear transmission system.", Inputs(),
                    builders.fig1,
                    caption="Schematic of the 6-DOF bending-torsional model (drawn)."))
register(FigureSpec(2, "Distribution of the system's phase trajectories on the plane.",
                    Inputs(figure_data=("fig2",)), builders.fig2,
                    caption="Phase plane split by x = +b and x = -b, with simulated steady "
                    "trajectories of impact states I = 0, 1 and 2."))
register(FigureSpec(3, "(Caption lost in our copy; the text: schematic diagram of two-parameter "
                    "co-simulation, the (u, v) plane divided into grids with the cell centres "
                    "a(i, j).)", Inputs(planes=("wb",)), builders.fig3,
                    caption="The co-simulation grid: a coarse view of the (w, b) plane."))
register(FigureSpec(4, "(a) Bifurcation diagram of mesh displacement; (b) I: DC diagram; (c) "
                    "Kmax diagram.", Inputs(sweeps=("standard",), optional_orbits=("standard",)),
                    builders.fig4,
                    caption="Standard forward sweep in w: Poincare points, I:DC and Kmax."))
register(FigureSpec(5, "Superpositions of the phase diagram and Poincaré mapping of the gear "
                    f"pair: {_panels(PAPER_FIG5)}.", Inputs(points=("fig5",)), builders.fig5,
                    caption="Phase trajectories with Poincare points at the paper's values of "
                    "w; every panel names the paper's pattern and ours."))
register(FigureSpec(6, f"FFT spectrum: {_panels(PAPER_FIG6)}.", Inputs(points=("fig6",)),
                    builders.fig6,
                    caption="FFT amplitude spectra of x, w and its sub-harmonics marked."))
register(FigureSpec(8, "Single-parameter bifurcation diagrams of mesh displacement under "
                    "different dimensionless backlash b: (a) b = 0.15, (b) b = 0.25, (c) b = "
                    "0.35.", Inputs(sweeps=("b015", "b025", "b035")),
                    builders.fig_sweeps(8, ("b015", "b025", "b035")),
                    caption="Bifurcation diagrams at b = 0.15, 0.25 and 0.35."))
_DOUBLE_SIDED = {
    n: f"{npq} double-sided impact motion, when b = {COEXIST_POINT['b']}, ω = "
       f"{COEXIST_POINT['w']}: (a) superposition of phase diagram and Poincaré map, (b) time "
       "history diagram, (c) dynamic load coefficient diagram."
    for n, npq in PAPER_FIG9_11.items()}
for _n in PAPER_FIG9_11:
    register(FigureSpec(_n, _DOUBLE_SIDED[_n], Inputs(figure_data=("fig9_11",)), builders.fig9_11,
                        group=(9, 10, 11), report_caption=f"fig{_n:02d}.rst"))
register(FigureSpec(15, "Single-parameter bifurcation diagrams of mesh displacement under "
                    "different meshing damping ratios ξ: (a) ξ = 0.05, (b) ξ = 0.09, (c) ξ = "
                    "0.15.", Inputs(sweeps=("xi005", "xi009", "xi015")),
                    builders.fig_sweeps(15, ("xi005", "xi009", "xi015")),
                    caption="Bifurcation diagrams at xi = 0.05, 0.09 and 0.15."))


def _plane_figures(plane: str, symbol: str, name: str, pattern: int, dc: int, kmax: int) -> None:
    """The paper's three figures of one plane ``(ω, symbol)``: pattern (Figs 7, 14), I:DC
    (Figs 12, 16) and Kmax (Figs 13, 17); ``name`` the second axis in ASCII."""
    axes = f"(ω, {symbol}) parameter plane"
    register(FigureSpec(pattern, f"Meshing motion law diagram of the system in the {axes}: (a) "
                        "relative micro-displacement bifurcation diagram of gear pair, (b) pattern "
                        "types and distribution regions of periodic motions.",
                        Inputs(planes=(plane,)), builders.fig_pattern(pattern, plane),
                        caption=f"(w, {name}) plane: 3-D bifurcation diagram and pattern map."))
    register(FigureSpec(dc, f"Impact states: disengagement duty cycle (I: DC) diagram in the "
                        f"{axes}: (a) DC cloud diagram, (b) I: DC plane distribution diagram.",
                        Inputs(planes=(plane,)), builders.fig_dc(dc, plane),
                        caption=f"(w, {name}) plane: DC surface and I:DC map."))
    register(FigureSpec(kmax, f"Maximum dynamic load coefficient in the {axes}: (a) cloud "
                        "diagram, (b) plane distribution diagram.", Inputs(planes=(plane,)),
                        builders.fig_kmax(kmax, plane),
                        caption=f"(w, {name}) plane: Kmax surface and contours."))


_plane_figures("wb", "b", "b", 7, 12, 13)
_plane_figures("wxi", "ξ", "xi", 14, 16, 17)

# ------------------------------------------------------------------ our own figures (18 and up)
register(FigureSpec(18, "(Not in the paper.) Forward and backward sweeps of the standard set "
                    "over the softening fold: bifurcation diagram and DC, hysteresis band.",
                    Inputs(sweeps=("hysteresis",)), multistability.fig18, in_paper=False,
                    caption="Hysteresis: forward and backward sweeps over the fold."))
register(FigureSpec(19, "(Not in the paper.) Basins of attraction at b = "
                    f"{COEXIST_POINT['b']}, w = {COEXIST_POINT['w']} (the point of Figs 9-11).",
                    Inputs(figure_data=("fig19",)), multistability.fig19, in_paper=False,
                    caption="Basins of attraction at Figs 9-11's point."))
register(FigureSpec(20, "(Not in the paper.) Basins of attraction inside the fold's "
                    "hysteresis band.", Inputs(figure_data=("fig20",)), multistability.fig20,
                    in_paper=False,
                    caption="Basins of attraction inside the hysteresis band."))
register(FigureSpec(21, "(Not in the paper.) Bifurcation curves in the (ω, b) plane over the "
                    "pattern map of Fig 7b.", Inputs(planes=("wb",), orbits=("wb_curves",)),
                    orbits.fig_curves(21, "wb"), in_paper=False,
                    caption="Period-doubling, fold and grazing curves (Newton-Floquet) over the "
                    "(w, b) pattern map."))
register(FigureSpec(22, "(Not in the paper.) Bifurcation curves in the (ω, ξ) plane over the "
                    "pattern map of Fig 14b.", Inputs(planes=("wxi",), orbits=("wxi_curves",)),
                    orbits.fig_curves(22, "wxi"), in_paper=False,
                    caption="Period-doubling, fold and grazing curves (Newton-Floquet) over the "
                    "(w, xi) pattern map."))
register(FigureSpec(23, "(Not in the paper.) Periodic branches of the standard set along ω "
                    "with their stability and located bifurcations.",
                    Inputs(orbits=("standard",)), orbits.fig23, in_paper=False,
                    caption="Continuation of the standard set in w: stable and unstable "
                    "periodic branches, folds, period doublings, grazings."))


def figures() -> dict[int, FigureSpec]:
    """Every registered figure, by number."""
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

