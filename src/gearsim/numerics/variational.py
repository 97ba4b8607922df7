"""Variational computations on the one field: tangent maps, monodromy matrices, Lyapunov spectra.

The tangent dynamics ``z' = J(t, y) z`` use the Jacobian of the frozen region's field
(:func:`gearsim.dynamics.model.field_tangent`), integrated by the same integrator and event layer
as the
state. The field is continuous across every contact switch, so the saltation matrix is the
identity: the product of the per-step tangent maps along the located-switch trajectory is the
exact derivative of the flow (of the stroboscopic map over whole mesh periods).

Only the states the model evolves take part (:func:`gearsim.dynamics.model.n_evolved`: 10 for the
6-DOF
model, ``(x, x')`` for the single-DOF model, whose bearing states are frozen).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gearsim.dynamics.model import N_STATE, n_evolved, pack_parameters
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.numerics.batch import steps_per_period, tangent_lanes_many
from gearsim.numerics.integrate import IntegrationSettings, run_periods
from gearsim.numerics.settings import Method


def tangent_map(
    params: ModelParameters,
    y0: np.ndarray,
    n_periods: int,
    settings: IntegrationSettings,
    Z: np.ndarray,
    *,
    start_period: int = 0,
    tangent_error: bool = False,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Flow ``n_periods`` mesh periods from ``y0`` and map the tangent vectors ``Z`` (columns).

    ``tangent_error``: DP5 controls the tangent's error too (see :func:`run_periods`).
    RK4: the columns run as SIMD lanes of the batched kernel
    (:func:`gearsim.numerics.batch.tangent_lanes_many`, the same steps: bit-identical).

    Returns ``(y_end, DPhi Z, status)``: the final state (10 entries), the image of every column
    of ``Z`` (shape ``(10, k)``) under the derivative of the ``n_periods``-period map, and the
    integrator status (0 ok). The integrator renormalises the tangent vector each period and
    records the log of its growth; the image is restored from those logs.
    """
    if settings.method is Method.RK4:
        # the same RK4 steps with the columns as SIMD lanes: one kernel call, same numbers
        return tangent_lanes_many([params], [y0], n_periods, settings, [Z], [start_period])[0]
    y0 = np.asarray(y0, dtype=float)[:N_STATE]
    Z = np.asarray(Z, dtype=float).reshape(N_STATE, -1)
    out = np.zeros_like(Z)
    y_end = y0.copy()
    status = 0
    for i in range(Z.shape[1]):
        z = Z[:, i]
        nz = float(np.linalg.norm(z))
        if nz == 0.0:
            continue
        r = run_periods(params, np.concatenate([y0, z / nz]), n_periods, settings,
                        start_period=start_period, tangent=True, tangent_error=tangent_error)
        status = max(status, r.status)
        if r.status != 0:
            out[:, i] = np.nan
            continue
        growth = float(np.sum(r.summaries.lyap))
        out[:, i] = r.state[N_STATE:] * (nz * math.exp(growth))
        y_end = r.state[:N_STATE]
    return y_end, out, status


