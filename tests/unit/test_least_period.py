"""An orbit counted at a multiple of its period is merged into its least-period reading
(gearsim.analysis.attractors.least_periods, multiple_copy)."""

import numpy as np

from gearsim.analysis.attractors import Attractor, CellAttractors, Steady, least_periods


def _steady(n, points, mu, dc=0.3462, I=1):
    pts = np.asarray(points, dtype=float)
    return Steady(status="ok", period=n, points=pts, scale_x=1.0, scale_v=2.0,
                  label=f"{I}/{n}T", info={"I": I, "dc": dc, "mu_max": mu})  # fmt: skip


def _cell(steadies, counts, labels, cont=None):
    k = len(labels)
    pairs = enumerate(zip(steadies, counts, strict=True))
    atts = [Attractor(index=i, steady=s, n_starts=c, basin_fraction=c / k, found_by=("start",),
                      n_early=c // 2) for i, (s, c) in pairs]
    return CellAttractors(attractors=atts, starts=np.zeros((k, 10)),
                          start_labels=np.array(labels), early=np.zeros(k, dtype=bool),
                          start_periods_run=np.full(k, 10),
                          continuation=cont or {})  # fmt: skip


ORBIT = [[0.40, 0.10]]


def test_period_two_copy_of_a_period_one_orbit_is_merged():
    one = _steady(1, ORBIT, 0.91128)
    two = _steady(2, ORBIT * 2 + np.array([[1e-4, 0], [-1e-4, 0]]), 0.91128**2)  # 1e-4 apart
    chaos = Steady(status="ok", period=0, points=np.random.default_rng(0).uniform(size=(64, 2)),
                   scale_x=1.0, scale_v=1.0, label="chaos", info={"I": 2, "dc": 0.1})
    ca = _cell([chaos, one, two], [7, 5, 1], [0] * 7 + [1] * 5 + [2] + [-1] * 3,
               cont={"forward": 2})
    out = least_periods(ca)
    assert [a.label for a in out.attractors] == ["chaos", "1/1T"]
    assert [a.n_starts for a in out.attractors] == [7, 6]
    assert out.attractors[1].n_early == 2 + 0
    assert np.isclose(out.attractors[1].basin_fraction, 6 / 16)
    assert list(out.start_labels) == [0] * 7 + [1] * 6 + [-1] * 3
    assert out.continuation == {"forward": 1}


def test_a_true_period_two_orbit_is_kept():
    one = _steady(1, ORBIT, 0.91)
    # its multiplier is not the square of the period-1 one: another orbit (e.g. born in a
    # period doubling elsewhere in the cell), even with points this close
    two = _steady(2, ORBIT * 2, 0.5)
    far = _steady(2, [[0.40, 0.10], [0.60, 0.10]], 0.91**2)  # squared mu, points apart
    other_dc = _steady(2, ORBIT * 2, 0.91**2, dc=0.40)
    for b in (two, far, other_dc):
        out = least_periods(_cell([one, b], [4, 4], [0] * 4 + [1] * 4))
        assert [a.steady.period for a in out.attractors] == [1, 2]


def test_without_margins_the_merge_tolerance_decides():
    nan = float("nan")
    one = _steady(1, ORBIT, nan)
    near = _steady(2, [[0.4 + 5e-4, 0.1], [0.4 - 5e-4, 0.1]], nan)  # within 1e-3 of the range
    split = _steady(2, [[0.4 + 5e-3, 0.1], [0.4 - 5e-3, 0.1]], nan)
    assert len(least_periods(_cell([one, near], [3, 3], [0] * 3 + [1] * 3)).attractors) == 1
    assert len(least_periods(_cell([one, split], [3, 3], [0] * 3 + [1] * 3)).attractors) == 2
