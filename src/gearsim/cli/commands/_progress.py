"""Progress of the long jobs (tiles, sweeps, attractor tiles, orbit refinement, the catalogue):
one module without the jobs' libraries, so that a job imports only its own.

On a terminal the progress is one line rewritten in place; in a log (a pipeline job, a
redirected command) it is a line every few seconds, plus the first and the last. Either says
cells done, cells per second and the time left at this run's rate.
"""

from __future__ import annotations

import sys
import time

#: Seconds between two progress lines in a log; between two rewrites of the line on a terminal.
LOG_INTERVAL = 5.0
TTY_INTERVAL = 0.5


def duration_text(seconds: float) -> str:
    """``47 s``, ``3 min 20 s``, ``2 h 05 min``."""
    if seconds != seconds or seconds == float("inf"):
        return "?"
    s = int(round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


class Progress:
    """``progress(done, total, elapsed)``: cells done of ``total`` after ``elapsed`` seconds of
    this run; ``start`` cells were done before it (a resumed run), so the rate and the time left
    count this run's cells only."""

    def __init__(self, label: str, total: int, *, stream=None, start: int = 0,
                 interval: float | None = None) -> None:
        self.label = label
        self.stream = stream or sys.stderr
        isatty = getattr(self.stream, "isatty", None)
        self.tty = bool(isatty and isatty())
        self.interval = interval if interval is not None else (
            TTY_INTERVAL if self.tty else LOG_INTERVAL)
        self.start = start
        self.total = total
        self.shown = -1.0  # monotonic time of the last line
        self.width = 0

    def text(self, done: int, total: int, elapsed: float) -> str:
        new = done - self.start
        rate = new / elapsed if elapsed > 0 else float("nan")
        left = (total - done) / rate if rate > 0 else float("nan")
        return (f"[{time.strftime('%H:%M:%S')}] {self.label}: {done}/{total} cells "
                f"({100 * done / max(total, 1):.0f}%), {rate:.2f} cells/s, "
                f"{duration_text(elapsed)} so far, {duration_text(left)} left")

    def __call__(self, done: int, total: int, elapsed: float) -> None:
        now = time.monotonic()
        last = done >= total
        if not last and self.shown >= 0 and now - self.shown < self.interval:
            return
        self.shown = now
        line = self.text(done, total, elapsed)
        if self.tty:
            pad = max(0, self.width - len(line))
            self.width = len(line)
            print("\r" + line + " " * pad, end="", file=self.stream, flush=True)
        else:
            print(line, file=self.stream, flush=True)

    def close(self) -> None:
        if self.tty and self.width:
            print(file=self.stream, flush=True)
            self.width = 0
