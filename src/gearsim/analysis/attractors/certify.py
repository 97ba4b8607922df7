"""Certified neighbourhoods of stable periodic orbits: where an early label needs no recurrence.

For a periodic attractor of period ``n`` (``n`` dividing the probing chunk and ``m``) whose
orbit is known on the section (a Newton-refined orbit, or a run settled to the classifier's
period test) and whose Floquet margin |mu|max is below 1 (:func:`stable_margin`), a radius
``r`` per orbit is *certified* when, for every phase ``j`` of the orbit, the ``m``-period map
``P^m`` (``FinderOptions.certify_periods``, 24: over one chunk of 8 periods the sup-norm ball
is not contracted at the corners of most 6-DOF orbits, whose bearing components first grow;
docs/decisions.md) takes

* the orbit's own section state ``c_j`` to within ``CENTRE_FRACTION r`` of itself, and
* every sampled point of the boundary of the ball ``|y - c_j|_s = r`` (both signs along every
  coordinate the model evolves, plus ``CORNERS`` seeded corners of the box) to inside the
  ball, with the orbit's own contact sequence (the entries into face and back contact of every
  period equal to the orbit's: no contact is gained or lost, no grazing on the sampled paths),

with the scaled sup norm ``|d|_s = max_i |d_i| / s_i``, ``s`` the orbit's displacement range
for displacements and ``w`` times it for velocities. Radii are tried from
``FinderOptions.certify_radius`` down by factors of 3 (``certify_tries`` of them); none passing
leaves the orbit uncertified (its starts keep the recurrence rule).

A probing start is labelled onto a certified orbit when, at a chunk check, its section state
lies inside a phase's ball *and* at the next chunk check (8 periods on) it lies inside the
ball again, closer to the orbit than before (the contraction confirmed on the start's own
trajectory). Sampled boundary points are evidence, not a proof of contraction over the whole
ball; the finder's tests check every early label against the start's full-length run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gearsim.analysis.attractors.results import Steady
from gearsim.dynamics.parameters import ModelParameters

#: the orbit's own state must return to within this fraction of the radius after m periods
CENTRE_FRACTION = 0.05
#: seeded corners of the ball's box sampled besides the 2 d axis points
CORNERS = 4


@dataclass(frozen=True)
class Certificate:
    """A certified ball around every phase of a period-``n`` orbit: centres ``(n, 10)``,
    per-component scales ``(10,)`` (inf on frozen components), radius ``r`` (scaled sup
    norm), the worst sampled contraction ``ratio`` (image distance / r) and the map's
    period count ``m``."""

    centres: np.ndarray
    scales: np.ndarray
    r: float
    ratio: float
    m: int

    def distance(self, y: np.ndarray) -> np.ndarray:
        """Scaled sup distance of states ``y`` ``(k, 10)`` to the nearest phase centre."""
        d = np.abs(y[:, None, :] - self.centres[None, :, :]) / self.scales[None, None, :]
        return d.max(axis=2).min(axis=1)


def _evolved(params: ModelParameters) -> np.ndarray:
    """Indices of the state the model evolves (the single-DOF model freezes the bearings)."""
    return np.arange(10) if params.model == "6dof" else np.arange(2)


def eligible(s: Steady, m: int) -> bool:
    """A periodic attractor whose neighbourhood may be certified for the ``m``-period map (its
    Floquet margin, where known, below 1)."""
    i = s.info or {}
    mu = i.get("mu_max")
    known = mu is not None and math.isfinite(mu)
    return (s.status == "ok" and s.period > 0 and m % s.period == 0
            and s.final_state is not None and (not known or mu < 1.0)
            and i.get("status", "ok") == "ok")  # fmt: skip


def stable_margin(params: ModelParameters, s: Steady, settings) -> bool:
    """Whether the orbit's Floquet margin |mu|max is below 1: its own (refined orbit, or
    computed before), else that of the orbit through its settled section state
    (:func:`gearsim.cell.verify.orbit_margins`, written into ``s.info`` as the finder's last
    step would)."""
    from gearsim.cell.verify import orbit_margins

    mu = (s.info or {}).get("mu_max")
    if mu is None or not math.isfinite(mu):
        got = orbit_margins([params], [s.period], [s.final_state], settings)[0]
        if got is None:
            return False
        s.info["mu_max"], s.info["critical"] = got
        mu = got[0]
    return bool(mu < 1.0)


def samples_per_phase(params: ModelParameters) -> int:
    """Lanes of one try per orbit phase: the centre, 2 per evolved coordinate, the corners."""
    return 1 + 2 * len(_evolved(params)) + CORNERS


def worth(params: ModelParameters, s: Steady, settings, open_starts: int, m: int,
          radius: float, recur_rtol: float) -> bool:
    """Whether certifying the orbit of ``s`` is expected to cost fewer lane-periods than it
    saves its cell's ``open_starts`` unlabelled starts: a start converging at the rate
    |mu|max per period reaches the ball of ``radius`` some ``ln(radius / recur_rtol) /
    ln(1 / |mu|max)`` periods before the recurrence rule's ``recur_rtol`` (the period test);
    one try costs :func:`samples_per_phase` x ``n`` x ``m`` lane-periods. Reads (and fills)
    the orbit's Floquet margin; False where it is not below 1."""
    if not stable_margin(params, s, settings):
        return False
    mu = float(s.info["mu_max"])
    if mu <= 0.0:
        return False
    saved = open_starts * math.log(radius / recur_rtol) / math.log(1.0 / mu)
    return saved > samples_per_phase(params) * s.period * m


