"""Progress lines of the long jobs (tiles, sweeps, attractor tiles, orbit refinement, the
catalogue): one module without the jobs' libraries, so that a job imports only its own."""

from __future__ import annotations

import sys
import time


class Progress:
    """Per-tile log lines (cells done/total, cells per second) and a tqdm bar on a terminal."""

    def __init__(self, label: str, total: int, *, stream=None) -> None:
        self.label = label
        self.stream = stream or sys.stderr
        self.bar = None
        if sys.stdout.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc=label, unit="cell", file=sys.stdout)
        self.last = 0

    def __call__(self, done: int, total: int, elapsed: float) -> None:
        rate = done / elapsed if elapsed > 0 else float("nan")
        if self.bar is not None:
            self.bar.update(done - self.last)
        self.last = done
        print(
            f"[{time.strftime('%H:%M:%S')}] {self.label}: {done}/{total} cells "
            f"({100 * done / max(total, 1):.0f}%), {rate:.2f} cells/s, {elapsed:.1f} s",
            file=self.stream,
            flush=True,
        )

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
