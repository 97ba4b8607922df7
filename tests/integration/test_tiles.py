"""Config validation, grids, tiles and row simulation (gearsim.study.tiles)."""

from __future__ import annotations

import copy
import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from gearsim.cell.simulate import IntegrationSettings, simulate_cell
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.study import config as gcfg
from gearsim.study import grid as ggrid
from gearsim.study import provenance as gprov
from gearsim.study import schema as gschema
from gearsim.study import tiles as gt

ROOT = Path(__file__).resolve().parents[2]
DEFAULT = ROOT / "config/config.yaml"
TINY = ROOT / "config/tiny.yaml"


@pytest.fixture(scope="module")
def tiny():
    return gcfg.load_config([DEFAULT, TINY])


def _raw():
    return yaml.safe_load(DEFAULT.read_text())


def _error(config) -> str:
    with pytest.raises(gcfg.ConfigError) as exc:
        gschema.validate_schema(config)
        gschema.check_config(config, gcfg.study_root())
        gcfg.Study.of(config)
    return str(exc.value)


def test_configs_load():
    for extra in ([], ["quick.yaml"], ["tiny.yaml"]):
        cfg = gcfg.load_config([DEFAULT, *(ROOT / "config" / e for e in extra)])
        assert set(cfg["planes"]) == {"wb", "wxi"}
        assert set(cfg["sweeps"]) == {
            "standard", "b015", "b025", "b035", "xi005", "xi009", "xi015", "hysteresis"
        }
    full = gcfg.load_config(DEFAULT)
    assert full["planes"]["wb"]["x"]["n"] * full["planes"]["wb"]["y"]["n"] == 160_000
    assert full["points"]["fig5"][0] == 0.48 and len(full["points"]["fig5"]) == 12


def test_schema_integration_matches_settings():
    """The schema's integration keys are IntegrationSettings' fields, and its defaults are the
    study's (config/config.yaml), so a config file that leaves a key out gets the study's value."""
    props = gschema.load_schema()["properties"]["integration"]["properties"]
    fields = {f.name for f in dataclasses.fields(IntegrationSettings)}
    assert set(props) == fields
    study = _raw()["integration"]
    assert set(study) == fields
    for name in fields:
        assert props[name]["default"] == study[name], name


def test_schema_defaults_equal_config_yaml():
    """Every scalar setting config/config.yaml gives equals the schema's default."""
    schema = gschema.load_schema()["properties"]
    raw = _raw()
    for key in ("standard_parameters", "tile_rows"):
        assert schema[key]["default"] == raw[key], key
    for section in ("integration", "cluster", "audit"):
        for name, value in raw[section].items():
            assert schema[section]["properties"][name]["default"] == value, f"{section}.{name}"
    assert raw["parameters"] == {} and schema.get("study", {}).get("default") is None


def test_defaults_filled():
    cfg = {"planes": {"p": {"x": {"name": "w", "min": 0.5, "max": 1, "n": 4},
                            "y": {"name": "b", "min": 0, "max": 1, "n": 4}}}}
    gschema.validate_schema(cfg)
    assert cfg["tile_rows"] == 80 and cfg["integration"]["method"] == "rk4"
    assert cfg["integration"]["transient_continuation"] == 40 and cfg["study"] is None
    assert cfg["planes"]["p"]["fixed"] == {} and cfg["cluster"]["scheduler_address"] is None


