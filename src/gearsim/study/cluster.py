"""The dask client of a pipeline job.

By default each tile job starts its own ``LocalCluster`` with one single-threaded worker process
per Snakemake thread (``--workers {threads}``); inside a SLURM job the worker count is the CPUs
SLURM gave the job (:func:`job_cpus`). When ``cluster.scheduler_address`` is set, the job connects
to that running scheduler instead (many machines, see docs/pipeline.md).

The SLURM profile (profiles/slurm) sizes its jobs with :func:`fit_threads` and
:func:`fit_memory`: what a rule asks for, bounded by the nodes of the partition the jobs go to.

Workers run Numba kernels with ``NUMBA_NUM_THREADS=1`` (no nested parallelism) and read the
on-disk Numba cache that ``gearsim compile`` warmed before the workers started.
"""

from __future__ import annotations

import contextlib
import functools
import getpass
import logging
import os
import re
import shutil
import subprocess
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from gearsim.errors import UsageError
from gearsim.study.config import project_root

#: Environment every worker gets (inherited by LocalCluster processes).
WORKER_ENV = {
    "NUMBA_NUM_THREADS": "1",
    "OMP_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
}


#: Most worker processes a job may start (``--workers``, Snakemake threads).
MAX_WORKERS = 256
#: A dask scheduler address: protocol://host:port.
ADDRESS = re.compile(r"(tcp|tls|inproc|ucx|ws|wss)://[A-Za-z0-9._\-]+(:[0-9]{1,5})?|"
                     r"(tcp|tls|ws|wss)://\[[0-9A-Fa-f:.]+\](:[0-9]{1,5})?")


def check_address(address: str) -> str:
    """``address`` if it looks like a scheduler address, else one-line UsageError."""
    if not isinstance(address, str) or not ADDRESS.fullmatch(address):
        shown = repr(address)[:80]
        raise UsageError(
            f"scheduler address {shown} is malformed; expected protocol://host:port, "
            "e.g. tcp://10.0.0.5:8786"
        )
    return address


def check_workers(workers: int) -> int:
    """``workers`` if 1 <= workers <= :data:`MAX_WORKERS`, else one-line UsageError."""
    if isinstance(workers, bool) or not isinstance(workers, int) or not (
        1 <= workers <= MAX_WORKERS
    ):
        raise UsageError(f"--workers must be in 1..{MAX_WORKERS}, got {workers!r}")
    return workers


#: How long to wait for a configured scheduler before giving up (env GEARSIM_SCHEDULER_TIMEOUT).
CONNECT_TIMEOUT = os.environ.get("GEARSIM_SCHEDULER_TIMEOUT", "10s")


def _prepare_environment() -> None:
    for k, v in WORKER_ENV.items():
        os.environ.setdefault(k, v)
    if "NUMBA_CACHE_DIR" not in os.environ:
        os.environ["NUMBA_CACHE_DIR"] = str(project_root() / ".numba_cache")


def job_cpus() -> int | None:
    """The CPUs SLURM gave this job step, or ``None`` outside SLURM.

    ``SLURM_CPUS_PER_TASK`` when srun exported it; else, inside a SLURM job (``SLURM_JOB_ID``:
    the executor's jobstep plugin keeps only the job's identity variables), the CPUs this process
    may run on (the step's CPU binding).
    """
    value = os.environ.get("SLURM_CPUS_PER_TASK", "")
    if value.isdigit() and int(value) > 0:
        return int(value)
    if os.environ.get("SLURM_JOB_ID"):
        return len(os.sched_getaffinity(0))
    return None


def local_workers(workers: int) -> int:
    """Worker processes of a job's LocalCluster: the CPUs SLURM gave the job, else ``workers``."""
    cpus = job_cpus()
    return check_workers(min(cpus, MAX_WORKERS) if cpus is not None else workers)


def _partition(partition: str | None) -> str:
    """``partition``, else $SBATCH_PARTITION (sbatch's own variable, which the profile passes on as
    ``slurm_partition``), else '' (the cluster's default partition)."""
    return partition if partition is not None else os.environ.get("SBATCH_PARTITION", "")