def certify(params: ModelParameters, s: Steady, settings, m: int, radius: float,
            tries: int, start_period: int = 0) -> tuple[Certificate | None, int]:
    """The largest certified radius of the orbit of ``s`` (module docstring), or None; and the
    lane-periods integrated to find it."""
    from gearsim.cell.simulate import initial_tangent
    from gearsim.numerics.batch import run_periods_batched

    if params.var_ratio != 0.0 or not eligible(s, m):
        return None, 0
    if not stable_margin(params, s, settings):
        return None, 0
    n = s.period
    t0 = initial_tangent(params)
    y0 = np.asarray(s.final_state, dtype=float)[:10]
    summ, _, status, _ = run_periods_batched([params], np.hstack([y0, t0])[None, :], n,
                                             settings, tangent=False)  # fmt: skip
    if status[0] != 0 or len(summ[0]) < n:
        return None, n
    centres = np.array(summ[0].section[:n], dtype=float)
    face = np.asarray(summ[0].nface[:n])
    back = np.asarray(summ[0].nback[:n])
    ev = _evolved(params)
    sx = max(s.scale_x, 1e-9)
    sv = max(s.scale_v, 1e-9)
    scales = np.full(10, np.inf)
    for i in ev:
        scales[i] = sx if i % 2 == 0 else sv
    rng = np.random.default_rng(0)
    dirs = []
    for i in ev:
        for sign in (1.0, -1.0):
            e = np.zeros(10)
            e[i] = sign
            dirs.append(e)
    for _ in range(CORNERS):
        e = np.zeros(10)
        e[ev] = rng.choice([-1.0, 1.0], size=len(ev))
        dirs.append(e)
    dirs = np.array(dirs)
    fin_scales = np.where(np.isfinite(scales), scales, 0.0)
    spent = n
    r = float(radius)
    for _ in range(int(tries)):
        rows, phase = [], []
        for j in range(n):
            rows.append(centres[j])
            phase.append(j)
            for e in dirs:
                rows.append(centres[j] + r * e * fin_scales)
                phase.append(j)
        y = np.hstack([np.array(rows), np.repeat(t0[None, :], len(rows), axis=0)])
        summ, fin, status, _ = run_periods_batched([params] * len(rows), y, m, settings,
                                                   start_periods=[start_period + j
                                                                  for j in phase],
                                                   tangent=False)  # fmt: skip
        spent += len(rows) * m
        phase = np.array(phase)
        d = np.max(np.abs(fin[:, :10] - centres[phase]) / scales[None, :], axis=1)
        ok = status == 0
        for q, sm in enumerate(summ):
            if not ok[q] or len(sm) < m:
                ok[q] = False
                continue
            want = (phase[q] + np.arange(m)) % n
            ok[q] = bool(np.array_equal(sm.nface[:m], face[want])
                         and np.array_equal(sm.nback[:m], back[want]))  # fmt: skip
        centre = np.zeros(len(rows), dtype=bool)
        centre[:: len(dirs) + 1] = True
        if (ok.all() and np.all(d[centre] <= CENTRE_FRACTION * r)
                and np.all(d[~centre] < r)):  # fmt: skip
            return Certificate(centres, scales, r, float(d[~centre].max() / r), m), spent
        r /= 3.0
    return None, spent
