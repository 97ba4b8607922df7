"""The finder's one entry point: the coexisting attractors of gear cells."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gearsim.analysis.attractors.gear import GearCells, sobol_unit
from gearsim.analysis.attractors.mapper import AttractorMapper
from gearsim.analysis.attractors.options import FinderOptions
from gearsim.analysis.attractors.pool import map_gear_cells
from gearsim.analysis.attractors.results import CellAttractors, Steady
from gearsim.cell.pool import PoolStats
from gearsim.dynamics.parameters import ModelParameters, ParameterError


def find_attractors(
    cells: ModelParameters | Sequence[ModelParameters],
    options: FinderOptions | None = None,
    *,
    settings=None,
    forward=None,
    backward=None,
    forward_results: Sequence[Steady | None] | None = None,
    start_states=None,
    stats: PoolStats | None = None,
    neighbours=None,
    mapper: AttractorMapper = map_gear_cells,
    backend=None,
) -> CellAttractors | list[CellAttractors]:
    """Coexisting attractors of one gear cell (``cells`` a :class:`ModelParameters`: one
    :class:`CellAttractors`) or of many (a sequence: one per cell, all starts in one lane pool).

    ``options``: :class:`FinderOptions` (default: 16 seeded Sobol starts over each cell's
    :func:`~gearsim.analysis.attractors.gear.start_box`, early labels by recurrence).
    ``settings``: the integration settings (RK4; ``transient`` periods from a start,
    ``transient_continuation`` from a continuation state). Per cell (one value for one cell):
    ``forward`` / ``backward`` continuation states (10 entries) or None; ``forward_results``
    the already classified forward motion (a :class:`Steady`, e.g. of the plane tile's row)
    used instead of running ``forward``; ``start_states`` its own ``(K, 10)`` start states
    instead of the Sobol starts (basin pictures). ``stats``: a
    :class:`gearsim.cell.pool.PoolStats` collecting the lane use. ``neighbours`` (many cells):
    per cell the indices of its neighbouring cells in ``cells`` (e.g.
    :func:`grid_neighbours`), whose motions seed it
    (``FinderOptions.neighbour_seeds``). ``mapper``: the :class:`AttractorMapper` that maps
    the starts (default the lane pool :func:`~gearsim.analysis.attractors.pool.map_gear_cells`;
    ``forward_results``, ``stats`` and ``neighbours`` are its keyword options, handed to a
    mapper only when given). ``backend``: where the starts' lanes run
    (:func:`gearsim.numerics.backend.select`; default the CPU). Attractors most likely first.
    """
    options = options if options is not None else FinderOptions()
    one = isinstance(cells, ModelParameters)

    def per_cell(v):
        return None if v is None else [v] if one else v

    cell_list = [cells] if one else list(cells)
    system = GearCells(cell_list, settings, backend)
    if start_states is None:
        unit = sobol_unit(options.starts, options.seed)
        starts = [system.start_states(c, unit) for c in range(len(cell_list))]
    else:
        starts = [np.asarray(start_states, dtype=float)] if one else start_states
    continuation = None
    if forward is not None or backward is not None:
        fw, bw = per_cell(forward), per_cell(backward)
        for name, seq in (("forward", fw), ("backward", bw)):
            if seq is not None and len(seq) != len(cell_list):
                raise ParameterError(f"{name}: one entry per cell expected")
        continuation = [{"forward": None if fw is None else fw[c],
                         "backward": None if bw is None else bw[c]}
                        for c in range(len(cell_list))]  # fmt: skip
    extra = {"forward_results": per_cell(forward_results), "stats": stats,
             "neighbours": None if one else neighbours}
    found = mapper(system, starts, options, continuation=continuation,
                   **{k: v for k, v in extra.items() if v is not None})
    return found[0] if one else found


def grid_neighbours(ij: Sequence[tuple[int, int]]) -> list[list[int]]:
    """Per cell of a grid sample (its indices ``(i, j)`` along x and y): the nearest cells of
    the sample on either side along each axis (at most four), as indices into ``ij``."""
    rows: dict[int, list[tuple[int, int]]] = {}
    cols: dict[int, list[tuple[int, int]]] = {}
    for k, (i, j) in enumerate(ij):
        rows.setdefault(int(j), []).append((int(i), k))
        cols.setdefault(int(i), []).append((int(j), k))
    out: list[list[int]] = [[] for _ in ij]
    for line in list(rows.values()) + list(cols.values()):
        line.sort()
        for (_, a), (_, b) in zip(line, line[1:], strict=False):
            out[a].append(b)
            out[b].append(a)
    return out
