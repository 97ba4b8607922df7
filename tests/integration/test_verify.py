"""Verified motions: the settle distance, Newton-refined labels and the Floquet margin.

References: geometric sequences with a known limit (the settle estimate), the linear single-DOF
limit (multipliers ``exp((-xi +/- i sqrt(1 - xi^2)) T)``, modulus ``exp(-xi 2 pi / w)``), the
orbit solver of ``gearsim orbit`` (:func:`gearsim.analysis.orbits.find_periodic_orbit`) at its
own tighter tolerance, and long simulations (4 000 periods) of the same cell.
"""

import math

import numpy as np
import pytest

from gearsim.analysis.attractors import FinderOptions, find_attractors, n_real
from gearsim.analysis.orbits import find_periodic_orbit
from gearsim.cell.classify import candidate_periods, settle_estimate
from gearsim.cell.simulate import IntegrationSettings, simulate_cell
from gearsim.cell.verify import BIFURCATION_MARGIN, REFINE_RTOL
from gearsim.dynamics.parameters import ModelParameters


def _sequence(mu, m, c=0.01, period=1, amp=1.0):
    """Section points ``P_k = O_(k mod period) + c mu^k (1, 0.5)`` of a period-``period`` orbit
    with range ``2 amp``."""
    k = np.arange(m)
    orbit_x = amp * np.cos(2 * np.pi * (k % period) / max(period, 1))
    orbit_v = amp * np.sin(2 * np.pi * (k % period) / max(period, 1))
    t = c * np.real(mu ** k.astype(float) if np.isrealobj(mu) else mu**k)
    return orbit_x + t, orbit_v + 0.5 * t


@pytest.mark.parametrize("mu, m", [(0.99, 200), (-0.99, 200), (0.9, 80), (-0.6, 30)])
def test_settle_estimate_reads_the_distance_and_the_multiplier(mu, m):
    x, v = _sequence(mu, m)
    dist, est = settle_estimate(x, v, 1, 2.0, 1.0)
    true = abs(0.01 * mu ** (m - 1)) / 2.0  # x distance of the last point over the range 2
    assert est == pytest.approx(mu, abs=2e-3)
    assert dist == pytest.approx(true, rel=0.05)


def test_settle_estimate_settled_short_and_growing():
    x, v = _sequence(0.5, 200)  # 0.5^200: settled to the noise floor
    assert settle_estimate(x, v, 1, 2.0, 1.0) == (pytest.approx(0.0, abs=1e-9), 0.0)
    x, v = _sequence(0.99, 5)  # too short for a rate
    d, mu = settle_estimate(x, v, 2, 2.0, 1.0)
    assert math.isinf(d) and math.isnan(mu)
    x, v = _sequence(1.01, 100)  # growing differences: not settling
    assert math.isinf(settle_estimate(x, v, 1, 2.0, 1.0)[0])


def test_candidate_periods_prefers_the_smallest_repeat():
    x, v = _sequence(0.95, 120, c=0.02, period=3)
    assert candidate_periods(x, v, 2.0, 1.0, 16)[0] == 3
    rng = np.random.default_rng(1)
    assert len(candidate_periods(rng.random(120), rng.random(120), 1.0, 1.0, 16)) == 1


# ---------------------------------------------------------------- the linear single-DOF limit
def _linear(w, xi):
    """In permanent contact (no impact: the forced amplitude stays below the mean load), no
    stiffness fluctuation: a damped linear oscillator of natural frequency 1."""
    return ModelParameters(model="1dof", w=w, xi=xi, eps=0.0, Fm=0.1, Fe=0.02, b=0.5)


@pytest.mark.parametrize("w", [0.7, 1.6, 2.2])
def test_linear_limit_floquet_margin_is_exp_minus_xi_T(w):
    xi = 0.05
    res = simulate_cell(_linear(w, xi), floquet="all")
    c = res.classification
    assert c.label == "0/1T" and c.refined and c.status == "ok"
    assert c.mu_max == pytest.approx(math.exp(-xi * 2 * math.pi / w), abs=1e-8)
    assert c.critical == "neimark_sacker"  # a complex pair: the damped free oscillation


