"""Newton shooting on the stroboscopic map: the one periodic-orbit solver.

The stroboscopic (Poincare) map ``P`` samples the state every mesh period ``T = 2 pi / w`` at
``tau = k T``; a period-``n`` motion is a fixed point of ``P^n``. ``P^n`` and its Jacobian (the
monodromy matrix, :func:`gearsim.numerics.variational.monodromy`) come from the one integrator with
located contact switches; the field is continuous across every switch, so the saltation matrix
is the identity.

It lives in the numerics layer because the cell classification (:mod:`gearsim.cell.simulate`)
refines slowly settling cells with it; :mod:`gearsim.analysis.orbits` builds the orbit tools
(section points, grazing margins, continuation) on it.

Shooting near grazing. For a continuous field the map has a 3/2-power term at grazing (the
Jacobian is continuous but its derivative is not), so plain Newton can overshoot across a grazing
boundary. Each Newton step is (i) capped by a trust radius (``trust`` times ``1 + |y|``), and
(ii) accepted only if the residual norm decreases (Armijo backtracking, halving down to 1/64);
the trust radius shrinks after a rejected step and grows after a full one.
"""

from __future__ import annotations

import numpy as np

from gearsim.dynamics.model import N_STATE, n_evolved
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.numerics.integrate import STATUS_OK, IntegrationSettings, run_periods
from gearsim.numerics.variational import monodromy

#: integrator settings for shooting: DP5 at tight tolerance (map noise ~1e-13). The kernel's
#: error norm covers the state only; in the 6-DOF model the tangent excites the fast bearing
#: modes (~7 rad per unit tau) that the forced state barely carries, so the monodromy's error is
#: ~6e4 rtol there (6e-8 at rtol 1e-12, against scipy.linalg.expm in the linear limit), ~rtol in
#: the single-DOF model.
SHOOTING = IntegrationSettings(method="dp5", rtol=1e-12, atol=1e-14, hmax=0.2)

#: the monodromy's DP5 error norm includes the tangent vector (6-DOF model; the kernel's
#: ``tangent_error`` option, used by this shooting path only): the tangent then is as accurate
#: as the state instead of ~6e4 rtol (docs/orbits.md, "Tolerance")
TANGENT_ERROR = True

#: multiplier kinds (the bifurcation a multiplier leaving the unit circle causes)
KIND_FOLD = "fold"
KIND_PD = "period_doubling"
KIND_NS = "neimark_sacker"

class OrbitError(RuntimeError):
    """Shooting did not converge (the message says how far it got)."""


def free_states(params: ModelParameters) -> np.ndarray:
    """Indices of the states the model evolves: ``(x, x')`` (1-DOF) or all ten (6-DOF)."""
    return np.arange(n_evolved(params.to_array()))


def check_periodic_forcing(params: ModelParameters) -> None:
    """One line (a :class:`ParameterError`) unless the forcing is T-periodic (``var_ratio``
    0): the mesh-period map has periodic orbits only then."""
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


def sorted_eigs(M: np.ndarray) -> np.ndarray:
    """Eigenvalues of ``M`` (the multipliers of a monodromy), by decreasing modulus; ``M`` may
    be a stack ``(k, d, d)`` (one LAPACK call for all): then ``(k, d)``, each row sorted."""
    mu = np.linalg.eigvals(M).astype(complex)
    order = np.argsort(-np.abs(mu), axis=-1, kind="stable")
    return np.take_along_axis(mu, order, axis=-1)


def newton_step(M: np.ndarray, G: np.ndarray) -> np.ndarray:
    """The full Newton step ``dy`` of ``G(y) = P^n(y) - y`` with monodromy ``M``:
    ``(M - I) dy = -G`` (least squares when singular)."""
    J = M - np.eye(len(G))
    try:
        return np.linalg.solve(J, -G)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(J, -G, rcond=None)[0]


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
    check_periodic_forcing(params)
    p = params.to_array() if parray is None else parray
    dims = free_states(params)
    y = np.asarray(guess, dtype=float)[:N_STATE].copy()
    yn, M = section_map(params, y, n, settings, parray=p, tangent_error=tangent_error)
    G = yn[dims] - y[dims]
    r = float(np.max(np.abs(G)))
    radius = trust * (1.0 + float(np.max(np.abs(y[dims]))))
    for it in range(1, max_iter + 1):
        if r < tol:
            return y, yn, M, r, it - 1
        dy = newton_step(M, G)
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
