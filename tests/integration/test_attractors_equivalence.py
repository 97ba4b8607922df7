"""The lane-pool finder against the reference finder on a 40 x 40 (w, b) plane.

Both get the same 16 Sobol starts per cell and long transients (400 periods from a start, 200
from the continuation state), so that both read settled motions; the pool takes each cell's
forward motion from its continuation row (as the pipeline does), the reference re-runs the
forward state (as it always did).

Criterion (the sampling error of 16 starts): a basin fraction estimated from 16 starts has
standard error sqrt(p (1 - p) / 16) <= 0.125. Per cell, every attractor with basin fraction
>= 2/16 in one finder is found by the other with the same label, and the two fractions differ
by at most 2 standard errors of their mean (plus one start); over the plane, the shares of
multistable cells and the mean number of attractors per cell agree within 0.02 and 0.05.
"""

import math

import numpy as np
import pytest
from attractor_checks import reference_attractors

from gearsim.analysis.attractors import FinderOptions, find_attractors, gear_steady
from gearsim.cell import chains
from gearsim.study.config import Study

N = 40


@pytest.fixture(scope="module")
def plane():
    base = Study.load().parameters().model
    st = Study.load().settings.with_(transient=400, transient_continuation=200)
    ws = 0.1 + (np.arange(N) + 0.5) * 2.4 / N
    bs = (np.arange(N) + 0.5) / N
    rows = [[base.with_(w=float(w), b=float(b)) for w in ws] for b in bs]
    res = chains.simulate_rows(rows, settings=st)
    cells = [c for r in rows for c in r]
    states = [x.final_state for r in res for x in r]
    motions = [gear_steady(x) for r in res for x in r]
    opts = FinderOptions(starts=16, seed=0)
    new = find_attractors(cells, opts, settings=st, forward_results=motions)
    old = reference_attractors(cells, opts, st, forward=states)
    return cells, new, old


def _basins(ca):
    out: dict[str, float] = {}
    for a in ca.attractors:
        if a.n_starts:
            out[a.label] = out.get(a.label, 0.0) + a.basin_fraction
    return out


def test_same_attractors_and_basins_within_sampling_error(plane):
    cells, new, old = plane
    bad = []
    for p, a, b in zip(cells, new, old, strict=True):
        fa, fb = _basins(a), _basins(b)
        for lab in set(fa) | set(fb):
            x, y = fa.get(lab, 0.0), fb.get(lab, 0.0)
            m = 0.5 * (x + y)
            tol = 2.0 * math.sqrt(m * (1.0 - m) / 16.0) + 1.0 / 16.0
            if max(x, y) >= 2 / 16 and (min(x, y) == 0.0 or abs(x - y) > tol):
                bad.append((round(p.w, 3), round(p.b, 3), lab, x, y))
    assert not bad, bad


def test_plane_statistics_agree(plane):
    _, new, old = plane

    def multi(found):
        return float(np.mean([len(_basins(ca)) >= 2 for ca in found]))

    def mean_n(found):
        return float(np.mean([len(_basins(ca)) for ca in found]))

    assert abs(multi(new) - multi(old)) <= 0.02
    assert abs(mean_n(new) - mean_n(old)) <= 0.05
