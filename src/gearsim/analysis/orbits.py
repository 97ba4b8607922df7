"""Periodic orbits of the gear pair: Newton shooting, Floquet multipliers, grazing margins.

The stroboscopic (Poincare) map ``P`` samples the state every mesh period ``T = 2 pi / w`` at
``tau = k T``; a period-``n`` motion is a fixed point of ``P^n``. Everything here is built on
the one field and the one integrator with located contact switches,
:func:`gearsim.numerics.integrate.run_periods` (``tangent=True`` carries the Jacobian-vector
product of :func:`gearsim.dynamics.model.rhs` along the located-switch trajectory). Because
every dead zone is continuous, the vector field is continuous across every contact switch and
the saltation matrix is the identity: the monodromy matrix ``M = dP^n/dy`` is the plain
variational solution, one column per tangent run (the kernel renormalises the tangent every
period and records the log of its norm, so ``M e = z_end exp(sum lyap)``).

Only the states the chosen model evolves are unknowns: ``(x, x')`` in the single-DOF model
(bearing states frozen, ``M`` is 2 x 2), all ten in the 6-DOF model (``M`` is 10 x 10).

Units: states are dimensionless (lengths over ``b_c``, time ``tau = w_n t``); multipliers are
per ``n`` mesh periods (a Floquet exponent is ``log|mu| / (n T)`` per unit ``tau``).

The Newton solver itself (``newton_orbit``, ``section_map``, the multiplier kinds) is
:mod:`gearsim.numerics.shooting`, re-exported here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gearsim.dynamics.model import (
    MODE_FRICTION,
    N_MODE,
    N_STATE,
    N_SWITCH,
    SWITCH_COORD,
    SWITCH_GAP,
    rhs,
)
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.numerics.integrate import STATUS_OK, IntegrationSettings, run_periods
from gearsim.numerics.shooting import (  # noqa: F401  (the solver's public names, re-exported)
    KIND_FOLD,
    KIND_NS,
    KIND_PD,
    SHOOTING,
    TANGENT_ERROR,
    OrbitError,
    check_periodic_forcing,
    free_states,
    multiplier_kind,
    newton_orbit,
    section_map,
    sorted_eigs,
)

#: The simulation whose final section state seeds Newton: adaptive DP5 at its default tolerances.
SEEDING = IntegrationSettings(method="dp5")
#: Dense samples per period with which :func:`turning_points` (and the grazing margins built
#: on them) bracket each sign change of a watched rate.
SUBSTEPS = 512

#: channel names of the contact boundaries (mesh, then bearing clearances)
_CHANNEL = ("x", "u_py", "u_pz", "u_gy", "u_gz")


@dataclass
class GrazingMargin:
    """Distance of the orbit's turning points to each contact boundary (units of ``b_c``).

    A contact is born or lost (grazing) when a turning point (local extremum) of a watched
    coordinate passes through a boundary; ``margins[name]`` is the smallest ``|extremum -
    boundary|`` over the orbit, ``signed[name]`` that turning point's ``extremum - boundary``.
    """

    margins: dict[str, float]
    signed: dict[str, float]
    switches: int  # located contact switches over the orbit
    x_min: float = math.nan  # smallest / largest turning point of the mesh displacement x
    x_max: float = math.nan

    @property
    def smallest(self) -> float:
        return min(self.margins.values()) if self.margins else math.inf


@dataclass
class PeriodicOrbit:
    """A periodic orbit of period ``n`` mesh periods (a fixed point of ``P^n``)."""

    params: ModelParameters = field(repr=False)
    n: int
    state: np.ndarray  # (10,) section state at tau = 0
    section: np.ndarray  # (n, 10) the n section points
    monodromy: np.ndarray  # (d, d) over free_states
    multipliers: np.ndarray  # complex, sorted by decreasing modulus
    residual: float  # max-norm of P^n(y) - y
    iterations: int
    grazing: GrazingMargin | None = None

    @property
    def mu_max(self) -> float:
        """Largest multiplier modulus (the orbit is stable when it is below 1)."""
        return float(abs(self.multipliers[0]))

    @property
    def stable(self) -> bool:
        return self.mu_max < 1.0

    @property
    def critical(self) -> complex:
        """The multiplier of largest modulus."""
        return complex(self.multipliers[0])

    @property
    def critical_kind(self) -> str:
        return multiplier_kind(self.critical)

    @property
    def minimal_period(self) -> int:
        """Smallest divisor ``m`` of ``n`` with ``P^m(y) = y`` to 1e-7 (the true period)."""
        s = self.section
        scale = 1.0 + float(np.max(np.abs(s[:, :2])))
        for m in range(1, self.n + 1):
            if self.n % m == 0 and np.all(np.abs(s[m % self.n] - s[0]) <= 1e-7 * scale):
                return m
        return self.n

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (multipliers as ``{"re", "im", "abs"}``)."""
        g = self.grazing
        return {
            "w": self.params.w,
            "model": self.params.model,
            "period": self.n,
            "minimal_period": self.minimal_period,
            "section_x": self.state[0],
            "section_v": self.state[1],
            "state": [float(v) for v in self.state],
            "residual": self.residual,
            "iterations": self.iterations,
            "multipliers": [
                {"re": float(m.real), "im": float(m.imag), "abs": float(abs(m))}
                for m in self.multipliers
            ],
            "mu_max": self.mu_max,
            "stable": self.stable,
            "critical_kind": self.critical_kind,
            "grazing_margin": None if g is None else g.smallest,
            "grazing_margins": None if g is None else g.margins,
            "contact_switches": None if g is None else g.switches,
        }


