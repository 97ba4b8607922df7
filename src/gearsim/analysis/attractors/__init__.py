"""Coexisting attractors of a cell: many seeded starts, early labels by recurrence onto known
attractors, basin fractions (docs/multistability.md).

One entry point, :func:`find_attractors`, with one options object, :class:`FinderOptions`.
Modules (after Attractors.jl's ``src/mapping``): ``api`` (the entry point), ``options``,
``results`` (what it returns), ``matching`` (one attractor or two, recurrence onto a known one,
the last step of every mapper), the finder's contract ``mapper``, the mappers ``pool`` (the
lane pool on the batched kernel: the gear model) and ``recurrence`` (model-agnostic: the
reference) and the gear adapter ``gear``.
A plane tile's attractor job is :mod:`gearsim.study.attractor_tiles`.
"""

from gearsim.analysis.attractors.api import find_attractors, grid_neighbours
from gearsim.analysis.attractors.gear import (
    GearCells,
    gear_steady,
    sobol_unit,
    start_box,
    steady_from_row,
)
from gearsim.analysis.attractors.matching import least_periods, same_attractor
from gearsim.analysis.attractors.options import FinderOptions
from gearsim.analysis.attractors.results import (
    FOUND_BY,
    Attractor,
    CellAttractors,
    Steady,
    n_real,
    summary_lines,
)

__all__ = [
    "FOUND_BY", "Attractor", "CellAttractors", "FinderOptions", "GearCells",
    "Steady", "find_attractors", "gear_steady", "grid_neighbours",
    "least_periods", "n_real", "same_attractor", "sobol_unit", "start_box",
    "steady_from_row", "summary_lines",
]
