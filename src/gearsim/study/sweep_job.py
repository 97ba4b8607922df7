"""One sweep job or point-set job (``gearsim sweep``): the configured sweep or figure point set
simulated, as its table and its provenance (the tables: :mod:`gearsim.study.sweeps`)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from gearsim.errors import UsageError
from gearsim.study import provenance
from gearsim.study.config import Study, results_dir

Progress = Callable[[int, int, float], None]


@dataclass(frozen=True)
class Recording:
    """How a point set's motions are recorded: the forward continuation ramp in ``w``, the
    recorded mesh periods and the samples per period."""

    ramp_from: float = 0.1
    ramp_step: float = 0.02
    periods: int = 64
    samples_per_period: int = 128

    def check(self) -> Recording:
        """One line naming the option outside its range."""
        for flag, v, lo, hi, closed in (
            ("--ramp-from", self.ramp_from, 0.0, 100.0, False),
            ("--ramp-step", self.ramp_step, 0.0, 10.0, False),
            ("--periods", self.periods, 1, 100_000, True),
            ("--samples-per-period", self.samples_per_period, 4, 100_000, True),
        ):
            if not (math.isfinite(v) and (lo <= v if closed else lo < v) and v <= hi):
                rng = f"[{lo}, {hi}]" if closed else f"({lo}, {hi}]"
                raise UsageError(f"{flag}: {v!r} is outside {rng}")
        return self


def default_out(study: Study, sweep: str | None, points: str | None) -> Path:
    """``<results>/sweeps/<sweep>.parquet`` or ``<results>/points/<set>.parquet``."""
    res = results_dir(study.config)
    return res / "sweeps" / f"{sweep}.parquet" if sweep else res / "points" / f"{points}.parquet"


def size(study: Study, sweep: str | None, points: str | None) -> int:
    """How many values or points the job simulates (the name checked: one line)."""
    from gearsim.study.grid import sweep_values
    from gearsim.study.sweeps import point_list

    kind, name = ("sweeps", sweep) if sweep else ("points", points)
    table = study.config[kind]
    if name not in table:
        what = "sweep" if sweep else "point set"
        raise UsageError(f"unknown {what} '{name}'; configured: {', '.join(table) or 'none'}")
    return len(sweep_values(table[name]) if sweep else point_list(table[name]))


def run(study: Study, sweep: str | None, points: str | None, recording: Recording,
        progress: Progress | None = None, backend=None) -> tuple[Any, dict]:
    """The sweep ``sweep`` (or the point set ``points``) simulated: its table and provenance.
    ``backend``: where a sweep's chain runs (None: the CPU; a point set's motions are recorded
    by the scalar integrator)."""
    from gearsim.study.grid import sweep_values
    from gearsim.study.sweeps import points_frame, sweep_frame

    size(study, sweep, points)
    started, t0 = provenance.now_iso(), time.perf_counter()
    if sweep:
        spec = study.config["sweeps"][sweep]
        df = sweep_frame(study.parameters(sweep=sweep).model, spec["name"], sweep_values(spec),
                         spec.get("direction", "forward"), study.settings, progress,
                         spec.get("start", "continuation"), backend)
        subtree, kind, name = provenance.sweep_subtree(study, sweep), "sweep", sweep
    else:
        df = points_frame(study, points, **asdict(recording), progress=progress)
        subtree = {**provenance.point_subtree(study, points), "recording": asdict(recording)}
        kind, name, backend = "points", points, None
    wall = time.perf_counter() - t0
    return df, provenance.provenance(subtree, kind=kind, name=name, study=study,
                                     started=started, finished=provenance.now_iso(),
                                     wall_s=wall, cells=len(df), workers="in-process",
                                     device=None if backend is None else backend.record())