def monodromy(
    params: ModelParameters,
    y0: np.ndarray,
    n_periods: int,
    settings: IntegrationSettings,
    *,
    start_period: int = 0,
    tangent_error: bool = False,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Jacobian of the ``n_periods``-period stroboscopic map at ``y0`` on the evolved states.

    Returns ``(y_end, M, status)`` with ``M`` of shape ``(d, d)``, ``d`` = :func:`n_evolved`
    (the monodromy matrix when ``y0`` lies on a period-``n_periods`` orbit; its eigenvalues are
    the Floquet multipliers).
    """
    d = n_evolved(pack_parameters(params))
    Z = np.zeros((N_STATE, d))
    Z[:d, :d] = np.eye(d)
    y_end, MZ, status = tangent_map(params, y0, n_periods, settings, Z, start_period=start_period,
                                    tangent_error=tangent_error)
    return y_end, MZ[:d, :], status


def monodromies(
    params_list: list[ModelParameters],
    y0s: list[np.ndarray],
    n_periods: int,
    settings: IntegrationSettings,
    backend=None,
) -> list[tuple[np.ndarray, np.ndarray, int]]:
    """:func:`monodromy` of many cells at once: RK4 cells of one step grid share kernel calls
    (:func:`gearsim.numerics.batch.tangent_lanes_many`, full SIMD blocks, on ``backend``; each
    result is that of its own call), others are computed one by one."""
    out: list = [None] * len(params_list)
    groups: dict[tuple, list[int]] = {}
    for i, p in enumerate(params_list):
        if settings.method is Method.RK4:
            key = (steps_per_period(p, settings), p.var_ratio_order if p.var_ratio else None)
            groups.setdefault(key, []).append(i)
        else:
            out[i] = monodromy(p, y0s[i], n_periods, settings)
    eye = np.eye(N_STATE)
    for idx in groups.values():
        packed = [pack_parameters(params_list[i]) for i in idx]
        ds = [n_evolved(pa) for pa in packed]
        res = tangent_lanes_many([params_list[i] for i in idx], [y0s[i] for i in idx],
                                 n_periods, settings, [eye[:, :d] for d in ds],
                                 packed=packed, backend=backend)  # fmt: skip
        for i, d, (y, MZ, st) in zip(idx, ds, res, strict=True):
            out[i] = (y, MZ[:d, :], st)
    return out


def trace_mean(params: ModelParameters) -> float:
    """Time average of the trace of the Jacobian (the exact sum of all Lyapunov exponents).

    Only the damping terms contribute: ``-2 xi (1 + rho_p + rho_g) - 2 (xi_py + xi_pz + xi_gy +
    xi_gz)`` for the 6-DOF model, ``-2 xi`` for the single-DOF model (the friction term
    ``-2 xi gamma lambda`` averages to zero over a mesh period, the stiffness terms are
    off-diagonal).
    """
    if params.model != "6dof":
        return -2.0 * params.xi
    brg = params.xi_py + params.xi_pz + params.xi_gy + params.xi_gz
    return -2.0 * params.xi * (1.0 + params.rho_p + params.rho_g) - 2.0 * brg


@dataclass
class Spectrum:
    """Lyapunov spectrum of a motion (per unit dimensionless time ``tau``), largest first."""

    exponents: np.ndarray
    periods: int
    trace: float  # time-averaged trace of the Jacobian: the exact sum of the exponents
    sum_error: float  # |sum(exponents) - trace|: the built-in sanity check

    def ok(self, tol: float = 1e-3) -> bool:
        return bool(self.sum_error <= tol * max(1.0, abs(self.trace)))


def lyapunov_spectrum(
    params: ModelParameters,
    y0: np.ndarray,
    periods: int,
    settings: IntegrationSettings,
    *,
    start_period: int = 0,
    seed: int = 20251022,
) -> Spectrum:
    """All Lyapunov exponents by repeated QR of a tangent basis (Benettin; Shimada and Nagashima).

    Starting at ``y0`` (on the attractor), every mesh period the orthonormal basis ``Q`` is mapped
    by the period's tangent map and re-orthonormalised (``QR``); the exponents are the averaged
    ``log |R_ii|`` per unit ``tau``. The sum is checked against :func:`trace_mean`.
    """
    if periods < 1:
        raise ParameterError(f"spectrum periods = {periods!r} must be >= 1")
    d = n_evolved(pack_parameters(params))
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.standard_normal((d, d)))
    y = np.asarray(y0, dtype=float)[:N_STATE].copy()
    T = params.mesh_period
    logs = np.zeros(d)
    Z = np.zeros((N_STATE, d))
    for k in range(periods):
        Z[:d, :] = Q
        y_next, MZ, status = tangent_map(params, y, 1, settings, Z, start_period=start_period + k)
        if status != 0:
            raise ParameterError("spectrum: the integration diverged")
        Q, R = np.linalg.qr(MZ[:d, :])
        diag = np.diag(R)
        Q = Q * np.sign(diag)  # keep the basis orientation (R with a positive diagonal)
        logs += np.log(np.abs(diag))
        y = y_next
    exps = np.sort(logs / (periods * T))[::-1]
    tr = trace_mean(params)
    return Spectrum(exps, periods, tr, float(abs(exps.sum() - tr)))
