"""What a fit's process records of itself: start and end, load, code, wall and CPU seconds."""

from __future__ import annotations

import os
import resource
import time
from datetime import UTC, datetime
from typing import Any

from gearsim.study.provenance import git_commit


def code() -> str:
    """Short git commit of the package's checkout (``+dirty`` with uncommitted changes in it),
    ``unknown`` outside a git checkout."""
    commit, dirty = git_commit(short=True)
    return "unknown" if commit is None else commit + ("+dirty" if dirty else "")


def utc_now() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def user_s() -> float:
    """User CPU seconds of this process and its finished children (the search's workers)."""
    return (resource.getrusage(resource.RUSAGE_SELF).ru_utime
            + resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime)


class Run:
    """What a fit's process records of itself: start and end (UTC), load average at the start
    (1, 5, 15 min), git commit, wall and user CPU seconds (:meth:`record`)."""

    def __init__(self) -> None:
        self.t0 = time.time()
        self.u0 = user_s()
        self.info = {"start": utc_now(), "load": " ".join(f"{v:.2f}" for v in os.getloadavg()),
                     "code": code()}

    def record(self) -> dict[str, Any]:
        return {**self.info, "wall_s": time.time() - self.t0, "user_s": user_s() - self.u0,
                "end": utc_now()}