def test_slow_linear_transient_is_labelled_by_its_orbit():
    """Multiplier modulus 0.995: 406 periods from rest leave 13 % of the transient, the window
    rotates with it (no period, exponent about 0: 'quasi-periodic' by the exponent alone)."""
    w = 1.6
    xi = -math.log(0.995) * w / (2 * math.pi)
    p = _linear(w, xi)
    c = simulate_cell(p).classification
    assert c.motion == "periodic" and c.label == "0/1T" and c.refined
    assert c.status == "ok" and 1.0 - c.mu_max > BIFURCATION_MARGIN
    assert c.mu_max == pytest.approx(0.995, abs=1e-8)
    # starts that stay in contact (the linear regime) all settle onto that one orbit
    ends = []
    for dx, dv in ((0.05, 0.0), (-0.05, 0.02), (0.0, -0.06)):
        y = np.array(simulate_cell(p, samples=24).final_state)
        y[0] += dx
        y[1] += dv
        r = simulate_cell(p, y, transient=150)
        assert r.classification.refined and r.classification.label == "0/1T"
        ends.append(r.poincare[0, :2])
    assert np.max(np.abs(np.array(ends) - ends[0])) < 1e-8


def test_margin_column_of_plane_cells_in_the_linear_limit():
    """The Floquet margin every periodic cell of a plane tile carries (the catalogue's
    ``mu_max``, per motion period ``n``: the margin of the cells' RK4 map, from the batched
    monodromy): ``exp(-xi 2 pi n / w)`` to 1e-8. The RK4 map's error decides the steps: at the
    study's 192 steps per period it is 1.2e-7 here (w = 0.6), at 384 7.7e-9, at 512 (this
    plane's setting) ~2.4e-9."""
    from gearsim.study.tiles import RowSpec, simulate_rows_batched

    st = IntegrationSettings(method="rk4", steps_per_period=512, floquet="margin")
    base = _linear(1.0, 0.05)
    specs = [RowSpec("linear", 0, j, base, st, "w", (0.6, 0.9, 1.3, 1.7, 2.2), "xi", xi)
             for j, xi in enumerate((0.03, 0.08))]
    records = simulate_rows_batched(specs)
    assert len(records) == 10
    for r in records:
        assert r["motion"] == "periodic" and r["status"] == "ok", r
        exact = math.exp(-r["xi"] * 2 * math.pi * r["n"] / r["w"])
        assert r["mu_max"] == pytest.approx(exact, abs=1e-8), (r["w"], r["xi"], r["n"])
        assert r["critical"] == "neimark_sacker"
    assert sum(not r["refined"] for r in records) >= 8  # the margin path, not the refinement


# ---------------------------------------------------------------- the standard (6-DOF) set
def test_one_orbit_next_to_the_doubling_is_one_attractor(standard):
    """w = 1.003, b = 0.9: the 1T orbit has |mu|max 0.989 (doubling at 1.0055); 150 periods
    leave ~19 % of a start's distance. All 16 starts are one attractor, its margin that of
    ``gearsim orbit``."""
    p = standard.with_(w=1.003, b=0.9)
    st = IntegrationSettings(method="rk4", steps_per_period=192)
    ca = find_attractors(p, FinderOptions(starts=16), settings=st)
    assert n_real(ca) == 1
    a = ca.attractors[0]
    assert a.label == "1/1T" and a.steady.info["refined"]
    orbit = find_periodic_orbit(p, 1, a.steady.final_state)
    assert a.steady.info["mu_max"] == pytest.approx(orbit.mu_max, abs=1e-6)
    assert a.steady.info["critical"] == "period_doubling"


