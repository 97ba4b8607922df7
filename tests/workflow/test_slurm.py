"""The workflow through profiles/slurm on a real one-node SLURM cluster, with the faults of a
cluster injected into its run.

`.ci/slurm-cluster up` installs what is missing (slurm-wlm daemons, munge, slurmdbd, MariaDB),
writes a slurm.conf for this machine and starts the daemons; `down` stops them afterwards. The
whole tiny configuration (config/tiny.yaml, the default target: tables, catalogue, figures,
diagrams, report, explorer) runs through the profile as a user would (partition and account from
SBATCH_PARTITION and SBATCH_ACCOUNT). Into that one run the test injects, one after the other
(:class:`Faults`, :data:`SBATCH`; docs/pipeline.md "When a cluster job fails"): a job that exits
1 on its node, the controller stopped and started again, a tile job cancelled, one timed out,
one requeued mid-run, and the Snakemake process killed with its jobs still queued; the same
command run again at once stops in one line, and run once those jobs are gone, it finishes.
Checked:

* every job of the run but the target rule ``all`` ran in a SLURM job, its own or its group's;
  every SLURM job of the run is in ``sacct`` under the given account; each faulted job has its
  state (FAILED, CANCELLED, TIMEOUT, REQUEUED then COMPLETED) and every Snakemake job's last
  SLURM job COMPLETED; the timed-out job's retry asked for twice its runtime;
* the catalogue equals the one of the session's local run (``tiny_run``, conftest.py: the same
  configuration on ``--cores 2``) value for value (ids and provenance aside); no temporary file
  is left, no job of the run is left in the queue;
* a tile run as a 2-CPU job step has a 2-worker LocalCluster (one worker per CPU SLURM gave);
* the profile's grouping: one SLURM job of one CPU per tile (the tile and its attractor tile),
  the small jobs in three group jobs of one CPU each;
* an account sacctmgr does not list for the user stops the run before anything is submitted.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import signal
import sqlite3
import subprocess
import sys
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
# a hang guard only: the run took 407-519 s on 2 cores at load average 1-15 (without faults)
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


def _squeue(prefix: str) -> dict[str, tuple[str, str, str]]:
    """This run's jobs in the queue: SLURM id -> (state, comment, time limit)."""
    out = subprocess.run(["squeue", "--noheader", "--format=%i|%j|%T|%k|%l"],
                         capture_output=True, text=True, check=True).stdout
    rows = [line.split("|", 4) for line in out.splitlines() if line.strip()]
    return {job: (state, comment, limit) for job, name, state, comment, limit in rows
            if name.startswith(prefix)}


def _sacct(prefix: str, since: str, duplicates: bool = False) -> pd.DataFrame:
    """This run's SLURM jobs (allocations, not steps) as sacct lists them; with ``duplicates``,
    each run of a requeued job too."""
    out = subprocess.run(
        ["sacct", "--allocations", "--parsable2", "--noheader", "--starttime", since,
         *(["--duplicates"] if duplicates else []),
         "--format=JobIDRaw,JobName%200,State,Account,AllocCPUS,Timelimit,Comment%200"],
        capture_output=True, text=True, check=True).stdout
    rows = [line.split("|") for line in out.splitlines() if line.strip()]
    df = pd.DataFrame(rows, columns=["job", "name", "state", "account", "cpus", "limit",
                                     "comment"])
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


