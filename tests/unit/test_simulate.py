"""simulate_cell / orbit_diagram drivers: early stopping, continuation, numerical faults."""

import numpy as np
import pytest
from reference import reference_settings

from gearsim.cell.simulate import IntegrationSettings, result_columns, simulate_cell
from gearsim.cell.sweep import continuation_chain, orbit_diagram
from gearsim.dynamics.parameters import ModelParameters
from gearsim.study.config import Study


def test_early_stop_for_period_one_and_full_budget_for_chaos():
    st = reference_settings()
    one = simulate_cell(ModelParameters(w=0.3), settings=st)
    assert one.classification.label == "0/1T"
    assert one.periods <= st.transient + 2 * st.chunk
    chaos = simulate_cell(ModelParameters(w=1.5), settings=st)
    assert chaos.classification.motion == "chaos" and chaos.classification.lyapunov > 0
    assert chaos.periods == st.transient + st.max_periods


def test_continuation_shortens_the_transient_and_keeps_the_attractor():
    st = reference_settings()
    p = ModelParameters(w=1.05)
    first = simulate_cell(p, settings=st)
    again = simulate_cell(p, first.final_state, settings=st, start_period=first.final_period)
    assert again.classification.label_npq == first.classification.label_npq == "2-2-0"
    assert again.periods < first.periods


def test_diverged_cell_is_recorded_and_the_chain_goes_on():
    """A divergence bound below the motion's size forces status 'diverged'."""
    st = reference_settings(divergence_bound=0.5)
    plist = [ModelParameters(w=0.3), ModelParameters(w=0.35)]
    res = continuation_chain(plist, settings=st)
    assert [r.classification.status for r in res] == ["diverged", "diverged"]
    assert np.isnan(res[0].classification.dc)
    # the record fills every column the catalogue requires (NOT NULL) with a value of its type
    row = res[0].row()
    for name, (typ, optional) in result_columns().items():
        if not optional and typ is not float:
            assert isinstance(row[name], typ), (name, row[name])
    ok = continuation_chain(plist, settings=reference_settings())
    assert all(r.classification.status == "ok" for r in ok)


def test_step_collapse_is_diverged():
    st = reference_settings(rtol=1e-300, atol=1e-300)
    r = simulate_cell(ModelParameters(w=1.0), settings=st, transient=2, samples=8)
    assert r.classification.status == "diverged"


def test_unsettled_motion_is_labelled_by_the_orbit_it_approaches():
    """No transient and a tiny budget from far away: no period in the 8-period window, but the
    window approaches a stable orbit: the cell is labelled by that Newton-refined orbit, the
    motion a long simulation from the same start settles to."""
    st = reference_settings(transient=0, chunk=8, max_periods=8)
    y0 = np.zeros(10)
    y0[0] = 3.0
    p = ModelParameters(w=0.3, b=1.0)
    r = simulate_cell(p, y0, settings=st, transient=0)
    c = r.classification
    assert c.refined and c.status == "ok" and c.mu_max < 1.0
    long = simulate_cell(p, y0, settings=reference_settings(), transient=2000).classification
    assert not long.refined and (c.label, c.label_npq) == (long.label, long.label_npq)
    assert c.dc == pytest.approx(long.dc, abs=1e-6)


def test_unsettled_without_an_orbit_is_not_converged(monkeypatch):
    """When no orbit is found (refinement fails) the unsettled window stays not_converged."""
    import gearsim.cell.verify as verify

    monkeypatch.setattr(verify, "refine", lambda *a, **k: None)
    st = reference_settings(transient=0, chunk=8, max_periods=8)
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


@pytest.mark.timeout(1200)  # a cold compile of both paths under load fits; 3e9 steps do not
def test_step_budget_ends_a_cell_and_the_chain_goes_on():
    """w -> 0: a period costs T / hmax steps; over the budget the cell is 'budget', at once."""
    from gearsim.cell.chains import simulate_rows
    from gearsim.cell.sweep import continuation_chain

    st = reference_settings(method="rk4", max_steps=200_000)
    cells = [ModelParameters(w=0.8), ModelParameters(w=1e-4), ModelParameters(w=0.9)]
    # the budget cell is refused before any step (steps == 0 below), not after the ~2e7 steps
    # per period of w = 1e-4 (the test's timeout bounds a regression)
    scalar = continuation_chain(cells, settings=st)
    batched = simulate_rows([cells], settings=st)[0]
    for res in (scalar, batched):
        assert [r.classification.status for r in res] == ["ok", "budget", "ok"]
        assert res[1].classification.label == "budget"
        assert res[1].classification.motion == "unsettled"
        assert res[1].steps == 0
    # after a budget cell the chain restarts from rest, as after a diverged one
    fresh = simulate_cell(cells[2], settings=st)
    assert scalar[2].classification.label == fresh.classification.label
    np.testing.assert_array_equal(batched[2].poincare, scalar[2].poincare)


def test_step_budget_during_measurement():
    """A cell still aperiodic when its steps exceed the budget stops at the next chunk."""
    p = ModelParameters(w=1.45, b=1.0)  # chaotic: measures until max_periods without a budget
    st = reference_settings(method="rk4", max_steps=30_000, transient=60)
    r = simulate_cell(p, settings=st)
    assert r.classification.status == "budget"
    assert 30_000 < r.steps < 30_000 + 25 * 256 * 2