@pytest.mark.parametrize(
    ("edit", "key", "words"),
    [
        (lambda c: c.update(tile_rowz=3), "tile_rowz", "unknown key"),
        (lambda c: c["planes"]["wb"]["x"].update(step=1), "planes.wb.x.step", "unknown key"),
        (lambda c: c.update(tile_rows="eight"), "tile_rows", "not of type integer"),
        (lambda c: c["planes"]["wb"]["y"].update(n=0), "planes.wb.y.n", "minimum"),
        (lambda c: c["planes"]["wb"]["y"].update(n=-5), "planes.wb.y.n", "minimum"),
        (lambda c: c["planes"]["wb"]["x"].update(min=2.5, max=0.1), "planes.wb.x", "reversed"),
        (lambda c: c["planes"]["wxi"]["y"].update(max=0.04), "planes.wxi.y", "empty or reversed"),
        (lambda c: c["planes"]["wb"]["y"].update(name="gap"), "planes.wb.y.name", "unknown"),
        (lambda c: c.update(tile_rows=401), "tile_rows", "larger than the grid"),
        (lambda c: c["planes"]["wb"]["fixed"].update(foo=1), "planes.wb.fixed.foo", "unknown"),
        (lambda c: c["parameters"].update(xi=-1), "parameters.xi", "outside"),
        (lambda c: c["sweeps"]["b015"].update(min=3, max=1), "sweeps.b015", "reversed"),
        (lambda c: c["integration"].update(rtol=2), "integration.rtol", "maximum"),
        (lambda c: c["planes"]["wb"]["y"].update(min=-1), "planes.wb.y.min", "outside"),
        (lambda c: c["planes"].update(sweeps=c["planes"]["wb"]), "planes.sweeps", "reserved"),
    ],
)
def test_bad_config_names_the_key(edit, key, words):
    cfg = _raw()
    edit(cfg)
    msg = _error(cfg)
    assert f"'{key}'" in msg, msg
    assert words in msg, msg
    assert "\n" not in msg


def test_new_plane_from_config_only():
    cfg = _raw()
    cfg["planes"]["eps_xi"] = {"x": {"name": "eps", "min": 0.0, "max": 0.5, "n": 5},
                               "y": {"name": "xi", "min": 0.02, "max": 0.1, "n": 3},
                               "fixed": {"w": 1.2}}
    cfg["tile_rows"] = 2
    cfg = gschema.check_config(gschema.validate_schema(cfg), gcfg.study_root())
    assert ggrid.n_tiles({**cfg, "tile_rows": 2}, "eps_xi") == 2
    specs = gt.row_specs(gcfg.Study.of({**cfg, "tile_rows": 2}), "eps_xi", 1)
    assert [s.j for s in specs] == [2]
    assert specs[0].params.w == 1.2 and specs[0].x_name == "eps"


def test_grid_and_tiles(tiny):
    xs = ggrid.axis_values(tiny["planes"]["wb"]["x"])
    assert np.allclose(xs, 0.1 + (np.arange(8) + 0.5) * 0.3)
    assert ggrid.tile_ids(tiny, "wb") == [0, 1]
    assert list(ggrid.tile_rows(tiny, "wb", 1)) == [4, 5, 6, 7]
    cfg = copy.deepcopy(tiny)
    cfg["tile_rows"] = 3
    assert ggrid.n_tiles(cfg, "wb") == 3 and list(ggrid.tile_rows(cfg, "wb", 2)) == [6, 7]
    with pytest.raises(gcfg.ConfigError):
        ggrid.tile_rows(tiny, "wb", 2)
    s = ggrid.sweep_values({"min": 0.1, "max": 2.5, "n": 1201})
    assert s[0] == 0.1 and s[-1] == 2.5 and np.isclose(s[1] - s[0], 0.002)