def find_periodic_orbit(
    params: ModelParameters,
    n: int,
    guess: np.ndarray | None = None,
    settings: IntegrationSettings = SHOOTING,
    *,
    tol: float = 1e-10,
    max_iter: int = 40,
    grazing: bool = True,
) -> PeriodicOrbit:
    """Find the period-``n`` orbit through the section point nearest ``guess``.

    Parameters
    ----------
    params
        Dimensionless model parameters (``var_ratio`` must be 0).
    n
        Period in mesh periods (``P^n(y) = y``).
    guess
        Start state on the section (10 entries), e.g. a simulated section point. Default: the
        steady motion simulated from rest (:func:`gearsim.cell.simulate.simulate_cell`).
    tol
        Residual target ``max |P^n(y) - y|`` (dimensionless state units).
    grazing
        Also compute the grazing margin (one dense run over the orbit).
    """
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise ParameterError(f"period 'n' = {n!r} must be an integer >= 1")
    check_periodic_forcing(params)
    p = params.to_array()
    if guess is None:
        from gearsim.cell.simulate import simulate_cell

        guess = simulate_cell(params).final_state
    y, yn, M, r, it = newton_orbit(params, n, guess, settings, tol=tol, max_iter=max_iter,
                                   parray=p)
    return make_orbit(params, n, y, M, r, it, settings, grazing=grazing, parray=p)


def make_orbit(
    params: ModelParameters,
    n: int,
    y: np.ndarray,
    M: np.ndarray,
    residual: float,
    iterations: int,
    settings: IntegrationSettings = SHOOTING,
    *,
    grazing: bool = True,
    parray: np.ndarray | None = None,
) -> PeriodicOrbit:
    """Assemble a :class:`PeriodicOrbit` (section points, multipliers, grazing margin)."""
    p = params.to_array() if parray is None else parray
    if grazing:
        gm, section = grazing_margin(params, y, n, settings, parray=p, return_section=True)
    else:
        gm = None
        section = run_periods(params, y, n, settings, parray=p).summaries.section.copy()
    return PeriodicOrbit(params, n, y.copy(), section, M, sorted_eigs(M), residual, iterations,
                         gm)


# ------------------------------------------------------------------ turning points / grazing
# quintic Hermite on s in [0, 1] from (x, h x', h^2 x'') at both ends: coefficient matrix
_Q = np.linalg.inv(
    np.array(
        [
            [1, 0, 0, 0, 0, 0],
            [0, 1, 0, 0, 0, 0],
            [0, 0, 2, 0, 0, 0],
            [1, 1, 1, 1, 1, 1],
            [0, 1, 2, 3, 4, 5],
            [0, 0, 2, 6, 12, 20],
        ],
        dtype=float,
    )
)


def _accel(params, p, t_in_period, y, T) -> np.ndarray:
    """Field at a sample, with every dead zone in the region of the sampled state."""
    mode = np.ones(N_MODE, dtype=np.int64)
    for c in range(N_SWITCH):
        gap = p[SWITCH_GAP[c]]
        u = y[SWITCH_COORD[c]]
        if c == 0 or gap > 0.0:
            mode[c] = 1 if u > gap else (-1 if u < -gap else 0)
    mode[MODE_FRICTION] = 1 if (t_in_period % T) < 0.5 * T else -1
    dy = np.zeros(2 * N_STATE)
    yy = np.zeros(2 * N_STATE)
    yy[:N_STATE] = y
    rhs(t_in_period % T, yy, p, mode, dy, False)
    return dy[:N_STATE]