def test_batched_lanes_compacted_as_cells_finish_give_the_same_results(monkeypatch):
    """simulate_cells packs the unfinished lanes into fewer SIMD blocks as cells finish:
    every cell's result equals its own single-lane run, bit for bit."""
    from gearsim.cell import chains
    from gearsim.cell.chains import simulate_cells

    sizes = []
    compact = chains.compact

    def counted(lanes, chains):
        sizes.append((lanes.n_blocks, len(chains)))
        return compact(lanes, chains)

    monkeypatch.setattr(chains, "compact", counted)

    st = reference_settings(method="rk4", transient=30, max_periods=96)
    ws = np.linspace(0.5, 2.2, 19)  # periodic cells finish early, chaotic ones use the budget
    cells = [ModelParameters(w=float(w), b=(0.15, 0.3)[k % 2]) for k, w in enumerate(ws)]
    # two cells on a finer step grid (T / hmax > 256 steps): run as their own group
    cells += [ModelParameters(w=0.105, b=0.15), ModelParameters(w=0.118, b=0.3)]
    together = simulate_cells(cells, settings=st)
    assert len({r.periods for r in together}) > 2  # cells finish at different times
    assert sizes and sizes[0][0] == 3  # 19 lanes of one grid in 3 blocks, then compacted
    for p, r in zip(cells, together, strict=True):
        alone = simulate_cells([p], settings=st)[0]
        ra, rb = r.row(), alone.row()
        assert ra.keys() == rb.keys()
        assert all(a == b or (a != a and b != b)  # NaN fields equal
                   for a, b in zip(ra.values(), rb.values(), strict=True))  # fmt: skip
        assert np.array_equal(r.final_state, alone.final_state)
        assert np.array_equal(r.poincare, alone.poincare)


# ------------------------------------------------------ transient_recurrence
def test_recurrence_probe_cuts_only_a_recurring_continued_start():
    """A continued start already on its attractor measures after the probe (fewer periods,
    the same label and section points as the full transient); a chaotic start does not recur
    and runs the whole transient; a cell from rest never probes."""
    off = reference_settings(method="rk4", transient_continuation=40)
    on = off.with_(transient_recurrence=24)
    p = ModelParameters(w=1.05)
    first = simulate_cell(p, settings=off)
    args = dict(start_period=first.final_period)
    a = simulate_cell(p, first.final_state, settings=off, **args)
    b = simulate_cell(p, first.final_state, settings=on, **args)
    assert b.classification.label_npq == a.classification.label_npq == "2-2-0"
    assert b.periods == a.periods - (40 - 24)
    np.testing.assert_allclose(np.sort(b.poincare[:, 0]), np.sort(a.poincare[:, 0]), atol=1e-7)
    c = ModelParameters(w=1.5)
    first = simulate_cell(c, settings=off)
    a = simulate_cell(c, first.final_state, settings=off, start_period=first.final_period)
    b = simulate_cell(c, first.final_state, settings=on, start_period=first.final_period)
    assert a.classification.motion == b.classification.motion == "chaos"
    assert b.periods == a.periods  # no recurrence: the whole transient
    assert simulate_cell(p, settings=on).periods == simulate_cell(p, settings=off).periods


def test_transient_recurrence_bad_values_exit_2_with_one_line(tmp_path):
    import subprocess
    import sys

    import pytest

    from gearsim.dynamics.parameters import ParameterError

    for bad in (8, 16, -1, True, 2.5):
        with pytest.raises(ParameterError, match="transient_recurrence"):
            IntegrationSettings(transient_recurrence=bad)
    with pytest.raises(ParameterError, match=r"\[30, 100000\]"):
        IntegrationSettings(transient_recurrence=24, tangent_lead=30)  # below the lead
    assert IntegrationSettings(transient_recurrence=17, tangent_lead=0).transient_recurrence == 17
    f = tmp_path / "bad.yaml"
    f.write_text("integration: {transient_recurrence: 10}\n")
    r = subprocess.run([sys.executable, "-m", "gearsim", "point", "--omega", "0.48",
                        "--configfile", str(f)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "transient_recurrence" in lines[0] and "[24, 100000]" in lines[0]


def test_audit_tighten_bad_value_is_one_config_error_and_sets_the_dp5_reference(tmp_path):
    import pytest

    from gearsim.errors import ConfigError
    from gearsim.study.audit import audit_settings
    from gearsim.study.config import study_config

    f = tmp_path / "bad.yaml"
    f.write_text("audit: {tighten: 0.5}\n")
    with pytest.raises(ConfigError, match="tighten"):
        study_config([f])
    cfg = study_config()
    st = Study.of(cfg).settings
    for k in (1, 10, 100):
        ref = audit_settings(Study.of({**cfg, "audit": {**cfg["audit"], "tighten": k}}))
        assert ref.method == "dp5" and ref.rtol == st.rtol / k and ref.hmax == st.hmax / 2
    t = st.with_(method="dp5").tightened()
    ref = audit_settings(Study.of({**cfg, "audit": {**cfg["audit"], "tighten": 100}}))
    assert (ref.rtol, ref.atol, ref.hmax) == (t.rtol, t.atol, t.hmax)
