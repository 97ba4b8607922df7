"""The workflow through profiles/slurm on a real one-node SLURM cluster.

`.ci/slurm-cluster up` installs what is missing (slurm-wlm daemons, munge, slurmdbd, MariaDB),
writes a slurm.conf for this machine and starts the daemons; `down` stops them afterwards. The
whole tiny configuration (config/tiny.yaml, the default target: tables, catalogue, figures,
diagrams, report, explorer) runs through the profile as a user would (partition and account from
SBATCH_PARTITION and SBATCH_ACCOUNT), and one tile's SLURM job (the tile and its attractor tile)
is cancelled with ``scancel`` while it runs. Checked:

* every job of the run but the target rule ``all`` ran in a SLURM job, its own or its group's;
  every SLURM job of the run is in ``sacct`` under the given account, COMPLETED, but the
  cancelled one, CANCELLED, which Snakemake submitted again and which then COMPLETED;
* the catalogue equals the one of the session's local run (``tiny_run``, conftest.py: the same
  configuration on ``--cores 2``) value for value (ids and provenance aside);
* a tile run as a 2-CPU job step has a 2-worker LocalCluster (one worker per CPU SLURM gave);
* the profile's grouping: one SLURM job of one CPU per tile (the tile and its attractor tile),
  the small jobs in three group jobs of one CPU each;
* an account sacctmgr does not list for the user stops the run before anything is submitted.
"""

from __future__ import annotations

import os
import re
import shutil
import sqlite3
import subprocess
import time
from pathlib import Path

import pandas as pd
import pytest
import yaml
from workflow_helpers import ROOT, SNAKEMAKE, _env, make_workdir, smk, tiny_run_once

pytestmark = pytest.mark.slow

SCRIPT = ROOT / ".ci/slurm-cluster"
PROFILE = ROOT / "profiles/slurm"
ACCOUNT = "gearsim-ci"  # created by .ci/slurm-cluster
CI = os.environ.get("CI") == "1"
CATALOGUE = "results/catalogue.d/build.sqlite"
# a hang guard only: the run took 407-519 s on 2 cores at load average 1-15
TIMEOUT = 1800
#: the profile's group jobs of small jobs (profiles/slurm/config.yaml, groups) and their CPUs
GROUPS = {"curves": 1, "tables": 1, "report": 1}
#: tiles of the tiny configuration: one SLURM job each (the tiles group)
TILES = 4


def _privileged() -> bool:
    if os.geteuid() == 0:
        return True
    return shutil.which("sudo") is not None and subprocess.run(
        ["sudo", "-n", "true"], capture_output=True).returncode == 0