def test_margin_of_plane_cells_equals_gearsim_orbit(standard):
    """Every periodic cell of two plane rows (w from 1.0 to 2.4, the study's settings, the
    batched driver and its margins) against ``gearsim orbit`` (DP5 at 1e-12, Newton from the
    cell's last state) on a sample: 1e-6. Below w = 1 the RK4 map at 192 steps per period
    differs from the flow by more (docs/decisions.md, "Floquet margin of every cell")."""
    from gearsim.cell.chains import simulate_rows
    from gearsim.cell.verify import fill_margins
    from gearsim.study.config import Study

    st = Study.load().settings.with_(floquet="margin")
    ws = np.linspace(1.0, 2.4, 36)
    rows = [[standard.with_(w=float(w), b=b) for w in ws] for b in (0.3, 0.7)]
    res = [r for row in simulate_rows(rows, settings=st) for r in row]
    fill_margins(res, st)
    periodic = [r for r in res if r.classification.n > 0 and r.classification.status == "ok"]
    assert all(np.isfinite(r.classification.mu_max) for r in periodic)
    sample = [r for r in periodic if not r.classification.refined and r.classification.n <= 2]
    assert len(sample) >= 20
    for r in sample[::2]:
        orbit = find_periodic_orbit(r.params, r.classification.n, r.final_state, grazing=False)
        assert r.classification.mu_max == pytest.approx(orbit.mu_max, abs=1e-6), r.params.w


@pytest.fixture(scope="module")
def standard():
    from gearsim.study.config import Study

    return Study.load().parameters().model


def test_refine_threshold_is_below_the_merge_tolerance():
    assert REFINE_RTOL <= 0.1 * 1e-3


# ---------------------------------------------------------------- next to bifurcations
#: cells next to period doublings, folds and grazings of both default planes, the xi = 0.15
#: sweep and the hysteresis sweep: where the study's budget left slow transients
#: (benchmarks/bench_refine.py rows; docs/decisions.md "Verified motions")
NEAR_BIFURCATIONS = [
    # (w, b, xi): None keeps the standard value
    (1.237, None, 0.04615), (1.243, None, 0.04615), (1.327, None, 0.04615),
    (1.615, None, 0.04615), (0.973, None, 0.04615), (1.393, None, 0.07615),
    (1.399, None, 0.07615), (1.525, None, 0.07615), (1.111, None, 0.10615),
    (1.117, None, 0.10615), (1.675, None, 0.10615), (1.255, None, 0.13615),
    (1.579, None, 0.13615), (1.009, 0.37625, None), (1.003, 0.9, None), (1.75, 0.55, None),
    (1.29, 0.55, None), (0.95, 0.15, None), (1.31, 0.35, None), (1.34, None, 0.15),
    (1.342, None, 0.15), (1.466, None, 0.15), (1.47, None, 0.15), (0.55, None, None),
    (0.6, None, None), (0.65, None, None),
]


