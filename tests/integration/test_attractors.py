"""Coexisting attractors: the finder against independent references.

- A hardening Duffing oscillator ``x'' + 2 zeta x' + x + gamma x^3 = F cos(W t)``, integrated with
  scipy (DOP853), drives the model-agnostic engine: inside the resonance band harmonic balance
  gives two stable branches, outside it one; amplitudes within 1 %.
- Gear cells: early labelling by recurrence gives exactly the basin fractions (and the attractor
  of every start) of full-length runs of every start; a chaotic attractor is counted once.
"""

import numpy as np
import pytest
from attractor_checks import assert_same_attractors_per_start
from reference import reference_settings
from scipy.integrate import solve_ivp

from gearsim.analysis.attractors import (
    FinderOptions,
    Steady,
    find_attractors,
    same_attractor,
    sobol_unit,
)
from gearsim.analysis.attractors.recurrence import map_attractors
from gearsim.dynamics.parameters import ModelParameters, ParameterError

ZETA, GAMMA, FORCE = 0.02, 0.1, 0.1


def harmonic_balance(W: float) -> np.ndarray:
    """Amplitudes ``A`` of ``x ~ A cos(W t - phi)``: ``A^2 [(1 - W^2 + 3/4 g A^2)^2 + (2 z W)^2]
    = F^2`` (all real positive roots, increasing; the middle one of three is unstable)."""
    a, d = 0.75 * GAMMA, 1.0 - W * W
    r = np.roots([a * a, 2 * d * a, d * d + (2 * ZETA * W) ** 2, -FORCE**2])
    r = np.sort(r[np.abs(r.imag) < 1e-9].real)
    return np.sqrt(r[r > 0])


class Duffing:
    """The Duffing oscillator as a system of the engine; one cell per forcing frequency."""

    transient = 200
    transient_continuation = 200

    def __init__(self, freqs):
        self.freqs = list(freqs)

    def start_states(self, cell, unit):
        return np.column_stack([(2 * unit[:, 0] - 1) * 4.0, (2 * unit[:, 1] - 1) * 4.0])

    def _integrate(self, W, states, n, dense=False):
        k = len(states)
        T = 2 * np.pi / W

        def f(t, y):
            x, v = y[:k], y[k:]
            return np.concatenate([v, -2 * ZETA * v - x - GAMMA * x**3 + FORCE * np.cos(W * t)])

        y0 = np.concatenate([states[:, 0], states[:, 1]])
        t_eval = np.linspace(0, n * T, 64 * n + 1) if dense else T * np.arange(1, n + 1)
        s = solve_ivp(f, (0, n * T), y0, method="DOP853", rtol=1e-10, atol=1e-12, t_eval=t_eval)
        return s.t, np.stack([s.y[:k], s.y[k:]], axis=-1)  # (k, m, 2)

    def advance(self, cells, states, n, start_periods):
        secs = np.zeros((len(cells), n, 2))
        for c in np.unique(cells):
            rows = np.nonzero(cells == c)[0]
            _, secs[rows] = self._integrate(self.freqs[c], np.asarray(states)[rows], n)
        return secs, secs[:, -1].copy(), np.zeros(len(cells), dtype=bool)

    def steady(self, cells, states, transient, start_periods):
        out = [None] * len(cells)
        states = np.asarray(states, dtype=float)
        if transient > 0:
            _, states = self.advance(cells, states, transient, start_periods)[:2]
        secs, _, _ = self.advance(cells, states, 24, start_periods)
        for r, c in enumerate(cells):
            W = self.freqs[c]
            t, tr = self._integrate(W, secs[r, -1:], 1, dense=True)
            x = tr[0, :-1, 0]
            th = W * t[:-1]
            amp = float(np.hypot(2 * np.mean(x * np.cos(th)), 2 * np.mean(x * np.sin(th))))
            scale = float(x.max() - x.min())
            s = secs[r]
            n = next(
                (n for n in range(1, 9) if np.all(np.abs(s[n:] - s[:-n]) <= 1e-6 * scale)), 0
            )
            pts = s[-n:] if n else s
            out[r] = Steady("ok", n, pts, scale, scale * W, f"P{n}", {"amplitude": amp})
        return out