#: The test's sbatch, first on the PATH of the run: it records every submission (kind of job,
#: runtime asked, SLURM id) and injects the faults that must happen inside a job: the first
#: compile job exits 1 on its node; the second one, once its work is done, marks it (``{mark}``)
#: and holds its node HOLD s before it exits with its work's status, so that the controller goes
#: away while a job runs and no job step starts (a step that starts while the controller is away
#: fails, "Unable to confirm allocation", and its job is submitted again: a race the test must
#: not depend on); the second tile job sleeps first, so that the time limit the test then sets
#: runs out before the tile starts.
SBATCH = """#!{python}
import fcntl, json, subprocess, sys
args = sys.argv[1:]
comment = args[args.index("--comment") + 1] if "--comment" in args else ""
kind = next((k for k in ("compile", "tiles", "curves", "tables", "report")
             if comment.startswith("rule_" + k)), "other")
with open({log!r}, "a+") as log:
    fcntl.flock(log, fcntl.LOCK_EX)
    log.seek(0)
    seen = [json.loads(line)["kind"] for line in log if line.strip()].count(kind)
    fault = {{("compile", 0): "exit", ("compile", 1): "outage",
              ("tiles", 1): "sleep"}}.get((kind, seen), "")
    wrap = next(i for i, a in enumerate(args) if a.startswith("--wrap="))
    if fault == "exit":
        args[wrap] = "--wrap=exit 1"
    elif fault == "outage":
        args[wrap] += "; rc=$?; touch {mark}; sleep {hold}; exit $rc"
    elif fault == "sleep":
        args[wrap] = "--wrap=sleep 120; " + args[wrap][len("--wrap="):]
    r = subprocess.run([{sbatch!r}, *args], capture_output=True, text=True)
    log.write(json.dumps({{"kind": kind, "fault": fault, "runtime": args[args.index("-t") + 1],
                          "job": r.stdout.strip().split(";")[0]}}) + "\\n")
sys.stdout.write(r.stdout)
sys.stderr.write(r.stderr)
sys.exit(r.returncode)
"""
#: How long the controller is away: longer than the plugin's status intervals then (5 s after a
#: submission, 10 s more per query while no job ends: the round after the first compile job's
#: failure comes 15 s after it) and than a query that finds no controller (~10 s)
OUTAGE = 40
#: How long the second compile job holds its node after its work: the outage and the
#: controller's start within it
HOLD = OUTAGE + 15
#: How far ahead of now the test sets the sleeping tile job's end: a second's race between
#: scontrol's clock and the controller's is otherwise refused, and its 120 s sleep leaves room
END_AHEAD = 5
CTLD_PID = Path(os.environ.get("GEARSIM_SLURM_DIR", "/tmp/gearsim-slurm")) / "slurmctld.pid"


def _root(*cmd: str) -> list[str]:
    return list(cmd) if os.geteuid() == 0 else ["sudo", "-n", *cmd]


def _controller_away(seconds: float) -> None:
    """slurmctld stopped (SIGTERM, as an administrator's restart) for ``seconds``, then started
    again as .ci/slurm-cluster starts it (its state, jobs included, in StateSaveLocation)."""
    pid = int(CTLD_PID.read_text())
    subprocess.run(_root("kill", str(pid)), check=True)
    deadline = time.monotonic() + 30
    while Path(f"/proc/{pid}").exists() and time.monotonic() < deadline:
        time.sleep(0.2)
    time.sleep(seconds)
    subprocess.run(_root("slurmctld"), check=True)


class Faults:
    """The faults the test injects into the running workflow, one at a time (`step` is called
    every 0.5 s), each once the one before is over, so that none hides another:

    1. the controller away for OUTAGE s while the second compile job runs, its work done (the
       first exited 1, see SBATCH): every other job waits for it, so nothing is submitted and
       no job step starts meanwhile, and the status queries fail;
    2. a running tile job cancelled (``scancel``);
    3. the sleeping tile job's time limit set to run out now (``scontrol update
       EndTime=now+END_AHEAD``: TIMEOUT within SLURM's 30 s check, during its sleep);
    4. another tile job requeued mid-run (``scontrol requeue``, as a preemption does) and let
       start again at once;
    5. once those jobs have left the queue and the plane tables' job runs, the Snakemake process
       killed (SIGKILL): its jobs (tables, curves) stay in the queue.
    """

    def __init__(self, prefix: str, submissions: Path, mark: Path):
        self.prefix, self.submissions, self.mark = prefix, submissions, mark
        self.cancelled = self.timed_out = self.requeued = None
        self.limit = ""  # the timed-out job's time limit before the test shortened it
        self.requeue_seen = self.back = self.killed = None
        self.requeue_back = False

    def sbatch(self) -> list[dict]:
        if not self.submissions.exists():
            return []
        return [json.loads(line) for line in self.submissions.read_text().splitlines()]

    def step(self, proc: subprocess.Popen) -> None:
        queue, now = _squeue(self.prefix), time.monotonic()
        sbatch = self.sbatch()
        if self.back is None:
            compiles = [e["job"] for e in sbatch if e["fault"] == "outage"]
            if compiles and compiles[0] in queue and self.mark.exists():
                _controller_away(OUTAGE)
                self.back = time.monotonic()
            return
        faulted = {e["job"] for e in sbatch if e["fault"]}
        tiles = [j for j, (state, comment, _) in queue.items()
                 if state == "RUNNING" and comment.startswith("rule_tiles_")]
        plain = [j for j in tiles if j not in faulted and j not in (self.cancelled,)]
        if self.cancelled is None and plain:
            self.cancelled = plain[0]
            subprocess.run(["scancel", self.cancelled], check=True)
            return
        sleeping = [j for j in tiles if j in faulted]
        if self.timed_out is None and sleeping:
            self.timed_out, self.limit = sleeping[0], queue[sleeping[0]][2]
            # a few seconds ahead: scontrol reads "now" on its clock's second and slurmctld
            # refuses an end in the past ("Invalid time specified") if its second has ticked on
            subprocess.run(_root("scontrol", "update", f"JobId={self.timed_out}",
                                 f"EndTime=now+{END_AHEAD}"), check=True)
            return
        if self.requeued is None and self.cancelled is not None and plain:
            self.requeue_seen = self.requeue_seen or (plain[0], now)
            if now - self.requeue_seen[1] > 3:  # mid-run: its tile has started
                self.requeued = self.requeue_seen[0]
                subprocess.run(_root("scontrol", "requeue", self.requeued), check=True)
            return
        requeued = queue.get(self.requeued, ("",))[0] if self.requeued else ""
        if requeued == "PENDING" and not self.requeue_back:
            # SLURM holds a requeued job ~2 min (BeginTime); a preempted job's wait is the
            # site's: let it start now. The queue was read a moment ago: a job that has started
            # since is "no longer pending", which is what this asked for
            done = subprocess.run(_root("scontrol", "update", f"JobId={self.requeued}",
                                        "StartTime=now"), capture_output=True, text=True)
            if done.returncode and "no longer pending" not in done.stderr + done.stdout:
                raise AssertionError(f"scontrol update StartTime=now: {done.stderr.strip()}")
        self.requeue_back = self.requeue_back or requeued == "RUNNING"
        gone = not {self.cancelled, self.timed_out, self.requeued} & set(queue)
        over = self.requeue_back and gone
        tables = any(state == "RUNNING" and comment.startswith("rule_tables_")
                     for state, comment, _ in queue.values())
        if self.killed is None and over and tables:
            proc.kill()
            self.killed = sorted(queue)


