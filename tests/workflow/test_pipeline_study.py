"""A study of one's own: a (w, eps) 30 x 30 plane and a mean-load sweep in a config
file with `study:`; the workflow runs only its jobs, into studies/<study>/, never touching
results/ of the paper's study; the same content under another file name re-runs nothing."""

from __future__ import annotations

import sqlite3

import pandas as pd
import pytest
import yaml
from workflow_helpers import job_counts, make_workdir, smk_in

from gearsim.study import config as gcfg

STUDY = {
    "study": "weps",
    "planes": {"weps": {"x": {"name": "w", "min": 0.1, "max": 2.5, "n": 30},
                        "y": {"name": "eps", "min": 0.05, "max": 0.6, "n": 30},
                        "fixed": {"b": 0.3}}},
    "sweeps": {"load": {"name": "Fm", "min": 0.05, "max": 0.3, "n": 11, "fixed": {"w": 1.02}}},
    "points": {},
    "tile_rows": 15,
    # tiny integration budget (tests only)
    "integration": {"method": "rk4", "steps_per_period": 64, "transient": 30,
                    "transient_continuation": 10, "chunk": 16, "max_periods": 32, "n_max": 8},
    "audit": {"fraction": 0.01, "threshold": 0.0},
    # the plane's bifurcation curves (DP5 shooting, ~3 min here) are the curve tests' subject
    "orbits": {"continuation": False, "curves": False},
}
STUDY_RESULTS = "studies/weps/results"
# targets of a study are named inside its folder (Snakemake runs in studies/<study>/)
TARGETS = ["results/weps/cells.parquet", "results/sweeps/load.parquet",
           "results/catalogue.d/build.sqlite"]


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    wd = make_workdir(tmp_path_factory.mktemp("study"))
    (wd / "config/weps.yaml").write_text(yaml.safe_dump(STUDY))
    return wd


def test_study_config_replaces_the_papers_lists(study):
    cfg = gcfg.study_config([study / "config/weps.yaml"], root=study)
    assert list(cfg["planes"]) == ["weps"] and list(cfg["sweeps"]) == ["load"]
    assert cfg["points"] == {} and cfg["study"] == "weps"
    assert str(gcfg.results_dir(cfg)) == STUDY_RESULTS
    # the rest still merges over config/config.yaml
    assert cfg["integration"]["rtol"] == 1e-9 and cfg["standard_parameters"]


def test_study_plans_only_its_own_jobs(study):
    r = smk_in(study, "-n", "--quiet", "rules", "--configfile", "config/weps.yaml")
    counts = job_counts(r.stdout + r.stderr)
    assert counts["simulate_tile"] == 2 and counts["sweep"] == 1 and counts["plane_cells"] == 1
    assert "points" not in counts and counts["catalogue"] == 1
    r = smk_in(study, "-n", "--configfile", "config/weps.yaml")
    out = r.stdout + r.stderr
    for other in ("plane=wb", "plane=wxi", "sweep=standard", "sweep=b015"):
        assert other not in out


def test_study_refuses_directory_option(study):
    r = smk_in(study, "-n", "-d", str(study), "--configfile", "config/weps.yaml", check=False)
    out = r.stdout + r.stderr
    assert r.returncode != 0 and "without --directory" in out and "Traceback" not in out


@pytest.mark.slow
def test_study_runs_into_its_own_folder(study):
    # targets first: --configfile takes a list
    smk_in(study, *TARGETS, "--cores", "2", "--configfile", "config/weps.yaml", timeout=1800)
    assert not (study / "results").exists()  # the paper's study is not touched
    cells = pd.read_parquet(study / f"{STUDY_RESULTS}/weps/cells.parquet")
    assert len(cells) == 900 and set(cells["i"]) == set(range(30))
    assert cells["eps"].between(0.05, 0.6).all() and cells["w"].between(0.1, 2.5).all()
    sweep = pd.read_parquet(study / f"{STUDY_RESULTS}/sweeps/load.parquet")
    assert len(sweep) == 11 and sweep["parameter"].eq("Fm").all()
    con = sqlite3.connect(study / f"{STUDY_RESULTS}/catalogue.d/build.sqlite")
    assert [r[0] for r in con.execute("SELECT name FROM planes")] == ["weps"]
    con.close()
    assert (study / "studies/weps/logs").is_dir()


@pytest.mark.slow
def test_same_content_under_another_name_reruns_nothing(study):
    smk_in(study, *TARGETS, "--cores", "2", "--configfile", "config/weps.yaml", timeout=1800)
    (study / "config/renamed.yaml").write_text((study / "config/weps.yaml").read_text())
    r = smk_in(study, *TARGETS, "-n", "--configfile", "config/renamed.yaml")
    assert "Nothing to be done" in r.stdout + r.stderr, r.stdout[-3000:]


def test_torque_sweep_in_newton_metres(study):
    """A study's sweep given in N m at a speed in rpm (with a gear file) is converted once, when
    the configuration is loaded, by gearsim.physical.units; the physical form stays for labels."""
    from gearsim.physical.units import axis_factor, load_gear

    doc = {"study": "torque", "gear": "config/gears/standard.yaml", "planes": {}, "points": {},
           "sweeps": {"torque": {"name": "torque_Nm", "min": 4.0, "max": 40.0, "n": 91,
                                 "fixed": {"speed_rpm": 6000}}}}
    f = study / "config/torque.yaml"
    f.write_text(yaml.safe_dump(doc))
    cfg = gcfg.study_config([f], root=gcfg.project_root())
    sw = cfg["sweeps"]["torque"]
    gear = load_gear(gcfg.project_root() / "config/gears/standard.yaml")
    k_t = axis_factor("torque_Nm", gear)[1]
    k_rpm = axis_factor("speed_rpm", gear)[1]
    assert sw["name"] == "Fm" and sw["min"] == pytest.approx(4.0 * k_t, rel=1e-12)
    assert sw["fixed"]["w"] == pytest.approx(6000 * k_rpm, rel=1e-12)
    assert sw["physical"] == {"name": "torque_Nm", "unit": "N m", "min": 4.0, "max": 40.0}
    again = gcfg.load_config([gcfg.project_root() / "config/config.yaml"], overrides=cfg,
                             root=gcfg.project_root())
    assert again["sweeps"] == cfg["sweeps"]  # loading the converted config again changes nothing
