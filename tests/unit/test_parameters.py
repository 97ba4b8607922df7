"""Every bad parameter raises its documented error, naming the parameter and the range."""

import math

import pytest

from gearsim.cell.simulate import IntegrationSettings
from gearsim.dynamics.parameters import PARAMETERS, ModelParameters, ParameterError

BAD_COMMON = [float("nan"), float("inf"), -float("inf"), "abc", None, True]


@pytest.mark.parametrize("name", sorted(PARAMETERS))
@pytest.mark.parametrize("bad", BAD_COMMON)
def test_non_numbers_and_non_finite_values_are_rejected(name, bad):
    with pytest.raises(ParameterError) as err:
        ModelParameters(**{name: bad})
    msg = str(err.value)
    assert f"'{name}'" in msg and "\n" not in msg


@pytest.mark.parametrize("name", sorted(PARAMETERS))
def test_values_below_the_range_are_rejected_with_the_range(name):
    lo, hi, lo_in, hi_in = PARAMETERS[name][:4]
    bad = lo - 1.0 if lo_in else lo
    with pytest.raises(ParameterError, match=rf"'{name}'.*allowed range") as err:
        ModelParameters(**{name: bad})
    assert f"{lo:g}" in str(err.value)


@pytest.mark.parametrize(
    "kw",
    [dict(xi=-0.01), dict(b=-0.1), dict(w=0.0), dict(w=-1.0), dict(kappa_py=0.0),
     dict(kappa_gz=-5.0), dict(xi_py=-1.0), dict(eps=1.0), dict(Fm=-0.1), dict(b_gy=-0.2)],
)
def test_physically_meaningless_values(kw):
    with pytest.raises(ParameterError):
        ModelParameters(**kw)


def test_unknown_names_and_models():
    with pytest.raises(ParameterError, match="unknown parameter 'omega'"):
        ModelParameters.from_mapping({"omega": 1.0})
    with pytest.raises(ParameterError, match="'model'"):
        ModelParameters(model="3dof")


def test_valid_values_round_trip_and_are_immutable():
    p = ModelParameters(w=1.3, b=0.25)
    assert p.with_(xi=0.09).xi == 0.09 and p.xi == 0.05
    with pytest.raises(AttributeError):
        p.w = 2.0  # frozen
    assert math.isclose(p.mesh_period, 2 * math.pi / 1.3)
    assert ModelParameters.from_mapping(p.to_dict()) == p


@pytest.mark.parametrize(
    "kw",
    [dict(method="euler"), dict(rtol=0.0), dict(rtol=float("nan")), dict(hmax=-1.0),
     dict(steps_per_period=2), dict(chunk=1.5), dict(max_periods=0), dict(n_max=0)],
)
def test_bad_integration_settings(kw):
    with pytest.raises(ParameterError):
        IntegrationSettings(**kw)


def test_integration_settings_are_defined_once():
    """The schema's `integration:` section is IntegrationSettings' fields, bounds and defaults, and
    the defaults are the study's (config/config.yaml): one definition, three readers."""
    from pathlib import Path

    import yaml

    root = Path(__file__).resolve().parents[2]
    schema = yaml.safe_load((root / "workflow/schemas/config.schema.yaml").read_text())
    assert schema["properties"]["integration"]["properties"] == IntegrationSettings.json_schema()
    study = yaml.safe_load((root / "config/config.yaml").read_text())["integration"]
    assert IntegrationSettings(**study) == IntegrationSettings()
    assert set(study) == set(IntegrationSettings().to_dict())


def test_the_column_dictionary_reads_each_parameters_meaning_from_its_definition():
    """Every model parameter has its dictionary row, and that row is the parameter's own
    definition (unit and meaning written once, in gearsim.dynamics.parameters)."""
    from gearsim.results.columns import PARAMETERS as DICTIONARY

    assert set(DICTIONARY) == {"model", *ModelParameters.names()}
    for name, spec in PARAMETERS.items():
        assert DICTIONARY[name] == (spec.unit, spec.meaning), name
        assert spec.meaning and spec.unit
