"""Checks shared by the attractor-finder tests: early labels against full-length runs."""

from __future__ import annotations

from gearsim.analysis.attractors import same_attractor


def assert_same_attractors_per_start(fast, full) -> int:
    """Assert that two finder results of the same cells and starts (``fast`` with early labels,
    ``full`` with every start's full-length run) give the same attractors with the same basin
    fractions, that every start reaches the same attractor, and that ``fast`` integrated fewer
    periods per cell. Returns the number of starts ``fast`` labelled early."""
    n_early = 0
    for a, b in zip(fast, full, strict=True):
        fa = sorted((x.basin_fraction, x.label) for x in a.attractors)
        fb = sorted((x.basin_fraction, x.label) for x in b.attractors)
        assert fa == fb
        for i in range(a.n_starts):
            la, lb = a.start_labels[i], b.start_labels[i]
            assert (la < 0) == (lb < 0)
            if la >= 0:
                assert same_attractor(a.attractors[la].steady, b.attractors[lb].steady)
        n_early += int(a.early.sum())
        assert a.start_periods_run.sum() < b.start_periods_run.sum()
    return n_early
