"""The finder's contract: what a model supplies (:class:`System`) and the one signature every
mapper implements (:class:`AttractorMapper`, as Attractors.jl's ``AttractorMapper``).

A mapper takes a system, per cell the start states to map, the finder's options and, where
given, per cell the continuation states ``{"forward": state, "backward": state}`` (either may
be missing or None), and returns one :class:`CellAttractors` per cell. The two mappers:
:func:`gearsim.analysis.attractors.recurrence.map_attractors` (model-agnostic, the reference)
and :func:`gearsim.analysis.attractors.pool.map_gear_cells` (the lane pool of the gear model).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Protocol

import numpy as np

from gearsim.analysis.attractors.options import FinderOptions
from gearsim.analysis.attractors.results import CellAttractors, Steady
from gearsim.dynamics.parameters import ParameterError

#: the continuation states a mapper accepts per cell
CONTINUATION = ("forward", "backward")


class System(Protocol):
    """What a mapper needs from a model: ``transient`` periods from a start,
    ``transient_continuation`` from a continuation state, and three operations on states of its
    cells (recurrence.py's module docstring)."""

    transient: int
    transient_continuation: int

    def start_states(self, cell: int, unit: np.ndarray) -> np.ndarray: ...

    def advance(
        self, cells: np.ndarray, states: np.ndarray, n_periods: int, start_periods: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...

    def steady(
        self, cells: np.ndarray, states: np.ndarray, transient: int, start_periods: np.ndarray
    ) -> list[Steady]: ...


class AttractorMapper(Protocol):
    """The one signature of a mapper (module docstring); a mapper may add keyword options."""

    def __call__(
        self,
        system: System,
        starts: Sequence[np.ndarray],
        options: FinderOptions | None = None,
        *,
        continuation: Sequence[Mapping[str, np.ndarray | None]] | None = None,
    ) -> list[CellAttractors]: ...


def check_inputs(starts: Sequence, continuation: Sequence | None) -> int:
    """The number of cells (one array of start states each), after checking that
    ``continuation`` has one mapping per cell naming only :data:`CONTINUATION` states."""
    n = len(starts)
    if continuation is not None:
        if len(continuation) != n:
            raise ParameterError("continuation: one mapping per cell expected")
        for m in continuation:
            for name in m or {}:
                if name not in CONTINUATION:
                    raise ParameterError(
                        f"continuation state {name!r}; allowed: {', '.join(CONTINUATION)}"
                    )
    return n