def turning_points(
    params: ModelParameters,
    y: np.ndarray,
    n: int,
    settings: IntegrationSettings = SHOOTING,
    *,
    substeps: int = SUBSTEPS,
    parray: np.ndarray | None = None,
) -> tuple[dict[int, np.ndarray], int, np.ndarray]:
    """Local extrema of every watched coordinate over ``n`` periods from ``y``.

    Dense samples (``substeps`` per period, landed exactly) bracket each sign change of the
    rate; the extremum is the stationary point of the quintic Hermite interpolant built from
    the state, its rate and the field's acceleration at both ends (error ~h^6).
    Returns ``({coordinate index: extrema}, number of located switches, section points)``.
    """
    p = params.to_array() if parray is None else parray
    r = run_periods(params, y, n, settings, substeps=substeps, record=True, event_capacity=4096,
                    parray=p)
    if r.status != STATUS_OK:
        raise OrbitError(f"integration diverged at w = {params.w}")
    tr = r.trajectory
    T = params.mesh_period
    h = T / substeps
    coords = [SWITCH_COORD[c] for c in range(N_SWITCH)
              if c == 0 or (params.model == "6dof" and p[SWITCH_GAP[c]] > 0.0)]
    out: dict[int, np.ndarray] = {}
    for ci in coords:
        v = tr[:, ci + 1]
        idx = np.nonzero(v[:-1] * v[1:] < 0.0)[0]
        ext = []
        for k in idx:
            t0 = k * h
            a0 = _accel(params, p, t0, tr[k], T)[ci + 1]
            a1 = _accel(params, p, t0 + h, tr[k + 1], T)[ci + 1]
            rhs_vec = np.array([tr[k, ci], h * v[k], h * h * a0, tr[k + 1, ci], h * v[k + 1],
                                h * h * a1])
            c = _Q @ rhs_vec  # ascending powers
            dc = np.array([c[1], 2 * c[2], 3 * c[3], 4 * c[4], 5 * c[5]])
            roots = np.roots(dc[::-1])
            best = None
            for s in roots:
                if abs(s.imag) < 1e-9 and -1e-9 <= s.real <= 1 + 1e-9:
                    s = min(max(s.real, 0.0), 1.0)
                    if best is None or abs(s - 0.5) < abs(best - 0.5):
                        best = s
            if best is None:
                best = 0.0 if abs(v[k]) < abs(v[k + 1]) else 1.0
            ext.append(float(np.polyval(c[::-1], best)))
        out[int(ci)] = np.array(ext)
    return out, r.n_events, r.summaries.section.copy()


def grazing_margin(
    params: ModelParameters,
    y: np.ndarray,
    n: int,
    settings: IntegrationSettings = SHOOTING,
    *,
    substeps: int = SUBSTEPS,
    parray: np.ndarray | None = None,
    return_section: bool = False,
):
    """Grazing margins of the orbit through ``y`` (see :class:`GrazingMargin`)."""
    p = params.to_array() if parray is None else parray
    ext, n_ev, section = turning_points(params, y, n, settings, substeps=substeps, parray=p)
    margins: dict[str, float] = {}
    signed: dict[str, float] = {}
    for c in range(N_SWITCH):
        ci = int(SWITCH_COORD[c])
        if ci not in ext:
            continue
        gap = float(p[SWITCH_GAP[c]])
        bounds = (gap, -gap) if gap > 0.0 else (0.0,)
        for bnd in bounds:
            if bnd == 0.0:
                name = f"{_CHANNEL[c]}=0"
            else:
                name = f"{_CHANNEL[c]}={'+' if bnd > 0 else '-'}{_CHANNEL_GAP[c]}"
            e = ext[ci]
            if len(e) == 0:
                continue
            k = int(np.argmin(np.abs(e - bnd)))
            margins[name] = float(abs(e[k] - bnd))
            signed[name] = float(e[k] - bnd)
    xe = ext.get(0, np.zeros(0))
    lo_x = float(xe.min()) if len(xe) else math.nan
    hi_x = float(xe.max()) if len(xe) else math.nan
    gm = GrazingMargin(margins, signed, int(n_ev), lo_x, hi_x)
    return (gm, section) if return_section else gm


_CHANNEL_GAP = ("b", "b_py", "b_pz", "b_gy", "b_gz")


def shooting_settings(rtol: float | None = None) -> IntegrationSettings:
    """:data:`SHOOTING`, optionally with another DP5 relative tolerance."""
    return SHOOTING if rtol is None else SHOOTING.with_(rtol=rtol, atol=rtol * 1e-2)
