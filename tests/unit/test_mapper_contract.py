"""Both attractor mappers implement the finder's one signature (``AttractorMapper``) and refuse
the same bad inputs the same way, before any integration."""

import inspect

import numpy as np
import pytest

from gearsim.analysis.attractors.gear import GearCells
from gearsim.analysis.attractors.mapper import AttractorMapper
from gearsim.analysis.attractors.pool import map_gear_cells
from gearsim.analysis.attractors.recurrence import map_attractors
from gearsim.dynamics.parameters import ModelParameters, ParameterError

MAPPERS = [map_attractors, map_gear_cells]


def _contract():
    params = list(inspect.signature(AttractorMapper.__call__).parameters.values())[1:]
    return [(p.name, p.kind, p.default) for p in params]


@pytest.mark.parametrize("mapper", MAPPERS, ids=lambda m: m.__name__)
def test_each_mapper_has_the_contracts_parameters_first(mapper):
    want = _contract()
    assert [n for n, _, _ in want] == ["system", "starts", "options", "continuation"]
    params = list(inspect.signature(mapper).parameters.values())
    got = [(p.name, p.kind, p.default) for p in params[: len(want)]]
    assert got == want
    # anything a mapper adds is a keyword option with a default
    for p in params[len(want):]:
        assert p.kind is inspect.Parameter.KEYWORD_ONLY and p.default is None


@pytest.mark.parametrize("mapper", MAPPERS, ids=lambda m: m.__name__)
@pytest.mark.parametrize("continuation, words", [
    ([{"sideways": np.zeros(10)}], "continuation state 'sideways'; allowed: forward, backward"),
    ([{}, {}], "continuation: one mapping per cell expected"),
])
def test_each_mapper_refuses_bad_continuation_alike(mapper, continuation, words):
    system = GearCells([ModelParameters()])
    starts = [system.start_states(0, np.array([[0.5, 0.5]]))]
    with pytest.raises(ParameterError) as err:
        mapper(system, starts, continuation=continuation)
    assert str(err.value) == words


def test_the_finder_maps_with_the_mapper_it_is_given():
    """find_attractors hands its system, starts, options and continuation to the given mapper
    and returns that mapper's answer: the recurrence mapper's, equal to calling it directly."""
    from gearsim.analysis.attractors import FinderOptions, find_attractors
    from gearsim.analysis.attractors.gear import sobol_unit

    cell = ModelParameters(w=0.9, b=0.15)
    options = FinderOptions(starts=4, seed=3)
    calls = []

    def spy(system, starts, options=None, *, continuation=None):
        calls.append((system, starts, options, continuation))
        return map_attractors(system, starts, options, continuation=continuation)

    got = find_attractors(cell, options, mapper=spy)
    (system, starts, opts, continuation), = calls
    assert isinstance(system, GearCells) and system.params == [cell] and opts is options
    assert continuation is None
    assert np.array_equal(starts[0], system.start_states(0, sobol_unit(4, 3)))
    (want,) = map_attractors(system, starts, options)
    assert np.array_equal(got.start_labels, want.start_labels)
    assert [a.basin_fraction for a in got.attractors] == [
        a.basin_fraction for a in want.attractors]
