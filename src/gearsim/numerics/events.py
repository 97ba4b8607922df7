"""The event layer: contact switches located inside steps, for every integration path.

Each dead zone is frozen in its region for a whole step (the field stays smooth, so the step keeps
its order). After a step, every switching channel (mesh ``x = +/-b``; bearing ``u = +/-b_j`` when
the clearance is non-zero) is checked by :func:`scan_switches`: a change of region, or an interior
excursion across the boundary predicted by the cubic Hermite interpolant of ``(x, x')`` (a grazing
contact inside the step), triggers location. The crossing time is found by a safeguarded
Newton-bisection iteration in which each trial is a real step of the same method from the step
start (:func:`gearsim.numerics.steps.trial_step`), to ``|g| <= 1e-12 (1 + gap)``; the state lands
on the
switch, the region changes, and the rest of the interval is integrated in the new region.

:func:`advance_interval` is that loop over one interval of a mesh period. The scalar integrator
(:func:`gearsim.numerics.integrate.integrate_periods`) calls it for every DP5 output interval and
for every
RK4 grid interval that its step flags; the batched kernel (:mod:`gearsim.numerics.batch`) calls it
for its
flagged lanes. At a mesh switch of a discontinuous field (damping only in contact) it applies
the saltation matrix to the tangent vector (:func:`apply_saltation`). It also keeps the
per-period accumulators (time inside the backlash, impact
counts, force and displacement extremes with the Hermite extremum inside a step) and the event
log.
"""

from __future__ import annotations

import math

from numba import njit

from gearsim.dynamics.model import (
    N_STATE,
    N_SWITCH,
    P_ACT,
    P_XIO,
    SWITCH_COORD,
    SWITCH_GAP,
    field_params,
    region_of,
    rhs,
    tracked_force,
)
from gearsim.dynamics.model import P_W as _P_W
from gearsim.numerics.steps import METHOD_DP5, METHOD_RK4, rk4_tangent_step, trial_step

# accumulator slots (float array ``acc``)
ACC_TD = 0  # time inside the backlash
ACC_FMAX = 1
ACC_FMIN = 2
ACC_XMAX = 3
ACC_XMIN = 4
ACC_H = 5  # DP5: next step size
ACC_K1 = 6  # DP5: 1.0 when ks[0] holds g(t, y) (FSAL)
N_ACC = 7
# counter slots (int array ``cnt``)
CNT_NF = 0  # face entries in the current period
CNT_NB = 1  # back entries
CNT_EV = 2  # events seen (may exceed the log's capacity)
CNT_STEPS = 3  # steps taken (trial steps included)
N_CNT = 4

STATUS_OK = 0
STATUS_DIVERGED = 1
STATUS_STEP_COLLAPSE = 2


@njit(cache=True, nogil=True, inline="always")
def hermite(x0, v0, x1, v1, h, s):
    """Cubic Hermite interpolant of x on [0, h] at fraction s in [0, 1]."""
    s2 = s * s
    s3 = s2 * s
    return (
        (2 * s3 - 3 * s2 + 1) * x0
        + (s3 - 2 * s2 + s) * h * v0
        + (-2 * s3 + 3 * s2) * x1
        + (s3 - s2) * h * v1
    )


@njit(cache=True, nogil=True, _nrt=False)
def hermite_extremum(x0, v0, x1, v1, h):
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


@njit(cache=True, nogil=True, inline="always")
def _bisect_hermite(x0, v0, x1, v1, h, bnd, pre_pos):
    """Fraction where the Hermite cubic crosses ``bnd``: 30 bisection steps on [0, 1].

    ``pre_pos``: the sign of ``x - bnd`` before the crossing. Two steps per round: the midpoint
    and the two points the next step can pick (the same ``0.5 (lo + hi)`` values, so the same
    interval as one step at a time) are evaluated first, as independent chains; the chain of 30
    dependent cubic evaluations (~50 cycles each) was the largest part of the flagged-lane redo.
    """
    lo = 0.0
    hi = 1.0
    for _ in range(15):
        m = 0.5 * (lo + hi)
        ml = 0.5 * (lo + m)
        mr = 0.5 * (m + hi)
        g = hermite(x0, v0, x1, v1, h, m) - bnd
        gl = hermite(x0, v0, x1, v1, h, ml) - bnd
        gr = hermite(x0, v0, x1, v1, h, mr) - bnd
        if (g > 0.0) == pre_pos:
            lo = m
            a, ga = mr, gr
        else:
            hi = m
            a, ga = ml, gl
        if (ga > 0.0) == pre_pos:
            lo = a
        else:
            hi = a
    return 0.5 * (lo + hi)


@njit(cache=True, nogil=True, _nrt=False)
def channels(p, mode, y, gaps, active, reset):
    """Fill the gaps and active flags of the switching channels from ``p``.

    With ``reset`` the regions ``mode[0:5]`` are set from the state ``y`` (start of a call).
    A channel without gap is linear: region +1 gives ``f(u, 0) = u`` on both sides. This holds
    for the mesh too: at zero backlash the teeth never separate, so a crossing of ``x = 0`` is
    no impact (no switch, no face or back entry, no time inside the backlash).
    """
    for c in range(N_SWITCH):
        gaps[c] = p[SWITCH_GAP[c]]
        active[c] = gaps[c] > 0.0 if c == 0 else p[P_ACT + c - 1] != 0.0
        if reset:
            mode[c] = region_of(y[SWITCH_COORD[c]], gaps[c]) if active[c] else 1