def _run(cmd: list[str], wd: Path, env: dict, log: Path, deadline: float,
         faults: Faults | None = None) -> int:
    with log.open("w") as out:
        proc = subprocess.Popen(cmd, cwd=wd, env=env, stdout=out, stderr=subprocess.STDOUT)
        try:
            while proc.poll() is None:
                if time.monotonic() > deadline:
                    raise AssertionError(f"no end after {TIMEOUT} s:\n{log.read_text()[-3000:]}")
                if faults is not None:
                    faults.step(proc)
                time.sleep(0.5)
        finally:
            if proc.poll() is None:
                # Ctrl-C: the plugin cancels its jobs (SIGTERM would wait for them to end)
                proc.send_signal(signal.SIGINT)
                proc.wait(timeout=120)
    return proc.returncode


@pytest.fixture(scope="module")
def slurm_run(cluster, tmp_path_factory):
    """The tiny configuration's default target through profiles/slurm with the faults of
    :class:`Faults` and of the test's sbatch; the Snakemake process is killed mid-run, and the
    same command, run again at once, must stop in one line; run once the earlier run's jobs have
    left the queue, it must finish."""
    wd = make_workdir(tmp_path_factory.mktemp("slurm"))
    prefix = f"gearsim_test_{os.getpid()}"
    bin_dir = wd / "test-bin"
    bin_dir.mkdir()
    submissions, mark = wd / "submissions.jsonl", wd / "compile-done"
    (bin_dir / "sbatch").write_text(SBATCH.format(
        python=sys.executable, log=str(submissions), sbatch=shutil.which("sbatch"),
        mark=shlex.quote(str(mark)), hold=HOLD))
    (bin_dir / "sbatch").chmod(0o755)
    env = {**_env(), "SBATCH_PARTITION": cluster, "SBATCH_ACCOUNT": ACCOUNT,
           "PATH": f"{bin_dir}:{os.environ['PATH']}"}
    # one CPU per tile job, as in the local run: on a 2-CPU node a 2-CPU tile job (the profile's
    # fit_threads(8) here) waits for the whole node, i.e. for every small job to end first
    # (measured: 529 s against 181 s locally, load ~10); the dask path under SLURM is checked by
    # test_tile_cluster_has_the_cpus_srun_gave below
    cmd = [str(SNAKEMAKE), "-s", str(ROOT / "Snakefile"), "-d", str(wd), "--workflow-profile",
           str(PROFILE), "--configfile", "config/tiny.yaml", "--slurm-jobname-prefix", prefix,
           "--set-threads", "simulate_tile=1", "attractor_tile=1"]
    since = time.strftime("%Y-%m-%dT%H:%M:%S")
    t0 = time.monotonic()
    deadline = t0 + TIMEOUT
    faults = Faults(prefix, submissions, mark)
    code = _run(cmd, wd, env, wd / "killed.log", deadline, faults)
    assert faults.killed, (code, (wd / "killed.log").read_text()[-3000:])
    # the documented resume after a hard kill: clear Snakemake's lock, then the same command
    subprocess.run([str(SNAKEMAKE), "-s", str(ROOT / "Snakefile"), "-d", str(wd), "--unlock",
                    "--configfile", "config/tiny.yaml"], cwd=wd, env=env, check=True,
                   capture_output=True)
    refused = subprocess.run(cmd, cwd=wd, env=env, capture_output=True, text=True, timeout=300)
    left = set(_squeue(prefix))
    while _squeue(prefix):  # the earlier run's jobs end on their own
        assert time.monotonic() < deadline, _squeue(prefix)
        time.sleep(2)
    code = _run(cmd, wd, env, wd / "snakemake.log", deadline)
    wall = time.monotonic() - t0
    logs = (wd / "killed.log").read_text() + (wd / "snakemake.log").read_text()
    assert code == 0, (wd / "snakemake.log").read_text()[-5000:]
    submitted = {int(j) for j in re.findall(r"submitted with SLURM jobid (\d+)", logs)}
    jobs = _sacct_settled(prefix, since, submitted)
    print(f"SLURM run with faults: {wall:.0f} s wall, {len(submitted)} SLURM jobs")
    return {"wd": wd, "jobs": jobs, "submitted": submitted, "faults": faults, "log": logs,
            "final_log": (wd / "snakemake.log").read_text(), "refused": refused, "left": left,
            "sbatch": faults.sbatch(),
            "all_runs": _sacct(prefix, since, duplicates=True),
            "local": lambda: tiny_run_once(tmp_path_factory)[0]}