def test_parameters_builtin_defaults_only_when_asked(tiny, tmp_path):
    cfg = copy.deepcopy(tiny)
    cfg["standard_parameters"] = str(tmp_path / "absent.yaml")
    with pytest.raises(gcfg.ConfigError, match=r"standard_parameters.*not found.*absent\.yaml"):
        gcfg.Study.of(cfg)  # a misspelled path is an error, never a silent fallback
    cfg["standard_parameters"] = None
    p = gcfg.Study.of(cfg).parameters()
    assert p.source == "builtin-defaults" and set(p.origin.values()) == {"default"}
    assert p.model == ModelParameters()
    f = tmp_path / "sp.yaml"
    f.write_text("dimensionless:\n  xi: {value: 0.07, provenance: calibrated}\n")
    cfg["standard_parameters"] = str(f)
    cfg["parameters"] = {"eps": 0.3}
    study = gcfg.Study.of(cfg)
    p = study.parameters(plane="wb")
    assert p.source == f"{f} + parameters eps=0.3"
    assert (p.model.xi, p.model.eps) == (0.07, 0.3)
    assert p.origin["xi"] == str(f) and p.origin["eps"] == "parameters"
    assert p.origin["b"] == "default"
    assert all(p.origin[k] == "planes.wb.fixed" for k in cfg["planes"]["wb"].get("fixed", {}))
    changed = study.parameters(plane="wb", words="--set xi=0.05", xi=0.05)
    assert changed.model.xi == 0.05 and changed.origin["xi"] == "--set xi=0.05"
    assert changed.source == f"{f} + parameters eps=0.3 + --set xi=0.05"
    prov = gprov.provenance(gprov.plane_subtree(study, "wb"), kind="tile", name="wb", study=study)
    assert prov["parameters_source"] == f"{f} + parameters eps=0.3"
    with pytest.raises(AttributeError):
        study.root = tmp_path  # frozen
    with pytest.raises(TypeError):
        study.config["tile_rows"] = 3  # read-only


def test_hashes_track_the_plane_subtree(tiny):
    a = gprov.config_hash(gprov.plane_subtree(gcfg.Study.of(tiny), "wb"))
    cfg = copy.deepcopy(tiny)
    cfg["planes"]["wxi"]["fixed"] = {"b": 0.5}
    assert gprov.config_hash(gprov.plane_subtree(gcfg.Study.of(cfg), "wb")) == a
    assert gprov.config_hash(gprov.plane_subtree(gcfg.Study.of(cfg), "wxi")) != gprov.config_hash(
        gprov.plane_subtree(gcfg.Study.of(tiny), "wxi")
    )
    assert gprov.code_version() == gprov.code_version() and len(gprov.code_version()) == 16


def test_row_is_a_continuation_chain(tiny):
    """A tile row equals simulate_cell run cell by cell with continuation."""
    cfg = copy.deepcopy(tiny)
    cfg["planes"]["wb"]["x"]["n"] = 4
    df = gt.run_tile(gcfg.Study.of(cfg), "wb", 0, client=None)
    assert len(df) == 4 * 4 and list(df.columns[:8]) == ["plane", "tile", "i", "j", "x", "y",
                                                         "w", "b"]
    settings = gcfg.integration_settings(cfg)
    base = gcfg.Study.of(cfg).parameters(plane="wb").model
    row = df[df.j == 2].sort_values("i")
    u0, start = None, 0
    for _, c in row.iterrows():
        r = simulate_cell(base.with_(w=c.w, b=c.b), u0, settings=settings, start_period=start)
        assert r.row()["label"] == c["label"] and r.row()["label_npq"] == c["label_npq"]
        assert np.isclose(r.row()["dc"], c["dc"], equal_nan=True)
        u0, start = r.final_state, r.final_period
    assert str(df["p"].dtype) == "Int64" and df["converged"].dtype == bool


def test_rk4_tiles_use_the_batched_kernel(tiny):
    """With method rk4 a tile runs gearsim.numerics.batch; rows equal the scalar RK4 continuation
    chain."""
    from gearsim.cell.sweep import continuation_chain

    cfg = copy.deepcopy(tiny)
    cfg["integration"]["method"] = "rk4"
    # the default budgets: with tiny.yaml's 32 periods a cell can sit at the edge of the period
    # test, where last-bit differences between the SIMD and scalar kernels decide the verdict
    cfg["integration"].update(transient=150, transient_continuation=16, chunk=24,
                              max_periods=256, n_max=64)
    cfg["planes"]["wb"]["x"]["n"] = 5
    df = gt.run_tile(gcfg.Study.of(cfg), "wb", 1, client=None)
    assert len(df) == 5 * 4 and list(df["j"].unique()) == [4, 5, 6, 7]
    settings = gcfg.integration_settings(cfg)
    base = gcfg.Study.of(cfg).parameters(plane="wb").model
    for j in (4, 7):
        row = df[df.j == j].sort_values("i")
        ref = continuation_chain([base.with_(w=c.w, b=c.b) for c in row.itertuples()],
                                 settings=settings)
        assert [r.row()["label_npq"] for r in ref] == list(row["label_npq"])
        assert [r.row()["label"] for r in ref] == list(row["label"])
        np.testing.assert_allclose([r.row()["dc"] for r in ref], row["dc"], rtol=1e-6,
                                   atol=1e-9)
    assert gt.row_groups(list(range(16)), 2) == [list(range(8)), list(range(8, 16))]
    assert gt.row_groups(list(range(8)), 2) == [list(range(8))]
    assert [len(g) for g in gt.row_groups(list(range(80)), 8)] == [16] * 5
    assert [len(g) for g in gt.row_groups(list(range(80)), 2)] == [40, 40]
    assert [len(g) for g in gt.row_groups(list(range(20)), 2)] == [16, 4]


