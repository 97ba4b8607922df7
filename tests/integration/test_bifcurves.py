"""Two-parameter bifurcation curves: the direct (secant) re-location against the windowed
continuation it replaces, parallel against serial, and closed doubled branches.

Reference for a curve point: a one-parameter continuation across a window around the predicted
point, locating the event by Brent's method (:func:`gearsim.analysis.relocation.relocate_window`).
The secant solve shares no code with that locator beyond the orbit Newton and the test
functions' ingredients (multipliers, turning points)."""

from __future__ import annotations

import numpy as np
import pytest

from gearsim.analysis.bifcurves import follow_curve, follow_curves
from gearsim.analysis.continuation import continue_orbit
from gearsim.analysis.continuation_options import Continuation
from gearsim.analysis.exact_landmarks import bifurcation_points
from gearsim.dynamics.parameters import ModelParameters
from gearsim.study.config_io import load_standard_parameters

STANDARD = ModelParameters.from_mapping(load_standard_parameters("config/standard_parameters.yaml"))
ONE = STANDARD.with_(model="1dof")


@pytest.fixture(scope="module")
def points():
    br = continue_orbit(ONE, "w", 0.9, 1.4, n=1, config=Continuation(ds=0.02, switch_depth=1))
    return bifurcation_points(br)


@pytest.mark.parametrize("kind", ["period_doubling", "grazing", "fold"])
def test_secant_relocation_equals_windowed_continuation(points, kind):
    r = points[points["kind"] == kind].iloc[0]
    a = follow_curve(ONE, r, "xi", 0.08, step2=0.006, method="secant", max_points=4)
    b = follow_curve(ONE, r, "xi", 0.08, step2=0.006, method="window", max_points=4)
    assert len(a) == len(b) == 4
    np.testing.assert_allclose(a["value2"], b["value2"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(a["value"], b["value"], rtol=0, atol=1e-8)
    # the secant did the work (a fallback would make the comparison empty)
    assert a.attrs["relocations"]["secant"] >= 2
    for _, p in a.iterrows():
        mu = np.array(p.mu_re) + 1j * np.array(p.mu_im)
        target = {"period_doubling": -1.0, "fold": 1.0}.get(kind)
        if target is not None:
            assert np.min(np.abs(mu - target)) < 1e-6


def test_parallel_curves_equal_serial(points):
    pts = points[points["kind"] == "period_doubling"].iloc[:1]
    one = follow_curves(ONE, pts, "xi", (0.055, 0.067), step2=0.004, workers=1)
    two = follow_curves(ONE, pts, "xi", (0.055, 0.067), step2=0.004, workers=2)
    assert len(one) == len(two) > 3
    np.testing.assert_array_equal(one["value"].to_numpy(), two["value"].to_numpy())
    assert one.attrs["reasons"] == two.attrs["reasons"]


def test_doubled_branch_ends_where_it_closes():
    """The 1T orbit doubles and un-doubles (1 -> 2 near w = 1.0 and 2 -> 1 further up): the
    2T branch joins the two doublings and must end there instead of running round the loop
    until max_points; the switch at the second doubling is then redundant."""
    br = continue_orbit(ONE, "w", 0.9, 2.5, n=1,
                        config=Continuation(ds=0.02, switch_depth=1, grazing=False,
                                            max_points=300))
    reasons = br.attrs["reasons"]
    pds = br[(br["event"] == "period_doubling") & (br["branch"] == 0)]["value"].to_numpy()
    assert len(pds) == 2
    two = br[br["branch"] == 1]
    assert len(two) < 300
    assert any("closed" in r or "merged" in r for r in reasons if r.startswith("branch 1"))
    assert any("no switch" in r for r in reasons)
    assert two["value"].min() >= pds.min() - 1e-6 and two["value"].max() <= pds.max() + 1e-6


def test_curve_is_vertical_in_b_while_the_orbit_has_no_back_contact(points):
    """Exact invariance (independent of the numerics): an orbit that never reaches x = -b sees
    the dead zone only through x - b, so shifting x by b removes b from its equations; its
    bifurcation points cannot move with b. The 1T period-doubling curve of the standard set
    (section x ~ 0.74, no back contact) must be a vertical line in (w, b)."""
    r = points[(points["kind"] == "period_doubling") & (points["period"] == 1)].iloc[0]
    c = follow_curve(ONE, r, "b", 0.6, step2=0.1, max_points=8, range2=(0.0, 1.0))
    assert len(c) == 8 and c["value2"].min() < 0.75
    assert np.ptp(c["value"].to_numpy()) < 1e-8
    # the orbit itself is shifted by the change of b
    np.testing.assert_allclose(c["x"] - c["value2"], c["x"].iloc[0] - c["value2"].iloc[0],
                               atol=1e-8)
