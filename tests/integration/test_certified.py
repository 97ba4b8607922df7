"""Certified early labels (gearsim.analysis.attractors.certify).

- The certified ellipsoid of a stable orbit is one of its Lyapunov norm (the linearised orbit
  map contracts it) inside the sup-norm ball of its radius, and points inside it reach that
  orbit in their own full-length runs (``simulate_cell`` from each, classified as a plane cell
  is).
- Early labels given by the certified rule (recurrence within 1e-9 of the range) are the
  attractors of every start's full-length run, on gear cells with 1-3 attractors.
- With the forward motion known (a plane tile's row), most starts are labelled inside a
  certified ellipsoid.
"""

import numpy as np
from attractor_checks import GEAR, REFERENCE, assert_same_attractors_per_start

from gearsim.analysis.attractors import (
    FinderOptions,
    GearCells,
    find_attractors,
    gear_steady,
    same_attractor,
)
from gearsim.analysis.attractors.certify import Certificate, certify
from gearsim.cell import chains
from gearsim.cell.pool import PoolStats
from gearsim.cell.simulate import simulate_cell
from gearsim.dynamics.parameters import ModelParameters
from gearsim.numerics.variational import monodromies

CELLS = [
    ModelParameters(w=1.1, b=0.15, **REFERENCE),
    ModelParameters(w=0.82, b=0.15, **REFERENCE),
    ModelParameters(w=0.66, b=1.0, **REFERENCE),  # the softening fold: two attractors
    ModelParameters(w=1.45, b=1.0, **REFERENCE),  # chaos and a 2-1-1
    ModelParameters(w=1.95, b=0.3, **REFERENCE),
]


def test_points_inside_a_certified_ellipsoid_reach_its_orbit():
    p = ModelParameters(w=0.82, b=0.15, **REFERENCE)
    st = GearCells([p], GEAR).settings
    orbit = gear_steady(simulate_cell(p, settings=st))
    cert, spent = certify(p, orbit, st, 0.3, 3)
    assert cert is not None and spent > 0
    assert 0.0 < cert.r <= 0.3 and cert.ratio < 1.0 and cert.rho < 1.0
    # the linearised orbit map contracts the norm by rho: M^T P M - rho^2 P is negative definite
    M = monodromies([p], [cert.centre], orbit.period, st)[0][1]
    Ms = M / cert.scales[:, None] * cert.scales[None, :]
    assert np.linalg.eigvalsh(Ms.T @ cert.P @ Ms - cert.rho**2 * cert.P).max() < 0.0
    # the ellipsoid lies inside the scaled sup-norm ball of its radius (P >= I)
    assert np.linalg.eigvalsh(cert.P).min() >= 1.0 - 1e-9
    rng = np.random.default_rng(3)
    for _ in range(4):
        u = rng.standard_normal(len(cert.ev))
        u *= 0.99 * cert.r / np.sqrt(u @ cert.P @ u)
        y = cert.centre.copy()
        y[cert.ev] += u * cert.scales
        assert cert.distance(y[None, :])[0] < 1.0
        own = gear_steady(simulate_cell(p, y, settings=st))
        assert same_attractor(own, orbit)


def test_certified_labels_alone_equal_full_length_runs():
    stats = PoolStats()
    opts = FinderOptions(starts=64, seed=5, lanes=64)  # 64: certifying pays off
    # recurrence within 1e-9 of the range: almost every early label is a certified one
    fast = find_attractors(CELLS, opts.with_(recur_rtol=1e-9), settings=GEAR, stats=stats)
    full = find_attractors(CELLS, opts.with_(early=False), settings=GEAR)
    # (a cell without a certified orbit, e.g. chaos, runs every start full: no fewer periods)
    n_early = assert_same_attractors_per_start(fast, full, fewer_periods=False)
    assert sum(int(a.start_periods_run.sum()) for a in fast) < sum(
        int(b.start_periods_run.sum()) for b in full)
    assert stats.early_recurrence <= stats.early_certified // 4
    assert n_early >= stats.early_certified >= 16
    assert any(r is not None for r in stats.radii)


def test_forward_motion_seeds_certified_labels():
    cells = CELLS[1:3]
    rows = chains.simulate_rows([cells], settings=GearCells(cells, GEAR).settings)[0]
    motions = [gear_steady(r) for r in rows]
    stats = PoolStats()
    opts = FinderOptions(starts=64, seed=1, lanes=64)
    fast = find_attractors(cells, opts, settings=GEAR, forward_results=motions, stats=stats)
    full = find_attractors(cells, opts.with_(early=False), settings=GEAR,
                           forward_results=motions)
    assert_same_attractors_per_start(fast, full)
    assert stats.early_certified >= 16


def test_confirmed_needs_two_points_one_orbit_period_apart_inside_and_closer():
    c = Certificate(np.zeros(10), np.arange(2), np.ones(2), np.eye(2), 0.1, 0.5, 0.5, 2)
    L = 6
    h = np.full((4, L, 10), np.nan)
    x = np.array([0.5, 0.3, 0.09, 0.2, 0.05, 0.3])  # distances along x, oldest first
    h[:, :, :] = 0.0
    h[:, :, 0] = x
    h[1, :, 0] = [0.5, 0.3, 0.09, 0.2, 0.095, 0.3]  # inside, then 2 periods on farther
    h[2, :, 0] = [0.5, 0.3, 0.09, 0.05, 0.2, 0.3]  # closer only 1 period on (n = 2)
    filled = np.array([L, L, L, 3])  # the last start: y_2 (0.09) not recorded
    assert c.confirmed(h, filled).tolist() == [True, False, False, False]
