"""The dask client of a pipeline job.

By default each tile job starts its own ``LocalCluster`` with one single-threaded worker process
per Snakemake thread (``--workers {threads}``); when ``cluster.scheduler_address`` is set, the job
connects to that running scheduler instead (many machines, see docs/pipeline.md).

Workers run Numba kernels with ``NUMBA_NUM_THREADS=1`` (no nested parallelism) and read the
on-disk Numba cache that ``gearsim compile`` warmed before the workers started.
"""

from __future__ import annotations

import contextlib
import os
import re
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


@contextlib.contextmanager
def open_client(workers: int = 1, scheduler_address: str | None = None) -> Iterator[Any]:
    """A ``distributed.Client``: connected to ``scheduler_address``, or to a new LocalCluster.

    Parameters
    ----------
    workers
        Worker processes of the LocalCluster (one thread each); ignored with a scheduler address.
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
        try:
            yield client
        finally:
            client.close()
        return
    check_workers(workers)
    with (
        LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=40,  # logging.ERROR
        ) as cluster,
        Client(cluster) as client,
    ):
        yield client


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