def test_every_job_went_through_slurm_and_every_fault_was_survived(slurm_run):
    """Every SLURM job of the run is in sacct under the given account; a job that did not
    complete (the injected faults) was submitted again by Snakemake and its last submission
    COMPLETED; the requeued job ran twice under its SLURM id and Snakemake did not submit it
    again."""
    jobs, faults, log = slurm_run["jobs"], slurm_run["faults"], slurm_run["log"]
    assert set(jobs["job"]) == slurm_run["submitted"], (jobs, slurm_run["submitted"])
    assert (jobs["account"] == ACCOUNT).all(), jobs
    state = dict(zip(jobs["job"], jobs["state"], strict=True))
    assert state[int(faults.cancelled)].startswith("CANCELLED"), jobs
    assert state[int(faults.timed_out)] == "TIMEOUT", jobs
    exits = [int(e["job"]) for e in slurm_run["sbatch"] if e["fault"] == "exit"]
    assert len(exits) == 1 and state[exits[0]] == "FAILED", (exits, jobs)
    runs = slurm_run["all_runs"]
    requeued = runs[runs["job"] == int(faults.requeued)]["state"].tolist()
    assert requeued == ["REQUEUED", "COMPLETED"], runs
    # each Snakemake job's SLURM jobs, in submission order: the last one COMPLETED
    by_job: dict[str, list[int]] = {}
    for job, slurm in re.findall(r"Job (\S+) has been submitted with SLURM jobid (\d+)", log):
        by_job.setdefault(job, []).append(int(slurm))
    for job, ids in by_job.items():
        assert state[ids[-1]] == "COMPLETED" or ids[-1] in slurm_run["left"], (job, ids, jobs)
        assert all(state[i] != "COMPLETED" for i in ids[:-1]), (job, ids, jobs)
    mine = [ids for ids in by_job.values() if int(faults.requeued) in ids]
    assert len(mine) == 1 and mine[0][-1] == int(faults.requeued), (mine, log[-3000:])


def test_the_controller_away_mid_run(slurm_run):
    """slurmctld stopped for OUTAGE s and started again while the compile job ran: the
    plugin's status rounds meanwhile found no controller (it then asks sacct: slurmdbd still
    answers), and the job, not forgotten, completed and was not submitted again."""
    faults, jobs = slurm_run["faults"], slurm_run["jobs"]
    assert faults.back is not None
    assert "Falling back to 'sacct' for status queries (MinJobAge=None" in slurm_run["log"]
    compiles = [int(e["job"]) for e in slurm_run["sbatch"] if e["kind"] == "compile"]
    states = [jobs.loc[jobs["job"] == j, "state"].item() for j in compiles]
    assert states == ["FAILED", "COMPLETED"], (compiles, jobs)


