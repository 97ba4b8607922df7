"""The adaptive transient (``integration.settle_check``): a cell settled to the period test's
tolerance ends early with the fixed plan's label; a slowly contracting one is not labelled from
its early windows. References: the fixed plan (``settle_check = 0``) from the same start and a
long simulation (2 000 transient periods) of the same cell."""

import numpy as np
import pytest

from gearsim.cell.chains import simulate_rows
from gearsim.cell.simulate import (
    EARLY_WINDOW,
    IntegrationSettings,
    PeriodSummaries,
    period_of,
    run_periods,
    settled_period,
    simulate_cell,
)
from gearsim.cell.sweep import continuation_chain
from gearsim.cell.verify import REFINE_RTOL, window_settle
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.study.config import Study

FIXED = IntegrationSettings(method="rk4")
ADAPTIVE = FIXED.with_(settle_check=8)
STANDARD = Study.load().parameters().model


def _continued(p: ModelParameters, dw: float = 0.006):
    """The start a plane row gives cell ``p``: its left neighbour's final state."""
    r = simulate_cell(p.with_(w=p.w - dw), settings=FIXED)
    return r.final_state, r.final_period


def _long(p: ModelParameters, y, k0):
    """The long-simulation reference: 2 000 periods of transient, then the fixed plan."""
    return simulate_cell(p, y, settings=FIXED, transient=2000, start_period=k0)


@pytest.mark.parametrize("w, b", [(0.6, None), (0.5, 0.1), (0.9, 0.1)])
def test_a_fast_cell_stops_early_with_the_fixed_plans_label(w, b):
    p = STANDARD.with_(w=w, **({} if b is None else {"b": b}))
    y, k0 = _continued(p)
    fixed = simulate_cell(p, y, settings=FIXED, start_period=k0)
    early = simulate_cell(p, y, settings=ADAPTIVE, start_period=k0)
    long = _long(p, y, k0)
    a, e, r = fixed.classification, early.classification, long.classification
    assert early.periods < fixed.periods == 64  # it does stop early
    assert early.steps < fixed.steps
    assert (e.label, e.label_npq, e.status, e.refined) == (a.label, a.label_npq, "ok", False)
    assert (e.label, e.label_npq) == (r.label, r.label_npq)
    # every point of the window within EARLY_RTOL / |1 - mu| of the orbit: DC and Kmax are the
    # long run's to ~1e-7 (measured 1e-9 .. 1e-7)
    assert abs(e.dc - r.dc) <= 1e-6 and abs(e.kmax - r.kmax) <= 1e-6 * r.kmax
    assert e.settle <= REFINE_RTOL
    # the next cell of a chain starts from this cell's end state
    np.testing.assert_array_equal(early.final_state, run_periods(
        p, y, early.periods, FIXED, start_period=k0).state)


@pytest.mark.parametrize("w, b, refined", [(1.003, 0.9, True), (0.95, 0.15, False)])
def test_a_slow_cell_next_to_a_doubling_is_not_labelled_early(w, b, refined):
    """|mu|max 0.989 next to a period doubling (w 1.003, b 0.9), 0.885 next to a fold (w 0.95,
    b 0.15): the repeat test alone passes on every early window, the settle distance (1e-3 ..
    1e-4) does not, so the cell runs the fixed plan; the first is then labelled by its refined
    orbit, the second by its window at 64 periods, settled to 7.6e-5. Both are the long
    simulation's labels."""
    p = STANDARD.with_(w=w, b=b)
    y, k0 = _continued(p)
    r = run_periods(p, np.concatenate([y, np.zeros(10)]), 64, FIXED, start_period=k0,
                    tangent=True)
    s = r.summaries
    for k in range(40, 64, 4):  # the adaptive transient's checks
        win = PeriodSummaries(*(getattr(s, f)[k - EARLY_WINDOW : k]
                                for f in s.__dataclass_fields__))  # fmt: skip
        n = period_of(win, p, FIXED)
        assert n == 1  # the period test alone would label it
        assert window_settle(p, win, n) > REFINE_RTOL
        assert settled_period(win, p, FIXED) == 0
    fixed = simulate_cell(p, y, settings=FIXED, start_period=k0)
    slow = simulate_cell(p, y, settings=ADAPTIVE, start_period=k0)
    long = _long(p, y, k0)
    a, c, g = fixed.classification, slow.classification, long.classification
    assert slow.periods == fixed.periods >= 64
    assert (c.label, c.label_npq, c.status, c.refined) == (a.label, a.label_npq, a.status,
                                                           a.refined)  # fmt: skip
    assert c.refined == refined
    # the refined orbit is the long run's to its Newton tolerance; the fixed plan's window
    # (its last point settled to REFINE_RTOL, its first 24 periods earlier) reads DC to 1.5e-4
    # here, within the 2e-3 of tests/integration/test_verify.py
    assert (c.label_npq, c.dc) == (g.label_npq, pytest.approx(g.dc, abs=1e-6 if refined
                                                              else 2e-3))
    # the window the fixed plan measures is the same: its numbers are equal
    assert c.dc == a.dc and c.kmax == a.kmax and c.lyapunov == a.lyapunov


def test_batched_chains_equal_the_scalar_chain_with_the_adaptive_transient():
    """simulate_rows against continuation_chain with settle_check on: the same cells stop at
    the same checks (periods, steps, labels, final states equal)."""
    rows = [[STANDARD.with_(w=w, b=b) for w in np.linspace(0.45, 2.3, 12)]
            for b in (0.1, 0.35)]  # fmt: skip
    batched = simulate_rows(rows, settings=ADAPTIVE)
    early = 0
    for row, got in zip(rows, batched, strict=True):
        ref = continuation_chain(row, settings=ADAPTIVE)
        for a, b in zip(ref, got, strict=True):
            ca, cb = a.classification, b.classification
            assert (ca.label, ca.label_npq, ca.status, a.periods, a.steps) == (
                cb.label, cb.label_npq, cb.status, b.periods, b.steps)
            np.testing.assert_allclose(b.final_state, a.final_state, rtol=0, atol=1e-12)
            if ca.n:
                assert cb.dc == pytest.approx(ca.dc, abs=1e-12)
                assert cb.kmax == pytest.approx(ca.kmax, rel=1e-12)
            early += a.periods < 64 and ca.n > 0
    assert early >= 2  # the set has cells that stop early


def test_settle_check_off_is_the_fixed_plan_and_on_needs_no_probe():
    p = STANDARD.with_(w=0.6)
    y, k0 = _continued(p)
    a = simulate_cell(p, y, settings=FIXED, start_period=k0)
    b = simulate_cell(p, y, settings=FIXED.with_(settle_check=0), start_period=k0)
    assert a.periods == b.periods == 64
    with pytest.raises(ParameterError, match="settle_check"):
        IntegrationSettings(settle_check=4, transient_recurrence=24)
    for bad in (-1, 2.5, True, 10_001):
        with pytest.raises(ParameterError, match="settle_check"):
            IntegrationSettings(settle_check=bad)