@functools.lru_cache(maxsize=8)
def node_limits(partition: str = "") -> tuple[int, int] | None:
    """(CPUs, memory in MB) of the largest node of ``partition`` ('' = the default partition), from
    ``sinfo``; ``None`` where no SLURM controller answers (nothing to fit: a dry run, or sbatch
    itself will refuse). A partition the controller does not know is a one-line UsageError.
    """
    if shutil.which("sinfo") is None:
        return None
    cmd = ["sinfo", "--noheader", "--format=%P %c %m"]
    if partition:
        cmd += ["--partition", partition]
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=30, check=True).stdout
    except (subprocess.CalledProcessError, subprocess.TimeoutExpired):
        return None
    rows = []
    for line in out.splitlines():
        name, cpus, mem = (f.rstrip("+") for f in line.split())  # "+": sizes above this one
        if (name.rstrip("*") == partition if partition else name.endswith("*")) and cpus.isdigit():
            rows.append((int(cpus), int(mem) if mem.isdigit() else 0))
    if not rows:
        where = f"partition {partition!r}" if partition else "a default partition"
        raise UsageError(f"SLURM has no {where} (sinfo lists: {out.split() or 'nothing'}); "
                         "set SBATCH_PARTITION to one of its partitions")
    return max(r[0] for r in rows), max(r[1] for r in rows)


def fit_threads(wanted: int, partition: str | None = None) -> int:
    """``wanted`` threads, at most the CPUs of the partition's largest node (a job asking for
    more would pend forever); ``wanted`` where there is no SLURM."""
    limits = node_limits(_partition(partition))
    return wanted if limits is None else max(1, min(wanted, limits[0]))


def fit_memory(mb_per_cpu: int, threads: int, rule: str = "a job",
               partition: str | None = None) -> int:
    """``mb_per_cpu`` if ``threads`` CPUs of it fit on one node of the partition, else a one-line
    UsageError before anything is submitted (less memory than a rule needs is not a fit)."""
    limits = node_limits(_partition(partition))
    if limits is not None and limits[1] and mb_per_cpu * threads > limits[1]:
        raise UsageError(
            f"{rule} needs {mb_per_cpu} MB per CPU x {threads} CPUs = {mb_per_cpu * threads} MB; "
            f"the largest node of partition {_partition(partition) or '(default)'} has "
            f"{limits[1]} MB: choose a partition with larger nodes (SBATCH_PARTITION)")
    return mb_per_cpu


@functools.lru_cache(maxsize=8)
def user_accounts(user: str) -> frozenset[str] | None:
    """The SLURM accounts ``user`` may submit under (``sacctmgr`` associations, lower case);
    ``None`` where nothing answers (no SLURM, or a cluster without accounting)."""
    if shutil.which("sacctmgr") is None:
        return None
    cmd = ["sacctmgr", "--noheader", "--parsable2", "list", "associations", f"user={user}",
           "format=account"]
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=30, check=True).stdout
    except (subprocess.CalledProcessError, subprocess.TimeoutExpired):
        return None
    return frozenset(a.strip().lower() for a in out.split() if a.strip())


def slurm_account(account: str | None = None) -> str:
    """``account`` (else $SBATCH_ACCOUNT, else ''), checked against the user's accounts before
    anything is submitted: an account sacctmgr does not list for the user is a one-line
    UsageError (the executor plugin 2.8.0 raises in its submission thread and the run waits
    forever). '' lets SLURM use the user's default account; where accounting does not answer,
    or lists no account for the user, the account goes to sbatch unchecked."""
    account = os.environ.get("SBATCH_ACCOUNT", "") if account is None else account
    if not account:
        return ""
    known = user_accounts(getpass.getuser())
    if known and account.lower() not in known:
        raise UsageError(
            f"SLURM account {account!r} is not one of yours (sacctmgr lists: "
            f"{', '.join(sorted(known))}); set SBATCH_ACCOUNT to one of them, or unset it for "
            "your default account")
    return account


def earlier_run_jobs() -> int:
    """0 where no SLURM job of an earlier Snakemake run in this folder is still in the queue;
    else a one-line UsageError naming them, their states and what to run.

    The profile evaluates it with every job's resources (once per process, before the first
    submission). A Snakemake killed without cancelling its jobs (SIGKILL, a lost login session)
    leaves them running; the same command run again would submit their jobs a second time, two
    SLURM jobs writing the same files. Inside a SLURM job (a job step's Snakemake) it is 0.
    """
    if os.environ.get("SLURM_JOB_ID") or shutil.which("squeue") is None:
        return 0
    return _earlier_run_jobs(os.path.realpath(os.getcwd()))


