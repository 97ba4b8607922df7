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


def test_a_2n_reading_beside_an_orbit_at_its_doubling_is_that_orbit():
    """w = 1.423, xi = 0.07015 (the wxi plane's row at xi index 100): a refined 1/4T orbit at
    its period doubling (|mu|max 0.99984) and a 1/8T reading without a margin whose points
    alternate 1.8e-3 of the range about it (the alternation not decayed): one orbit, reported
    at period 4. The same reading beside an orbit that is not at a doubling is kept."""
    nan = float("nan")
    four = [[0.89445, 0.05926], [0.67055, -0.47917], [0.60228, 0.03778], [0.88108, -0.45994]]
    eight = [[0.60345, 0.03806], [0.88015, -0.46057], [0.89316, 0.05977], [0.67115, -0.47961],
             [0.6012, 0.03751], [0.88195, -0.45934], [0.89562, 0.05872], [0.67005, -0.47873]]
    at = dict(refined=True, status="bifurcation", critical="period_doubling", label_npq="4-3-0")
    short = _steady(4, four, 0.999836, dc=0.60833)
    short.scale_x, short.scale_v = 1.2269, 1.2269 * 1.423
    short.info.update(at)
    long = _steady(8, eight, nan, dc=0.60844)
    long.scale_x, long.scale_v = 1.2276, 1.2276 * 1.423
    out = least_periods(_cell([short, long], [14, 2], [0] * 14 + [1] * 2))
    assert [(a.steady.period, a.n_starts) for a in out.attractors] == [(4, 16)]
    for change in ({"status": "ok"}, {"critical": "fold"}, {"refined": False}):
        other = _steady(4, four, 0.999836, dc=0.60833)
        other.scale_x, other.scale_v = short.scale_x, short.scale_v
        other.info.update({**at, **change})
        kept = least_periods(_cell([other, long], [14, 2], [0] * 14 + [1] * 2))
        assert [a.steady.period for a in kept.attractors] == [4, 8]
