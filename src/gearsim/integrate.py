"""Compiled integrators with contact-switch location and exact Poincare-section landing.

Two methods share one event-handling core (no Python in the inner loop):

* ``METHOD_DP5``: adaptive Dormand-Prince 5(4) (FSAL), RMS error norm over the physical states
  with ``atol + rtol * max(|y_old|, |y_new|)``, step factor ``0.9 err^(-1/5)`` clipped to
  [0.2, 5], absolute cap ``hmax``.
* ``METHOD_RK4``: classical fixed-step RK4 with ``N`` equal steps per mesh period (so every
  section time is a grid point); ``N = max(steps_per_period, ceil(T / hmax))`` keeps the step
  below the stability limit of the stiff bearing modes at low ``w``.

Contact switches. Each dead zone is frozen in its region for a whole step (the field stays
smooth, so the step keeps its order). After a step, every switching channel (mesh ``x = +/-b``;
bearing ``u = +/-b_j`` when the clearance is non-zero) is checked: a change of region, or an
interior excursion across the boundary predicted by the cubic Hermite interpolant of ``(x, x')``
(a grazing contact inside the step), triggers location. The crossing time is found by a
safeguarded Newton-bisection iteration in which each trial is a real step of the same method from
the step start, to ``|g| <= 1e-12 (1 + gap)``; the state lands on the switch, the region
changes, and the remainder of the interval is integrated in the new region.

Sections. Integration runs period by period (``T = 2 pi / w``), each period split into
``substeps`` equal output intervals whose ends are landed on exactly; per period the kernel
records the section state, impact counts, disengaged time, force and displacement extremes and
the growth of the tangent vector (largest Lyapunov exponent).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .model import (
    MODE_FRICTION,
    N_MODE,
    N_STATE,
    N_SWITCH,
    P_B,
    P_DOF6,
    P_EPS,
    P_GAMMA,
    P_T0,
    P_W,
    P_XI,
    SWITCH_COORD,
    SWITCH_GAP,
    dead_zone,
    region_of,
    rhs,
)

METHOD_DP5 = 0
METHOD_RK4 = 1
METHODS = {"dp5": METHOD_DP5, "rk4": METHOD_RK4}

STATUS_OK = 0
STATUS_DIVERGED = 1
STATUS_STEP_COLLAPSE = 2
STATUS_NAMES = {STATUS_OK: "ok", STATUS_DIVERGED: "diverged", STATUS_STEP_COLLAPSE: "diverged"}


# Dormand-Prince 5(4) tableau
_A21 = 1.0 / 5.0
_A31, _A32 = 3.0 / 40.0, 9.0 / 40.0
_A41, _A42, _A43 = 44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0
_A51, _A52, _A53, _A54 = 19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0
_A61, _A62, _A63, _A64, _A65 = (
    9017.0 / 3168.0,
    -355.0 / 33.0,
    46732.0 / 5247.0,
    49.0 / 176.0,
    -5103.0 / 18656.0,
)
_B1, _B3, _B4, _B5, _B6 = 35.0 / 384.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0
_E1, _E3, _E4, _E5, _E6, _E7 = (
    71.0 / 57600.0,
    -71.0 / 16695.0,
    71.0 / 1920.0,
    -17253.0 / 339200.0,
    22.0 / 525.0,
    -1.0 / 40.0,
)
_C2, _C3, _C4, _C5 = 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0


@njit(cache=True, nogil=True)
def _rk4_step(t, y, h, p, mode, n, tangent, ks, ytmp, yout):
    k1 = ks[0]
    k2 = ks[1]
    k3 = ks[2]
    k4 = ks[3]
    rhs(t, y, p, mode, k1, tangent)
    for i in range(n):
        ytmp[i] = y[i] + 0.5 * h * k1[i]
    rhs(t + 0.5 * h, ytmp, p, mode, k2, tangent)
    for i in range(n):
        ytmp[i] = y[i] + 0.5 * h * k2[i]
    rhs(t + 0.5 * h, ytmp, p, mode, k3, tangent)
    for i in range(n):
        ytmp[i] = y[i] + h * k3[i]
    rhs(t + h, ytmp, p, mode, k4, tangent)
    for i in range(n):
        yout[i] = y[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
    return 0.0


@njit(cache=True, nogil=True)
def _dp5_step(t, y, h, p, mode, n, nerr, tangent, ks, ytmp, yout, rtol, atol, k1_valid):
    """One DP5 step; returns the RMS error norm. ``ks[0]`` must hold g(t, y) if ``k1_valid``."""
    k1 = ks[0]
    k2 = ks[1]
    k3 = ks[2]
    k4 = ks[3]
    k5 = ks[4]
    k6 = ks[5]
    k7 = ks[6]
    if not k1_valid:
        rhs(t, y, p, mode, k1, tangent)
    for i in range(n):
        ytmp[i] = y[i] + h * _A21 * k1[i]
    rhs(t + _C2 * h, ytmp, p, mode, k2, tangent)
    for i in range(n):
        ytmp[i] = y[i] + h * (_A31 * k1[i] + _A32 * k2[i])
    rhs(t + _C3 * h, ytmp, p, mode, k3, tangent)
    for i in range(n):
        ytmp[i] = y[i] + h * (_A41 * k1[i] + _A42 * k2[i] + _A43 * k3[i])
    rhs(t + _C4 * h, ytmp, p, mode, k4, tangent)
    for i in range(n):
        ytmp[i] = y[i] + h * (_A51 * k1[i] + _A52 * k2[i] + _A53 * k3[i] + _A54 * k4[i])
    rhs(t + _C5 * h, ytmp, p, mode, k5, tangent)
    for i in range(n):
        ytmp[i] = y[i] + h * (
            _A61 * k1[i] + _A62 * k2[i] + _A63 * k3[i] + _A64 * k4[i] + _A65 * k5[i]
        )
    rhs(t + h, ytmp, p, mode, k6, tangent)
    for i in range(n):
        yout[i] = y[i] + h * (
            _B1 * k1[i] + _B3 * k3[i] + _B4 * k4[i] + _B5 * k5[i] + _B6 * k6[i]
        )
    rhs(t + h, yout, p, mode, k7, tangent)
    acc = 0.0
    for i in range(nerr):
        e = h * (
            _E1 * k1[i] + _E3 * k3[i] + _E4 * k4[i] + _E5 * k5[i] + _E6 * k6[i] + _E7 * k7[i]
        )
        sc = atol + rtol * max(abs(y[i]), abs(yout[i]))
        acc += (e / sc) ** 2
    return math.sqrt(acc / nerr)


@njit(cache=True, nogil=True)
def _step(method, t, y, h, p, mode, n, nerr, tangent, ks, ytmp, yout, rtol, atol, k1_valid):
    if method == METHOD_RK4:
        return _rk4_step(t, y, h, p, mode, n, tangent, ks, ytmp, yout)
    return _dp5_step(t, y, h, p, mode, n, nerr, tangent, ks, ytmp, yout, rtol, atol, k1_valid)


@njit(cache=True, nogil=True)
def _hermite(x0, v0, x1, v1, h, s):
    """Cubic Hermite interpolant of x on [0, h] at fraction s in [0, 1]."""
    s2 = s * s
    s3 = s2 * s
    return (
        (2 * s3 - 3 * s2 + 1) * x0
        + (s3 - 2 * s2 + s) * h * v0
        + (-2 * s3 + 3 * s2) * x1
        + (s3 - s2) * h * v1
    )


@njit(cache=True, nogil=True)
def _hermite_extremum(x0, v0, x1, v1, h):
    """Fraction s in (0, 1) where the Hermite cubic has zero slope (v0, v1 of opposite sign)."""
    # derivative / h: a s^2 + b s + c
    a = 6 * x0 / h + 3 * v0 - 6 * x1 / h + 3 * v1
    b = -6 * x0 / h - 4 * v0 + 6 * x1 / h - 2 * v1
    c = v0
    if abs(a) < 1e-300:
        if b == 0.0:
            return -1.0
        s = -c / b
        return s if 0.0 < s < 1.0 else -1.0
    disc = b * b - 4 * a * c
    if disc < 0.0:
        return -1.0
    sq = math.sqrt(disc)
    s1 = (-b - sq) / (2 * a)
    s2 = (-b + sq) / (2 * a)
    best = -1.0
    if 0.0 < s1 < 1.0:
        best = s1
    if 0.0 < s2 < 1.0 and (best < 0.0 or s2 < best):
        best = s2
    return best


@njit(cache=True, nogil=True)
def _mesh_force_local(t, x, v, p, region):
    return (1.0 + p[P_EPS] * math.cos(p[P_W] * t)) * dead_zone(x, p[P_B], region) + 2.0 * p[
        P_XI
    ] * v


@njit(cache=True, nogil=True)
def integrate_periods(
    y0,
    k0,
    p,
    method,
    rtol,
    atol,
    hmax,
    steps_per_period,
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
    bound=1.0e6,
):
    """Integrate ``n_periods`` mesh periods starting at ``tau = k0 T`` from state ``y0``.

    ``y0`` has 10 entries (20 with ``tangent``: state then tangent vector) and is updated in
    place to the final state. Per period ``k`` the kernel writes ``sec[k]`` (state at the start
    of the period), ``nface[k]``/``nback[k]`` (entries into face / back contact), ``tdis[k]``
    (time inside the backlash), ``fmax``/``fmin`` (mesh force extremes), ``xmax``/``xmin`` and
    ``lyap[k]`` (log growth of the tangent vector, renormalised each period). If ``traj`` has
    rows, it receives the state at every output point (``substeps`` per period, plus the start).
    Switch events go to ``ev_t``/``ev_code`` (code = 4 * channel + new region + 1) up to their
    capacity. A state component beyond ``bound`` (or NaN) stops the run with status 1.

    Returns ``(status, periods_done, n_events, h_last, n_steps)``.
    """
    n = 20 if tangent else 10
    pl = p.copy()  # local copy: pl[P_T0] carries the absolute start time of the current period
    dof6 = p[P_DOF6] != 0.0
    nerr = 10 if dof6 else 2
    w = p[P_W]
    T = 2.0 * math.pi / w
    half_break = p[P_GAMMA] != 0.0
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
    for c in range(N_SWITCH):
        gaps[c] = p[SWITCH_GAP[c]]
        active[c] = c == 0 or (dof6 and gaps[c] > 0.0)
        # a channel without gap is linear: region +1 gives f(u, 0) = u on both sides
        mode[c] = region_of(y[SWITCH_COORD[c]], gaps[c]) if active[c] else 1
    n_rk = max(steps_per_period, int(math.ceil(T / hmax)))
    n_rk = substeps * int(math.ceil(n_rk / substeps))
    h_rk = T / n_rk
    h = h_init if h_init > 0.0 else min(hmax, T / 64.0)
    h_min = 1e-12 * T
    n_ev = 0
    n_steps = 0
    k1_valid = False
    status = 0
    traj_rows = traj.shape[0]
    row = 0
    periods_done = 0
    for k in range(n_periods):
        # Time runs relative to the period start: the mesh phase w t is then exact (cos(w k T + s)
        # = cos(s)) and step sizes keep full resolution late in a long chain, where absolute
        # times ~1e5 would leave switch landings below the float spacing and stall. Terms that
        # are not T-periodic (variable ratio) read the offset from pl[P_T0].
        t_abs0 = (k0 + k) * T
        pl[P_T0] = t_abs0
        t_start = 0.0
        for i in range(N_STATE):
            sec[k, i] = y[i]
        if k == 0 and row < traj_rows:
            for i in range(N_STATE):
                traj[row, i] = y[i]
            row += 1
        nf = 0
        nb = 0
        td = 0.0
        f0 = _mesh_force_local(t_start, y[0], y[1], p, mode[0])
        fmx = f0
        fmn = f0
        xmx = y[0]
        xmn = y[0]
        t = t_start
        for s in range(substeps):
            if s == substeps - 1:
                t_target = T
            else:
                t_target = t_start + (s + 1) * T / substeps
            while t < t_target:
                stop = t_target
                if half_break:
                    th = t_start + 0.5 * T
                    if t < th - 1e-14 * T and th < stop:
                        stop = th
                if half_break:
                    # the friction direction of this step (steps never straddle T/2); a flip
                    # invalidates the FSAL stage, which was evaluated with the old direction
                    lam = 1 if t - t_start < 0.5 * T * (1.0 - 1e-12) else -1
                    if lam != mode[MODE_FRICTION]:
                        mode[MODE_FRICTION] = lam
                        k1_valid = False
                if method == METHOD_RK4:
                    # next grid point of the fixed-step mesh
                    j = int(math.floor((t - t_start) / h_rk + 1e-9)) + 1
                    tg = t_start + j * h_rk
                    if tg > stop:
                        tg = stop
                    hh = tg - t
                    if hh <= 1e-14 * T:
                        t = tg
                        continue
                else:
                    hh = min(h, hmax, stop - t)
                    if stop - t - hh < 1e-9 * hh:
                        hh = stop - t
                err = _step(
                    method, t, y, hh, pl, mode, n, nerr, tangent, ks, ytmp, ynew, rtol, atol,
                    k1_valid,
                )
                n_steps += 1
                if method == METHOD_DP5:
                    if not (err <= 1.0):
                        if err != err:  # NaN
                            status = 1
                            break
                        h = hh * max(0.2, 0.9 * err ** -0.2)
                        k1_valid = True  # k1 is still g(t, y)
                        if h < h_min:
                            status = 2
                            break
                        continue
                # ---- accepted step of size hh: look for switches inside it
                first_c = -1
                first_s = 2.0
                graze = False
                for c in range(N_SWITCH):
                    if not active[c]:
                        continue
                    ci = SWITCH_COORD[c]
                    gap = gaps[c]
                    r_new = region_of(ynew[ci], gap)
                    x0 = y[ci]
                    v0 = y[ci + 1]
                    x1 = ynew[ci]
                    v1 = ynew[ci + 1]
                    s_est = -1.0
                    if r_new != mode[c]:
                        # boundary crossed first, in the direction of motion
                        if r_new > mode[c]:
                            bnd = -gap if mode[c] == -1 else gap
                        else:
                            bnd = gap if mode[c] == 1 else -gap
                        # bisection on the Hermite cubic for a starting fraction
                        lo = 0.0
                        hi = 1.0
                        pre_pos = r_new < mode[c]  # sign of x - bnd before the crossing
                        for _ in range(30):
                            mid = 0.5 * (lo + hi)
                            gm = _hermite(x0, v0, x1, v1, hh, mid) - bnd
                            if (gm > 0.0) == pre_pos:
                                lo = mid
                            else:
                                hi = mid
                        s_est = 0.5 * (lo + hi)
                    elif v0 * v1 < 0.0:
                        se = _hermite_extremum(x0, v0, x1, v1, hh)
                        if se > 0.0:
                            xe = _hermite(x0, v0, x1, v1, hh, se)
                            if region_of(xe, gap) != mode[c]:
                                s_est = se  # possible grazing excursion: verified below
                    if s_est >= 0.0 and s_est < first_s:
                        first_s = s_est
                        first_c = c
                        graze = r_new == mode[c]
                if first_c >= 0:
                    c = first_c
                    ci = SWITCH_COORD[c]
                    gap = gaps[c]
                    x0 = y[ci]
                    lo_t = 0.0
                    hi_t = hh
                    if graze:
                        # verify the excursion with a real step to the predicted extremum
                        te = first_s * hh
                        _step(method, t, y, te, pl, mode, n, nerr, tangent, ks, ytmp, ytry,
                              rtol, atol, False)
                        n_steps += 1
                        r_e = region_of(ytry[ci], gap)
                        if r_e == mode[c]:
                            first_c = -1  # no real contact change: keep the step
                        else:
                            hi_t = te
                            first_s = 0.5 * te / hh
                if first_c >= 0:
                    r_far = region_of(ytry[ci], gap) if graze else region_of(ynew[ci], gap)
                    if r_far > mode[c]:
                        bnd = -gap if mode[c] == -1 else gap
                        new_region = 0 if mode[c] == -1 else 1
                    else:
                        bnd = gap if mode[c] == 1 else -gap
                        new_region = 0 if mode[c] == 1 else -1
                    if gap == 0.0:
                        new_region = r_far
                    pre_pos = r_far < mode[c]  # sign of x - bnd on the side we leave
                    th = first_s * hh
                    for _ in range(60):
                        _step(method, t, y, th, pl, mode, n, nerr, tangent, ks, ytmp, ytry,
                              rtol, atol, False)
                        n_steps += 1
                        g = ytry[ci] - bnd
                        if abs(g) <= 1e-12 * (1.0 + gap):
                            break
                        if (g > 0.0) == pre_pos:
                            lo_t = th
                        else:
                            hi_t = th
                        vel = ytry[ci + 1]
                        tn = th - g / vel if vel != 0.0 else -1.0
                        if not (lo_t < tn < hi_t):
                            tn = 0.5 * (lo_t + hi_t)
                        th = tn
                        if hi_t - lo_t < 1e-15 * T:
                            break
                    # land on the switch (old region up to here)
                    t_new = t + th
                    if mode[0] == 0:
                        td += th
                    for i in range(n):
                        y[i] = ytry[i]
                    t = t_new
                    if c == 0:
                        if new_region == 1:
                            nf += 1
                        elif new_region == -1:
                            nb += 1
                    if n_ev < ev_t.shape[0]:
                        ev_t[n_ev] = t_abs0 + t
                        ev_code[n_ev] = 4 * c + new_region + 1
                    n_ev += 1
                    mode[c] = new_region
                    k1_valid = False
                    fl = _mesh_force_local(t, y[0], y[1], p, mode[0])
                    fmx = max(fmx, fl)
                    fmn = min(fmn, fl)
                    xmx = max(xmx, y[0])
                    xmn = min(xmn, y[0])
                    continue
                # ---- no switch: accept the whole step
                if mode[0] == 0:
                    td += hh
                v0 = y[1]
                v1 = ynew[1]
                if v0 * v1 < 0.0:
                    se = _hermite_extremum(y[0], v0, ynew[0], v1, hh)
                    if se > 0.0:
                        xe = _hermite(y[0], v0, ynew[0], v1, hh, se)
                        xmx = max(xmx, xe)
                        xmn = min(xmn, xe)
                        fe = (1.0 + p[P_EPS] * math.cos(w * (t + se * hh))) * dead_zone(
                            xe, gaps[0], mode[0]
                        )
                        fmx = max(fmx, fe)
                        fmn = min(fmn, fe)
                for i in range(n):
                    y[i] = ynew[i]
                    ks[0, i] = ks[6, i]
                t = t + hh
                if t > stop or stop - t < 1e-12 * T:
                    t = stop
                k1_valid = method == METHOD_DP5
                fl = _mesh_force_local(t, y[0], y[1], p, mode[0])
                fmx = max(fmx, fl)
                fmn = min(fmn, fl)
                xmx = max(xmx, y[0])
                xmn = min(xmn, y[0])
                bad = False
                for i in range(N_STATE):
                    if not (abs(y[i]) < bound):
                        bad = True
                if bad:
                    status = 1
                    break
                if method == METHOD_DP5:
                    fac = 5.0 if err == 0.0 else min(5.0, max(0.2, 0.9 * err ** -0.2))
                    h = hh * fac
            if status != 0:
                break
            if row < traj_rows:
                for i in range(N_STATE):
                    traj[row, i] = y[i]
                row += 1
            # re-check the frozen regions against the state on the section (guards drift)
            t = t_target
        if status != 0:
            break
        nface[k] = nf
        nback[k] = nb
        tdis[k] = td
        fmax[k] = fmx
        fmin[k] = fmn
        xmax[k] = xmx
        xmin[k] = xmn
        if tangent:
            nrm = 0.0
            for i in range(10, 20):
                nrm += y[i] * y[i]
            nrm = math.sqrt(nrm)
            if nrm > 0.0 and nrm == nrm:
                lyap[k] = math.log(nrm)
                for i in range(10, 20):
                    y[i] /= nrm
            else:
                lyap[k] = 0.0
        periods_done = k + 1
    for i in range(n):
        y0[i] = y[i]
    return status, periods_done, n_ev, h, n_steps