@njit(cache=True, nogil=True, _nrt=False)
def scan_switches(y, ynew, hh, mode, gaps, active):
    """First switch inside a step from ``y`` to ``ynew``: ``(channel, fraction, graze)``.

    ``channel`` is -1 when no channel changes region and no Hermite extremum crosses a boundary.
    """
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
            pre_pos = r_new < mode[c]  # sign of x - bnd before the crossing
            s_est = _bisect_hermite(x0, v0, x1, v1, hh, bnd, pre_pos)
        elif v0 * v1 < 0.0:
            se = hermite_extremum(x0, v0, x1, v1, hh)
            if se > 0.0:
                xe = hermite(x0, v0, x1, v1, hh, se)
                if region_of(xe, gap) != mode[c]:
                    s_est = se  # possible grazing excursion: verified by a real step
        if s_est >= 0.0 and s_est < first_s:
            first_s = s_est
            first_c = c
            graze = r_new == mode[c]
    return first_c, first_s, graze


@njit(cache=True, nogil=True, _nrt=False)
def apply_saltation(t, y, p, mode, new_region, fm, fp):
    """Jump of the tangent vector ``y[10:20]`` at a landed mesh switch of a discontinuous field.

    With damping only in contact (``mesh_damping_contact > 0``) the field jumps at ``x = +/-b``;
    the variational solution then crosses the switch with the saltation matrix
    ``S = I + (f+ - f-) e_x^T / (e_x^T f-)`` (switching surface ``x -/+ b = 0``, time-independent:
    normal ``e_x``, ``e_x^T f- = x'``). ``f-`` is the field in the old region, ``f+`` in
    ``new_region``, both at the switch point; ``fm``, ``fp`` are scratch rows (10+ entries).
    """
    v = y[1]
    if v == 0.0:
        return
    old = mode[0]
    rhs(t, y, p, mode, fm, False)
    mode[0] = new_region
    rhs(t, y, p, mode, fp, False)
    mode[0] = old
    s = y[N_STATE] / v
    for i in range(N_STATE):
        y[N_STATE + i] += (fp[i] - fm[i]) * s


@njit(cache=True, nogil=True, _nrt=False)
def _track(acc, ph, y, p, mode):
    """Fold the state at a landed point (mesh phase ``ph``) into the force and displacement
    extremes (the force of the model form: :func:`gearsim.dynamics.model.tracked_force`)."""
    r0 = float(mode[0])
    fl = tracked_force(math.cos(ph), math.sin(ph), y[0], y[1], field_params(p, 0, 1), r0,
                       abs(r0))
    acc[ACC_FMAX] = max(acc[ACC_FMAX], fl)
    acc[ACC_FMIN] = min(acc[ACC_FMIN], fl)
    acc[ACC_XMAX] = max(acc[ACC_XMAX], y[0])
    acc[ACC_XMIN] = min(acc[ACC_XMIN], y[0])


@njit(cache=True, nogil=True, _nrt=False)
def turn_extremum(x0, v0, x1, v1, hh, t, w, P, r0):
    """The turning point of x inside an accepted step (x' changes sign): ``(found, xe, fe)``.

    ``xe`` the Hermite cubic's extremum on the step from time ``t`` (within the period) over
    ``hh``, ``fe`` the tracked mesh force there (x' = 0, mesh phase ``w (t + s hh)``), for the
    per-period extremes. The one source for the event layer's accepted steps and the RK4 grid
    steps that stand with a turning point (:func:`gearsim.numerics.steps.grid_step_flag`).
    """
    se = hermite_extremum(x0, v0, x1, v1, hh)
    if se > 0.0:
        xe = hermite(x0, v0, x1, v1, hh, se)
        pe = w * (t + se * hh)
        fe = tracked_force(math.cos(pe), math.sin(pe), xe, 0.0, P, r0, abs(r0))
        return True, xe, fe
    return False, 0.0, 0.0


