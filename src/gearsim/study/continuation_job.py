"""A continuation job (``gearsim continue``): its options checked, the start orbit found from a
settled simulation, the branches followed, and the tables it writes (branches, located points,
exact landmarks beside a simulated sweep) with the lines that report them."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from gearsim.analysis.continuation import continue_orbit
from gearsim.analysis.continuation_options import Continuation
from gearsim.analysis.exact_landmarks import bifurcation_points, exact_landmarks, report_lines
from gearsim.analysis.orbits import SEEDING, find_periodic_orbit, shooting_settings
from gearsim.cell.simulate import simulate_cell
from gearsim.dynamics.parameters import ModelParameters
from gearsim.errors import UsageError

#: Wall-clock budget of a continuation (s): the standard one takes ~1 CPU-minute, 4 minutes
#: of wall on a loaded machine (benchmarks/README.md); a normal run is never cut.
DEFAULT_BUDGET_S = 1800.0


@dataclass(frozen=True)
class ContinuationJob:
    """What ``gearsim continue`` asks: the parameter, its range, the start period (None: the
    period simulated from rest) and the follower's steps and budget."""

    name: str
    start: float
    stop: float
    period: int | None = None
    ds: float = 0.01
    ds_max: float = 0.05
    max_points: int = 400
    switch_depth: int = 2
    budget_s: float = DEFAULT_BUDGET_S
    rtol: float | None = None

    def check(self) -> None:
        """One line naming the option and its allowed range (a usage error)."""
        for key in ("ds", "ds_max"):
            v = getattr(self, key)
            if not (0 < v <= 1):
                raise UsageError(f"--{key.replace('_', '-')} = {v} must be in (0, 1]")
        if self.max_points < 2:
            raise UsageError(f"--max-points = {self.max_points} must be >= 2")
        if not 0 <= self.switch_depth <= 6:
            raise UsageError(f"--switch-depth = {self.switch_depth} must be in [0, 6]")
        if self.start == self.stop:
            raise UsageError(f"--from and --to are equal ({self.start}): empty range")
        if not 0 < self.budget_s <= 7 * 86400:
            raise UsageError(f"--budget-s = {self.budget_s:g} must be in (0, 604800]")

    def default_out(self, period: int | str) -> Path:
        """The branch table's default path, beside the pipeline's orbit tables."""
        return Path(f"results/orbits/continue_{self.name}_{self.start:g}_{self.stop:g}_p"
                    f"{period}.parquet")


@dataclass
class ContinuationRun:
    """A finished (or budget-cut) continuation: the branch table, its located points, the
    exact landmarks (with a sweep), the start period and the wall time."""

    branches: pd.DataFrame
    points: pd.DataFrame
    landmarks: pd.DataFrame | None
    period: int
    elapsed_s: float


def start_period(job: ContinuationJob, params: ModelParameters) -> tuple[int, object]:
    """The start orbit's period (the job's, else the one simulated from rest) and the settled
    simulation it starts from."""
    sim = simulate_cell(params, settings=SEEDING)
    return (job.period if job.period is not None else max(sim.classification.n, 1)), sim


def run(job: ContinuationJob, params: ModelParameters, source: str, *,
        sweep: str | Path | None = None, period: int | None = None, sim=None,
        log: Callable[[str], None] = lambda line: None) -> ContinuationRun:
    """Follow ``job`` from ``params`` (start period and settled simulation from
    :func:`start_period` unless given); with ``sweep`` (a simulated sweep's Parquet of the same
    parameter set) the exact landmarks beside it."""
    if sweep is not None and not Path(sweep).is_file():
        raise UsageError(f"--sweep: file not found: {sweep}")
    t0 = time.perf_counter()
    deadline = time.monotonic() + job.budget_s
    if period is None or sim is None:
        period, sim = start_period(job, params)
    st = shooting_settings(job.rtol)
    orbit = find_periodic_orbit(params, period, sim.final_state, st, grazing=False)
    cfg = Continuation(ds=job.ds, ds_max=job.ds_max, max_points=job.max_points,
                       switch_depth=job.switch_depth, settings=st, progress=log,
                       deadline=deadline)
    df = continue_orbit(params, job.name, job.start, job.stop, orbit, config=cfg)
    df.attrs["parameters_source"] = source
    points = bifurcation_points(df).assign(name2="", value2=math.nan)
    landmarks = (None if sweep is None
                 else exact_landmarks(bifurcation_points(df), pd.read_parquet(sweep)))
    return ContinuationRun(df, points, landmarks, period, time.perf_counter() - t0)


def summary(job: ContinuationJob, result: ContinuationRun, params: ModelParameters,
            source: str) -> list[str]:
    """The lines a finished continuation prints: its source, size, located events, reasons,
    the landmarks beside the sweep and the budget's stop."""
    df = result.branches
    lines = [] if result.landmarks is None else list(report_lines(result.landmarks))
    lines += [f"parameters: {source} (model {params.model})",
              f"{len(df)} branch points on {df['branch'].nunique()} branches in "
              f"{result.elapsed_s:.1f} s"]
    for r in df[df["event"] != ""].itertuples():
        extra = f" ({r.boundary})" if r.boundary else ""
        lines.append(f"  {r.event:16s}{extra:10s} {job.name} = {r.value:.10f}  period "
                     f"{r.period}  x = {r.x:.6f}")
    lines += [f"  {reason}" for reason in df.attrs["reasons"]]
    if df.attrs.get("status") == "budget":
        lines.append(f"stopped at the budget of {job.budget_s:g} s (status budget): the "
                     "branches are partial")
    return lines


def as_json(job: ContinuationJob, result: ContinuationRun, source: str,
            paths: dict[str, Path | None]) -> dict:
    """The ``--json`` record of a continuation (``paths``: parquet, figure, landmarks)."""
    df = result.branches
    ev = df[df["event"] != ""]
    return {
        "parameters_source": source, "name": job.name, "period": result.period,
        "points": int(len(df)), "elapsed_s": result.elapsed_s, "parquet": str(paths["parquet"]),
        "figure": str(paths["figure"]),
        "events": [{"event": r.event, "value": r.value, "period": int(r.period),
                    "branch": int(r.branch), "boundary": r.boundary, "x": r.x}
                   for r in ev.itertuples()],
        "reasons": df.attrs["reasons"], "status": df.attrs.get("status", "ok"),
        "landmarks": None if paths["landmarks"] is None else str(paths["landmarks"]),
    }