@pytest.mark.parametrize("W", [1.12, 1.13])
def test_duffing_bistable_band_two_attractors_harmonic_balance(W):
    hb = harmonic_balance(W)
    assert len(hb) == 3  # inside the band
    sys_ = Duffing([W])
    (ca,) = map_attractors(sys_, [sys_.start_states(0, sobol_unit(16, 5))])
    assert len(ca.attractors) == 2
    amps = sorted(a.steady.info["amplitude"] for a in ca.attractors)
    assert all(a.steady.period == 1 for a in ca.attractors)
    assert amps[0] == pytest.approx(hb[0], rel=0.01)
    assert amps[1] == pytest.approx(hb[2], rel=0.01)
    assert sum(a.basin_fraction for a in ca.attractors) == pytest.approx(1.0)
    assert ca.early.sum() > 0  # recurrence labelled some starts


@pytest.mark.parametrize("W", [0.9, 1.3])
def test_duffing_monostable_band_one_attractor(W):
    hb = harmonic_balance(W)
    assert len(hb) == 1
    sys_ = Duffing([W])
    (ca,) = map_attractors(sys_, [sys_.start_states(0, sobol_unit(8, 5))])
    assert len(ca.attractors) == 1
    assert ca.attractors[0].basin_fraction == 1.0
    assert ca.attractors[0].steady.info["amplitude"] == pytest.approx(hb[0], rel=0.01)


def test_duffing_early_equals_full_length():
    sys_ = Duffing([1.12])
    st = [sys_.start_states(0, sobol_unit(6, 2))]
    fast = map_attractors(sys_, st)
    full = map_attractors(sys_, st, FinderOptions(early=False))
    for a, b in zip(fast, full, strict=True):
        assert [x.basin_fraction for x in a.attractors] == [x.basin_fraction for x in b.attractors]
        assert np.array_equal(a.start_labels, b.start_labels)


def _steady(n, pts, scale=1.0):
    pts = np.asarray(pts, dtype=float)
    return Steady("ok", n, pts, scale, scale, f"P{n}")


def test_same_attractor_cyclic_shift_and_tolerance():
    a = _steady(3, [[0.0, 0.0], [1.0, 0.5], [0.5, -0.5]])
    shifted = _steady(3, [[1.0, 0.5], [0.5, -0.5], [0.0, 0.0]])
    assert same_attractor(a, shifted)
    near = _steady(3, [[1.0 + 5e-4, 0.5], [0.5, -0.5], [0.0, 0.0]])
    assert same_attractor(a, near)
    far = _steady(3, [[1.0 + 5e-3, 0.5], [0.5, -0.5], [0.0, 0.0]])
    assert not same_attractor(a, far)
    assert not same_attractor(a, _steady(6, np.vstack([a.points, a.points])))
    rng = np.random.default_rng(0)
    ring = rng.uniform(0, 2 * np.pi, (2, 200))
    c1 = _steady(0, np.column_stack([np.cos(ring[0]), np.sin(ring[0])]))
    c2 = _steady(0, np.column_stack([np.cos(ring[1]), np.sin(ring[1])]))
    c3 = _steady(0, np.column_stack([np.cos(ring[1]) + 3, np.sin(ring[1])]))
    assert same_attractor(c1, c2)
    assert not same_attractor(c1, c3)


def test_readings_of_one_orbit_merge():
    """A refined 1/2T orbit and the bifurcation-status window reading of the same orbit (its
    points a few 1e-3 of the range off, DC within 1e-3) are one attractor; a different n-p-q,
    DC or orbit is not; the basin of the merged attractor counts both starts."""
    from gearsim.analysis.attractors.matching import KnownAttractors

    orbit = [[0.08371, -0.18005], [-0.10163, -0.23235]]
    info = {"label_npq": "2-1-1", "dc": 0.4683, "status": "ok", "refined": True}
    ok = Steady("ok", 2, np.array(orbit), 0.5, 0.5, "1/2T", dict(info))
    off = np.array(orbit) + [[2e-3, -1e-3], [-1.5e-3, 2e-3]]  # up to 4e-3 of the range 0.5
    bif = Steady("ok", 2, off, 0.5, 0.5, "1/2T",
                 {**info, "dc": 0.4689, "status": "bifurcation", "refined": False})
    assert same_attractor(ok, bif) and same_attractor(bif, ok)
    other_npq = Steady("ok", 2, off, 0.5, 0.5, "1/2T", {**bif.info, "label_npq": "2-2-1"})
    other_dc = Steady("ok", 2, off, 0.5, 0.5, "1/2T", {**bif.info, "dc": 0.4710})
    other_orbit = Steady("ok", 2, np.array(orbit) + 0.1, 0.5, 0.5, "1/2T", dict(bif.info))
    for s in (other_npq, other_dc, other_orbit):
        assert not same_attractor(ok, s)
    kn = KnownAttractors(FinderOptions())
    assert kn.add(ok) == kn.add(bif) == 0 and kn.add(other_orbit) == 1


