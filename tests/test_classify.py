"""The classifier on constructed per-period records with known n, p, q, DC."""

import math

import numpy as np
import pytest

from gearsim.classify import PeriodSummaries, classify_motion, estimate_period, impact_state


def _summaries(section_x, nface, nback, tdis, lyap=None, fmax=None, xv=None):
    m = len(section_x)
    sec = np.zeros((m, 10))
    sec[:, 0] = section_x
    sec[:, 1] = xv if xv is not None else 0.0
    return PeriodSummaries(
        section=sec,
        nface=np.asarray(nface, dtype=np.int64),
        nback=np.asarray(nback, dtype=np.int64),
        tdis=np.asarray(tdis, dtype=float),
        fmax=np.full(m, 2.0) if fmax is None else np.asarray(fmax, float),
        fmin=np.full(m, -0.1),
        xmax=np.full(m, 1.5),
        xmin=np.full(m, -0.5),
        lyap=np.full(m, -0.1) if lyap is None else np.asarray(lyap, float),
    )


def _periodic_signal(n, m, rng):
    base = rng.uniform(-1, 1, n)
    return np.array([base[k % n] for k in range(m)])


@pytest.mark.parametrize("n", [1, 2, 3, 4, 8, 16, 24, 64])
def test_estimate_period_finds_known_period(n):
    rng = np.random.default_rng(n)
    m = 3 * n + 40
    x = _periodic_signal(n, m, rng) + rng.normal(0, 1e-8, m)  # noise far below tolerance
    v = _periodic_signal(n, m, np.random.default_rng(n + 100))
    assert estimate_period(x, v, scale=2.0, w=1.0, n_max=64) == n


def test_estimate_period_rejects_aperiodic_and_too_long():
    rng = np.random.default_rng(0)
    x = rng.uniform(-1, 1, 300)  # aperiodic
    assert estimate_period(x, x, scale=2.0, w=1.0) == 0
    x80 = _periodic_signal(80, 300, rng)  # period beyond n_max
    assert estimate_period(x80, x80, scale=2.0, w=1.0, n_max=64) == 0


def test_tolerance_is_scale_aware():
    """The same relative perturbation classifies the same at any scale."""
    rng = np.random.default_rng(3)
    base = _periodic_signal(2, 80, rng) + rng.normal(0, 1e-7, 80)
    for scale in (1e-4, 1.0, 1e3):
        assert estimate_period(base * scale, base * scale, scale=2 * scale, w=1.0) == 2
    noisy = _periodic_signal(2, 80, rng) + rng.normal(0, 1e-3, 80)
    assert estimate_period(noisy, noisy, scale=2.0, w=1.0) == 0


def test_classify_period_two_double_sided():
    """A hand-built 2-2-1 motion: n = 2, p = 2, q = 1, I = 2, DC from the disengaged time."""
    w = 1.0
    T = 2 * math.pi / w
    m = 40
    x = np.tile([0.4, 0.9], m // 2)
    nface = np.tile([1, 1], m // 2)
    nback = np.tile([1, 0], m // 2)
    tdis = np.tile([0.3 * T, 0.1 * T], m // 2)
    s = _summaries(x, nface, nback, tdis)
    c = classify_motion(s, w=w, b=0.15, eps=0.2, xi=0.05, Fm=0.1, Fe=0.2, n=2)
    assert (c.n, c.p, c.q, c.I) == (2, 2, 1, 2)
    assert c.label == "2/2T" and c.label_npq == "2-2-1"
    assert c.dc == pytest.approx(0.2)
    assert c.kmax_peak_mean == pytest.approx(2.0 / 0.1)
    assert c.kmax_peak_static == pytest.approx(2.0 / (0.1 + 0.2))
    # section force: (1 + eps) f(x, b) + 2 xi x' at x = 0.9, x' = 0
    assert c.kmax_section_mean == pytest.approx(1.2 * (0.9 - 0.15) / 0.1)
    assert c.lyapunov == pytest.approx(-0.1 / T)
    assert c.motion == "periodic" and c.converged


def test_classify_no_impact_and_chaos_and_quasiperiodic():
    w = 2.0
    T = 2 * math.pi / w
    s0 = _summaries(np.full(20, 1.1), np.zeros(20), np.zeros(20), np.zeros(20))
    c0 = classify_motion(s0, w=w, b=1.0, eps=0.2, xi=0.05, Fm=0.1, Fe=0.2, n=1)
    assert (c0.label, c0.label_npq, c0.I, c0.dc) == ("0/1T", "1-0-0", 0, 0.0)
    rng = np.random.default_rng(1)
    x = rng.uniform(0, 1, 64)
    chaos = _summaries(x, np.ones(64), np.zeros(64), np.full(64, 0.5 * T), lyap=np.full(64, 0.3))
    cc = classify_motion(chaos, w=w, b=1.0, eps=0.2, xi=0.05, Fm=0.1, Fe=0.2, n=0)
    assert cc.motion == "chaos" and cc.label == "chaos" and cc.I == 1 and cc.p is None
    assert cc.lyapunov == pytest.approx(0.3 / T)
    quasi = _summaries(x, np.ones(64), np.zeros(64), np.zeros(64), lyap=np.full(64, 1e-4))
    cq = classify_motion(quasi, w=w, b=1.0, eps=0.2, xi=0.05, Fm=0.1, Fe=0.2, n=0)
    assert cq.motion == "quasi-periodic"
    slow = _summaries(x, np.ones(64), np.zeros(64), np.zeros(64), lyap=np.full(64, -0.5))
    cs = classify_motion(slow, w=w, b=1.0, eps=0.2, xi=0.05, Fm=0.1, Fe=0.2, n=0)
    assert cs.motion == "unsettled" and cs.status == "not_converged" and not cs.converged


@pytest.mark.parametrize(
    "face,back,dis,total,expected",
    [(0, 0, 0.0, 1.0, 0), (2, 0, 0.3, 1.0, 1), (0, 1, 0.2, 1.0, -1), (3, 1, 0.4, 1.0, 2),
     (0, 0, 1.0, 1.0, -2)],
)
def test_impact_state(face, back, dis, total, expected):
    assert impact_state(face, back, dis, total) == expected


def test_counts_come_from_the_last_motion_period():
    """p and q are counted over exactly one motion period (here n = 4: 4-3-0)."""
    m = 48
    x = np.tile([0.1, 0.2, 0.3, 0.4], m // 4)
    nface = np.tile([1, 1, 0, 1], m // 4)
    s = _summaries(x, nface, np.zeros(m), np.full(m, 1.0))
    c = classify_motion(s, w=1.0, b=0.05, eps=0.2, xi=0.05, Fm=0.1, Fe=0.2, n=4)
    assert c.label_npq == "4-3-0" and c.label == "1/4T"


def test_decaying_alternation_is_not_period_two():
    """Next to a period doubling: x_k = x* + A mu^k with mu = -0.995 repeats after 2 samples to
    within the tolerance but its spread decays -- not a period-2 motion (yet)."""
    k = np.arange(60)
    x = 1.0 + 2e-3 * (-0.995) ** k
    v = np.zeros(60)
    assert estimate_period(x, v, scale=1.0, w=1.0, period_rtol=1e-4) == 0
    # a true period-2 orbit with the same spread is accepted
    x2 = 1.0 + 2e-3 * (-1.0) ** k
    assert estimate_period(x2, v, scale=1.0, w=1.0, period_rtol=1e-4) == 2
