"""The scalar integrator: mesh periods with located contact switches and exact section landing.

Two methods on the one field (:mod:`gearsim.dynamics.model`) and the one event layer
(:mod:`gearsim.numerics.events`), no Python in the inner loop:

* ``METHOD_DP5``: adaptive Dormand-Prince 5(4) (FSAL), RMS error norm over the evolved states
  with ``atol + rtol * max(|y_old|, |y_new|)``, step factor ``0.9 err^(-1/5)`` clipped to
  [0.2, 5], absolute cap ``hmax``. Every output interval is one :func:`events.advance_interval`.
* ``METHOD_RK4``: classical fixed-step RK4 with ``N`` equal steps per mesh period
  (:func:`gearsim.numerics.steps.rk4_steps_per_period`), phases from the tables of
  :func:`gearsim.numerics.steps.phase_tables`. A grid step that
  :func:`gearsim.numerics.steps.grid_step_flag` flags
  (a region change, a watched bearing velocity sign change, a turning point of x that may graze
  the mesh boundary, the divergence bound) is redone by the event layer; a step with a turning
  point inside its region stands, its extremum folded in (:func:`events.turn_extremum`). This
  is the batched kernel's algorithm for one lane, so the two give bit-identical section points
  (tests/unit/test_batch.py).

Sections. Integration runs period by period (``T = 2 pi / w``, time measured within the period so
the mesh phase is exact late in long chains), each period split into ``substeps`` equal output
intervals whose ends are landed on exactly; per period the kernel records the section state, impact
counts, disengaged time, force and displacement extremes and the log growth of the tangent vector
(renormalised every period; the largest Lyapunov exponent).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from gearsim.dynamics.model import (
    MODE_FRICTION,
    N_MODE,
    N_STATE,
    N_SWITCH,
    P_ACT,
    P_DOF6,
    P_GAM,
    P_W,
    field_params,
    mode_tuple,
    set_period,
    tracked_force,
    variable_ratio,
)
from gearsim.dynamics.parameters import ModelParameters
from gearsim.numerics.events import (
    ACC_FMAX,
    ACC_FMIN,
    ACC_H,
    ACC_K1,
    ACC_TD,
    ACC_XMAX,
    ACC_XMIN,
    CNT_EV,
    CNT_NB,
    CNT_NF,
    CNT_STEPS,
    N_ACC,
    N_CNT,
    STATUS_DIVERGED,
    STATUS_OK,
    STATUS_STEP_COLLAPSE,
    advance_interval,
    channels,
    turn_extremum,
)
from gearsim.numerics.settings import IntegrationSettings, Method
from gearsim.numerics.steps import (
    FASTMATH,
    METHOD_DP5,
    METHOD_DP5_TANGENT,
    METHOD_RK4,
    METHODS,
    grid_step_flag,
    phase_tables,
    rk4_state,
    rk4_steps_per_period,
    rk4_tangent,
    turn_stands,
)

__all__ = [
    "METHODS",
    "METHOD_DP5",
    "METHOD_RK4",
    "STATUS_OK",
    "STATUS_DIVERGED",
    "STATUS_STEP_COLLAPSE",
    "STATUS_NAMES",
    "integrate_periods",
    "IntegrationSettings",
    "Run",
    "run_periods",
    "steps_lower_bound",
    "start_period_accumulators",
    "end_period_tangent",
]

STATUS_NAMES = {STATUS_OK: "ok", STATUS_DIVERGED: "diverged", STATUS_STEP_COLLAPSE: "diverged"}


@dataclass
class PeriodSummaries:
    """Per-period records of a stretch of integration (arrays of equal length ``m``)."""

    section: np.ndarray  # (m, 10) state at the start of each period
    nface: np.ndarray  # (m,) entries into face contact
    nback: np.ndarray  # (m,) entries into back contact
    tdis: np.ndarray  # (m,) time inside the backlash
    fmax: np.ndarray
    fmin: np.ndarray
    xmax: np.ndarray
    xmin: np.ndarray
    lyap: np.ndarray  # (m,) log growth of the tangent vector

    def __len__(self) -> int:
        return len(self.nface)

    def tail(self, m: int) -> PeriodSummaries:
        m = min(m, len(self))
        return PeriodSummaries(*(getattr(self, f)[-m:] for f in self.__dataclass_fields__))

    @staticmethod
    def concat(parts: list[PeriodSummaries]) -> PeriodSummaries:
        names = PeriodSummaries.__dataclass_fields__
        return PeriodSummaries(*(np.concatenate([getattr(p, f) for p in parts]) for f in names))



@njit(cache=True, nogil=True, inline="always")
def start_period_accumulators(y, P, r0, acc, cnt):
    """Reset the per-period accumulators at a period start (``cos(w tau) = 1`` there)."""
    f0 = tracked_force(1.0, 0.0, y[0], y[1], P, r0, abs(r0))
    acc[ACC_TD] = 0.0
    acc[ACC_FMAX] = f0
    acc[ACC_FMIN] = f0
    acc[ACC_XMAX] = y[0]
    acc[ACC_XMIN] = y[0]
    cnt[CNT_NF] = 0
    cnt[CNT_NB] = 0


@njit(cache=True, nogil=True, inline="always")
def end_period_tangent(z):
    """Log growth of the tangent vector ``z`` over the period; renormalises ``z`` in place."""
    nrm = 0.0
    for i in range(z.shape[0]):
        nrm += z[i] * z[i]
    nrm = math.sqrt(nrm)
    if nrm > 0.0 and nrm == nrm:
        for i in range(z.shape[0]):
            z[i] /= nrm
        return math.log(nrm)
    return 0.0


@njit(cache=True, nogil=True, fastmath=FASTMATH)
def _rk4_grid_interval(j, h, y, p, mode, tangent, C, S, LAM, CV, SV, Q, bearings, bound, acc):
    """The vector kernel's grid step for one cell; returns True if the event layer must redo it.

    Same arithmetic as ``kernel.lane_step`` and its turning-point pass (both inline
    :func:`rk4_state`, :func:`rk4_tangent` and :func:`grid_step_flag`, then call
    :func:`turn_extremum`): a step that stands is stored with its accumulators.
    """
    i2 = 2 * j
    P = field_params(p, 0, 1)
    M = mode_tuple(mode)
    lam = LAM[j]
    ys = (y[0], y[1], y[2], y[3], y[4], y[5], y[6], y[7], y[8], y[9])
    vA = variable_ratio(p, CV[i2], SV[i2])
    vM = variable_ratio(p, CV[i2 + 1], SV[i2 + 1])
    vB = variable_ratio(p, CV[i2 + 2], SV[i2 + 2])
    yn = rk4_state(ys, h, C[i2], S[i2], vA, C[i2 + 1], S[i2 + 1], vM, C[i2 + 2], S[i2 + 2], vB,
                   lam, Q[i2], Q[i2 + 1], Q[i2 + 2], P, M)
    A = (p[P_ACT], p[P_ACT + 1], p[P_ACT + 2], p[P_ACT + 3])
    event, turn = grid_step_flag(ys, yn, P, M, A, bound, bearings)
    if event or (turn and not turn_stands(ys, yn, h, P, M[0])):
        return True
    if tangent:
        z = (y[10], y[11], y[12], y[13], y[14], y[15], y[16], y[17], y[18], y[19])
        zn = rk4_tangent(z, h, C[i2], C[i2 + 1], C[i2 + 2], lam, Q[i2], Q[i2 + 1], Q[i2 + 2], P,
                         M)
        for i in range(N_STATE):
            y[10 + i] = zn[i]
    for i in range(N_STATE):
        y[i] = yn[i]
    r0 = M[0]
    if r0 == 0.0:
        acc[ACC_TD] += h
    fl = tracked_force(C[i2 + 2], S[i2 + 2], yn[0], yn[1], P, r0, M[1])
    acc[ACC_FMAX] = max(acc[ACC_FMAX], fl)
    acc[ACC_FMIN] = min(acc[ACC_FMIN], fl)
    acc[ACC_XMAX] = max(acc[ACC_XMAX], yn[0])
    acc[ACC_XMIN] = min(acc[ACC_XMIN], yn[0])
    if turn:
        found, xe, fe = turn_extremum(ys[0], ys[1], yn[0], yn[1], h, j * h, p[P_W], P, r0)
        if found:
            acc[ACC_XMAX] = max(acc[ACC_XMAX], xe)
            acc[ACC_XMIN] = min(acc[ACC_XMIN], xe)
            acc[ACC_FMAX] = max(acc[ACC_FMAX], fe)
            acc[ACC_FMIN] = min(acc[ACC_FMIN], fe)
    return False


@njit(cache=True, nogil=True, fastmath=FASTMATH)
def integrate_periods(
    y0,
    k0,
    p,
    method,
    rtol,
    atol,
    hmax,
    n_rk,
    n_periods,
    substeps,
    tangent,
    h_init,
    sec,
    nface,
    nback,
    tdis,
    fmax,
    fmin,
    xmax,
    xmin,
    lyap,
    traj,
    ev_t,
    ev_code,
    bound,
    C,
    S,
    LAM,
    CV,
    SV,
    Q,
):
    """Integrate ``n_periods`` mesh periods starting at ``tau = k0 T`` from state ``y0``.

    ``y0`` has 10 entries (20 with ``tangent``: state then tangent vector) and is updated in
    place to the final state. ``p`` is the packed parameter vector (a private copy is used).
    ``n_rk`` is the RK4 steps per period (a multiple of ``substeps``; ``C, S, LAM, CV, SV, Q`` its
    phase tables); DP5 ignores them. Per period ``k`` the kernel writes ``sec[k]`` (state at the
    start of the period), ``nface[k]``/``nback[k]`` (entries into face / back contact),
    ``tdis[k]`` (time inside the backlash), ``fmax``/``fmin`` (mesh force extremes),
    ``xmax``/``xmin`` and ``lyap[k]`` (log growth of the tangent vector, renormalised each
    period). If ``traj`` has rows, it receives the state at every output point (``substeps`` per
    period, plus the start). Switch events go to ``ev_t``/``ev_code`` (code = 4 * channel + new
    region + 1) up to their capacity. A state component beyond ``bound`` (or NaN) stops the run
    with status 1.

    Returns ``(status, periods_done, n_events, h_last, n_steps)``.
    """
    n = 20 if tangent else 10
    pl = p.copy()  # the per-period slots (variable-ratio phase) are written here
    nerr = N_STATE if p[P_DOF6] != 0.0 else 2
    if method == METHOD_DP5_TANGENT:  # DP5 with the tangent in the error norm (shooting only)
        method = METHOD_DP5
        if tangent and p[P_DOF6] != 0.0:
            nerr = 2 * N_STATE
    w = p[P_W]
    T = 2.0 * math.pi / w
    friction = p[P_GAM] != 0.0
    y = np.zeros(20)
    for i in range(n):
        y[i] = y0[i]
    ks = np.zeros((7, 20))
    ytmp = np.zeros(20)
    ynew = np.zeros(20)
    ytry = np.zeros(20)
    mode = np.zeros(N_MODE, dtype=np.int64)
    mode[MODE_FRICTION] = 1
    gaps = np.zeros(N_SWITCH)
    active = np.zeros(N_SWITCH, dtype=np.bool_)
    channels(p, mode, y, gaps, active, True)
    # from the array, never the constant False: a Literal[bool] first guess would compile the
    # grid step twice
    bearings = active[1] | active[2] | active[3] | active[4]
    acc = np.zeros(N_ACC)
    cnt = np.zeros(N_CNT, dtype=np.int64)
    acc[ACC_H] = h_init if h_init > 0.0 else min(hmax, T / 64.0)
    h_rk = T / n_rk
    per_out = n_rk // substeps
    status = STATUS_OK
    traj_rows = traj.shape[0]
    row = 0
    periods_done = 0
    for k in range(n_periods):
        t_abs0 = (k0 + k) * T
        set_period(pl, k0 + k)
        for i in range(N_STATE):
            sec[k, i] = y[i]
        if k == 0 and row < traj_rows:
            for i in range(N_STATE):
                traj[row, i] = y[i]
            row += 1
        start_period_accumulators(y, field_params(pl, 0, 1), float(mode[0]), acc, cnt)
        if method == METHOD_RK4:
            for j in range(n_rk):
                mode[MODE_FRICTION] = int(LAM[j])
                cnt[CNT_STEPS] += 1
                if _rk4_grid_interval(j, h_rk, y, pl, mode, tangent, C, S, LAM, CV, SV, Q,
                                      bearings, bound, acc):
                    t_end = T if j == n_rk - 1 else (j + 1) * h_rk
                    cnt[CNT_STEPS] -= 1  # the event layer counts its own steps
                    status = advance_interval(
                        METHOD_RK4, j * h_rk, t_end, y, pl, mode, gaps, active, n, nerr,
                        tangent, ks, ytmp, ynew, ytry, rtol, atol, hmax, T, bound, acc, cnt,
                        ev_t, ev_code, t_abs0,
                    )
                    if status != STATUS_OK:
                        break
                if row < traj_rows and (j + 1) % per_out == 0:
                    for i in range(N_STATE):
                        traj[row, i] = y[i]
                    row += 1
        else:
            t = 0.0
            for s in range(substeps):
                t_target = T if s == substeps - 1 else (s + 1) * T / substeps
                th = 0.5 * T
                while status == STATUS_OK and t < t_target:
                    # the friction direction flips at T/2: steps never straddle it
                    stop = th if (friction and t < th - 1e-14 * T and th < t_target) else t_target
                    lam = 1 if (not friction or t < th * (1.0 - 1e-12)) else -1
                    if lam != mode[MODE_FRICTION]:
                        mode[MODE_FRICTION] = lam
                        acc[ACC_K1] = 0.0  # the FSAL stage saw the old direction
                    status = advance_interval(
                        METHOD_DP5, t, stop, y, pl, mode, gaps, active, n, nerr, tangent, ks,
                        ytmp, ynew, ytry, rtol, atol, hmax, T, bound, acc, cnt, ev_t, ev_code,
                        t_abs0,
                    )
                    t = stop
                if status != STATUS_OK:
                    break
                if row < traj_rows:
                    for i in range(N_STATE):
                        traj[row, i] = y[i]
                    row += 1
            if friction and mode[MODE_FRICTION] != 1:
                mode[MODE_FRICTION] = 1
                acc[ACC_K1] = 0.0
        if status != STATUS_OK:
            break
        nface[k] = cnt[CNT_NF]
        nback[k] = cnt[CNT_NB]
        tdis[k] = acc[ACC_TD]
        fmax[k] = acc[ACC_FMAX]
        fmin[k] = acc[ACC_FMIN]
        xmax[k] = acc[ACC_XMAX]
        xmin[k] = acc[ACC_XMIN]
        if tangent:
            lyap[k] = end_period_tangent(y[10:20])
            acc[ACC_K1] = 0.0  # the FSAL stage holds the derivative of the unnormalised tangent
        periods_done = k + 1
    for i in range(n):
        y0[i] = y[i]
    return status, periods_done, cnt[CNT_EV], acc[ACC_H], cnt[CNT_STEPS]



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
    tangent_error: bool = False,
) -> Run:
    """Integrate ``n_periods`` mesh periods from ``y0`` (unchanged) at ``tau = start_period T``.

    ``tangent_error`` (DP5 with ``tangent`` only): the tangent vector enters the error norm
    too (6-DOF model), so the variational solution is as accurate as the state (the shooting
    path, :mod:`gearsim.analysis.orbits`; measured cells do not use it)."""
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
    n_rk = rk4_steps_per_period(params, settings, substeps)
    nu = params.var_ratio_order if params.var_ratio != 0.0 else 0.0
    code = METHODS[settings.method]
    if tangent_error and tangent and code == METHOD_DP5:
        code = METHOD_DP5_TANGENT
    status, done, n_ev, h_last, n_steps = integrate_periods(
        y, start_period, p, code, settings.rtol, settings.atol,
        settings.hmax, n_rk, m, substeps, tangent, h_init, sec, ints[0], ints[1], *floats, traj,
        ev_t, ev_c, settings.divergence_bound, *phase_tables(n_rk, nu),
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


def steps_lower_bound(params: ModelParameters, settings: IntegrationSettings,
                      periods: int) -> int:
    """Fewest steps ``periods`` mesh periods can take (RK4: its grid; DP5: the step cap)."""
    if settings.method is Method.RK4:
        per = rk4_steps_per_period(params, settings)
    else:
        per = int(math.ceil(params.mesh_period / settings.hmax))
    return per * int(periods)