@njit(cache=True, nogil=True, _nrt=False)
def advance_interval(method, t, t_stop, y, p, mode, gaps, active, n, nerr, tangent, ks, ytmp,
                     ynew, ytry, rtol, atol, hmax, T, bound, acc, cnt, ev_t, ev_code, t_abs0):
    """Integrate from ``t`` to ``t_stop`` (times within the period) with located switches.

    ``y`` (``n`` entries: state, then the tangent vector if ``tangent``) and ``mode`` are updated
    in place. RK4 takes one step over the whole interval (the caller passes one grid interval)
    and cuts it at switches; DP5 steps adaptively (``acc[ACC_H]`` carries the step size, capped at
    ``hmax``). Switch events go to ``ev_t``/``ev_code`` (code = 4 * channel + new region + 1) up
    to their capacity, at absolute time ``t_abs0 + t``. Returns the status (0 ok, 1 diverged,
    2 step collapse).
    """
    w = p[_P_W]
    h_min = 1e-12 * T
    status = STATUS_OK
    # RK4: trial steps of the state alone, the tangent vector stepped once over each step that
    # stands (rk4_tangent_step: the same numbers; the switch search's trial steps are ~4 a switch)
    lazy = tangent and method == METHOD_RK4
    tg = tangent and not lazy
    while t < t_stop:
        if method == METHOD_RK4:
            hh = t_stop - t
            if hh <= 1e-14 * T:
                break
        else:
            hh = min(acc[ACC_H], hmax, t_stop - t)
            if t_stop - t - hh < 1e-9 * hh:
                hh = t_stop - t
        err = trial_step(method, t, y, hh, p, mode, n, nerr, tg, ks, ytmp, ynew, rtol, atol,
                         acc[ACC_K1] != 0.0)
        cnt[CNT_STEPS] += 1
        if method == METHOD_DP5:
            if not (err <= 1.0):
                if err != err:  # NaN
                    status = STATUS_DIVERGED
                    break
                acc[ACC_H] = hh * max(0.2, 0.9 * err ** -0.2)
                acc[ACC_K1] = 1.0  # k1 is still g(t, y)
                if acc[ACC_H] < h_min:
                    status = STATUS_STEP_COLLAPSE
                    break
                continue
        # ---- accepted step of size hh: look for switches inside it
        c, first_s, graze = scan_switches(y, ynew, hh, mode, gaps, active)
        if c >= 0:
            ci = SWITCH_COORD[c]
            gap = gaps[c]
            lo_t = 0.0
            hi_t = hh
            if graze:
                # verify the excursion with a real step to the predicted extremum
                te = first_s * hh
                trial_step(method, t, y, te, p, mode, n, nerr, tg, ks, ytmp, ytry, rtol,
                           atol, False)
                cnt[CNT_STEPS] += 1
                if region_of(ytry[ci], gap) == mode[c]:
                    c = -1  # no real contact change: keep the step
                else:
                    hi_t = te
                    first_s = 0.5 * te / hh
        if c >= 0:
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
            th_try = th
            for _ in range(60):
                trial_step(method, t, y, th, p, mode, n, nerr, tg, ks, ytmp, ytry, rtol,
                           atol, False)
                th_try = th
                cnt[CNT_STEPS] += 1
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
            if lazy:
                rk4_tangent_step(t, y, th_try, p, mode, ytry)
            if mode[0] == 0:
                acc[ACC_TD] += th
            for i in range(n):
                y[i] = ytry[i]
            t = t + th
            if c == 0:
                if new_region == 1:
                    cnt[CNT_NF] += 1
                elif new_region == -1:
                    cnt[CNT_NB] += 1
            if tangent and c == 0 and p[P_XIO] != 0.0:
                # the field jumps here (contact-only damping); ks rows are free until the next step
                apply_saltation(t, y, p, mode, new_region, ks[1], ks[2])
            k_ev = cnt[CNT_EV]
            if k_ev < ev_t.shape[0]:
                ev_t[k_ev] = t_abs0 + t
                ev_code[k_ev] = 4 * c + new_region + 1
            cnt[CNT_EV] = k_ev + 1
            mode[c] = new_region
            acc[ACC_K1] = 0.0
            _track(acc, w * t, y, p, mode)
            continue
        # ---- no switch: accept the whole step
        if lazy:
            rk4_tangent_step(t, y, hh, p, mode, ynew)
        if mode[0] == 0:
            acc[ACC_TD] += hh
        if y[1] * ynew[1] < 0.0:
            found, xe, fe = turn_extremum(y[0], y[1], ynew[0], ynew[1], hh, t, w,
                                          field_params(p, 0, 1), float(mode[0]))
            if found:
                acc[ACC_XMAX] = max(acc[ACC_XMAX], xe)
                acc[ACC_XMIN] = min(acc[ACC_XMIN], xe)
                acc[ACC_FMAX] = max(acc[ACC_FMAX], fe)
                acc[ACC_FMIN] = min(acc[ACC_FMIN], fe)
        for i in range(n):
            y[i] = ynew[i]
            ks[0, i] = ks[6, i]
        t = t + hh
        if t > t_stop or t_stop - t < 1e-12 * T:
            t = t_stop
        acc[ACC_K1] = 1.0 if method == METHOD_DP5 else 0.0
        _track(acc, w * t, y, p, mode)
        bad = False
        for i in range(N_STATE):
            if not (abs(y[i]) < bound):
                bad = True
        if bad:
            status = STATUS_DIVERGED
            break
        if method == METHOD_DP5:
            fac = 5.0 if err == 0.0 else min(5.0, max(0.2, 0.9 * err ** -0.2))
            acc[ACC_H] = hh * fac
    if status == STATUS_OK:
        for i in range(N_STATE):
            if not (abs(y[i]) < bound):
                status = STATUS_DIVERGED  # a NaN from a switch search on a bad state
    return status
