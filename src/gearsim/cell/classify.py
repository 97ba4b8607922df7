"""Classification of a steady motion from per-period summaries of the integrator.

Everything here works on what :func:`gearsim.numerics.integrate.integrate_periods` records once per
mesh
period ``T = 2 pi / w``: the Poincare section state, the number of entries into face / back
contact (counted at *located* switches, never from samples), the time spent inside the backlash
(integrated between located switches), force and displacement extremes and the log growth of the
tangent vector.

Definitions
-----------
period ``n``
    Smallest ``n <= n_max`` such that the section points repeat after ``n`` samples over a
    confirmation window of ``max(2 n, min_confirm)`` consecutive comparisons, with tolerance
    ``period_rtol * scale`` where ``scale`` is the displacement range of the orbit (velocity
    tolerance scaled by ``w``). Scale-aware: the same relative test for tiny and large orbits.
    Or (:func:`_converges_geometrically`): the differences ``P_k - P_{k-n}`` decay at one
    steady geometric rate over the measured tail and extrapolate to below that tolerance --
    the sequence converges onto a period-``n`` orbit whose Floquet multiplier is real and near
    the unit circle (next to a period doubling ``mu -> -1``: the transient alternates, repeats
    after ``2 n`` samples within the tolerance and the repeat test alone takes it for period
    ``2 n``; docs/orbits.md, "Simulated labels next to a period doubling").
settle distance
    (:func:`settle_estimate`) how far the last section point still is from the period-``n``
    orbit the sequence converges to, relative to ``scale``: the last relative difference
    ``|P_m - P_{m-n}|`` over ``|1 - mu|``, ``mu`` the contraction per motion period read from
    the decay of those differences over the window (signed: an alternating transient has
    ``mu < 0``). A cell farther than :data:`gearsim.cell.verify.REFINE_RTOL` from settled is
    labelled by its Newton-refined orbit (:mod:`gearsim.cell.verify`), not by the window.
``p``, ``q``
    Face (x crosses +b upward) and back (x crosses -b downward) impacts per motion period.
``I``
    0 no disengagement; 1 face impacts only; -1 back impacts only; 2 both; -2 never in contact.
``DC``
    Fraction of time inside the backlash (``|x| < b``) over the analysed window.
``Kmax``
    Four readings (see :data:`KMAX_READINGS`): peak of the mesh force over the whole window or
    the largest value at the Poincare section, each divided by the mean load ``Fm`` or by the
    total static excitation ``Fm + Fe w^2``.
diverged
    A motion that leaves the divergence bound: not an attractor, no pattern. Where the linear
    limit of the mesh is unstable, also one without a period whose long run grows
    (:mod:`gearsim.cell.growth`). A window whose amplitude grows throughout
    (:func:`amplitude_grows`) is ``unsettled``, not diverged by itself: a slow transient onto a
    larger bounded orbit rises the same way (the long run tells the two apart where the
    linear limit is unstable; elsewhere a large motion is bounded by it).
Lyapunov exponent
    Largest exponent per unit dimensionless time from the variational equations (exact across
    the switches because the field is continuous), averaged over the analysed window.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gearsim.cell.motion import DEFAULT_KMAX, KMAX_READINGS, MOTIONS  # noqa: F401  (re-exported)
from gearsim.cell.record import Classification
from gearsim.dynamics.model import pack_parameters, section_force
from gearsim.dynamics.parameters import ModelParameters
from gearsim.numerics.integrate import PeriodSummaries

#: a motion without a period whose largest peak-to-peak amplitude x_max - x_min rises from each
#: quarter of the analysed window to the next by at least GROWTH_STEP, the last quarter's at
#: least GROWTH_MIN times the first's, grows: never chaos or quasi-periodic; ``unsettled`` from
#: its window (a slow approach to a larger bounded orbit rises so too), ``diverged`` when the
#: long run of gearsim.cell.growth grows (the parametric instability of the nearly linear mesh
#: at w near 2; docs/decisions.md)
GROWTH_MIN = 1.1
GROWTH_STEP = 1.02

#: relative lag-n difference below which a section sequence counts as settled whatever its rate
#: (the RK4 map repeats a settled orbit to ~1e-14 of its scale)
SETTLED_FLOOR = 1e-9


@njit(cache=True, nogil=True)
def estimate_period(section_x, section_v, scale, w, n_max=64, period_rtol=1e-5, min_confirm=16):
    """Smallest period ``n`` (in mesh periods) of the section sequence, or 0 if none ``<= n_max``.

    Compiled (the one period test: the scalar driver, the batched driver and every diagnostic
    call it).

    Parameters
    ----------
    section_x, section_v
        Poincare samples of ``x`` and ``x'`` (oldest first).
    scale
        Displacement scale of the orbit (its range ``xmax - xmin``); tolerances are relative to it.
    w
        Dimensionless mesh frequency; scales the velocity tolerance.
    """
    m = len(section_x)
    scale = max(scale, 1e-9)
    tol_x = period_rtol * scale
    tol_v = period_rtol * scale * max(w, 1e-3)
    for n in range(1, n_max + 1):
        window = max(2 * n, min_confirm)
        if window + n > m:
            return 0
        if repeats_after(section_x, section_v, n, m - window, tol_x, tol_v):
            if n > 1 and (_spread_decays(section_x, m, window, n, tol_x)
                          or _lower_period_at_end(section_x, section_v, m, n, tol_x, tol_v)):
                return 0  # a decaying transient mimics period n: integrate on
            return n
        if _converges_geometrically(section_x, section_v, m, n, scale, tol_x, min_confirm):
            if n > 1 and _lower_period_transient(section_x, m, n, min_confirm):
                return 0  # the lag-d differences decay as well: a lower period's transient
            return n
    return 0


@njit(cache=True, nogil=True)
def window_period(section_x, section_v, xmax, xmin, w, n_max, period_rtol):
    """:func:`estimate_period` of a window of recorded periods, its tolerances relative to the
    window's x range (``max(xmax) - min(xmin)``, NaN if any is NaN): the period test of a
    measuring chunk, on the host and inside a CUDA thread (no allocation)."""
    hi = xmax[0]
    lo = xmin[0]
    for i in range(1, len(xmax)):
        if xmax[i] > hi or xmax[i] != xmax[i]:
            hi = xmax[i]
        if xmin[i] < lo or xmin[i] != xmin[i]:
            lo = xmin[i]
    return estimate_period(section_x, section_v, hi - lo, w, n_max, period_rtol, 16)


@njit(cache=True, nogil=True)
def repeats_after(section_x, section_v, n, first, tol_x, tol_v):
    """Whether every section point from index ``first`` on repeats the one ``n`` samples
    earlier to ``tol_x`` in ``x`` and ``tol_v`` in ``x'`` (NaN fails): the one repeat
    comparison of the period test and of :func:`repeats_throughout`."""
    for i in range(max(first, n), len(section_x)):
        if not (abs(section_x[i] - section_x[i - n]) <= tol_x
                and abs(section_v[i] - section_v[i - n]) <= tol_v):
            return False
    return True


@njit(cache=True, nogil=True)
def repeats_throughout(section_x, section_v, scale, w, n_max, rtol):
    """Smallest ``n <= n_max`` such that every point of the section sequence repeats after
    ``n`` samples to ``rtol`` (``x`` relative to ``scale``, ``x'`` to ``scale w``, as the period
    test), or 0 (NaN fails)."""
    tol_x = rtol * scale
    tol_v = rtol * scale * max(w, 1e-3)
    for n in range(1, n_max + 1):
        if len(section_x) <= n:
            return 0
        if repeats_after(section_x, section_v, n, n, tol_x, tol_v):
            return n
    return 0


@njit(cache=True, nogil=True)
def _lower_period_transient(section_x, m, n, min_confirm, max_window=96, share=0.5):
    """True if, over the window of :func:`_converges_geometrically`, the differences at some lag
    ``d`` dividing ``n`` (``d < n``) shrink by at least ``share`` of the relative decay of the
    lag-``n`` differences: the points converge onto a period-``d`` orbit (e.g. a 1T orbit with a
    complex multiplier whose square is nearly real and negative: ``P_k - P_{k-2}`` decays
    steadily). Approaching a true period-``n`` orbit of amplitude ``A`` with a residual ``c``,
    the lag-``d`` differences shrink only by ``~c / A`` of that."""
    j0 = m - 1 - 4 * _quarter_window(m, n, max_window)
    sn0 = _tail_spread(section_x, j0, 2 * n, n)
    sn4 = _tail_spread(section_x, m - 1, 2 * n, n)
    if not sn0 > 0.0:
        return False
    rel_n = (sn0 - sn4) / sn0
    for d in range(1, n):
        if n % d != 0:
            continue
        sd0 = _tail_spread(section_x, j0, 2 * n, d)
        sd4 = _tail_spread(section_x, m - 1, 2 * n, d)
        if sd0 > 0.0 and (sd0 - sd4) / sd0 >= share * rel_n:
            return True
    return False


@njit(cache=True, nogil=True)
def _lower_period_at_end(section_x, section_v, m, n, tol_x, tol_v):
    """True if the window's last ``2 n`` points already repeat after a divisor ``d < n`` of
    ``n``: the points converge onto a period-``d`` orbit (the lag-``d`` differences fall below
    the tolerance inside the window, e.g. a 1T orbit with a complex multiplier near -1 whose
    alternation decays by beats), and the window reads period ``n`` only because lag ``n``
    reached the tolerance first. The least period is ``d``, not settled yet. A true
    period-``n`` orbit's lag-``d`` differences are its own spread, above the tolerance."""
    for d in range(1, n):
        if n % d == 0 and repeats_after(section_x, section_v, d, m - 2 * n, tol_x, tol_v):
            return True
    return False


