"""Tightening the tolerance (DP5) or halving the step (RK4) changes no classification.

The cells sit inside pattern intervals of a fixed reference parameter set (the starting
reconstruction of MODEL.md with stiff bearings, written out here so calibration does not move
them); classification *at* a bifurcation point is ill-posed and is not what this test is about.
Every cell starts from the static state (coexisting attractors make continuation differ).
"""

import pytest
from reference import reference_settings

from gearsim.cell.simulate import simulate_cell
from gearsim.dynamics.parameters import ModelParameters
from gearsim.study.config import Study

REFERENCE_SET = dict(
    Fm=0.1, Fe=0.1724, eps=0.371, xi=0.05, phi_e=-0.7853981633974483, friction=0.0,
    rho_p=0.2, rho_g=0.2, kappa_py=20.0, kappa_pz=20.0, kappa_gy=20.0, kappa_gz=20.0,
    xi_py=0.03, xi_pz=0.03, xi_gy=0.03, xi_gz=0.03,
)

# (w, b, expected label, expected n-p-q) -- covering 1T, 2T, 4T, 8T, chaos, double-sided
CELLS = [
    (0.20, 1.0, "0/1T", "1-0-0"),
    (0.30, 1.0, "0/1T", "1-0-0"),
    (0.45, 1.0, "0/1T", "1-0-0"),
    (0.80, 1.0, "1/1T", "1-1-0"),
    (0.90, 1.0, "1/1T", "1-1-0"),
    (1.05, 1.0, "1/2T", "2-2-0"),
    (1.20, 1.0, "1/2T", "2-1-0"),
    (1.29, 1.0, "1/4T", "4-2-0"),
    (1.30, 1.0, "1/4T", "4-2-0"),
    (1.45, 1.0, "chaos", ""),
    (1.55, 1.0, "chaos", ""),
    (1.60, 1.0, "chaos", ""),
    (1.627, 1.0, "1/8T", "8-6-0"),
    (1.635, 1.0, "1/4T", "4-3-0"),
    (1.70, 1.0, "1/2T", "2-2-0"),
    (2.00, 1.0, "1/1T", "1-1-0"),
    (2.20, 1.0, "1/1T", "1-1-0"),
    (0.70, 0.3, "2/1T", "1-1-1"),
    (1.22, 0.3, "2/2T", "2-1-1"),
    (0.80, 0.15, "2/1T", "1-1-1"),
    (1.10, 0.15, "2/3T", "3-2-2"),
    (1.40, 0.15, "2/2T", "2-1-1"),
    (1.52, 0.15, "2/4T", "4-3-2"),
    (1.40, 1.0, "chaos", ""),
    (1.75, 0.15, "1/2T", "2-2-0"),
    (0.30, 0.15, "0/1T", "1-0-0"),
    (1.00, 0.3, "1/2T", "2-2-0"),
    (1.20, 0.15, "2/2T", "2-2-1"),
    (1.50, 1.0, "chaos", ""),
    (1.10, 0.3, "1/2T", "2-2-0"),
]


def _classify(w, b, settings):
    c = simulate_cell(ModelParameters(w=w, b=b, **REFERENCE_SET), settings=settings).classification
    return c.label, c.label_npq


@pytest.mark.parametrize("w,b,label,npq", CELLS)
def test_dp5_tightened_tolerance_keeps_classification(w, b, label, npq):
    base = reference_settings()
    assert _classify(w, b, base) == (label, npq)
    assert _classify(w, b, base.tightened()) == (label, npq)


@pytest.mark.parametrize("w,b,label,npq", CELLS)
def test_rk4_halved_step_keeps_classification(w, b, label, npq):
    base = reference_settings(method="rk4")
    assert _classify(w, b, base) == (label, npq)
    assert _classify(w, b, base.tightened()) == (label, npq)




def test_recurrence_probe_keeps_every_label_of_the_set():
    """transient_recurrence: every cell of the set from rest, then again continued
    from its own final state (a start on its attractor, where the probe ends the transient):
    the option changes no label, and it does cut the repeats' transients (not vacuous).
    (A chain through the set's cells, e.g. w 1.7 -> 2.0 at b = 1, lands on one of two
    coexisting attractors (1T, 3T) depending on the 1e-7 differences of its start: that
    multistability is not the probe's, docs in benchmarks/CHANGELOG.md (l).)"""
    from gearsim.cell.chains import simulate_rows

    base = Study.load().settings.with_(transient_recurrence=0)
    rows = [[ModelParameters(w=w, b=b, **REFERENCE_SET)] * 2 for w, b, _, _ in CELLS]
    off = simulate_rows(rows, settings=base)
    on = simulate_rows(rows, settings=base.with_(transient_recurrence=24))
    cut = 0
    for (_, _, label, npq), row_off, row_on in zip(CELLS, off, on, strict=True):
        for a, c in zip(row_off, row_on, strict=True):
            assert (c.classification.label, c.classification.label_npq) == (
                a.classification.label, a.classification.label_npq)
        assert (c.classification.label, c.classification.label_npq) == (label, npq)
        cut += row_on[1].periods < row_off[1].periods
    assert cut >= 20