GEAR = reference_settings(method="rk4")
REFERENCE = dict(
    Fm=0.1, Fe=0.1724, eps=0.371, xi=0.05, phi_e=-0.7853981633974483, friction=0.0,
)  # the fixed reference set of tests/integration/test_convergence.py (calibration does not move it)


def test_gear_early_labelling_equals_full_length_runs():
    cells = [
        ModelParameters(w=1.1, b=0.15, **REFERENCE),
        ModelParameters(w=0.82, b=0.15, **REFERENCE),
        ModelParameters(w=1.5, b=1.0, **REFERENCE),
        ModelParameters(w=0.66, b=1.0, **REFERENCE),
        ModelParameters(w=1.95, b=0.3, **REFERENCE),
    ]
    opts = FinderOptions(starts=24, seed=7)
    fast = find_attractors(cells, opts, settings=GEAR)
    full = find_attractors(cells, opts.with_(early=False), settings=GEAR)
    n_early = assert_same_attractors_per_start(fast, full)
    assert n_early >= 0.5 * 24 * len(cells)
    assert any(len(a.attractors) >= 2 for a in fast)


def test_gear_chaotic_attractor_counted_once():
    ca = find_attractors(ModelParameters(w=1.45, b=1.0, **REFERENCE),
                         FinderOptions(starts=32, seed=3), settings=GEAR)  # fmt: skip
    chaos = [a for a in ca.attractors if a.label == "chaos"]
    assert len(chaos) == 1
    assert chaos[0].n_starts >= 8  # many starts landed on it, one attractor
    assert chaos[0].steady.info["lyapunov"] > 0.005
    assert sum(a.n_starts for a in ca.attractors) + int(np.sum(ca.start_labels < 0)) == 32


def test_gear_continuation_states_found_by():
    from gearsim.cell.simulate import simulate_cell

    p = ModelParameters(w=1.1, b=0.15, **REFERENCE)
    fwd = simulate_cell(p.with_(w=1.09), settings=GEAR).final_state
    ca = find_attractors(p, FinderOptions(starts=8, seed=1), settings=GEAR, forward=fwd)
    assert "forward" in ca.continuation
    k = ca.continuation["forward"]
    assert "forward" in ca.attractors[k].found_by
    assert sum(a.basin_fraction for a in ca.attractors) + ca.diverged_fraction == pytest.approx(1)


def test_bad_settings_rejected():
    with pytest.raises(ParameterError, match="starts"):
        sobol_unit(0, 1)
    with pytest.raises(ParameterError, match="chunk"):
        map_attractors(Duffing([1.0]), [np.zeros((1, 2))], FinderOptions(chunk=0))


def test_forward_backward_sweeps_differ_only_inside_fold_band():
    """The standard set's softening fold: the increasing-w sweep jumps up, the decreasing-w
    sweep jumps down at a lower w, and the two sweeps differ exactly between the jumps."""
    from pathlib import Path

    from gearsim.analysis.hysteresis import hysteresis
    from gearsim.study.config_io import load_standard_parameters
    from gearsim.study.sweeps import sweep_frame

    root = Path(__file__).resolve().parents[2]
    base = ModelParameters.from_mapping(
        load_standard_parameters(root / "config/standard_parameters.yaml")
    )
    vals = np.round(np.arange(0.40, 0.9001, 0.01), 10)
    st = reference_settings(method="rk4", transient=150, transient_continuation=40)
    df = sweep_frame(base, "w", vals, "both", st)
    assert list(df["direction"].unique()) == ["forward", "backward"]
    h = hysteresis(df)
    lo, hi = h.band
    assert 0.45 < lo < hi < 0.85 and hi - lo >= 0.03
    assert h.jump_forward == hi and h.jump_backward == lo  # softening: jump up at the upper end
    assert h.dc_forward[1] > h.dc_forward[0] + 0.15  # DC jumps up going forward
    assert h.dc_backward[1] < h.dc_backward[0] - 0.15  # and down going backward
    inside = [float(v) for v in vals if lo < v < hi]
    assert len(inside) >= 3
    assert h.differ == pytest.approx(inside)
    assert any("hysteresis band" in line for line in h.lines())