def test_a_timed_out_job_is_submitted_again_with_twice_its_runtime(slurm_run):
    """The profile's runtime grows with the attempt: the retry of the timed-out tile job asks
    for twice the first attempt's minutes."""
    faults, sbatch = slurm_run["faults"], slurm_run["sbatch"]
    first = next(e for e in sbatch if e["job"] == faults.timed_out)
    log = slurm_run["log"]
    job = dict((s, j) for j, s in re.findall(
        r"Job (\S+) has been submitted with SLURM jobid (\d+)", log))[faults.timed_out]
    again = [s for j, s in re.findall(r"Job (\S+) has been submitted with SLURM jobid (\d+)", log)
             if j == job and s != faults.timed_out]
    assert again, log[-3000:]
    retry = next(e for e in sbatch if e["job"] == again[0])
    assert int(retry["runtime"]) == 2 * int(first["runtime"]), (first, retry)
    # squeue showed the first attempt's limit (minutes) before the test cut it short
    assert faults.limit == f"{int(first['runtime'])}:00", faults.limit


def test_a_rerun_while_the_killed_runs_jobs_are_queued_stops_in_one_line(slurm_run):
    """The same command run again (after `snakemake --unlock`) while the killed run's jobs are
    still in the queue submits nothing and says, in one line, which jobs, their states and what
    to run."""
    refused, wd = slurm_run["refused"], slurm_run["wd"]
    text = refused.stdout + refused.stderr
    assert refused.returncode != 0, text[-3000:]
    assert "submitted with SLURM jobid" not in text
    said = {ln[ln.index("SLURM job "):] for ln in text.splitlines() if "of an earlier run in" in ln}
    assert len(said) == 1, text[-3000:]
    line = said.pop()
    match = re.fullmatch(
        rf"SLURM job (\d+) \(rule_\w+\) of an earlier run in {re.escape(str(wd))} is "
        r"(RUNNING|PENDING|COMPLETING)( and \d+ more)?: wait until `squeue --me` no longer lists "
        r"them or cancel them \(scancel ([\d ]+)\), then run the same command again", line)
    assert match, line
    # the jobs still queued right after it are among those it named
    assert set(match.group(4).split()) >= slurm_run["left"], (line, slurm_run["left"])


def test_nothing_is_left_in_the_queue_and_no_partial_file(slurm_run):
    wd = slurm_run["wd"]
    prefix = f"gearsim_test_{os.getpid()}"
    assert _squeue(prefix) == {}
    assert not list((wd / "results").rglob(".*.tmp-*")), list((wd / "results").rglob(".*"))
    for f in (wd / "results").rglob("*.parquet"):
        pd.read_parquet(f)


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
    """One SLURM job of one CPU per tile, its attractor tile in it; a tile whose job did not
    complete has one more."""
    jobs, log = slurm_run["jobs"], slurm_run["log"]
    tiles = jobs[jobs["comment"].str.startswith("rule_tiles_")]
    assert (tiles["cpus"] == 1).all(), tiles
    assert (tiles["state"] == "COMPLETED").sum() == TILES, tiles
    assert len(re.findall(r"\] Group job tiles ", log)) >= len(tiles), log[-3000:]


def test_every_rule_job_ran_in_slurm(slurm_run):
    """Snakemake's log names every job it ran: a job run by the main process is a `localrule`,
    a job in a SLURM job (its own or a group's) a `rule`."""
    log, final = slurm_run["log"], slurm_run["final_log"]
    jobs = re.findall(r"^\s*(localrule|rule) (\w+):$", log, re.M)
    local = [name for kind, name in jobs if kind == "localrule"]
    assert local == ["all"], local
    ran = {name for _, name in jobs}
    assert {"catalogue", "report", "explorer", "figures_index", "plane_maps", "attractor_maps",
            "sweep_diagram", "table1", "figure_01", "figure_20"} <= ran, ran
    total = int(re.search(r"^total\s+(\d+)", final, re.M).group(1))
    assert re.search(rf"^{total} of {total} steps \(100%\) done$", final, re.M), final[-3000:]


def test_small_jobs_went_in_three_group_jobs_of_one_cpu(slurm_run):
    jobs, log = slurm_run["jobs"], slurm_run["log"]
    groups = {g for g in re.findall(r"\] Group job (\w+) ", log) if g != "tiles"}
    assert groups == set(GROUPS), groups
    for group, cpus in GROUPS.items():
        mine = jobs[jobs["comment"].str.startswith(f"rule_{group}_")]
        assert len(mine) >= 1 and (mine["cpus"] == cpus).all(), jobs


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
