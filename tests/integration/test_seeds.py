"""Seeds from the plane row: the forward-continuation motion of a cell is a recurrence target
from the first chunk once it is a stable orbit Newton-converged in that cell at its least
period (gearsim.analysis.attractors.gear.newton_verified).

- Every motion it accepts is a fixed point of the cell's own n-period map, checked by the one
  orbit solver from the motion's state, with |mu|max < 1 from that solver's monodromy; a
  period-2n reading of a period-n orbit and a state off the orbit are refused.
- With the seeds, every start's label equals its full-length run on the cells of a row next
  to a change of its motion, and fewer periods run than without them.
"""

import copy

import numpy as np
from attractor_checks import GEAR, REFERENCE, assert_same_attractors_per_start

from gearsim.analysis.attractors import FinderOptions, GearCells, find_attractors, gear_steady
from gearsim.analysis.attractors.gear import newton_verified
from gearsim.cell import chains
from gearsim.dynamics.parameters import ModelParameters
from gearsim.numerics.shooting import newton_orbit, sorted_eigs

ROW = [ModelParameters(w=float(w), b=0.15, **REFERENCE) for w in np.linspace(0.5, 1.9, 8)]


def _row():
    st = GearCells(ROW, GEAR).settings
    return st, [gear_steady(r) for r in chains.simulate_rows([ROW], settings=st)[0]]


def test_accepted_motions_are_newton_orbits_of_their_cell():
    st, motions = _row()
    ok = newton_verified(list(zip(ROW, motions, strict=True)), st)
    assert sum(ok) >= 4
    for p, s, good in zip(ROW, motions, ok, strict=True):
        if not good:
            continue
        y, _, M, r, _ = newton_orbit(p, s.period, s.final_state, st, tol=1e-9, max_iter=8)
        scale = max(s.scale_x, 1e-9)
        assert r < 1e-9
        assert np.max(np.abs(y[:10:2] - s.final_state[:10:2])) < 1e-4 * scale
        assert abs(sorted_eigs(M)[0]) < 1.0
    p, s = next((p, s) for p, s, g in zip(ROW, motions, ok, strict=True) if g)
    doubled = copy.deepcopy(s)
    doubled.period = 2 * s.period
    doubled.points = np.vstack([s.points[-s.period:], s.points[-s.period:]])
    off = copy.deepcopy(s)
    off.final_state = s.final_state.copy()
    off.final_state[0] += 1e-3 * s.scale_x
    assert newton_verified([(p, doubled), (p, off), (p, s)], st) == [False, False, True]


def test_seeded_labels_equal_full_length_runs_next_to_changes():
    """On the cells of a row next to a change of its motion (a doubling, fold or grazing
    between two neighbouring cells), and on the row above: every start's label equals its
    full-length run; the seeds save periods."""
    row = [ModelParameters(w=float(w), b=0.15, **REFERENCE) for w in np.linspace(0.4, 2.0, 33)]
    st = GearCells(row, GEAR).settings
    motions = [gear_steady(r) for r in chains.simulate_rows([row], settings=st)[0]]
    key = [(m.status, m.period, m.label) for m in motions]
    near = [k for k in range(len(row)) if (k > 0 and key[k - 1] != key[k])
            or (k + 1 < len(row) and key[k + 1] != key[k])]  # fmt: skip
    assert len(near) >= 6
    cells, known = [row[k] for k in near], [motions[k] for k in near]
    opts = FinderOptions(starts=16, seed=2, lanes=64)
    fast = find_attractors(cells, opts, settings=GEAR, forward_results=known)
    unseeded = find_attractors(cells, opts.with_(newton_seeds=False), settings=GEAR,
                               forward_results=known)  # fmt: skip
    full = find_attractors(cells, opts.with_(early=False), settings=GEAR, forward_results=known)
    assert assert_same_attractors_per_start(fast, full, fewer_periods=False) >= 16 * len(near) // 2
    assert sum(int(a.start_periods_run.sum()) for a in fast) < sum(
        int(a.start_periods_run.sum()) for a in unseeded)