def test_labels_next_to_bifurcations_agree_with_long_simulations(standard, monkeypatch):
    """The study's budget (150 + 256 periods) with refinement against 12 000 transient periods
    from the same start: no cell is quasi-periodic where the long run settles on a period, and
    a periodic label is the long run's (cells at a bifurcation excepted: there the two sides
    are one grid step apart and both labels are readings of the same critical orbit)."""
    from gearsim.cell.chains import simulate_cells
    from gearsim.study.config import Study

    st = Study.load().settings
    cells = []
    for w, b, xi in NEAR_BIFURCATIONS:
        ch = {"w": w} | ({"b": b} if b is not None else {}) | ({"xi": xi} if xi else {})
        cells.append(standard.with_(**ch))
    short = simulate_cells(cells, settings=st)
    # the reference: the plain long simulation, no refinement. 12 000 periods: at w = 1.47,
    # xi = 0.15 the 1T orbit has |mu|max 0.99876 (e-folding 800 periods); after 4 000 the
    # decaying alternation still reads as 2-2-0, after 12 000 it is 1-1-0, the refined label
    import gearsim.cell.verify as verify

    monkeypatch.setattr(verify, "needs_refinement", lambda cls, floquet="slow": False)
    long = simulate_cells(cells, settings=st.with_(transient=12000))
    refined, compared, bad, lines = 0, 0, [], []
    for p, s, g in zip(cells, short, long, strict=True):
        a, r = s.classification, g.classification
        where = (f"w={p.w} b={p.b} xi={p.xi}: {a.label} {a.label_npq} {a.status} "
                 f"refined={a.refined} mu={a.mu_max:.5f} vs {r.label} {r.label_npq} {r.status}")
        lines.append(where)
        refined += bool(a.refined)
        if r.motion == "periodic" and a.motion == "quasi-periodic":
            bad.append(where)
        # a claim is a settled label: not_converged says there is none, bifurcation that the
        # cell sits on the critical orbit (both sides are readings of it)
        if a.status != "ok" or r.status != "ok":
            continue
        if r.motion == "periodic" and a.motion == "periodic":
            compared += 1
            if (a.n, a.p, a.q) != (r.n, r.p, r.q) or abs(a.dc - r.dc) > 2e-3:
                bad.append(where)
    print("\n".join(lines))
    assert not bad, "\n".join(bad)
    assert refined >= len(cells) // 3  # the set does exercise the refinement
    assert compared >= 20
    # the Floquet margin of a refined cell is gearsim orbit's (DP5 at 1e-12) to 1e-6 for
    # periods 1 and 2; a longer orbit carries the RK4 map's error over its n periods (measured:
    # 4T 1.6e-6, 16T 4.4e-5 at 384 steps per period), checked to 1e-4
    checked = 0
    for p, s in zip(cells, short, strict=True):
        a = s.classification
        if a.refined:
            orbit = find_periodic_orbit(p, a.n, s.poincare[0], grazing=False)
            tol = 1e-6 if a.n <= 2 else 1e-4
            assert a.mu_max == pytest.approx(orbit.mu_max, abs=tol), (p.w, p.b, p.xi)
            checked += a.n <= 2
    assert checked >= 10


def test_floquet_margin_map_draws_margins_bifurcations_and_the_rest():
    import matplotlib

    matplotlib.use("Agg")
    import pandas as pd

    from gearsim.presentation.figures.multistability import figure_floquet_margin

    xs, ys = np.linspace(0.5, 2.0, 4), np.array([0.05, 0.1])
    rows = []
    kinds = {(0, 0): ("periodic", "ok", 0.9), (1, 0): ("periodic", "bifurcation", 0.9995),
             (2, 0): ("periodic", "ok", np.nan), (3, 0): ("chaos", "ok", np.nan)}
    for j, y in enumerate(ys):
        for i, x in enumerate(xs):
            motion, status, mu = kinds.get((i, j), ("periodic", "ok", 0.5))
            rows.append({"x": x, "y": y, "motion": motion, "status": status, "mu_max": mu})
    fig = figure_floquet_margin(pd.DataFrame(rows), "w", "xi")
    ax = fig.axes[0]
    under, margin = (np.ma.filled(m.get_array(), np.nan).reshape(2, 4) for m in ax.collections)
    assert margin[0, 0] == pytest.approx(0.1) and margin[1, 2] == pytest.approx(0.5)
    assert np.isnan(margin[0, 1]) and under[0, 1] == 2  # bifurcation: black
    assert under[0, 2] == 1 and under[0, 3] == 0  # settled fast (grey), no orbit (white)


def test_closed_curve_test_tells_a_torus_section_from_a_cloud():
    from gearsim.cell.verify import on_closed_curve

    k = np.arange(200)
    theta = 2 * np.pi * k * (math.sqrt(5) - 1) / 2  # an irrational rotation: a torus section
    curve = np.column_stack([0.3 * np.cos(theta) + 0.05 * np.cos(3 * theta),
                             2.0 * np.sin(theta)])  # fmt: skip
    assert on_closed_curve(curve, 0.7, 4.0)
    cloud = np.random.default_rng(3).random((200, 2)) * np.array([0.7, 4.0])
    assert not on_closed_curve(cloud, 0.7, 4.0)
    assert not on_closed_curve(curve[:10], 0.7, 4.0)  # too few points to tell


