"""Checks shared by the attractor-finder tests: early labels against full-length runs."""

from __future__ import annotations

from reference import reference_settings

from gearsim.analysis.attractors import same_attractor

#: the gear settings and the fixed reference set (tests/integration/test_convergence.py) of the
#: finder's tests
GEAR = reference_settings(method="rk4", transient=150, transient_continuation=40)
REFERENCE = dict(
    Fm=0.1, Fe=0.1724, eps=0.371, xi=0.05, phi_e=-0.7853981633974483, friction=0.0,
)  # the fixed reference set of tests/integration/test_convergence.py


def assert_same_attractors_per_start(fast, full, fewer_periods: bool = True) -> int:
    """Assert that two finder results of the same cells and starts (``fast`` with early labels,
    ``full`` with every start's full-length run) give the same attractors with the same basin
    fractions, that every start reaches the same attractor, and (``fewer_periods``) that
    ``fast`` integrated fewer periods per cell. Returns the number of starts ``fast`` labelled
    early."""
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
        assert not fewer_periods or a.start_periods_run.sum() < b.start_periods_run.sum()
    return n_early


def reference_attractors(cells, options, settings, forward=None):
    """The recurrence mapper (``gearsim.analysis.attractors.recurrence.map_attractors``, the
    reference the lane pool is checked against) on gear cells: the same Sobol starts, forward
    states and last steps (margins, least periods, the long run of clouds next to diverging
    starts) as ``find_attractors``."""
    import numpy as np

    from gearsim.analysis.attractors import GearCells, least_periods, sobol_unit
    from gearsim.analysis.attractors.gear import bounded_clouds
    from gearsim.analysis.attractors.recurrence import map_attractors

    system = GearCells(cells, settings)
    opts = options.resolved(system.settings.period_rtol)
    unit = sobol_unit(opts.starts, opts.seed)
    starts = [system.start_states(c, unit) for c in range(len(cells))]
    cont = None
    if forward is not None:
        cont = [{} if y is None else {"forward": np.asarray(y, dtype=float)[:10]}
                for y in forward]  # fmt: skip
    found = map_attractors(system, starts, opts, continuation=cont)
    system.fill_margins(found)
    return bounded_clouds(cells, [least_periods(ca, opts.merge_rtol) for ca in found],
                          system.settings)
