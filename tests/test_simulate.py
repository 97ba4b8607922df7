"""simulate_cell / orbit_diagram drivers: early stopping, continuation, numerical faults."""

import numpy as np

from gearsim.parameters import ModelParameters
from gearsim.simulate import IntegrationSettings, simulate_cell
from gearsim.sweep import continuation_chain, orbit_diagram


def test_early_stop_for_period_one_and_full_budget_for_chaos():
    st = IntegrationSettings()
    one = simulate_cell(ModelParameters(w=0.3), settings=st)
    assert one.classification.label == "0/1T"
    assert one.periods <= st.transient + 2 * st.chunk
    chaos = simulate_cell(ModelParameters(w=1.5), settings=st)
    assert chaos.classification.motion == "chaos" and chaos.classification.lyapunov > 0
    assert chaos.periods == st.transient + st.max_periods


def test_continuation_shortens_the_transient_and_keeps_the_attractor():
    st = IntegrationSettings()
    p = ModelParameters(w=1.05)
    first = simulate_cell(p, settings=st)
    again = simulate_cell(p, first.final_state, settings=st, start_period=first.final_period)
    assert again.classification.label_npq == first.classification.label_npq == "2-2-0"
    assert again.periods < first.periods


def test_diverged_cell_is_recorded_and_the_chain_goes_on():
    """A divergence bound below the motion's size forces status 'diverged'."""
    st = IntegrationSettings(divergence_bound=0.5)
    plist = [ModelParameters(w=0.3), ModelParameters(w=0.35)]
    res = continuation_chain(plist, settings=st)
    assert [r.classification.status for r in res] == ["diverged", "diverged"]
    assert np.isnan(res[0].classification.dc)
    ok = continuation_chain(plist, settings=IntegrationSettings())
    assert all(r.classification.status == "ok" for r in ok)


def test_step_collapse_is_diverged():
    st = IntegrationSettings(rtol=1e-300, atol=1e-300)
    r = simulate_cell(ModelParameters(w=1.0), settings=st, transient=2, samples=8)
    assert r.classification.status == "diverged"


def test_unsettled_motion_is_not_converged():
    """No transient and a tiny budget from far away: no period yet, contracting -> not_converged."""
    st = IntegrationSettings(transient=0, chunk=8, max_periods=8)
    y0 = np.zeros(10)
    y0[0] = 3.0
    r = simulate_cell(ModelParameters(w=0.3, b=1.0), y0, settings=st, transient=0)
    assert r.classification.status == "not_converged"
    assert not r.classification.converged


def test_orbit_diagram_directions():
    vals = [1.0, 1.05, 1.1]
    fw = orbit_diagram(ModelParameters(), "w", vals)
    bw = orbit_diagram(ModelParameters(), "w", vals, direction="backward")
    assert list(fw.value) == sorted(vals) and list(bw.value) == sorted(vals, reverse=True)
    assert {"label", "label_npq", "dc", "kmax", "poincare_x"} <= set(fw.columns)
    assert all(len(px) == n for px, n in zip(fw.poincare_x, fw.n, strict=True))
