"""Drivers: integrate a cell to its steady motion and classify it; record trajectories.

``simulate_cell`` runs a transient without the tangent vector, then measures in chunks of mesh
periods (tangent vector on) and stops as soon as a period ``n <= n_max`` is established and
confirmed, or when the budget ``max_periods`` is spent (then chaos / quasi-periodic / unsettled is
decided by the Lyapunov exponent).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from .classify import Classification, PeriodSummaries, classify_motion, estimate_period
from .integrate import METHODS, STATUS_OK, integrate_periods
from .model import N_STATE, static_state
from .parameters import ModelParameters, ParameterError

TANGENT_SEED = 20251022  # fixed seed of the initial tangent vector (recorded in provenance)


@dataclass(frozen=True)
class IntegrationSettings:
    """Numerical settings of a cell simulation (all times in mesh periods unless stated).

    method
        ``"dp5"`` adaptive Dormand-Prince 5(4) or ``"rk4"`` fixed step.
    rtol, atol
        DP5 tolerances (RMS norm over the physical states).
    hmax
        Absolute step cap in dimensionless time (stiff bearing modes at low ``w``).
    steps_per_period
        RK4 steps per mesh period (raised to ``ceil(T / hmax)`` when needed).
    transient
        Periods integrated before measuring, starting from the static state / ``u0``.
    transient_continuation
        Periods of transient when a continuation start ``u0`` is given.
    chunk
        Periods per measuring chunk; the period is tested after each chunk.
    max_periods
        Budget of measured periods.
    n_max, period_rtol
        Largest period looked for, relative tolerance of the period test.
    lyap_threshold
        Lyapunov exponents above it (per unit tau) mean chaos, within +/- it quasi-periodic.
    divergence_bound
        A state component beyond it (or NaN) ends the cell with status ``diverged``.
    """

    method: str = "dp5"
    rtol: float = 1e-9
    atol: float = 1e-12
    hmax: float = 0.2
    steps_per_period: int = 256
    transient: int = 150
    transient_continuation: int = 16
    chunk: int = 24
    max_periods: int = 256
    n_max: int = 64
    period_rtol: float = 1e-5
    lyap_threshold: float = 0.005
    divergence_bound: float = 1.0e6

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ParameterError(
                f"setting 'method' = {self.method!r}; allowed: {', '.join(METHODS)}"
            )
        positive = {
            "rtol": (0, 1),
            "atol": (0, 1),
            "hmax": (0, 100),
            "period_rtol": (0, 1),
            "lyap_threshold": (0, 10),
            "divergence_bound": (0, 1e300),
        }
        for name, (lo, hi) in positive.items():
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and lo < v < hi):
                raise ParameterError(f"setting '{name}' = {v!r} must be in ({lo}, {hi})")
        integers = {
            "steps_per_period": 4,
            "transient": 0,
            "transient_continuation": 0,
            "chunk": 4,
            "max_periods": 8,
            "n_max": 1,
        }
        for name, lo in integers.items():
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < lo:
                raise ParameterError(f"setting '{name}' = {v!r} must be an integer >= {lo}")

    @classmethod
    def from_config(cls, config: Any = None) -> IntegrationSettings:
        """The study's settings: ``config['integration']`` of a loaded configuration, or with no
        argument those of ``config/config.yaml`` (:func:`gearsim.config.study_config`: RK4, 256
        steps per period, a 40-period continuation transient), as the pipeline uses them."""
        # imported here: gearsim.config builds on this module (pipe session's addition)
        from .config import integration_settings, study_config

        return integration_settings(study_config() if config is None else config)

    def with_(self, **changes: Any) -> IntegrationSettings:
        return replace(self, **changes)

    def tightened(self) -> IntegrationSettings:
        """Settings for convergence checks: 100x tighter DP5 tolerance, half the RK4 step."""
        return replace(
            self,
            rtol=self.rtol / 100,
            atol=self.atol / 100,
            steps_per_period=self.steps_per_period * 2,
            hmax=self.hmax / 2,
        )

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class Run:
    """Raw output of :func:`run_periods`."""

    summaries: PeriodSummaries
    state: np.ndarray  # final state (10, or 20 with tangent)
    status: int
    periods_done: int
    events_t: np.ndarray
    events_code: np.ndarray
    n_events: int
    h_last: float
    n_steps: int
    trajectory: np.ndarray | None


def run_periods(
    params: ModelParameters,
    y0: np.ndarray,
    n_periods: int,
    settings: IntegrationSettings,
    *,
    start_period: int = 0,
    tangent: bool = False,
    substeps: int = 1,
    record: bool = False,
    event_capacity: int = 0,
    h_init: float = 0.0,
    parray: np.ndarray | None = None,
) -> Run:
    """Integrate ``n_periods`` mesh periods from ``y0`` (unchanged) at ``tau = start_period T``."""
    p = params.to_array() if parray is None else parray
    y = np.zeros(20)
    y[: len(y0)] = y0
    m = n_periods
    sec = np.zeros((m, N_STATE))
    ints = [np.zeros(m, dtype=np.int64) for _ in range(2)]
    floats = [np.zeros(m) for _ in range(6)]
    traj = np.zeros((m * substeps + 1 if record else 0, N_STATE))
    ev_t = np.zeros(event_capacity)
    ev_c = np.zeros(event_capacity, dtype=np.int64)
    status, done, n_ev, h_last, n_steps = integrate_periods(
        y,
        start_period,
        p,
        METHODS[settings.method],
        settings.rtol,
        settings.atol,
        settings.hmax,
        settings.steps_per_period,
        m,
        substeps,
        tangent,
        h_init,
        sec,
        ints[0],
        ints[1],
        floats[0],
        floats[1],
        floats[2],
        floats[3],
        floats[4],
        floats[5],
        traj,
        ev_t,
        ev_c,
        settings.divergence_bound,
    )
    s = PeriodSummaries(sec, ints[0], ints[1], *floats)
    if done < m:
        s = PeriodSummaries(*(getattr(s, f)[:done] for f in PeriodSummaries.__dataclass_fields__))
    return Run(
        summaries=s,
        state=y[: 20 if tangent else 10].copy(),
        status=int(status),
        periods_done=int(done),
        events_t=ev_t[: min(n_ev, event_capacity)],
        events_code=ev_c[: min(n_ev, event_capacity)],
        n_events=int(n_ev),
        h_last=float(h_last),
        n_steps=int(n_steps),
        trajectory=traj if record else None,
    )


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

    def row(self) -> dict[str, Any]:
        """Flat record for tables (the catalogue's cell columns)."""
        c = asdict(self.classification)
        c["kmax"] = self.classification.kmax
        c["periods"] = self.periods
        c["steps"] = self.steps
        return c


def _initial_tangent() -> np.ndarray:
    v = np.random.default_rng(TANGENT_SEED).standard_normal(N_STATE)
    return v / np.linalg.norm(v)


def simulate_cell(
    params: ModelParameters,
    u0: np.ndarray | None = None,
    *,
    settings: IntegrationSettings | None = None,
    transient: int | None = None,
    samples: int | None = None,
    start_period: int = 0,
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
    if transient > 0:
        r = run_periods(params, y, transient, st, start_period=k, parray=p)
        y, k, steps, h, status = r.state, k + r.periods_done, r.n_steps, r.h_last, r.status
    parts: list[PeriodSummaries] = []
    yt = np.concatenate([y, _initial_tangent()])
    n = 0
    measured = 0
    while status == STATUS_OK and measured < max_periods:
        m = min(st.chunk, max_periods - measured)
        r = run_periods(params, yt, m, st, start_period=k, tangent=True, h_init=h, parray=p)
        parts.append(r.summaries)
        yt, k, h, status = r.state, k + r.periods_done, r.h_last, r.status
        steps += r.n_steps
        measured += r.periods_done
        if status != STATUS_OK:
            break
        s = PeriodSummaries.concat(parts)
        scale = float(s.xmax.max() - s.xmin.min())
        n = estimate_period(
            s.section[:, 0], s.section[:, 1], scale, params.w, st.n_max, st.period_rtol
        )
        if n > 0:
            break
    summaries = PeriodSummaries.concat(parts) if parts else None
    if status != STATUS_OK or summaries is None or len(summaries) == 0:
        cls = Classification(
            motion="diverged", status="diverged", I=0, n=0, p=None, q=None, label="diverged",
            label_npq="", dc=float("nan"), kmax_peak_mean=float("nan"),
            kmax_peak_static=float("nan"), kmax_section_mean=float("nan"),
            kmax_section_static=float("nan"), kmin_peak_mean=float("nan"),
            lyapunov=float("nan"), x_min=float("nan"), x_max=float("nan"), converged=False,
            window_periods=0,
        )
        final = static_state(p)
        return CellResult(cls, final, 0, np.zeros((0, N_STATE)), k, steps, params)
    if n > 0:
        # analyse whole motion periods only; drop the early part of the measurement when long
        keep = n * max(1, min(len(summaries), 4 * max(n, 8)) // n)
        window = summaries.tail(keep)
    else:
        window = summaries
    cls = classify_motion(
        window,
        w=params.w,
        b=params.b,
        eps=params.eps,
        xi=params.xi,
        Fm=params.Fm,
        Fe=params.Fe,
        n=n,
        lyap_threshold=st.lyap_threshold,
    )
    n_keep = n if n > 0 else min(len(window), 2 * st.n_max)
    poincare = window.section[-n_keep:].copy()
    return CellResult(cls, yt[:N_STATE].copy(), k, poincare, k - start_period, steps, params)


@dataclass
class Trajectory:
    """A recorded stretch of motion: uniform samples and located switch events."""

    tau: np.ndarray  # (m,) dimensionless time
    state: np.ndarray  # (m, 10)
    mesh_force: np.ndarray  # (m,) F / (Km b_c)
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
    x, v = states[:, 0], states[:, 1]
    f = np.where(x > params.b, x - params.b, np.where(x < -params.b, x + params.b, 0.0))
    force = (1.0 + params.eps * np.cos(params.w * tau)) * f + 2.0 * params.xi * v
    return Trajectory(tau, states, force, r.events_t, r.events_code, r.summaries.section)