@pytest.fixture(scope="module")
def cluster():
    """The partition of a running one-node cluster: started here (and stopped after the module)
    unless one answers already."""
    if not _privileged():
        if CI:
            pytest.fail("CI=1: starting the SLURM cluster needs root or passwordless sudo")
        pytest.skip("starting a SLURM cluster needs root or passwordless sudo")
    running = subprocess.run([str(SCRIPT), "status"], capture_output=True).returncode == 0
    r = subprocess.run([str(SCRIPT), "up"], capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stdout + r.stderr
    try:
        yield r.stdout.strip().splitlines()[-1]
    finally:
        if not running:
            d = subprocess.run([str(SCRIPT), "down"], capture_output=True, text=True, timeout=120)
            assert d.returncode == 0, d.stdout + d.stderr


def _squeue_running(prefix: str) -> list[tuple[str, str]]:
    out = subprocess.run(["squeue", "--noheader", "--states=RUNNING", "--format=%i|%j|%k"],
                         capture_output=True, text=True, check=True).stdout
    rows = [line.split("|", 2) for line in out.splitlines() if line.strip()]
    return [(job, comment) for job, name, comment in rows if name.startswith(prefix)]


def _sacct(prefix: str, since: str) -> pd.DataFrame:
    """This run's SLURM jobs (allocations, not steps) as sacct lists them."""
    out = subprocess.run(
        ["sacct", "--allocations", "--parsable2", "--noheader", "--starttime", since,
         "--format=JobIDRaw,JobName%200,State,Account,AllocCPUS,Comment%200"],
        capture_output=True, text=True, check=True).stdout
    rows = [line.split("|") for line in out.splitlines() if line.strip()]
    df = pd.DataFrame(rows, columns=["job", "name", "state", "account", "cpus", "comment"])
    return df[df["name"].str.startswith(prefix)].astype({"job": int, "cpus": int})


def _sacct_settled(prefix: str, since: str, jobs: set[int], timeout: float = 60) -> pd.DataFrame:
    """sacct once slurmdbd has every job of ``jobs`` in a final state (it learns asynchronously)."""
    deadline = time.monotonic() + timeout
    while True:
        df = _sacct(prefix, since)
        final = df["state"].str.match(r"COMPLETED|CANCELLED|FAILED|TIMEOUT|OUT_OF_ME|NODE_FAIL")
        if set(df["job"]) >= jobs and final.all() or time.monotonic() > deadline:
            return df
        time.sleep(1)


@pytest.fixture(scope="module")
def slurm_run(cluster, tmp_path_factory):
    """The tiny configuration's default target through profiles/slurm; the first tile job seen
    running is cancelled."""
    wd = make_workdir(tmp_path_factory.mktemp("slurm"))
    prefix = f"gearsim_test_{os.getpid()}"
    env = {**_env(), "SBATCH_PARTITION": cluster, "SBATCH_ACCOUNT": ACCOUNT}
    # one CPU per tile job, as in the local run: on a 2-CPU node a 2-CPU tile job (the profile's
    # fit_threads(8) here) waits for the whole node, i.e. for every small job to end first
    # (measured: 529 s against 181 s locally, load ~10); the dask path under SLURM is checked by
    # test_tile_cluster_has_the_cpus_srun_gave below
    cmd = [str(SNAKEMAKE), "-s", str(ROOT / "Snakefile"), "-d", str(wd), "--workflow-profile",
           str(PROFILE), "--configfile", "config/tiny.yaml", "--slurm-jobname-prefix", prefix,
           "--set-threads", "simulate_tile=1", "attractor_tile=1"]
    since = time.strftime("%Y-%m-%dT%H:%M:%S")
    log = wd / "snakemake.log"
    t0 = time.monotonic()
    with log.open("w") as out:
        proc = subprocess.Popen(cmd, cwd=wd, env=env, stdout=out, stderr=subprocess.STDOUT)
        killed = None
        try:
            while proc.poll() is None:
                if time.monotonic() - t0 > TIMEOUT:
                    raise AssertionError(f"no end after {TIMEOUT} s:\n{log.read_text()[-3000:]}")
                if killed is None:
                    tiles = [j for j in _squeue_running(prefix) if "simulate_tile" in j[1]]
                    if tiles:
                        killed = tiles[0]
                        subprocess.run(["scancel", killed[0]], check=True)
                time.sleep(0.5)
        finally:
            if proc.poll() is None:
                proc.terminate()  # the plugin cancels its jobs
                proc.wait(timeout=120)
    wall = time.monotonic() - t0
    text = log.read_text()
    assert proc.returncode == 0, text[-5000:]
    submitted = {int(j) for j in re.findall(r"submitted with SLURM jobid (\d+)", text)}
    jobs = _sacct_settled(prefix, since, submitted)
    print(f"SLURM run: {wall:.0f} s wall, {len(submitted)} SLURM jobs")
    return {"wd": wd, "jobs": jobs, "submitted": submitted, "killed": killed, "log": text,
            "local": lambda: tiny_run_once(tmp_path_factory)[0]}


def test_every_job_went_through_slurm_and_completed(slurm_run):
    jobs, killed = slurm_run["jobs"], slurm_run["killed"]
    assert killed is not None, "no tile job was seen running"
    assert set(jobs["job"]) == slurm_run["submitted"], (jobs, slurm_run["submitted"])
    assert (jobs["account"] == ACCOUNT).all(), jobs
    cancelled = jobs[jobs["job"] == int(killed[0])]
    assert cancelled["state"].str.startswith("CANCELLED").all() and len(cancelled) == 1, jobs
    rest = jobs[jobs["job"] != int(killed[0])]
    assert (rest["state"] == "COMPLETED").all(), jobs
    # the cancelled job was submitted again (Snakemake's job id, SLURM's new one) and completed
    log = slurm_run["log"]
    submitted = dict(re.findall(r"Job (\S+) has been submitted with SLURM jobid (\d+)", log))
    by_slurm = {int(s): j for j, s in re.findall(
        r"Job (\S+) has been submitted with SLURM jobid (\d+)", log)}
    job = by_slurm[int(killed[0])]
    assert f"Trying to restart job {job}." in log, log[-3000:]
    again = int(submitted[job])  # the last submission of that job
    assert again > int(killed[0]) and again in set(rest["job"]), (again, jobs)


def _tables(db: Path) -> dict[str, pd.DataFrame]:
    """Every table of a catalogue without its row ids and run provenance, in a canonical order."""
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    try:
        names = [n for (n,) in con.execute(
            "SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")]
        out = {}
        for name in names:
            df = pd.read_sql(f'SELECT * FROM "{name}"', con)
            if name == "catalogue_info":
                df = df[~df["key"].isin(BUILD_INFO)]
            df = df.drop(columns=[c for c in VOLATILE.get(name, ()) + ("id", "run_id", "elapsed_s")
                                  if c in df.columns])
            out[name] = df.sort_values(list(df.columns)).reset_index(drop=True)
        return out
    finally:
        con.close()


#: Provenance: where, when and on what a table was made, not what it holds.
VOLATILE: dict[str, tuple[str, ...]] = {"runs": ("workers", "started", "finished", "wall_s")}
#: catalogue_info rows of the build itself
BUILD_INFO = ("built", "git_commit", "git_dirty")


def test_catalogue_equals_the_local_run(slurm_run):
    ours = _tables(slurm_run["wd"] / CATALOGUE)
    local = _tables(slurm_run["local"]() / CATALOGUE)  # waits for tiny_run if it still runs
    assert ours.keys() == local.keys()
    assert len(local["cells"]) == 128
    for name in local:
        pd.testing.assert_frame_equal(ours[name], local[name], check_exact=True, obj=name)


def test_tile_cluster_has_the_cpus_srun_gave(cluster, tmp_path):
    """A tile run as a SLURM job step of 2 CPUs maps its rows over a 2-worker LocalCluster
    whatever --workers says, and the profile's tile threads fit the node (2 CPUs, not 8)."""
    from gearsim.study.cluster import fit_threads, node_limits

    node_limits.cache_clear()
    assert fit_threads(8) == 2
    small = tmp_path / "small.yaml"
    small.write_text(yaml.safe_dump({"planes": {"wb": {"x": {"name": "w", "min": 0.3,
                                                             "max": 2.1, "n": 6}}}}))
    gearsim = Path(SNAKEMAKE).parent / "gearsim"
    cmd = ["srun", "--ntasks=1", "--cpus-per-task=2", f"--partition={cluster}",
           f"--account={ACCOUNT}", str(gearsim), "simulate-tile", "--plane", "wb", "--tile",
           "1", "--configfile", str(ROOT / "config/config.yaml"), str(ROOT / "config/tiny.yaml"),
           str(small), "--workers", "8", "--out", str(tmp_path / "tile.parquet")]
    r = subprocess.run(cmd, cwd=tmp_path, env=_env(), capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    assert ": 2 workers, 2 threads" in r.stderr, r.stderr


def test_tile_jobs_got_what_they_asked_for(slurm_run):
    """One SLURM job of one CPU per tile, its attractor tile in it; the cancelled one twice."""
    jobs, log = slurm_run["jobs"], slurm_run["log"]
    tiles = jobs[jobs["comment"].str.startswith("rule_tiles_")]
    assert len(tiles) == TILES + 1 and (tiles["cpus"] == 1).all(), tiles
    assert len(re.findall(r"\] Group job tiles ", log)) == TILES + 1, log[-3000:]


def test_every_rule_job_ran_in_slurm(slurm_run):
    """Snakemake's log names every job it ran: a job run by the main process is a `localrule`,
    a job in a SLURM job (its own or a group's) a `rule`."""
    log = slurm_run["log"]
    jobs = re.findall(r"^\s*(localrule|rule) (\w+):$", log, re.M)
    local = [name for kind, name in jobs if kind == "localrule"]
    total = int(re.search(r"^total\s+(\d+)", log, re.M).group(1))
    assert local == ["all"], local
    # 60 jobs in the tiny configuration; the cancelled SLURM job's two (a tile and its attractor
    # tile) twice more: in the group's error report and on its resubmission
    assert (total, len(jobs)) == (60, 64), (total, len(jobs))
    ran = {name for _, name in jobs}
    assert {"catalogue", "report", "explorer", "figures_index", "plane_maps", "attractor_maps",
            "sweep_diagram", "table1", "figure_01", "figure_20"} <= ran, ran
    assert re.search(r"^60 of 60 steps \(100%\) done$", log, re.M), log[-3000:]


def test_small_jobs_went_in_three_group_jobs_of_one_cpu(slurm_run):
    jobs, log = slurm_run["jobs"], slurm_run["log"]
    groups = [g for g in re.findall(r"\] Group job (\w+) ", log) if g != "tiles"]
    assert sorted(groups) == sorted(GROUPS), groups
    for group, cpus in GROUPS.items():
        mine = jobs[jobs["comment"].str.startswith(f"rule_{group}_")]
        assert len(mine) == 1 and (mine["cpus"] == cpus).all(), jobs
    # compile, 4 tile jobs (one twice: the cancelled and its second submission), the 3 groups
    assert len(jobs) == 1 + TILES + 1 + len(GROUPS), jobs


def test_profile_names_only_rules_of_the_workflow(tmp_path):
    profile = yaml.safe_load((PROFILE / "config.yaml").read_text())
    r = smk(make_workdir(tmp_path), "--list-rules", "--configfile", "config/tiny.yaml")
    rules = set(r.stdout.split())
    named = {*profile["groups"], *profile["set-resources"], *profile["set-threads"]}
    assert named - rules <= {"figure_21", "figure_22", "figure_23"}, named - rules
    figures = {r for r in rules if r.startswith("figure")} | {"sweep_diagram", "plane_maps"}
    assert figures <= set(profile["groups"]), figures - set(profile["groups"])


def test_an_account_not_yours_stops_the_run_before_submitting(cluster, tmp_path):
    """The executor plugin (2.8.0) raises on an account sacctmgr does not list in its submission
    thread and the run waits forever; the profile's slurm_account stops it first, in one line."""
    from gearsim.errors import UsageError
    from gearsim.study.cluster import slurm_account, user_accounts

    user_accounts.cache_clear()
    assert slurm_account(ACCOUNT) == ACCOUNT and slurm_account("") == ""
    with pytest.raises(UsageError, match=f"'nope' is not one of yours .*{ACCOUNT}"):
        slurm_account("nope")
    wd = make_workdir(tmp_path)
    prefix = f"gearsim_acct_{os.getpid()}"
    env = {**_env(), "SBATCH_PARTITION": cluster, "SBATCH_ACCOUNT": "nope"}
    r = subprocess.run([str(SNAKEMAKE), "-s", str(ROOT / "Snakefile"), "--workflow-profile",
                        str(PROFILE), "--configfile", "config/tiny.yaml", "--slurm-jobname-prefix",
                        prefix, "results/table1.md"], cwd=wd, env=env, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode != 0, r.stdout + r.stderr
    assert "SLURM account 'nope' is not one of yours" in r.stdout + r.stderr, r.stdout + r.stderr
    assert "submitted with SLURM jobid" not in r.stdout + r.stderr
