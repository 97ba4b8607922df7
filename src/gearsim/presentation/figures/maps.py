"""The maps drawn for every plane of a study, whatever its two axes (pattern, DC, Kmax, and any
an extension registers): :data:`PLANE_MAPS` and :func:`build_maps`."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import pandas as pd

from gearsim.errors import UsageError
from gearsim.presentation.figures.context import _grid_note, axes_text, paper_comparison
from gearsim.presentation.figures.multistability import map_floquet


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
    from gearsim.cell.motion import KMAX_DEFINITION
    from gearsim.presentation.figures.planes import figure_kmax

    return (figure_kmax(df), f"Maximum dynamic load coefficient in the {axes_text(df)} plane: "
            "(a) surface; (b) filled contours.",
            [_grid_note(df), f"Kmax = {KMAX_DEFINITION} (the catalogue's kmax)."])


register_map(MapSpec("pattern", "pattern I/nT", _map_pattern, ("I", "label", "poincare_x")))
register_map(MapSpec("dc", "disengagement duty cycle", _map_dc, ("I", "dc")))
register_map(MapSpec("kmax", "maximum dynamic load coefficient", _map_kmax, ("kmax",)))
register_map(MapSpec("floquet", "Floquet margin of the periodic cells", map_floquet,
                     ("mu_max", "status", "motion")))


def build_maps(plane: str, df: pd.DataFrame, kinds: Sequence[str] | None = None
               ) -> list[tuple[MapSpec, Any, str, list[str]]]:
    """Draw the maps ``kinds`` (default: every registered one) of one plane of any axes:
    ``(spec, figure, caption, notes)`` each; a map whose columns the table lacks is left out."""
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