def test_tile_records_do_not_depend_on_the_worker_split(tiny, tmp_path, capsys):
    """One worker (in this process) and two workers (two row groups) give the same records, and
    `simulate-tile --workers 1` without a scheduler runs in-process (no LocalCluster)."""
    import pandas as pd

    from gearsim.cli.main import main

    cfg = copy.deepcopy(tiny)
    cfg["integration"].update(method="rk4", transient=40, transient_continuation=8, chunk=16,
                              max_periods=64)
    cfg["tile_rows"] = 16
    for plane in ("wb", "wxi"):
        cfg["planes"][plane]["y"]["n"] = 16
    cfg["planes"]["wb"]["x"]["n"] = 6
    whole = gt.run_tile(gcfg.Study.of(cfg), "wb", 0, client=None)
    specs = gt.row_specs(gcfg.Study.of(cfg), "wb", 0)
    groups = gt.row_groups(specs, 2)
    assert [len(g) for g in groups] == [8, 8]
    split = gt.records_to_frame([r for g in groups for r in gt.simulate_rows_batched(g)])
    split = split.sort_values(["j", "i"], kind="stable").reset_index(drop=True)
    cols = [c for c in whole.columns if c != "elapsed_s"]
    pd.testing.assert_frame_equal(whole[cols], split[cols])

    cfg_file = tmp_path / "c.yaml"
    cfg_file.write_text(yaml.safe_dump({k: cfg[k] for k in ("integration", "tile_rows",
                                                            "planes")}))
    out = tmp_path / "t.parquet"
    assert main(["simulate-tile", "--plane", "wb", "--tile", "0", "--workers", "1",
                 "--configfile", str(cfg_file), "--out", str(out)]) == 0
    assert "in-process" in capsys.readouterr().err
    got = pd.read_parquet(out)
    pd.testing.assert_frame_equal(got[cols], whole[cols], check_dtype=False)


def test_a_row_task_carries_the_studys_own_objects(tiny):
    """A tile's row tasks hold the study's frozen parameters and settings as they are (no dict
    round trip on the way to a worker: they pickle equal), and the method is a type whose
    record reads as before (the settings' hash is unchanged)."""
    import pickle

    from gearsim.numerics.settings import Method

    study = gcfg.Study.of(tiny)
    spec = gt.row_specs(study, "wb", 0)[0]
    assert spec.params == study.parameters(plane="wb").model and spec.settings is study.settings
    again = pickle.loads(pickle.dumps(spec))
    assert again == spec and again.settings.method is study.settings.method
    assert IntegrationSettings(method="dp5").method is Method.DP5 and not Method.DP5.lanes
    assert Method.RK4.lanes and Method("rk4") is Method.RK4
    record = IntegrationSettings(method="rk4").to_dict()
    assert type(record["method"]) is str and record["method"] == "rk4"
    assert gprov.config_hash(record) == gprov.config_hash({**record, "method": "rk4"})
    with pytest.raises(ParameterError, match="setting 'method' = 'euler'; allowed: dp5, rk4"):
        IntegrationSettings(method="euler")
