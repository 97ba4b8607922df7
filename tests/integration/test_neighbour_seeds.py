"""Seeds from the neighbours: a cell's known attractors also come from its neighbouring cells'
periodic motions, continued by Newton into the cell (gearsim.analysis.attractors.gear
continue_orbits) and confirmed by a run there.

- A continued orbit is a fixed point of the cell's own n-period map (the one orbit solver from
  its state converges at once) with |mu|max < 1 and no shorter period; the period-2n motion of
  the cell past a period doubling, continued back into the period-n cell, is refused.
- With the seeds, every start's label equals its full-length run on a row crossing folds,
  doublings and chaos, and the seeds were run and confirmed there.
"""

import numpy as np
from attractor_checks import GEAR, REFERENCE, assert_same_attractors_per_start

from gearsim.analysis.attractors import (
    FinderOptions,
    GearCells,
    find_attractors,
    gear_steady,
    grid_neighbours,
)
from gearsim.analysis.attractors.certify import continue_orbits
from gearsim.analysis.attractors.gear import shorter_period
from gearsim.cell import chains
from gearsim.cell.pool import PoolStats
from gearsim.dynamics.parameters import ModelParameters
from gearsim.numerics.shooting import newton_orbit, sorted_eigs


def _row(b: float):
    row = [ModelParameters(w=float(w), b=b, **REFERENCE) for w in np.linspace(0.4, 2.0, 33)]
    st = GearCells(row, GEAR).settings
    return row, st, [gear_steady(r) for r in chains.simulate_rows([row], settings=st)[0]]


def test_continued_orbits_are_stable_orbits_of_their_cell():
    row, st, motions = _row(0.5)
    pairs, doubled = [], []
    for k in range(len(row) - 1):
        a, c = motions[k], motions[k + 1]
        if a.period > 0 and c.period > 0 and a.status == c.status == "ok":
            pairs.append((row[k + 1], a))  # the motion of cell k continued into cell k + 1
            if c.period == 2 * a.period:
                doubled.append((row[k], c))  # past a doubling, back into the period-n cell
    assert len(doubled) >= 2
    got = continue_orbits(pairs, st)
    assert sum(g is not None for g in got) >= len(pairs) // 2
    for (p, s), g in zip(pairs, got, strict=True):
        if g is None:
            continue
        y, pts = g
        y2, _, M, r, it = newton_orbit(p, s.period, y, st, tol=1e-9, max_iter=8)
        assert r < 1e-9 and it == 0  # already the cell's own fixed point
        assert abs(sorted_eigs(M)[0]) < 1.0
        sc = np.array([max(s.scale_x, 1e-9), max(s.scale_v, 1e-9)])
        assert pts.shape == (s.period, 2) and not shorter_period(pts, sc)
    assert continue_orbits(doubled, st) == [None] * len(doubled)


def test_neighbour_seeded_labels_equal_full_length_runs():
    row, _st, motions = _row(0.5)
    neighbours = grid_neighbours([(k, 0) for k in range(len(row))])
    assert neighbours[0] == [1] and sorted(neighbours[5]) == [4, 6]
    opts = FinderOptions(starts=16, seed=2, lanes=64)
    stats = PoolStats()
    fast = find_attractors(row, opts, settings=GEAR, forward_results=motions,
                           neighbours=neighbours, stats=stats)  # fmt: skip
    full = find_attractors(row, opts.with_(early=False), settings=GEAR, forward_results=motions)
    assert stats.seeds_confirmed >= 3
    assert assert_same_attractors_per_start(fast, full, fewer_periods=False) >= 16 * len(row) // 2