def _synthetic_sweeps():
    """Hand-built fold: forward stays on the DC = 0 branch up to w = 0.67, backward on the
    DC ~ 0.6 branch down to w = 0.58 (so the band is 0.575 ... 0.675 between the midpoints)."""
    import pandas as pd

    ws = np.round(np.arange(0.50, 0.751, 0.01), 10)
    rows = []
    for d, order in (("forward", ws), ("backward", ws[::-1])):
        for w in order:
            upper = w >= 0.68 if d == "forward" else w >= 0.58
            rows.append({"parameter": "w", "value": float(w), "direction": d,
                         "label": "1/1T" if upper else "0/1T",
                         "label_npq": "1-1-0" if upper else "1-0-0", "I": 1 if upper else 0,
                         "n": 1, "p": 1 if upper else 0, "q": 0, "motion": "periodic",
                         "dc": 0.6 if upper else 0.0, "kmax": 1.0,
                         "poincare_x": [1.0 if upper else 0.3], "poincare_v": [0.0]})
    return pd.DataFrame(rows)


def test_hysteresis_of_a_hand_built_fold_and_its_figure(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    from gearsim.analysis.hysteresis import hysteresis
    from gearsim.presentation.figures.multistability import figure_hysteresis
    from gearsim.presentation.figures.registry import figures

    h = hysteresis(_synthetic_sweeps())
    assert h.jump_forward == pytest.approx(0.675) and h.jump_backward == pytest.approx(0.575)
    assert h.band == pytest.approx((0.575, 0.675))
    assert h.differ == pytest.approx([0.58, 0.59, 0.60, 0.61, 0.62, 0.63, 0.64, 0.65, 0.66,
                                      0.67])  # fmt: skip
    fig, _ = figure_hysteresis(_synthetic_sweeps())
    fig.savefig(tmp_path / "h.png")
    assert {18, 19, 20} <= set(figures())
    with pytest.raises(ParameterError, match="backward"):
        hysteresis(_synthetic_sweeps().query("direction == 'forward'"))


def test_probing_without_tangent_gives_the_same_states_bit_for_bit():
    """The attractor probes run without the tangent vector: the event layer decides
    on the state only, so section points, contact counts and final states are identical."""
    from gearsim.cell.simulate import initial_tangent
    from gearsim.dynamics.model import static_state
    from gearsim.numerics.batch import run_periods_batched

    cells = [ModelParameters(w=w, b=b) for w, b in ((0.6, 0.15), (1.02, 0.15), (1.37, 0.15),
                                                     (1.53, 0.15), (1.1, 0.0), (2.0, 1.0))]
    cells += [ModelParameters(w=0.9, b=0.2, b_py=0.05, b_gz=0.05, friction=0.02)]
    st = reference_settings(method="rk4")
    y = np.array([np.concatenate([static_state(p.to_array()), initial_tangent(p)])
                  for p in cells])  # fmt: skip
    a = run_periods_batched(cells, y, 30, st, tangent=True)
    b = run_periods_batched(cells, y, 30, st, tangent=False)
    for sa, sb in zip(a[0], b[0], strict=True):
        for name in ("section", "nface", "nback", "tdis", "fmax", "fmin", "xmax", "xmin"):
            assert np.array_equal(getattr(sa, name), getattr(sb, name)), name
    assert np.array_equal(a[1][:, :10], b[1][:, :10])
    assert np.array_equal(a[2], b[2]) and np.array_equal(a[3], b[3])
