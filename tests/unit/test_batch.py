"""The batched RK4 path (gearsim.numerics.batch) against the scalar core.

* the lane vector field equals :func:`gearsim.dynamics.model.rhs` (state and tangent, every region);
* per-period summaries equal ``integrate_periods`` (METHOD_RK4, same steps per period) to a
  stated tolerance, including double-sided impacts, bearing clearances and chaos;
* 30 fixed cells (1T, 2T, 3T, 4T, 8T, chaos, double-sided impacts) are classified exactly as
  :func:`gearsim.cell.simulate.simulate_cell` with the reference DP5 settings;
* ``simulate_rows`` equals ``continuation_chain`` with RK4 on continuation chains.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from reference import reference_settings

from gearsim.cell import chains
from gearsim.cell.classify import estimate_period
from gearsim.cell.simulate import initial_tangent, run_periods, simulate_cell
from gearsim.cell.sweep import continuation_chain
from gearsim.cell.verify import fill_margins
from gearsim.dynamics.model import (
    N_SWITCH,
    field_state,
    field_tangent,
    rhs,
    set_period,
    static_state,
)
from gearsim.dynamics.parameters import ModelParameters
from gearsim.numerics import batch

RK4 = reference_settings(method="rk4")

#: Tolerance of the summaries against integrate_periods (absolute; orbits are O(1)); the
#: tangent log-growth is more sensitive to the switch times (measured: <= 2.5e-9).
SUMMARY_ATOL = 1e-9
LYAP_ATOL = 1e-8

#: (b, w): chosen inside their pattern regions (neighbours at w +/- 0.002..0.004 agree).
CELLS = [
    (0.15, 0.49),  # 1/1T 1-1-0
    (0.15, 0.76),  # 2/1T 1-1-1 double-sided
    (0.15, 0.86),  # 2/1T 1-1-1
    (0.15, 1.07),  # 2/2T 2-2-1
    (0.15, 1.13),  # 2/3T 3-2-2
    (0.15, 1.22),  # 2/2T 2-2-1
    (0.15, 1.40),  # 2/2T 2-1-1
    (0.15, 1.53),  # 2/4T 4-3-2
    (0.15, 1.70),  # 1/2T 2-2-0
    (0.15, 2.00),  # 1/1T 1-1-0
    (0.3, 0.69),  # 2/1T 1-1-1
    (0.3, 0.85),  # 1/1T 1-1-0
    (0.3, 1.05),  # 1/2T 2-2-0
    (0.3, 1.15),  # 1/2T 2-1-0
    (0.3, 1.22),  # 2/2T 2-1-1
    (0.3, 1.31),  # 1/4T 4-2-0
    (0.3, 1.359),  # 1/8T 8-5-0
    (0.3, 1.45),  # chaos
    (0.3, 1.55),  # chaos
    (0.3, 1.72),  # 1/2T 2-2-0
    (0.3, 2.20),  # 1/1T 1-1-0
    (1.0, 0.35),  # 0/1T 1-0-0
    (1.0, 0.80),  # 1/1T 1-1-0
    (1.0, 1.02),  # 1/2T 2-2-0
    (1.0, 1.20),  # 1/2T 2-1-0
    (1.0, 1.30),  # 1/4T 4-2-0
    (1.0, 1.359),  # 1/8T 8-5-0
    (1.0, 1.42),  # chaos
    (1.0, 1.60),  # chaos
    (1.0, 1.636),  # 1/4T 4-3-0
]


def _key(c):
    return (c.motion, c.label, c.label_npq, c.I, c.n, c.p, c.q)


# ------------------------------------------------------------------------------ vector field
def _lane_field(p: ModelParameters, t, y, mode, friction_sign):
    """Evaluate the tuple field for one lane, its parameters packed by hand from ``p``."""
    w = p.w
    c, s = math.cos(w * t), math.sin(w * t)
    P = (
        p.eps, 2 * p.xi, p.b, p.Fm, p.Fe * w * w, math.cos(p.phi_e), math.sin(p.phi_e),
        p.friction, math.cos(p.alpha), math.sin(p.alpha),
        p.rho_p * math.cos(p.alpha), p.rho_p * math.sin(p.alpha),
        p.rho_g * math.cos(p.alpha), p.rho_g * math.sin(p.alpha),
        p.kappa_py, p.kappa_pz, p.kappa_gy, p.kappa_gz,
        2 * p.xi_py, 2 * p.xi_pz, 2 * p.xi_gy, 2 * p.xi_gz,
        p.b_py, p.b_pz, p.b_gy, p.b_gz,
        -(1.0 - p.te_damping) * p.Fe * w, 2 * p.xi * p.mesh_damping_contact, p.friction_arm_var,
    )  # fmt: skip
    regions = [float(mode[k]) for k in range(5)]
    M = (regions[0], abs(regions[0]), *regions[1:], *(abs(r) for r in regions[1:]))
    vr = p.var_ratio * w * w * math.sin(p.var_ratio_order * w * t)
    q = (w * t) * (1.0 / math.pi) - 1.0  # the friction arm's phase (t: time within the period)
    dy = field_state(c, s, friction_sign, q, vr, tuple(y[:10]), P, M)
    dz = field_tangent(c, friction_sign, q, tuple(y[10:]), P, M)
    return np.array(dy + dz)


@pytest.mark.parametrize("seed", range(6))
def test_lane_field_equals_model_rhs(seed):
    rng = np.random.default_rng(seed)
    p = ModelParameters(
        w=float(rng.uniform(0.2, 2.5)), b=float(rng.uniform(0, 1)), friction=0.1 * (seed % 2),
        var_ratio=0.05 * (seed % 3 == 0), b_py=0.01 * (seed % 2), b_gz=0.02, kappa_pz=7.0,
        xi_gy=0.07, phi_e=float(rng.uniform(-3, 3)), alpha=0.4,
    )  # fmt: skip
    arr = p.to_array()
    set_period(arr, 0)  # variable-ratio phase of period 0: t is absolute time then
    for _ in range(20):
        t = float(rng.uniform(0, 50))
        y = rng.standard_normal(20)
        mode = rng.integers(-1, 2, N_SWITCH)
        lam = 1.0 if math.sin(p.w * t) >= 0 else -1.0
        ref = np.zeros(20)
        rhs(t, y, arr, np.append(mode, int(lam)), ref, True)  # mode[5]: friction direction
        got = _lane_field(p, t, y, mode, lam)
        np.testing.assert_allclose(got, ref, rtol=1e-13, atol=1e-13)


# ------------------------------------------------------------------------------ summaries
def _post_transient(cells, periods=60):
    ys = []
    for p in cells:
        r = run_periods(p, static_state(p.to_array()), periods, RK4)
        ys.append(np.concatenate([r.state, initial_tangent(p)]))
    return np.array(ys)


SUMMARY_CELLS = [
    ModelParameters(w=0.76, b=0.15),  # double-sided impacts
    ModelParameters(w=1.13, b=0.15),  # 3T, face and back
    ModelParameters(w=0.49, b=1.0),  # grazing region
    ModelParameters(w=1.36, b=0.3),  # 8T
    ModelParameters(w=1.45, b=1.0),  # chaos
    ModelParameters(w=0.9, b=0.3, b_py=0.002, b_gz=0.003),  # bearing clearances switch too
    ModelParameters(w=1.25, b=0.3, var_ratio=0.02),  # slow variable-ratio forcing
    ModelParameters(w=0.6, b=1.0, alpha=0.5, kappa_gy=35.0, rho_g=0.3),
]


def test_summaries_equal_integrate_periods_rk4():
    y0 = _post_transient(SUMMARY_CELLS)
    m = 24
    start = [60] * len(SUMMARY_CELLS)
    out, finals, status, steps = batch.run_periods_batched(
        SUMMARY_CELLS, y0, m, RK4, start_periods=start
    )
    assert np.all(status == 0)
    for i, p in enumerate(SUMMARY_CELLS):
        ref = run_periods(p, y0[i], m, RK4, tangent=True, start_period=60)
        a, b = ref.summaries, out[i]
        assert len(b) == m
        np.testing.assert_array_equal(b.nface, a.nface, err_msg=f"cell {i}")
        np.testing.assert_array_equal(b.nback, a.nback, err_msg=f"cell {i}")
        for name in ("section", "tdis", "fmax", "fmin", "xmax", "xmin", "lyap"):
            tol = LYAP_ATOL if name == "lyap" else SUMMARY_ATOL
            np.testing.assert_allclose(
                getattr(b, name), getattr(a, name), rtol=0, atol=tol,
                err_msg=f"cell {i} ({p.w}, {p.b}): {name}",
            )  # fmt: skip
        np.testing.assert_allclose(finals[i], ref.state, rtol=0, atol=SUMMARY_ATOL)
        # the same RK4 steps, Newton trials and graze checks (to a rounding-level tie or two)
        assert abs(int(steps[i]) - ref.n_steps) <= 2
    # the comparison is not vacuous: the chaotic cell's section wanders, impacts happen
    assert np.ptp(out[4].section[:, 0]) > 1e-2
    assert sum(int(o.nface.sum() + o.nback.sum()) for o in out) > 100


def test_bearing_channels_switch_in_the_clearance_cell():
    p = SUMMARY_CELLS[5]
    y0 = _post_transient([p])
    out, *_ = batch.run_periods_batched([p], y0, 8, RK4)
    ref = run_periods(p, y0[0], 8, RK4, tangent=True, event_capacity=10_000)
    assert np.any(ref.events_code >= 4), "the clearance cell must have bearing switches"
    np.testing.assert_allclose(out[0].section, ref.summaries.section, atol=SUMMARY_ATOL)


def test_divergent_lane_stops_alone():
    good = ModelParameters(w=1.0, b=0.3)
    y = np.array([static_state(good.to_array())] * 2)
    y[1, 0] = 1e7  # beyond the divergence bound after the first step
    y = np.hstack([y, np.tile(initial_tangent(good), (2, 1))])
    out, _, status, _ = batch.run_periods_batched([good, good], y, 5, RK4)
    assert list(status) == [0, 1]
    assert len(out[0]) == 5 and len(out[1]) == 0


# ------------------------------------------------------------------------------ classification
@pytest.fixture(scope="module")
def batched_cells():
    cells = [ModelParameters(w=w, b=b) for b, w in CELLS]
    return cells, chains.simulate_cells(cells, settings=reference_settings())


def test_cell_set_covers_the_patterns(batched_cells):
    _, res = batched_cells
    labels = {r.classification.label for r in res}
    ns = {r.classification.n for r in res}
    assert {1, 2, 3, 4, 8} <= ns
    assert "chaos" in labels
    assert any(r.classification.I == 2 for r in res), "double-sided impacts"
    assert any(r.classification.I == 0 for r in res)


def test_batched_classifies_like_reference_reference_settings(batched_cells):
    cells, res = batched_cells
    st = reference_settings()  # the reference DP5 settings
    assert st.method == "dp5"
    mism = []
    for p, r in zip(cells, res, strict=True):
        ref = simulate_cell(p, settings=st).classification
        got = r.classification
        if _key(got) != _key(ref):
            mism.append((p.w, p.b, _key(got), _key(ref)))
        elif got.n > 0:
            # periodic: the measured quantities agree to the accuracy of RK4 at 256 steps
            # (the force peak is sampled at the step points: O(h^2) ~ 1e-4 relative)
            assert got.dc == pytest.approx(ref.dc, abs=1e-4)
            assert got.kmax == pytest.approx(ref.kmax, rel=1e-3)
            assert got.x_max == pytest.approx(ref.x_max, abs=1e-4)
    assert not mism, mism


def _period_reference(x, v, scale, w, n_max=64, period_rtol=1e-5, min_confirm=16):
    """The period test written out with numpy (the definition in gearsim.cell.classify's
    docstring)."""
    m = len(x)
    scale = max(scale, 1e-9)
    tol_x, tol_v = period_rtol * scale, period_rtol * scale * max(w, 1e-3)
    for n in range(1, n_max + 1):
        window = max(2 * n, min_confirm)
        if window + n > m:
            return 0
        dx = np.abs(x[m - window:] - x[m - window - n:m - n])
        dv = np.abs(v[m - window:] - v[m - window - n:m - n])
        if dx.max() <= tol_x and dv.max() <= tol_v:
            if n > 1:
                early = np.abs(np.diff(x[m - window - 1:m - window + n])).mean()
                late = np.abs(np.diff(x[m - n - 1:m])).mean()
                if early - late > max(2.0 * tol_x, 1e-3 * early):
                    return 0
            return n
    return 0


def test_compiled_period_test_equals_numpy_reference(batched_cells):
    _, res = batched_cells
    rng = np.random.default_rng(3)
    seqs = []
    for r in res:  # real section sequences (periodic and chaotic), with and without noise
        sec = np.tile(r.poincare, (max(1, 80 // max(1, len(r.poincare))), 1))[:80]
        seqs.append(sec)
        seqs.append(sec + rng.normal(0, 1e-7, sec.shape))
    seqs.append(np.full((40, 10), np.nan))
    found = set()
    for sec in seqs:
        scale = float(np.ptp(sec[:, 0])) if np.all(np.isfinite(sec)) else 1.0
        for m in (17, 24, 40, len(sec)):
            args = (sec[:m, 0], sec[:m, 1], scale, 1.3, 64, 1e-5)
            got = estimate_period(*args)
            assert got == _period_reference(*args)
            found.add(got)
    assert {0, 1, 2}.issubset(found)  # not vacuous: periodic and aperiodic sequences


# ------------------------------------------------------------------------------ driver
def test_simulate_rows_equals_continuation_chain():
    ws = [0.45, 0.7, 0.95, 1.1, 1.25, 1.32]
    rows = [[ModelParameters(w=w, b=b) for w in ws] for b in (0.15, 1.0)]
    got = chains.simulate_rows(rows, settings=RK4)
    # the batched callers fill the margins afterwards, many cells per kernel call
    fill_margins([r for row in got for r in row], RK4)
    assert sum(np.isfinite(r.classification.mu_max) for row in got for r in row) >= 6
    for row, res in zip(rows, got, strict=True):
        ref = continuation_chain(row, settings=RK4)
        for a, b in zip(res, ref, strict=True):
            ra, rb = a.row(), b.row()
            assert _key(a.classification) == _key(b.classification)
            for k, v in rb.items():
                if isinstance(v, float) and k != "lyapunov":
                    assert ra[k] == pytest.approx(v, rel=1e-7, abs=1e-9, nan_ok=True), k
            assert a.classification.lyapunov == pytest.approx(
                b.classification.lyapunov, abs=1e-8
            )
            assert a.final_period == b.final_period
            assert a.periods == b.periods
            np.testing.assert_allclose(a.poincare, b.poincare, atol=1e-8)
            np.testing.assert_allclose(a.final_state, b.final_state, atol=1e-8)


def test_simulate_rows_callback_and_single_dof_fallback():
    seen = []
    rows = [
        [ModelParameters(w=0.8, b=0.3), ModelParameters(w=0.9, b=0.3)],
        [ModelParameters(w=0.8, b=0.3, model="1dof")],
        [],
    ]
    res = chains.simulate_rows(rows, settings=RK4, on_cell=lambda r, i, c: seen.append((r, i)))
    assert [len(r) for r in res] == [2, 1, 0]
    assert sorted(seen) == [(0, 0), (0, 1), (1, 0)]
    one = simulate_cell(rows[1][0], settings=RK4)
    assert _key(res[1][0].classification) == _key(one.classification)


def test_simulate_cells_with_start_states_and_periods():
    """simulate_cells(params, u0=[...], start_periods=[...]) = simulate_cell per cell (RK4)."""
    cells = [ModelParameters(w=w, b=0.3, var_ratio=0.01 * (i % 2)) for i, w in
             enumerate((0.7, 0.9, 1.1))]  # fmt: skip
    starts = [None, static_state(cells[1].to_array()) + 0.01, static_state(cells[2].to_array())]
    ks = [0, 7, 40]
    got = chains.simulate_cells(cells, settings=RK4, u0=starts, start_periods=ks)
    for p, u, k, a in zip(cells, starts, ks, got, strict=True):
        b = simulate_cell(p, u, settings=RK4, start_period=k)
        assert _key(a.classification) == _key(b.classification)
        assert a.final_period == b.final_period and a.periods == b.periods
        np.testing.assert_allclose(a.final_state, b.final_state, atol=1e-8)


def test_lanes_with_different_steps_per_period_wait_for_each_other():
    # w < 2 pi / (hmax * 256) needs more than 256 steps per period (the hmax cap)
    low = [ModelParameters(w=w, b=0.3) for w in (0.103, 0.115)]
    high = [ModelParameters(w=w, b=0.3) for w in (0.5, 0.6)]
    assert batch.steps_per_period(low[0], RK4) > batch.steps_per_period(low[1], RK4) > 256
    got = chains.simulate_rows([low, high], settings=RK4)
    for row, res in zip([low, high], got, strict=True):
        ref = continuation_chain(row, settings=RK4)
        for a, b in zip(res, ref, strict=True):
            assert a.steps == pytest.approx(b.steps, abs=4)
            np.testing.assert_allclose(a.final_state, b.final_state, atol=1e-8)


# ------------------------------------------------------------------------------ one RK4
BIT_CELLS = SUMMARY_CELLS + [
    ModelParameters(w=1.1, b=0.15, model="1dof"),  # single-DOF lanes run in the kernel too
    ModelParameters(w=1.2, b=0.3, friction=0.05),  # friction direction flips at T/2
]


def test_scalar_rk4_and_batched_rk4_are_bit_identical():
    """The scalar RK4 path and the SIMD lanes run one algorithm: identical to the last bit."""
    st = RK4.with_(transient=30, chunk=8, max_periods=48)
    got = chains.simulate_cells(BIT_CELLS, settings=st)
    labels = set()
    for p, a in zip(BIT_CELLS, got, strict=True):
        b = simulate_cell(p, settings=st)
        np.testing.assert_array_equal(a.poincare, b.poincare, err_msg=f"{p.w}, {p.b}")
        np.testing.assert_array_equal(a.final_state, b.final_state)
        assert _key(a.classification) == _key(b.classification)
        assert a.classification.lyapunov == b.classification.lyapunov
        assert a.classification.dc == b.classification.dc
        assert a.steps == b.steps and a.periods == b.periods
        labels.add(a.classification.label)
    assert len(labels) >= 4  # impacting, chaotic and multi-period motions are compared


def test_recurrence_probe_scalar_and_batched_are_bit_identical():
    """transient_recurrence on: continuation chains through the lanes and through
    simulate_cell agree to the last bit. Every cell comes twice in a row: the repeat starts on
    its attractor (the probe ends its transient), a chaotic repeat does not recur (the whole
    transient), so both branches run in the same lanes. (After a cut the next cell starts
    1e-7 away from off's start: a chaotic cell's exponent, and so chaos or quasi-periodic at
    the threshold, may then differ from off's; only cut cells are compared with off.)"""
    st = RK4.with_(transient_continuation=40, transient_recurrence=24)
    ws = (0.45, 0.7, 1.05, 1.25, 1.5, 1.55)
    rows = [[ModelParameters(w=w, b=b) for w in ws for _ in (0, 1)] for b in (0.15, 1.0)]
    got = chains.simulate_rows(rows, settings=st)
    off = chains.simulate_rows(rows, settings=st.with_(transient_recurrence=0))
    cut = full = 0
    for row, res, res_off in zip(rows, got, off, strict=True):
        ref = continuation_chain(row, settings=st)
        for a, b, c in zip(res, ref, res_off, strict=True):
            np.testing.assert_array_equal(a.poincare, b.poincare)
            np.testing.assert_array_equal(a.final_state, b.final_state)
            assert _key(a.classification) == _key(b.classification)
            assert a.classification.lyapunov == b.classification.lyapunov
            assert a.steps == b.steps and a.periods == b.periods
            if a.periods == c.periods - 16:  # cut: the label of the option off
                cut += 1
                assert _key(a.classification) == _key(c.classification)
            elif a.steps > c.steps:  # restarted after the probe: off's plan, probe steps added
                full += 1
                assert a.periods == c.periods
    assert cut >= 6 and full >= 4  # both branches of the probe are compared


def test_single_dof_lanes_equal_scalar_and_keep_bearings_frozen():
    p = ModelParameters(w=1.02, b=1.0, model="1dof")
    (a,) = chains.simulate_cells([p], settings=RK4)
    np.testing.assert_array_equal(a.final_state[2:], 0.0)
    assert a.classification.label == simulate_cell(p, settings=RK4).classification.label


# ------------------------------------------------------------------------------ quick config
#: The quick configuration's wxi plane, row j = 9, cell i = 15 (w = 1.03, xi = 0.0685; a
#: quasi-periodic cell with friction). Its start is the final state of cell 14 of that row's
#: continuation chain (absolute period 1070), recorded from the kernel before its one-source
#: refactor.
QUICK_CELL = dict(
    w=1.03, Fm=0.1184623614, Fe=0.2115055312, eps=0.3175445853, xi=0.0685, phi_e=-0.7258227962,
    friction=7.987869645e-05, alpha=0.3490658504, var_ratio_order=0.1111111111, rho_p=0.4,
    rho_g=0.1, kappa_py=40.0, kappa_pz=40.0, kappa_gy=10.0, kappa_gz=10.0,
)
QUICK_U0 = (
    "0x1.6f20fb173fbf2p-1", "-0x1.67fdf89ab96b6p-3", "0x1.0292088c9626bp-12",
    "0x1.e0f4dbde73fe4p-11", "0x1.7872a1a15232ep-14", "0x1.5e1b9144586c6p-12",
    "-0x1.0e42d62d6febap-12", "0x1.54bf299b5d2f3p-8", "-0x1.8977cbea80b99p-14",
    "0x1.f0162fc7bae0cp-10",
)
#: Its final state after simulate_cell's flow (40 periods of transient, then 256 measured
#: periods with the tangent vector in chunks of 24: period 1366), the same on both paths. A grid
#: step with a turning point of x inside its contact region stands (its table-phase RK4 step)
#: instead of being redone by the event layer with libm phases: 1.6e-15 from the state pinned
#: before that change, in every component (the RK4 step error here is ~1e-6 a period;
#: docs/decisions.md, "Turning points without the event layer").
QUICK_FINAL = (
    "0x1.a439dd6e484fep-1", "-0x1.67e5853d4a2ecp-3", "-0x1.2f16eef574731p-14",
    "0x1.45a23c56175bep-10", "-0x1.b943292f0f998p-16", "0x1.da157d643ad72p-12",
    "-0x1.dd1a4c9b1ae7ep-12", "0x1.47ca0b105ee7fp-7", "-0x1.5b4d69289f020p-13",
    "0x1.dd38db1a94c9cp-9",
)


def test_a_long_impacting_trajectory_is_pinned_to_the_bit_on_both_paths():
    """296 periods (77,541 RK4 steps, the event layer included) of a quick-configuration cell
    whose two paths once drifted 1 ulp apart at period 165: the scalar integrator and the batched
    kernel, each in simulate_cell's sequence of calls (no tangent lead; regions reset at every
    call), agree with each other and with the recorded final state to the last bit. The period
    test is not involved (its later changes may relabel the cell; the trajectory is pinned)."""
    p = ModelParameters.from_mapping(QUICK_CELL)
    st = RK4.with_(transient_continuation=40, tangent_lead=0)
    u0 = np.array([float.fromhex(v) for v in QUICK_U0])
    k = 1070
    r = run_periods(p, u0, 40, st, start_period=k)
    out, yb, _, steps_b = batch.run_periods_batched([p], np.concatenate([u0, np.zeros(10)])[None],
                                                    40, st, start_periods=[k], tangent=False)
    np.testing.assert_array_equal(out[0].section, r.summaries.section)
    steps = [r.n_steps, int(steps_b[0])]
    ys = np.concatenate([r.state, initial_tangent(p)])
    yb = np.concatenate([yb[0, :10], initial_tangent(p)])[None]
    k += 40
    for m in [24] * 10 + [16]:
        r = run_periods(p, ys, m, st, start_period=k, tangent=True)
        out, yb, _, sb = batch.run_periods_batched([p], yb, m, st, start_periods=[k])
        np.testing.assert_array_equal(out[0].section, r.summaries.section)
        np.testing.assert_array_equal(out[0].lyap, r.summaries.lyap)
        ys, k = r.state, k + m
        steps[0] += r.n_steps
        steps[1] += int(sb[0])
    assert k == 1366 and steps == [77541, 77541]
    final = np.array([float.fromhex(v) for v in QUICK_FINAL])
    np.testing.assert_array_equal(ys[:10], final)
    np.testing.assert_array_equal(yb[0, :10], final)


# ------------------------------------------------------------------------------ tangent lanes
@pytest.mark.parametrize("params, n", [
    (ModelParameters(w=1.3, b=0.3), 2),  # impacts: event redos in every lane
    (ModelParameters(w=0.4, b=0.9), 3),
    (ModelParameters(model="1dof", w=1.2, xi=0.05), 1),
    (ModelParameters(w=1.1, var_ratio=0.05), 2),  # the variable-ratio phase per lane
])
def test_tangent_lanes_equal_one_scalar_run_per_column(params, n):
    """The monodromy's columns as SIMD lanes are the scalar RK4 runs of each column, to the bit
    (the same steps, the same event redos), so Newton shooting and the Floquet margin of an
    RK4 cell do not depend on which path computed them."""
    from gearsim.numerics.variational import monodromies

    y = run_periods(params, np.full(10, 0.1), 50, RK4).state[:10]
    Z = np.eye(10)
    y_end, image, status = batch.tangent_lanes_many([params], [y], n, RK4, [Z], [7])[0]
    ref = np.zeros((10, 10))
    for i in range(10):
        r = run_periods(params, np.concatenate([y, Z[:, i]]), n, RK4, start_period=7,
                        tangent=True)  # fmt: skip
        ref[:, i] = r.state[10:] * math.exp(float(np.sum(r.summaries.lyap)))
    assert status == 0
    assert np.array_equal(image, ref) and np.array_equal(y_end, r.state[:10])
    # many cells in one call (from period 0): each cell's result is that of its own call
    other = params.with_(b=params.b * 0.9)
    many = monodromies([params, other], [y, y], n, RK4)
    d = many[0][1].shape[0]
    for p, (_, M, _) in zip((params, other), many, strict=True):
        assert np.array_equal(M, batch.tangent_lanes_many([p], [y], n, RK4, [Z])[0][1][:d, :d])
