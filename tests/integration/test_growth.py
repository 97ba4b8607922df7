"""Unbounded motions are ``diverged``: the parametric instability of the nearly linear mesh at
w near 2 (small backlash) against long simulations of the same start.

References: a 4 000-period run from the same state (the scalar integrator) that leaves the
divergence bound, or whose amplitude stays put; the classifier's verdict comes from the cell's
own 256-period window only.
"""

import numpy as np
import pytest

from gearsim.cell.classify import GROWTH_MIN, GROWTH_STEP, amplitude_grows
from gearsim.cell.simulate import run_periods, simulate_cell
from gearsim.study.config import Study

ST = Study.load().settings
#: a wb plane cell whose chain restarts from the static state (its left neighbour diverged):
#: a growing motion that the window alone called chaos (Kmax 1.5e4)
GROWING = dict(w=1.897, b=0.00625)
#: a bounded chaotic cell of the wb plane and its forward-continuation start
BOUNDED = dict(w=1.519, b=0.95125)
BOUNDED_U0 = [0.7383030830150809, 0.008700769117431756, -0.00030498370861931865,
              -0.015455274457362889, -0.00011100499187393824, -0.005625259864914677,
              -0.002584768728846375, 0.004981088414862557, -0.0009407788797654878,
              0.001812967917264589]


def test_amplitude_grows_rule():
    k = np.arange(256)
    grow = 0.5 * np.exp(0.002 * k)  # x1.67 over the window
    assert amplitude_grows(grow, -grow)
    flat = 1.0 + 0.05 * np.sin(0.37 * k)  # bounded, quarters of equal maxima
    assert not amplitude_grows(flat, -flat)
    slow = np.exp(np.log(GROWTH_MIN) * 0.9 * k / 255)  # rises, but less than GROWTH_MIN
    assert not amplitude_grows(slow, -slow)
    # settling within the window onto a larger bounded motion: rises every quarter, by 13 % in
    # all, but the later quarters by less than GROWTH_STEP
    settle = 1.0 - 0.95 * np.exp(-(k + 1) / 30.0)
    top = settle.reshape(4, 64).max(axis=1)
    assert np.all(np.diff(top) > 0) and top[3] / top[0] > GROWTH_MIN
    assert (top[2] / top[1]) < GROWTH_STEP
    assert not amplitude_grows(settle, -settle)
    assert amplitude_grows(np.r_[1.0, 2.0, 3.0, np.inf], np.zeros(4))


def test_growing_motion_is_diverged_and_the_long_run_confirms_it():
    p = Study.load().parameters(**GROWING).model
    res = simulate_cell(p, settings=ST, transient=ST.transient)
    c = res.classification
    assert (c.motion, c.status, c.label, c.label_npq) == ("diverged", "diverged", "diverged", "")
    # the reference: the same start left to run leaves the divergence bound
    long = run_periods(p, _rest(p), 4000, ST)
    assert long.status != 0 and len(long.summaries) < 4000


def test_bounded_chaos_stays_chaos_and_the_long_run_stays_bounded():
    p = Study.load().parameters(**BOUNDED).model
    res = simulate_cell(p, np.array(BOUNDED_U0), settings=ST,
                        transient=ST.transient_continuation)  # fmt: skip
    assert res.classification.motion == "chaos"
    long = run_periods(p, np.array(BOUNDED_U0), 4000, ST)
    assert long.status == 0
    a = long.summaries.xmax - long.summaries.xmin
    assert a[-500:].max() == pytest.approx(a[:500].max(), rel=0.05)


def _rest(p):
    from gearsim.dynamics.model import static_state

    return static_state(p.to_array())


def test_the_issue_cell_holds_one_orbit_at_its_least_period_and_no_growing_attractor():
    """w = 2.029, b = 0.06875 (standard set, study settings, 16 starts): starts that grow end
    diverged (they used to make a "chaos" attractor with Kmax 6e5) and the 1/1T orbit is listed
    once (a start whose window read it as 1/2T, |mu|max the square of the 1T one's, used to be a
    second attractor); the early labels are those of every start's full-length run."""
    from gearsim.analysis.attractors import FinderOptions, find_attractors

    p = Study.load().parameters(w=2.029, b=0.06875).model
    opts = FinderOptions(starts=16)
    ca = find_attractors(p, opts, settings=ST)
    full = find_attractors(p, opts.with_(early=False), settings=ST)
    for c in (ca, full):
        assert [(a.label, a.steady.period) for a in c.attractors] == [("1/1T", 1)]
        assert all(a.steady.info["kmax"] < 10 for a in c.attractors)
        assert 0 < c.diverged_fraction < 1
    assert np.array_equal(ca.start_labels, full.start_labels)
    assert ca.early.sum() > 0


def test_a_cloud_next_to_diverging_starts_is_checked_by_a_long_run():
    """w = 1.873, b = 0.00125 (standard set, 16 starts): 15 starts diverge; the 16th's window
    reads quasi-periodic (Kmax 0.4, amplitude flat over the window) and its 4 000-period run
    from the same start grows: no attractor, every start diverged. The reference: the long run
    itself (the scalar integrator; its amplitude ~0.5 after the transient, ~2e4 at the end)."""
    from gearsim.analysis.attractors import FinderOptions, find_attractors

    p = Study.load().parameters(w=1.873, b=0.00125).model
    ca = find_attractors(p, FinderOptions(starts=16), settings=ST)
    assert ca.attractors == [] and ca.diverged_fraction == 1.0
    # the start whose window read a cloud: its own long run grows without bound
    longest = int(np.argmax(ca.start_periods_run))
    assert ca.start_periods_run[longest] > 3000
    long = run_periods(p, ca.starts[longest], 4000, ST)
    a = long.summaries.xmax - long.summaries.xmin
    assert long.status != 0 or a[-100:].min() > 100 * a[250:350].max()