@njit(cache=True, nogil=True)
def _quarter_window(m, n, max_window):
    """A quarter of the geometric rule's window: whole pairs of motion periods, the window
    ``4 * quarter <= min(m - 3 n, max_window)`` (shared by both rules so they read one window)."""
    return (min(m - 3 * n, max_window) // 4) // (2 * n) * (2 * n)


@njit(cache=True, nogil=True)
def _tail_spread(a, j, n, lag):
    """Sum over ``i = j-n+1 .. j`` of ``|a[i] - a[i-lag]|`` (one motion period of differences)."""
    s = 0.0
    for i in range(j - n + 1, j + 1):
        s += abs(a[i] - a[i - lag])
    return s


@njit(cache=True, nogil=True)
def _converges_geometrically(section_x, section_v, m, n, scale, tol_x, min_confirm,
                             max_window=96, steady=0.2, resolved=0.02, limit_rtol=0.05,
                             near=1e-2):
    """True if the section sequence converges geometrically onto a period-``n`` orbit.

    ``S_j`` = sum of ``|P_i - P_{i-n}|`` (x component) over the ``2 n`` samples ending at
    ``j``. Over the longest window
    ``W <= min(m - 3 n, max_window)`` (a multiple of ``8 n``, at least ``min_confirm``) take
    ``S`` at its five quarter points. A linear transient onto a period-``n`` orbit with one
    dominant real multiplier ``mu`` of ``P^n`` gives ``S_j ~ |mu|^(j / n)``: the four quarter
    ratios are equal and below 1 (sums over pairs of motion periods: a smaller second mode makes
    ``|P_i - P_{i-n}|`` alternate in size under an alternating dominant one). Accepted when

    - every quarter ratio is below 1 and they agree to ``steady`` times the decay rate
      ``1 - mean ratio`` (one steady geometric rate: a quasi-periodic or chaotic sequence, or
      a complex multiplier whose rotation is not a multiple of ``2 pi / n``, fails);
    - the decay over the window is resolved (``S`` falls by at least ``resolved``);
    - Aitken's extrapolation of ``S`` from the first, middle and last point is zero within
      ``max(2 n tol_x, limit_rtol * S_end)`` (the points repeat after ``n`` in the limit; a
      spread that levels off at a finite value ``A``, e.g. a period-``n`` sequence approaching
      a period-``2 n`` orbit, extrapolates to ``A`` and fails unless the motion is still 20
      times farther from that orbit than its amplitude -- then ``near`` bounds ``A`` to 5e-4
      of the scale, an orbit within ``~A^2`` of its doubling). The relative part absorbs the
      weak nonlinearity of a transient of 1e-3 of the scale (its rate drifts with its
      amplitude);
    - the motion is near its limit (``S_end / 2 n <= near * scale``) and the velocity
      differences do not grow.
    """
    # quarters of whole pairs of motion periods: an alternating dominant mode plus a smaller
    # non-alternating one makes |P_i - P_{i-n}| alternate in size; pairs average it out
    w4 = _quarter_window(m, n, max_window)
    W = 4 * w4
    if W < max(8 * n, min_confirm):
        return False
    j0 = m - 1 - W
    # the cheap necessary conditions first (most aperiodic sequences stop here)
    s0 = _tail_spread(section_x, j0, 2 * n, n)
    s4 = _tail_spread(section_x, j0 + 4 * w4, 2 * n, n)
    if not (s0 > 0.0 and s4 <= (1.0 - resolved) * s0 and s4 <= near * scale * 2 * n):
        return False  # no resolved decay, not near the limit, or NaN
    # five scalars, no array: the test also runs inside a CUDA thread (gearsim.cell.device_chains)
    s1 = _tail_spread(section_x, j0 + w4, 2 * n, n)
    s2 = _tail_spread(section_x, j0 + 2 * w4, 2 * n, n)
    s3 = _tail_spread(section_x, j0 + 3 * w4, 2 * n, n)
    if not (math.isfinite(s0) and math.isfinite(s1) and math.isfinite(s2)
            and math.isfinite(s3) and math.isfinite(s4)):
        return False
    r0 = _ratio(s1, s0)
    r1 = _ratio(s2, s1)
    r2 = _ratio(s3, s2)
    r3 = _ratio(s4, s3)
    rsum = ((r0 + r1) + r2) + r3
    rmin = min(min(min(r0, r1), r2), r3)
    rmax = max(max(max(r0, r1), r2), r3)
    rate = 1.0 - rsum / 4.0
    if not (rmax < 1.0 and rmax - rmin <= steady * rate):
        return False
    d1 = s4 - s2
    d0 = s2 - s0
    if d1 - d0 == 0.0:
        return False
    limit = s4 - d1 * d1 / (d1 - d0)
    if abs(limit) > max(2 * n * tol_x, limit_rtol * s4):
        return False
    v_early = _tail_spread(section_v, j0, 2 * n, n)
    v_late = _tail_spread(section_v, m - 1, 2 * n, n)
    return v_late <= v_early


@njit(cache=True, nogil=True, inline="always")
def _ratio(b, a):
    """``b / a`` of two successive spreads, 2 (no decay) where ``a`` is not positive."""
    return b / a if a > 0.0 else 2.0


@njit(cache=True, nogil=True)
def _spread_decays(section_x, m, window, n, tol_x):
    """True if the spread of the n section points shrinks over the window.

    Next to a period doubling a period-1 orbit has a Floquet multiplier near -1 (near a
    rotation angle 2 pi / n in general): its transient alternates and decays slowly, repeats after
    n samples to within the tolerance and would pass for period n. A true period-n orbit keeps
    its spread (mean |P_k - P_{k-1}| over a motion period); a transient's spread decays.
    """
    early = _tail_spread(section_x, m - window + n - 1, n, 1) / n
    late = _tail_spread(section_x, m - 1, n, 1) / n
    return early - late > max(2.0 * tol_x, 1e-3 * early)


@njit(cache=True, nogil=True)
def _rel_diff(section_x, section_v, i, lag, scale, sv):
    return max(abs(section_x[i] - section_x[i - lag]) / scale,
               abs(section_v[i] - section_v[i - lag]) / sv)


@njit(cache=True, nogil=True)
def settle_estimate(section_x, section_v, n, scale, w, max_window=96):
    """``(distance, mu)``: how far the sequence still is from its period-``n`` limit.

    ``e`` = mean relative difference ``|P_i - P_{i-n}|`` (x over ``scale``, x' over ``scale w``)
    over the last ``2 n`` samples (pairs: an alternating second mode averages out). Over the
    longest window ``W <= min(m - 3 n, max_window)`` (whole pairs of motion periods) ``e`` falls
    by ``|mu|^(W / n)``: ``|mu|`` is the contraction per motion period, its sign that of the
    correlation of successive differences (``-``: the transient alternates, a multiplier near
    -1). With ``P_k = O + c mu^(k/n) v`` the last point lies ``|mu|^(2 - 1/(2n)) e / |1 -
    mu|`` from the orbit ``O``. Returns ``(e, 0)`` when ``e <= SETTLED_FLOOR`` (settled to the
    map's noise), ``(e, nan)`` when the window is too short for a rate, ``(inf, mu)`` when the
    differences do not shrink. ``distance`` is relative to ``scale``.
    """
    m = len(section_x)
    scale = max(scale, 1e-9)
    sv = scale * max(w, 1e-3)
    if m < 3 * n:
        return np.inf, np.nan
    e_end = 0.0
    for i in range(m - 2 * n, m):
        e_end += _rel_diff(section_x, section_v, i, n, scale, sv)
    e_end /= 2 * n
    if not np.isfinite(e_end):
        return np.inf, np.nan
    if e_end <= SETTLED_FLOOR:
        return e_end, 0.0
    W = (min(m - 3 * n, max_window) // (2 * n)) * (2 * n)
    if W < 2 * n:
        return e_end, np.nan
    e_start = 0.0
    corr = 0.0
    for i in range(m - 1 - W - 2 * n + 1, m - 1 - W + 1):
        e_start += _rel_diff(section_x, section_v, i, n, scale, sv)
    e_start /= 2 * n
    for i in range(m - W, m):
        corr += (section_x[i] - section_x[i - n]) * (section_x[i - n] - section_x[i - 2 * n])
    if not e_start > 0.0:
        return np.inf, np.nan
    rate = (e_end / e_start) ** (n / W)
    mu = -rate if corr < 0.0 else rate
    if rate >= 1.0:
        return np.inf, mu
    # d_i = P_i - P_(i-n) = c mu^((i-n)/n) (mu - 1): the last point is |d_(m-1)| |mu| / |1 - mu|
    # from the orbit, and the mean over the 2 n samples is |d| at their geometric middle
    return e_end * rate ** (1.0 + (2 * n - 1) / (2.0 * n)) / abs(1.0 - mu), mu


def candidate_periods(section_x, section_v, scale, w, n_max, *, near=0.05, k=2):
    """Up to ``k`` periods ``n <= n_max`` whose last relative differences ``|P_i - P_{i-n}|``
    (mean over ``2 n`` samples) are below ``near``: the periodic orbits an unsettled sequence
    may be approaching, closest first; a multiple of an accepted period is skipped. None below
    ``near``: the one with the smallest difference (a transient still far from its orbit)."""
    m = len(section_x)
    scale = max(float(scale), 1e-9)
    sv = scale * max(float(w), 1e-3)
    found = []
    best = (math.inf, 0)
    for n in range(1, int(n_max) + 1):
        if 3 * n > m:
            break
        e = float(np.mean([_rel_diff(section_x, section_v, i, n, scale, sv)
                           for i in range(m - 2 * n, m)]))  # fmt: skip
        best = min(best, (e, n))
        if e < near:
            found.append((e, n))
    if not found and best[1] > 0 and math.isfinite(best[0]):
        found = [best]  # a slow transient far from its orbit: the best repeat only
    out: list[int] = []
    for _, n in sorted(found):
        if not any(n % a == 0 for a in out):
            out.append(n)
        if len(out) >= k:
            break
    return out


def impact_state(face: int, back: int, disengaged_time: float, total_time: float) -> int:
    """Impact state I from impact counts and disengagement over a window."""
    if face > 0 and back > 0:
        return 2
    if face > 0:
        return 1
    if back > 0:
        return -1
    if disengaged_time >= total_time * (1.0 - 1e-12) and total_time > 0:
        return -2
    return 0


def amplitude_grows(xmax: np.ndarray, xmin: np.ndarray) -> bool:
    """Whether the per-period amplitudes ``xmax - xmin`` of a window grow: the largest of each
    quarter >= :data:`GROWTH_STEP` x the previous quarter's, the last >= :data:`GROWTH_MIN` x
    the first's."""
    a = np.asarray(xmax, dtype=float) - np.asarray(xmin, dtype=float)
    q = len(a) // 4
    if q < 1:
        return False
    top = np.array([a[k * q : (k + 1) * q].max() for k in range(4)])
    if not np.all(np.isfinite(top)):
        return True  # the amplitude left the floating-point range: it grew
    return bool(np.all(top[1:] >= GROWTH_STEP * top[:-1]) and top[3] >= GROWTH_MIN * top[0])


def classify_motion(
    s: PeriodSummaries,
    params: ModelParameters,
    *,
    n: int,
    lyap_threshold: float = 0.005,
    settled: bool = True,
) -> Classification:
    """Classify the motion recorded in ``s`` at ``params`` given its period ``n`` (0 if none was
    found). The section force is the model's (:func:`gearsim.dynamics.model.section_force`,
    every model form)."""
    w, Fm, Fe = params.w, params.Fm, params.Fe
    T = 2.0 * math.pi / w
    if n > 0:
        reps = max(1, len(s) // n)
        win = s.tail(reps * n)
        last = s.tail(n)
        p = int(last.nface.sum())
        q = int(last.nback.sum())
    else:
        win = s
        p = q = None
    m = len(win)
    total = m * T
    dis = float(win.tdis.sum())
    face_any = int(win.nface.sum())
    back_any = int(win.nback.sum())
    I = impact_state(face_any if n == 0 else p, back_any if n == 0 else q, dis, total)
    dc = dis / total if total > 0 else 0.0
    f_sec = section_force(pack_parameters(params), win.section[:, 0], win.section[:, 1])
    static = Fm + Fe * w * w
    fm = Fm if Fm > 0 else float("nan")
    lyap = float(win.lyap.sum() / total) if total > 0 else float("nan")
    if n > 0:
        motion = "periodic"
        status = "ok" if settled else "not_converged"
        label = f"{I}/{n}T"
        label_npq = f"{n}-{p}-{q}"
    elif not np.all(np.isfinite(np.asarray(win.xmax) - np.asarray(win.xmin))):
        # the amplitude left the floating-point range: not an attractor, no pattern
        motion = status = label = "diverged"
        label_npq = ""
    else:
        if amplitude_grows(win.xmax, win.xmin):
            # the amplitude rises throughout the window: a slow transient onto a larger bounded
            # motion, or the parametric instability; no label from this window either way
            # (where the linear limit is unstable gearsim.cell.growth's long run decides)
            motion = "unsettled"
        elif lyap > lyap_threshold:
            motion = "chaos"
        elif lyap >= -lyap_threshold:
            motion = "quasi-periodic"
        else:
            motion = "unsettled"
        status = "ok" if motion != "unsettled" else "not_converged"
        label = motion
        label_npq = ""
    return Classification(
        motion=motion,
        status=status,
        I=I,
        n=n,
        p=p,
        q=q,
        label=label,
        label_npq=label_npq,
        dc=dc,
        kmax_peak_mean=float(win.fmax.max() / fm),
        kmax_peak_static=float(win.fmax.max() / static),
        kmax_section_mean=float(f_sec.max() / fm),
        kmax_section_static=float(f_sec.max() / static),
        kmin_peak_mean=float(win.fmin.min() / fm),
        lyapunov=lyap,
        x_min=float(win.xmin.min()),
        x_max=float(win.xmax.max()),
        converged=(n > 0 and settled) or motion in ("chaos", "quasi-periodic"),
        window_periods=m,
    )