def test_sweep_passage_next_to_a_saddle_is_labelled_by_where_it_goes(standard, monkeypatch):
    """The xi = 0.15 sweep (forward continuation, the study's settings) just past the 1T orbit's
    period doubling: the continued trajectory lingers next to that orbit, now a saddle
    (multiplier -1.003 to -1.004), and the budget's window read 'quasi-periodic' (w = 1.338,
    1.34) or an unsettled 2T. Followed along the saddle's unstable direction, each cell
    reaches the stable 2T orbit, as the reference does: 4 000 transient periods from the same
    start (the cell's continuation state), no refinement."""
    import gearsim.cell.verify as verify
    from gearsim.cell.chains import simulate_rows
    from gearsim.study.config import Study

    st = Study.load().settings
    ws = np.round(np.arange(1.300, 1.3405, 0.002), 3)
    cells = [standard.with_(xi=0.15, w=float(w)) for w in ws]
    left = [verify.follow_motion]
    calls = []

    def spy(*a, **kw):
        out = left[0](*a, **kw)
        calls.append(out is not None)
        return out

    monkeypatch.setattr(verify, "follow_motion", spy)
    again = simulate_rows([cells], settings=st)[0]
    monkeypatch.undo()
    verify.fill_margins(again, st)  # what a sweep or tile does after the chains
    starts = {float(w): (r.final_state, r.final_period) for w, r in zip(ws[1:], again[:-1],
                                                                          strict=True)}
    near = [k for k, w in enumerate(ws) if 1.334 <= w <= 1.340]
    assert any(calls)
    # a followed cell's points and Floquet margin are those of the orbit it reached:
    # gearsim orbit's (DP5 at 1e-12) to the RK4 map's error at w > 1 (decisions.md)
    for k in near:
        a, pts = again[k].classification, again[k].poincare
        assert len(pts) == a.n
        orbit = find_periodic_orbit(cells[k], a.n, pts[0], grazing=False)
        assert a.mu_max == pytest.approx(orbit.mu_max, abs=1e-5), (ws[k], a.mu_max)
    monkeypatch.setattr(verify, "needs_refinement", lambda cls, floquet="slow": False)
    for k in near:
        a = again[k].classification
        assert a.motion == "periodic" and a.status == "ok", (ws[k], a.label, a.status)
        y, k0 = starts[float(ws[k])]
        ref = simulate_cell(cells[k], y, settings=st, transient=4000, start_period=k0)
        r = ref.classification
        assert (a.n, a.p, a.q) == (r.n, r.p, r.q) and a.label == r.label == "1/2T", ws[k]
        assert abs(a.dc - r.dc) < 2e-3


def test_sweep_window_without_period_or_orbit_is_followed(standard, monkeypatch):
    """xi = 0.15, w = 0.696 (forward continuation from w = 0.6): the budget's window has no
    period, no chaos (exponent -0.001) and Newton finds no orbit from it (it stalls); the
    window is a passage, and 4 000 periods on it is the reference's 1/1T."""
    import gearsim.cell.verify as verify
    from gearsim.cell.chains import simulate_rows
    from gearsim.study.config import Study

    st = Study.load().settings
    ws = np.linspace(0.1, 2.5, 1201)
    ws = ws[(ws > 0.6) & (ws < 0.697)]
    cells = [standard.with_(xi=0.15, w=float(w)) for w in ws]
    res = simulate_rows([cells], settings=st)[0]
    a = res[-1].classification
    assert abs(ws[-1] - 0.696) < 1e-9
    assert a.motion == "periodic" and a.status == "ok" and a.label == "1/1T"
    monkeypatch.setattr(verify, "needs_refinement", lambda cls, floquet="slow": False)
    short = simulate_cell(cells[-1], res[-2].final_state, settings=st,
                          start_period=res[-2].final_period).classification  # fmt: skip
    assert short.motion != "periodic"  # the budget alone does not settle it
    ref = simulate_cell(cells[-1], res[-2].final_state, settings=st, transient=4000,
                        start_period=res[-2].final_period).classification  # fmt: skip
    assert (a.n, a.p, a.q, a.label) == (ref.n, ref.p, ref.q, ref.label)
    assert abs(a.dc - ref.dc) < 2e-3
