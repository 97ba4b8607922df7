"""Periodic orbits of the gear pair: Newton shooting, Floquet multipliers, grazing margins.

The stroboscopic (Poincare) map ``P`` samples the state every mesh period ``T = 2 pi / w`` at
``tau = k T``; a period-``n`` motion is a fixed point of ``P^n``. Everything here is built on the
one field and the one integrator with located contact switches,
:func:`gearsim.cell.simulate.run_periods` (``tangent=True`` carries the Jacobian-vector product of
:func:`gearsim.dynamics.model.rhs` along the located-switch trajectory). Because every dead zone is
continuous, the vector field is continuous across every contact switch and the saltation matrix
is the identity: the monodromy matrix ``M = dP^n/dy`` is the plain variational solution, one
column per tangent run (the kernel renormalises the tangent every period and records the log of
its norm, so ``M e = z_end exp(sum lyap)``).

Only the states the chosen model evolves are unknowns: ``(x, x')`` in the single-DOF model
(bearing states frozen, ``M`` is 2 x 2), all ten in the 6-DOF model (``M`` is 10 x 10).

Units: states are dimensionless (lengths over ``b_c``, time ``tau = w_n t``); multipliers are
per ``n`` mesh periods (a Floquet exponent is ``log|mu| / (n T)`` per unit ``tau``).

Shooting near grazing. For a continuous field the map has a 3/2-power term at grazing (the
Jacobian is continuous but its derivative is not), so plain Newton can overshoot across a grazing
boundary. Each Newton step is (i) capped by a trust radius (``trust`` times ``1 + |y|``), and
(ii) accepted only if the residual norm decreases (Armijo backtracking, halving down to 1/64);
the trust radius shrinks after a rejected step and grows after a full one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gearsim.cell.simulate import IntegrationSettings, run_periods
from gearsim.dynamics.model import (
    MODE_FRICTION,
    N_MODE,
    N_STATE,
    N_SWITCH,
    SWITCH_COORD,
    SWITCH_GAP,
    n_evolved,
    rhs,
)
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.numerics.integrate import STATUS_OK
from gearsim.numerics.variational import monodromy

#: integrator settings for shooting: DP5 at tight tolerance (map noise ~1e-13). The kernel's
#: error norm covers the state only; in the 6-DOF model the tangent excites the fast bearing
#: modes (~7 rad per unit tau) that the forced state barely carries, so the monodromy's error is
#: ~6e4 rtol there (6e-8 at rtol 1e-12, against scipy.linalg.expm in the linear limit), ~rtol in
#: the single-DOF model.
SHOOTING = IntegrationSettings(method="dp5", rtol=1e-12, atol=1e-14, hmax=0.2)
#: The simulation whose final section state seeds Newton: adaptive DP5 at its default tolerances.
SEEDING = IntegrationSettings(method="dp5")

#: the monodromy's DP5 error norm includes the tangent vector (6-DOF model; the kernel's
#: ``tangent_error`` option, used by this shooting path only): the tangent then is as accurate
#: as the state instead of ~6e4 rtol (docs/orbits.md, "Tolerance")
TANGENT_ERROR = True

#: multiplier kinds (the bifurcation a multiplier leaving the unit circle causes)
KIND_FOLD = "fold"
KIND_PD = "period_doubling"
KIND_NS = "neimark_sacker"

#: channel names of the contact boundaries (mesh, then bearing clearances)
_CHANNEL = ("x", "u_py", "u_pz", "u_gy", "u_gz")


class OrbitError(RuntimeError):
    """Shooting did not converge (the message says how far it got)."""


def free_states(params: ModelParameters) -> np.ndarray:
    """Indices of the states the model evolves: ``(x, x')`` (1-DOF) or all ten (6-DOF)."""
    return np.arange(n_evolved(params.to_array()))


def _check_params(params: ModelParameters) -> None:
    if params.var_ratio != 0.0:
        raise ParameterError(
            f"parameter 'var_ratio' = {params.var_ratio!r}: periodic orbits of the mesh-period "
            "map need var_ratio = 0 (the variable-ratio forcing is not T-periodic)"
        )


def section_map(
    params: ModelParameters,
    y0: np.ndarray,
    n: int,
    settings: IntegrationSettings = SHOOTING,
    *,
    jacobian: bool = True,
    parray: np.ndarray | None = None,
    tangent_error: bool | None = None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """``P^n(y0)`` and (if ``jacobian``) the monodromy matrix over the model's free states.

    Returns ``(y_n, M)``: ``y_n`` the full 10-state after ``n`` mesh periods from ``tau = 0``,
    ``M`` the ``d x d`` matrix ``d y_n / d y_0`` restricted to :func:`free_states`.
    The monodromy is the one variational computation,
    :func:`gearsim.numerics.variational.monodromy`;
    ``tangent_error`` (default :data:`TANGENT_ERROR`) puts the tangent into DP5's error norm.
    Raises :class:`OrbitError` if the integration diverges.
    """
    p = params.to_array() if parray is None else parray
    y0 = np.asarray(y0, dtype=float)[:N_STATE]
    if not jacobian:
        r = run_periods(params, y0, n, settings, parray=p)
        if r.status != STATUS_OK:
            raise OrbitError(f"integration diverged from {y0[:2]} at w = {params.w}")
        return r.state[:N_STATE].copy(), None
    te = TANGENT_ERROR if tangent_error is None else tangent_error
    yn, M, status = monodromy(params, y0, n, settings, tangent_error=te)
    if status != STATUS_OK:
        raise OrbitError(f"integration diverged from {y0[:2]} at w = {params.w}")
    return yn.copy(), M


def multiplier_kind(mu: complex) -> str:
    """The bifurcation a multiplier causes when it leaves the unit circle (fold / PD / NS)."""
    if abs(mu.imag) > 1e-9 * max(abs(mu), 1e-300):
        return KIND_NS
    return KIND_FOLD if mu.real > 0 else KIND_PD


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


def _sorted_eigs(M: np.ndarray) -> np.ndarray:
    mu = np.linalg.eigvals(M).astype(complex)
    return mu[np.argsort(-np.abs(mu), kind="stable")]


def newton_orbit(
    params: ModelParameters,
    n: int,
    guess: np.ndarray,
    settings: IntegrationSettings = SHOOTING,
    *,
    tol: float = 1e-10,
    max_iter: int = 40,
    trust: float = 0.5,
    parray: np.ndarray | None = None,
    tangent_error: bool | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, int]:
    """Safeguarded Newton on ``G(y) = P^n(y) - y``: returns ``(y, P^n(y), M, residual, iters)``.

    Steps are capped by a trust radius and accepted by Armijo backtracking on ``|G|`` (see the
    module docstring: the 3/2-power grazing singularity).
    """
    _check_params(params)
    p = params.to_array() if parray is None else parray
    dims = free_states(params)
    d = len(dims)
    y = np.asarray(guess, dtype=float)[:N_STATE].copy()
    yn, M = section_map(params, y, n, settings, parray=p, tangent_error=tangent_error)
    G = yn[dims] - y[dims]
    r = float(np.max(np.abs(G)))
    radius = trust * (1.0 + float(np.max(np.abs(y[dims]))))
    for it in range(1, max_iter + 1):
        if r < tol:
            return y, yn, M, r, it - 1
        J = M - np.eye(d)
        try:
            dy = np.linalg.solve(J, -G)
        except np.linalg.LinAlgError:
            dy = np.linalg.lstsq(J, -G, rcond=None)[0]
        nd = float(np.linalg.norm(dy))
        if nd > radius:
            dy *= radius / nd
        lam = 1.0
        accepted = False
        while lam >= 1.0 / 64.0:
            yt = y.copy()
            yt[dims] += lam * dy
            try:
                ynt, Mt = section_map(params, yt, n, settings, parray=p,
                                      tangent_error=tangent_error)
            except OrbitError:
                lam *= 0.5
                continue
            Gt = ynt[dims] - yt[dims]
            rt = float(np.max(np.abs(Gt)))
            if rt < (1.0 - 1e-4 * lam) * r or rt < tol:
                accepted = True
                break
            lam *= 0.5
        if not accepted:
            if r < 100 * tol:  # map noise floor reached
                return y, yn, M, r, it
            raise OrbitError(
                f"Newton stalled at residual {r:.3g} (period {n}, w = {params.w:.6g})"
            )
        radius = radius * 2.0 if lam == 1.0 else radius * 0.5
        radius = min(max(radius, 1e-8), 10.0 * (1.0 + float(np.max(np.abs(y[dims])))))
        y, yn, M, G, r = yt, ynt, Mt, Gt, rt
    if r < tol:
        return y, yn, M, r, max_iter
    raise OrbitError(
        f"Newton did not converge in {max_iter} iterations: residual {r:.3g} "
        f"(period {n}, w = {params.w:.6g})"
    )


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
    _check_params(params)
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
    return PeriodicOrbit(params, n, y.copy(), section, M, _sorted_eigs(M), residual, iterations,
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
    substeps: int = 512,
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
    substeps: int = 512,
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