@functools.lru_cache(maxsize=8)
def _earlier_run_jobs(workdir: str) -> int:
    # %k: the comment the executor plugin gives each job (rule_<rule or group>...), %Z: its
    # working directory (sbatch -D, the folder Snakemake ran in)
    cmd = ["squeue", "--me", "--noheader", "--format=%i|%T|%k|%Z"]
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=30, check=True).stdout
    except (subprocess.CalledProcessError, subprocess.TimeoutExpired):
        return 0  # no controller answers: sbatch will say so
    jobs = []
    for line in out.splitlines():
        job, state, comment, folder = (line.split("|", 3) + ["", "", ""])[:4]
        if comment.startswith("rule_") and os.path.realpath(folder) == workdir:
            jobs.append((job, state, comment))
    if not jobs:
        return 0
    job, state, comment = jobs[0]
    more = f" and {len(jobs) - 1} more" if len(jobs) > 1 else ""
    raise UsageError(
        f"SLURM job {job} ({comment[:48]}) of an earlier run in {workdir} is {state}{more}: "
        f"wait until `squeue --me` no longer lists them or cancel them (scancel "
        f"{' '.join(j for j, _, _ in jobs)}), then run the same command again")


@contextlib.contextmanager
def open_client(workers: int = 1, scheduler_address: str | None = None) -> Iterator[Any]:
    """A ``distributed.Client``: connected to ``scheduler_address``, or to a new LocalCluster.

    Parameters
    ----------
    workers
        Worker processes of the LocalCluster (one thread each) outside SLURM; inside a SLURM job
        the CPUs SLURM gave it (:func:`local_workers`). Ignored with a scheduler address.
    scheduler_address
        ``tcp://host:port`` of a running ``dask scheduler``; ``None`` = LocalCluster.
    """
    _prepare_environment()
    # imported here, not at module level: `import distributed` costs ~0.6 s (measured with
    # python -X importtime) and every `gearsim` command imports this module through tiles
    from distributed import Client, LocalCluster

    if scheduler_address:
        check_address(scheduler_address)
        try:
            client = Client(scheduler_address, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError, ValueError, TypeError) as exc:
            raise UsageError(f"cannot reach dask scheduler {scheduler_address}: {exc}") from None
        # the client's own log of a lost scheduler is a traceback per reconnection attempt; the
        # one line below says what happened and what to run
        log = logging.getLogger("distributed.client")
        level = log.level
        log.setLevel(logging.CRITICAL)
        try:
            yield client
        except BaseException as exc:  # a cancelled future is an asyncio.CancelledError
            if not _scheduler_lost(exc):
                raise
            raise UsageError(
                f"lost dask scheduler {scheduler_address} mid-job; nothing was written: start "
                "the scheduler again, then run the same command"
            ) from None
        finally:
            client.close()
            log.setLevel(level)
        return
    check_workers(workers)
    with (
        LocalCluster(
            n_workers=local_workers(workers),
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=40,  # logging.ERROR
        ) as cluster,
        Client(cluster) as client,
    ):
        yield client


def _scheduler_lost(exc: BaseException) -> bool:
    """Whether ``exc`` is how a client learns that its scheduler went away: its futures are
    cancelled for "scheduler-connection-lost", or a call finds the connection closed."""
    from distributed.client import FutureCancelledError
    from distributed.comm import CommClosedError

    if isinstance(exc, FutureCancelledError):
        return exc.reason == "scheduler-connection-lost"
    return isinstance(exc, CommClosedError)


def map_unordered(client, fn: Callable, items: Sequence[Any]) -> Iterator[Any]:
    """Submit ``fn(item)`` for every item and yield results as they finish.

    Tasks are submitted with ``pure=False`` so repeated runs are never served from a cache.
    """
    from distributed import as_completed  # lazy: see open_client

    futures = client.map(fn, list(items), pure=False)
    for fut in as_completed(futures):
        yield fut.result()
        fut.release()


def describe(client) -> str:
    """One line: scheduler address and worker count."""
    nthreads = client.nthreads()  # every worker (scheduler_info() lists only a few)
    address = client.scheduler.address if client.scheduler else "?"
    return f"scheduler {address}: {len(nthreads)} workers, {sum(nthreads.values())} threads"
