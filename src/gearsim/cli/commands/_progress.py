"""Progress of the long jobs (tiles, sweeps, attractor tiles, orbit refinement, the catalogue):
one module without the jobs' libraries, so that a job imports only its own.

On a terminal the progress is one line rewritten in place; in a log (a pipeline job, a
redirected command) it is a line every few seconds, plus the first and the last. Either says
cells done, cells per second and the time left at this run's rate. The rate is measured from
the first cell this run finished (the time before it, loading or compiling the kernels and
starting the workers, is not a cell's), and neither it nor the time left is shown before
:data:`MEASURE_CELLS` cells and :data:`MEASURE_SECONDS` seconds went into it ("measuring").

A line rewritten on a terminal is open until :meth:`Progress.close`; :func:`end_line` ends any
open line (the command line's Ctrl-C message then starts on a line of its own).
"""

from __future__ import annotations

import sys
import time

#: Seconds between two progress lines in a log; between two rewrites of the line on a terminal.
LOG_INTERVAL = 5.0
TTY_INTERVAL = 0.5
#: A rate (and the time left) is shown once this many cells and seconds went into measuring it.
MEASURE_CELLS = 3
MEASURE_SECONDS = 5.0

#: the progress lines open on a terminal (rewritten in place, not yet ended by a newline)
_OPEN: set[Progress] = set()


def end_line() -> None:
    """End every progress line open on a terminal (a newline), so that what follows starts on a
    line of its own."""
    for p in list(_OPEN):
        p.close()


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
        self.first: tuple[int, float] | None = None  # (done, elapsed) at this run's first cell

    def rate(self, done: int, total: int, elapsed: float) -> float | None:
        """Cells per second of this run, None while it is being measured."""
        if done >= total:  # the last line: this run's average
            new = done - self.start
            return new / elapsed if elapsed > 0 and new > 0 else None
        if self.first is None:
            return None
        cells, seconds = done - self.first[0], elapsed - self.first[1]
        if cells < MEASURE_CELLS or seconds < MEASURE_SECONDS:
            return None
        return cells / seconds

    def text(self, done: int, total: int, elapsed: float) -> str:
        self._note_first(done, elapsed)
        rate = self.rate(done, total, elapsed)
        if rate is not None:
            left = (total - done) / rate if done < total else 0.0
            speed = (f"{rate:.2f} cells/s, {duration_text(elapsed)} so far, "
                     f"{duration_text(left)} left")
        else:
            speed = f"{duration_text(elapsed)} so far, time left: measuring the rate"
        return (f"[{time.strftime('%H:%M:%S')}] {self.label}: {done}/{total} cells "
                f"({100 * done / max(total, 1):.0f}%), {speed}")

    def _note_first(self, done: int, elapsed: float) -> None:
        if self.first is None and done > self.start:
            self.first = (done, elapsed)

    def __call__(self, done: int, total: int, elapsed: float) -> None:
        self._note_first(done, elapsed)  # every call: the rate's reference is the first cell
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
            _OPEN.add(self)
        else:
            print(line, file=self.stream, flush=True)

    def close(self) -> None:
        _OPEN.discard(self)
        if self.tty and self.width:
            print(file=self.stream, flush=True)
            self.width = 0
