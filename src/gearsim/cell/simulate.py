"""Drivers: integrate a cell to its steady motion and classify it; record trajectories.

``simulate_cell`` runs a transient (its last ``tangent_lead`` periods with the tangent vector;
with ``transient_recurrence`` a continued cell's transient ends early when its start recurs),
then measures in chunks of mesh periods and stops as soon as a period ``n <= n_max`` is
established and confirmed, or when the budget ``max_periods`` is spent (then chaos,
quasi-periodic or unsettled is decided by the Lyapunov exponent).

With ``settle_check = s > 0`` the transient adapts to the contraction: the tangent lead (the
transient's last ``tangent_lead`` periods) is recorded, and from :data:`EARLY_LEAD` +
:data:`EARLY_WINDOW` periods into it, every ``s`` periods, its last :data:`EARLY_WINDOW` periods
are a window for the period test: the cell ends at once when that window has a period, is
settled and repeats to :data:`EARLY_RTOL` throughout (:func:`settled_period`; it is labelled as
it stands). A cell that does not settle so reaches the end of its transient plus ``chunk``
periods: that last window is the fixed plan's first measuring chunk, and measuring goes on as
without the option (period test, budget, refinement and statuses unchanged). The chain's next
cell starts from the state where the cell ended.

A motion without a period where the mesh's linear limit is unstable is labelled only after its
long run shows it bounded (:func:`gearsim.cell.growth.check_growth`, the last step here and in
the batched driver).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from gearsim.cell.classify import repeats_throughout, window_period
from gearsim.cell.growth import check_growth
from gearsim.cell.record import Classification, result_columns, row_values
from gearsim.cell.verify import (
    FLOQUET,
    REFINE_RTOL,
    OrbitCache,
    fill_margins,
    read_window,
    verify_motion,
    window_settle,
)
from gearsim.dynamics.model import (
    N_STATE,
    mesh_force_series,
    pack_parameters,
    project_tangent,
    static_state,
)
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.numerics.integrate import (
    STATUS_OK,
    IntegrationSettings,
    PeriodSummaries,
    Run,
    run_periods,
    steps_lower_bound,
)
from gearsim.numerics.settings import TANGENT_SEED
from gearsim.numerics.variational import Spectrum, lyapunov_spectrum

__all__ = [
    "TANGENT_SEED",
    "IntegrationSettings",
    "Run",
    "run_periods",
    "CellResult",
    "result_columns",
    "simulate_cell",
    "finish_cell",
    "diverged_result",
    "seeds_continuation",
    "period_of",
    "settled_period",
    "EARLY_WINDOW",
    "next_settle_check",
    "recurrence_probe",
    "initial_tangent",
    "Trajectory",
    "trajectory",
]

@dataclass
class CellResult:
    """Outcome of :func:`simulate_cell`: the classification plus what continuation needs."""

    classification: Classification
    final_state: np.ndarray  # (10,) state on the section at the end
    final_period: int  # absolute period index of final_state (tau = final_period T)
    poincare: np.ndarray  # (k, 10) section states of the analysed window (k <= 2 n_max)
    periods: int  # mesh periods integrated in all
    steps: int  # integrator steps taken
    params: ModelParameters = field(repr=False)
    spectrum: Spectrum | None = field(default=None, repr=False)  # with simulate_cell(spectrum=)

    def row(self) -> dict[str, Any]:
        """Flat record for tables (the catalogue's cell columns: :func:`result_columns`)."""
        c = row_values(self.classification)  # no readings of a motion that never settled
        c["periods"] = self.periods
        c["steps"] = self.steps
        return c


def initial_tangent(params: ModelParameters) -> np.ndarray:
    """The fixed (seeded) initial tangent vector, on the states the model evolves.

    In the single-DOF model the bearing states are frozen: their tangent components are zero, so
    the Lyapunov exponent measures the mesh mode (a frozen component would never decay and pull
    the estimate to zero).
    """
    return project_tangent(_tangent_unit(), pack_parameters(params))


@functools.cache
def _tangent_unit() -> np.ndarray:
    v = np.random.default_rng(TANGENT_SEED).standard_normal(N_STATE)
    v = v / np.linalg.norm(v)
    v.flags.writeable = False
    return v


def diverged_result(params: ModelParameters, k: int, steps: int,
                    status: str = "diverged") -> CellResult:
    """The record of a cell that did not reach a steady motion.

    ``status`` ``"diverged"`` (the state left the divergence bound, or the step collapsed) or
    ``"budget"`` (the cell needs more than ``IntegrationSettings.max_steps`` steps; its motion
    is ``unsettled``).
    """
    nan = float("nan")
    values = {f.name: nan for f in fields(Classification)}
    values.update(motion="diverged" if status == "diverged" else "unsettled", status=status,
                  I=0, n=0, p=None, q=None, label=status, label_npq="", converged=False,
                  window_periods=0, critical="", refined=False)
    final = static_state(pack_parameters(params))
    return CellResult(Classification(**values), final, 0, np.zeros((0, N_STATE)), k, steps,
                      params)


def seeds_next(status: str, long_run: float) -> bool:
    """Whether a cell of this ``status`` and ``long_run`` starts the next cell of a continuation
    chain from its final state: not after a divergence or the step budget (the next cell starts
    from the static state); a cell that only its long run showed growing
    (:mod:`gearsim.cell.growth`, checked after the chain) seeds with its window's end state. The
    one rule for results (:func:`seeds_continuation`) and for their table rows (the audit)."""
    return status not in ("diverged", "budget") or long_run == long_run


def chain_start(prev) -> tuple[np.ndarray | None, int]:
    """``(u0, start_period)`` of a chain's cell from its left neighbour's table row ``prev`` (a
    mapping with ``status``, ``long_run``, ``final_state``, ``final_period``; None for a row's
    first cell): where the chain started it (:func:`seeds_next`; ``(None, 0)``: the static
    state). Tables written before ``long_run`` existed lack it (NaN)."""
    if prev is None:
        return None, 0
    long_run = prev.get("long_run")
    if not seeds_next(str(prev["status"]), float("nan") if long_run is None else float(long_run)):
        return None, 0
    return np.asarray(prev["final_state"], dtype=float), int(prev["final_period"])


def seeds_continuation(res: CellResult) -> bool:
    """:func:`seeds_next` of a result."""
    c = res.classification
    return seeds_next(c.status, c.long_run)


def period_of(s: PeriodSummaries, params: ModelParameters, st: IntegrationSettings) -> int:
    """The period test on recorded periods ``s`` (:func:`~gearsim.cell.classify.window_period`,
    tolerances relative to the orbit's x range): the motion's period ``n``, 0 if none.
    The one call of the scalar and the batched driver, for measuring chunks and the probe."""
    # every argument given: a call that leaves a default out misses Numba's fast dispatch
    # (~0.4 ms of argument typing per call)
    return window_period(s.section[:, 0], s.section[:, 1], s.xmax, s.xmin, params.w, st.n_max,
                         st.period_rtol)


#: the adaptive transient ends when, besides the period test, every section point of the window
#: repeats after ``n`` to this (relative, as the period test): then its oldest point is within
#: ``EARLY_RTOL / |1 - mu|`` of the orbit, and the window's DC and Kmax (over all its periods)
#: are those of the fixed plan's later window to ~1e-6 (docs/decisions.md, "Adaptive settling")
EARLY_RTOL = 1e-7
#: the adaptive transient's window (at most ``chunk``): the period test's shortest window for
#: periods up to 4 (``max(2 n, 16) + n`` points); a longer period is confirmed by the fixed plan
EARLY_WINDOW = 20
#: periods of tangent lead before the adaptive transient's first window (the window's exponent
#: is that of a vector aligned over at least these periods)
EARLY_LEAD = 4


def settled_period(s: PeriodSummaries, params: ModelParameters,
                   st: IntegrationSettings) -> int:
    """The period ``n`` of window ``s`` if it would be labelled as it stands, settled
    throughout: every point within :data:`EARLY_RTOL` of the one ``n`` periods later
    (:func:`~gearsim.cell.classify.repeats_throughout`, the cheap test first: most windows
    fail it), the period test's period (:func:`period_of`) and a settle distance at most
    :data:`~gearsim.cell.verify.REFINE_RTOL`; else 0. The adaptive transient's test."""
    scale = max(float(s.xmax.max() - s.xmin.min()), 1e-9)
    n = repeats_throughout(s.section[:, 0], s.section[:, 1], scale, float(params.w), 4,
                           EARLY_RTOL)
    if n == 0 or period_of(s, params, st) != n or not window_settle(params, s, n) <= REFINE_RTOL:
        return 0
    return n


def next_settle_check(done: int, st: IntegrationSettings, transient: int, window: int) -> int:
    """Periods since the cell's start at the adaptive transient's next check after ``done``:
    :data:`EARLY_LEAD` + :data:`EARLY_WINDOW` periods into the tangent lead, then every
    ``settle_check`` periods, at most ``transient + window`` (the last check: the fixed plan's
    first measuring chunk)."""
    first = transient - min(st.tangent_lead, transient) + EARLY_LEAD + min(EARLY_WINDOW, window)
    return min(first if done < first else done + st.settle_check, transient + window)


def recurrence_probe(st: IntegrationSettings, continued: bool, transient: int) -> int:
    """Periods of the recurrence probe of a cell (``transient_recurrence``), 0 for none: only a
    continued cell whose transient is longer than the probe has one."""
    k = st.transient_recurrence
    return k if continued and 0 < k < transient else 0


def finish_cell(
    params: ModelParameters,
    summaries: PeriodSummaries,
    n: int,
    st: IntegrationSettings,
    final_state: np.ndarray,
    k: int,
    start_period: int,
    steps: int,
    floquet: str = "slow",
    orbits: OrbitCache | None = None,
) -> CellResult:
    """Classify the measured periods of a cell (period ``n``, 0 if none) into its result.

    Whole motion periods only are analysed; the early part of a long measurement is dropped.
    The settle distance is read from all measured periods; a cell that is not settled, or has
    no period and no chaos, is labelled by its Newton-refined orbit where one is found
    (:func:`gearsim.cell.verify.verify_motion`; ``floquet``, or ``st.floquet`` when stronger:
    ``"all"`` refines every periodic cell). The one tail of :func:`simulate_cell` and of the
    batched driver. The ``"margin"`` of the other periodic cells is the caller's
    (:func:`gearsim.cell.verify.fill_margins`: a batched driver's cells share kernel calls).
    """
    if floquet not in FLOQUET:
        raise ParameterError(f"floquet = {floquet!r}; allowed: {', '.join(FLOQUET)}")
    # the stronger of the caller's mode and the settings' (``integration: floquet``)
    floquet = max(floquet, st.floquet, key=FLOQUET.index)
    window, cls = read_window(params, summaries, n, st)
    cls, orbit = verify_motion(params, summaries, cls, st, final_state, floquet, orbits)
    if orbit is not None:
        poincare = orbit
    else:
        n_keep = n if n > 0 else min(len(window), 2 * st.n_max)
        poincare = window.section[-n_keep:].copy()
    return CellResult(cls, np.asarray(final_state, dtype=float)[:N_STATE].copy(), k, poincare,
                      k - start_period, steps, params)


def simulate_cell(
    params: ModelParameters,
    u0: np.ndarray | None = None,
    *,
    settings: IntegrationSettings | None = None,
    transient: int | None = None,
    samples: int | None = None,
    start_period: int = 0,
    spectrum: bool | int = False,
    floquet: str = "slow",
) -> CellResult:
    """Integrate one parameter cell to its steady motion and classify it.

    Parameters
    ----------
    params
        Dimensionless model parameters.
    u0
        Initial state (10 entries) on the section, e.g. the previous cell's ``final_state``
        (continuation). Default: the static equilibrium.
    settings
        Numerical settings; ``transient`` and ``samples`` override its ``transient`` and
        ``max_periods``.
    start_period
        Absolute period index of ``u0`` (matters only for the slow variable-ratio forcing).
    spectrum
        Also all Lyapunov exponents (:func:`gearsim.numerics.variational.lyapunov_spectrum`)
        of the steady motion, over ``max(200, analysed window)`` periods (``True``) or that
        many periods (an integer), in ``CellResult.spectrum`` (sum checked against the trace).
    floquet
        ``"slow"`` (Newton-refine the cells that settle too slowly), ``"margin"`` (also the
        Floquet margin ``mu_max`` of every other periodic cell:
        :func:`gearsim.cell.verify.fill_margins`) or ``"all"`` (Newton-refine every periodic
        cell): :func:`finish_cell`; the stronger of this and ``settings.floquet`` applies.
    """
    st = settings or IntegrationSettings()
    if transient is None:
        transient = st.transient if u0 is None else st.transient_continuation
    max_periods = st.max_periods if samples is None else int(samples)
    p = params.to_array()
    y = static_state(p) if u0 is None else np.asarray(u0, dtype=float)[:N_STATE].copy()
    if y.shape != (N_STATE,) or not np.all(np.isfinite(y)):
        raise ParameterError("initial state 'u0' must be 10 finite numbers")
    k = start_period
    steps = 0
    h = 0.0
    status = STATUS_OK
    if steps_lower_bound(params, st, transient + min(st.chunk, max_periods)) > st.max_steps:
        return diverged_result(params, k, 0, status="budget")
    lead = min(st.tangent_lead, transient)
    yt = None
    n = 0
    measured = 0
    parts: list[PeriodSummaries] = []
    probe = recurrence_probe(st, u0 is not None, transient)
    if probe:
        # the start of the transient with the tangent on, recorded: if it already recurs (on
        # the attractor) measuring starts at once; else the cell restarts from u0 with the
        # plan below, so a cell the probe does not cut is the plan without it to the bit
        r = run_periods(params, np.concatenate([y, initial_tangent(params)]), probe, st,
                        start_period=k, tangent=True, parray=p)
        steps, status = r.n_steps, r.status
        if status != STATUS_OK or period_of(r.summaries, params, st) > 0:
            yt, k, h, lead, transient = r.state, k + r.periods_done, r.h_last, 0, 0
    if transient - lead > 0:
        r = run_periods(params, y, transient - lead, st, start_period=k, parray=p)
        y, k, h, status = r.state, k + r.periods_done, r.h_last, r.status
        steps += r.n_steps
    if yt is None:
        yt = np.concatenate([y, initial_tangent(params)])
    if st.settle_check > 0 and lead > 0 and status == STATUS_OK:
        # the adaptive transient (module docstring): the lead recorded, checked every s periods
        window = min(st.chunk, max_periods)
        done = transient - lead
        while True:
            r = run_periods(params, yt, next_settle_check(done, st, transient, window) - done,
                            st, start_period=k, tangent=True, h_init=h, parray=p)
            yt, k, h, status = r.state, k + r.periods_done, r.h_last, r.status
            steps += r.n_steps
            done += r.periods_done
            if status != STATUS_OK:
                break
            parts = [PeriodSummaries.concat([*parts, r.summaries]).tail(window)]
            if done >= transient + window:
                # the fixed plan's first measuring chunk: its period test and budget
                measured = window
                n = period_of(parts[0], params, st)
                if n == 0 and measured < max_periods and steps > st.max_steps:
                    return diverged_result(params, k, steps, status="budget")
                break
            n = settled_period(parts[0].tail(EARLY_WINDOW), params, st)
            if n > 0:
                parts = [parts[0].tail(EARLY_WINDOW)]
                break
        lead = 0
    if lead > 0 and status == STATUS_OK:
        # the tangent vector aligns during the end of the transient (not recorded)
        r = run_periods(params, yt, lead, st, start_period=k, tangent=True, h_init=h, parray=p)
        yt, k, h, status = r.state, k + r.periods_done, r.h_last, r.status
        steps += r.n_steps
    while status == STATUS_OK and n == 0 and measured < max_periods:
        m = min(st.chunk, max_periods - measured)
        r = run_periods(params, yt, m, st, start_period=k, tangent=True, h_init=h, parray=p)
        parts.append(r.summaries)
        yt, k, h, status = r.state, k + r.periods_done, r.h_last, r.status
        steps += r.n_steps
        measured += r.periods_done
        if status != STATUS_OK:
            break
        n = period_of(PeriodSummaries.concat(parts), params, st)
        if n > 0:
            break
        if steps > st.max_steps:
            return diverged_result(params, k, steps, status="budget")
    summaries = PeriodSummaries.concat(parts) if parts else None
    if status != STATUS_OK or summaries is None or len(summaries) == 0:
        return diverged_result(params, k, steps)
    res = finish_cell(params, summaries, n, st, yt, k, start_period, steps, floquet)
    fill_margins([res], st.with_(floquet=max(floquet, st.floquet, key=FLOQUET.index)))
    check_growth([res], st)
    if spectrum:
        periods = (max(200, res.classification.window_periods) if spectrum is True
                   else int(spectrum))
        res.spectrum = lyapunov_spectrum(params, res.final_state, periods, st,
                                         start_period=res.final_period)
    return res


@dataclass
class Trajectory:
    """A recorded stretch of motion: uniform samples and located switch events."""

    tau: np.ndarray  # (m,) dimensionless time
    state: np.ndarray  # (m, 10)
    mesh_force: np.ndarray  # (m,) F / (Km b_c), every model form (model.mesh_force_series)
    events_tau: np.ndarray  # switch times
    events_code: np.ndarray  # 4 * channel + new region + 1
    section: np.ndarray  # (periods, 10)


def trajectory(
    params: ModelParameters,
    u0: np.ndarray | None = None,
    *,
    periods: int = 64,
    samples_per_period: int = 64,
    settings: IntegrationSettings | None = None,
    transient: int = 0,
    start_period: int = 0,
    event_capacity: int = 100_000,
) -> Trajectory:
    """Record ``periods`` mesh periods at ``samples_per_period`` uniform points per period.

    The integrator lands exactly on every output time, so spectra can use the samples directly.
    """
    st = settings or IntegrationSettings()
    p = params.to_array()
    y = static_state(p) if u0 is None else np.asarray(u0, dtype=float)[:N_STATE].copy()
    k = start_period
    if transient > 0:
        r = run_periods(params, y, transient, st, start_period=k, parray=p)
        y, k = r.state, k + r.periods_done
    r = run_periods(
        params,
        y,
        periods,
        st,
        start_period=k,
        substeps=samples_per_period,
        record=True,
        event_capacity=event_capacity,
        parray=p,
    )
    T = params.mesh_period
    m = r.periods_done * samples_per_period + 1
    tau = k * T + np.arange(m) * (T / samples_per_period)
    states = r.trajectory[:m]
    force = mesh_force_series(p, tau, states[:, 0], states[:, 1])
    return Trajectory(tau, states, force, r.events_t, r.events_code, r.summaries.section)
