"""Model parameters: the dimensionless set the equations use, validated on construction.

All quantities here are dimensionless (see docs/model.md for the scalings):

* lengths are divided by the nominal length ``b_c`` (so ``b`` is half the backlash over ``b_c``),
* time is ``tau = w_n t`` with ``w_n = sqrt(Km / Me)``,
* forces are divided by ``Km b_c`` (so ``Fm`` is the mean load, ``Fe`` the transmission-error
  amplitude ``Em / b_c``; the error forcing is ``Fe w**2 cos(w tau + phi_e)``).

The dimensional gear description and its conversion live in :mod:`gearsim.physical.geometry`.
"""

from __future__ import annotations

import math
import sys
from dataclasses import asdict, dataclass, fields
from typing import Any, NamedTuple

import numpy as np

from gearsim.errors import ParameterError, reject_unknown  # noqa: E402  (ParameterError re-exported)


class ParameterSpec(NamedTuple):
    """A model parameter's one description: its allowed range (``lower``, ``upper``, each
    bound inclusive or not), what it is, and its unit as the column dictionary writes it."""

    lower: float
    upper: float
    lower_in: bool
    upper_in: bool
    meaning: str
    unit: str = "1"


#: every numeric model parameter: its range, meaning and unit, written once (the checks below,
#: the error lines and the catalogue's column dictionary, gearsim.results.columns, read them)
PARAMETERS: dict[str, ParameterSpec] = {
    "w": ParameterSpec(
        0.0, 100.0, False, True,
        'mesh frequency over the natural frequency w_n = sqrt(Km / Me)',
        '1 (w_h / w_n)',
    ),
    "Fm": ParameterSpec(0.0, 1000.0, True, True, 'mean mesh load', '1 (Tp / (Rp Km b_c))'),
    "Fe": ParameterSpec(0.0, 1000.0, True, True, 'transmission-error amplitude', '1 (Em / b_c)'),
    "eps": ParameterSpec(0.0, 1.0, True, False, 'mesh stiffness fluctuation', '1 (Ka / Km)'),
    "xi": ParameterSpec(0.0, 10.0, True, True, 'mesh damping ratio, C_n = 2 xi sqrt(Km Me)', '1'),
    "b": ParameterSpec(0.0, 1000.0, True, True, 'half backlash', '1 (B / b_c)'),
    "phi_e": ParameterSpec(
        -2 * math.pi, 2 * math.pi, True, True,
        'phase of the transmission error',
        'rad',
    ),
    "friction": ParameterSpec(0.0, 1.0, True, False, 'friction factor gamma', '1 (mu L_p / R_p)'),
    "alpha": ParameterSpec(0.0, math.pi / 2, True, True, 'pressure angle', 'rad'),
    "var_ratio": ParameterSpec(0.0, 10.0, True, True, 'variable-ratio forcing amplitude A_vr', '1'),
    "var_ratio_order": ParameterSpec(
        0.0, 10.0, False, True,
        'variable-ratio frequency over the mesh frequency (nu)',
        '1',
    ),
    "rho_p": ParameterSpec(0.0, 1000.0, True, True, 'pinion mass ratio', '1 (Me / M_p)'),
    "rho_g": ParameterSpec(0.0, 1000.0, True, True, 'gear mass ratio', '1 (Me / M_g)'),
    "kappa_py": ParameterSpec(
        0.0, 100000000.0, False, True,
        'pinion bearing stiffness, y',
        '1 ((K / Km) rho)',
    ),
    "kappa_pz": ParameterSpec(
        0.0, 100000000.0, False, True,
        'pinion bearing stiffness, z',
        '1 ((K / Km) rho)',
    ),
    "kappa_gy": ParameterSpec(
        0.0, 100000000.0, False, True,
        'gear bearing stiffness, y',
        '1 ((K / Km) rho)',
    ),
    "kappa_gz": ParameterSpec(
        0.0, 100000000.0, False, True,
        'gear bearing stiffness, z',
        '1 ((K / Km) rho)',
    ),
    "xi_py": ParameterSpec(0.0, 10.0, True, True, 'pinion bearing damping ratio, y', '1'),
    "xi_pz": ParameterSpec(0.0, 10.0, True, True, 'pinion bearing damping ratio, z', '1'),
    "xi_gy": ParameterSpec(0.0, 10.0, True, True, 'gear bearing damping ratio, y', '1'),
    "xi_gz": ParameterSpec(0.0, 10.0, True, True, 'gear bearing damping ratio, z', '1'),
    "b_py": ParameterSpec(
        0.0, 1000.0, True, True,
        'pinion bearing half clearance, y',
        '1 (B_p / b_c)',
    ),
    "b_pz": ParameterSpec(
        0.0, 1000.0, True, True,
        'pinion bearing half clearance, z',
        '1 (B_p / b_c)',
    ),
    "b_gy": ParameterSpec(
        0.0, 1000.0, True, True,
        'gear bearing half clearance, y',
        '1 (B_g / b_c)',
    ),
    "b_gz": ParameterSpec(
        0.0, 1000.0, True, True,
        'gear bearing half clearance, z',
        '1 (B_g / b_c)',
    ),
    "te_damping": ParameterSpec(
        0.0, 1.0, True, True,
        "fraction of the transmission-error rate the mesh damper follows "
        "(1: C (x' - e') of Eq 3, 0: C x')",
        '1',
    ),
    "mesh_damping_contact": ParameterSpec(
        0.0, 1.0, True, True,
        'fraction of the mesh damping acting only in contact (0: always, 1: only in contact)',
        '1',
    ),
    "friction_arm_var": ParameterSpec(
        0.0, 10.0, True, True,
        'friction-arm variation: half range of the sawtooth L_p of Eq 9 over its mean',
        '1',
    ),
}
#: what the text parameter ``model`` selects (docs/model.md)
MODEL_MEANING = "model variant: 6dof (bearings elastic) or 1dof (rigid bearings)"

MODELS = ("6dof", "1dof")


def interval_text(spec: tuple) -> str:
    """``spec = (lower, upper, lower inclusive, upper inclusive, ...)`` as ``[lo, hi)`` etc."""
    lo, hi, lo_in, hi_in = spec[:4]
    return f"{'[' if lo_in else '('}{lo:g}, {hi:g}{']' if hi_in else ')'}"


def in_interval(v: float, spec: tuple) -> bool:
    """``v`` finite and inside ``spec = (lower, upper, lower inclusive, upper inclusive, ...)``."""
    lo, hi, lo_in, hi_in = spec[:4]
    return math.isfinite(v) and (v >= lo if lo_in else v > lo) and (v <= hi if hi_in else v < hi)


def check_number(name: str, value: Any, spec: tuple, kind: str = "parameter") -> float:
    """Return ``value`` as a float if it is a finite, normal (or zero) number inside ``spec``.

    ``spec = (lower, upper, lower inclusive, upper inclusive, meaning)``; ``kind`` names the
    family in the message (``parameter``, ``gear parameter``).

    Raises
    ------
    ParameterError
        One line naming the field, its meaning, the bad value and the allowed range.
    """
    rng, meaning = interval_text(spec), spec[4]
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ParameterError(f"{kind} '{name}' ({meaning}) must be a number in {rng}, "
                             f"got {value!r}")
    v = float(value)
    if v != 0.0 and abs(v) < sys.float_info.min:
        raise ParameterError(
            f"{kind} '{name}' ({meaning}) = {value!r} is subnormal; allowed range "
            f"{rng} with |value| >= {sys.float_info.min:g} or 0"
        )
    if not in_interval(v, spec):
        raise ParameterError(f"{kind} '{name}' ({meaning}) = {value!r} is outside the allowed "
                             f"range {rng}")
    return v


def check_value(name: str, value: Any) -> float:
    """Return ``value`` as a float if it is a number inside the range of parameter ``name``
    (:func:`check_number`); an unknown name raises :class:`ParameterError` too."""
    if name not in PARAMETERS:
        allowed = ", ".join(sorted(PARAMETERS))
        raise ParameterError(f"unknown parameter '{name}'; allowed: {allowed}")
    return check_number(name, value, PARAMETERS[name])


@dataclass(frozen=True)
class ModelParameters:
    """Dimensionless parameters of the curve-face gear model (immutable, validated).

    Defaults are MODEL.md's starting reconstruction (single-DOF fit at xi = 0.05:
    Fe/Fm = 1.724, eps = 0.371, phi_e = -45 deg) with stiff bearings; the calibrated
    standard set lives in ``config/standard_parameters.yaml``.
    """

    w: float = 1.0
    Fm: float = 0.1
    Fe: float = 0.1724
    eps: float = 0.371
    xi: float = 0.05
    b: float = 1.0
    phi_e: float = -math.pi / 4
    friction: float = 0.0
    alpha: float = math.radians(20.0)
    var_ratio: float = 0.0
    var_ratio_order: float = 2.0 / 18.0
    rho_p: float = 0.2
    rho_g: float = 0.2
    kappa_py: float = 20.0
    kappa_pz: float = 20.0
    kappa_gy: float = 20.0
    kappa_gz: float = 20.0
    xi_py: float = 0.03
    xi_pz: float = 0.03
    xi_gy: float = 0.03
    xi_gz: float = 0.03
    b_py: float = 0.0
    b_pz: float = 0.0
    b_gy: float = 0.0
    b_gz: float = 0.0
    te_damping: float = 1.0
    mesh_damping_contact: float = 0.0
    friction_arm_var: float = 0.0
    model: str = "6dof"

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name == "model":
                continue
            object.__setattr__(self, f.name, check_value(f.name, getattr(self, f.name)))
        if self.model not in MODELS:
            raise ParameterError(
                f"parameter 'model' = {self.model!r}; allowed: {', '.join(MODELS)}"
            )

    # ------------------------------------------------------------------ helpers
    @classmethod
    def names(cls) -> tuple[str, ...]:
        """Names of all numeric parameters (what a plane axis or ``--set`` may name)."""
        return tuple(PARAMETERS)

    @classmethod
    def from_mapping(cls, values: dict[str, Any]) -> ModelParameters:
        """Build from a mapping, rejecting unknown keys with a clear error."""
        reject_unknown(values, sorted(f.name for f in fields(cls)), "parameter")
        return cls(**values)

    def with_(self, **changes: Any) -> ModelParameters:
        """A copy with some parameters changed; only the changed values are validated again.

        (A plane builds one copy per cell: re-validating all fields cost ~150 us each.)
        """
        new = object.__new__(type(self))
        new.__dict__.update(self.__dict__)
        for name, value in changes.items():
            if name == "model":
                if value not in MODELS:
                    raise ParameterError(
                        f"parameter 'model' = {value!r}; allowed: {', '.join(MODELS)}"
                    )
                object.__setattr__(new, name, value)
            else:
                object.__setattr__(new, name, check_value(name, value))
        return new

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @property
    def static_load(self) -> float:
        """Total static excitation amplitude ``Fm + Fe w**2`` (a Kmax normaliser)."""
        return self.Fm + self.Fe * self.w**2

    @property
    def mesh_period(self) -> float:
        """Dimensionless mesh period ``T = 2 pi / w``."""
        return 2.0 * math.pi / self.w

    def to_array(self) -> np.ndarray:
        """The float64 vector the Numba kernels read
        (:func:`gearsim.dynamics.model.pack_parameters`)."""
        from gearsim.dynamics import model as _m  # Numba: loaded where the kernels are

        return _m.pack_parameters(self)


# ---------------------------------------------------------------- the frequency scale (a mapping)
FREQUENCY_SCALES = ("mesh", "coupled")


def mesh_mode_ratio(params: ModelParameters) -> float:
    """``r = w_c / w_n``: the coupled mesh-mode frequency of the 6-DOF model over ``sqrt(Km / Me)``.

    The undamped linear model in contact at the mean stiffness (``eps = 0``, every bearing in its
    loaded region) has five modes; the mesh mode is the one with the largest share of its strain
    energy in the mesh spring (``x^2`` against ``sum (K_ij / Km) u_ij^2 = sum kappa_ij / rho_i
    u_ij^2``). Bearing compliance in series with the mesh lowers it below 1; the single-DOF model
    (rigid bearings) has ``r = 1``. The matrix comes from the field's own Jacobian
    (:func:`gearsim.dynamics.model.rhs` with the tangent), so it follows the equations as
    implemented.

    Reading the paper's ``w`` as ``w_h / w_c`` (docs/model.md, "Model forms") means simulating at
    ``w = r w_paper`` (:func:`at_axis_w`).
    """
    if params.model != "6dof" or params.rho_p == 0.0 or params.rho_g == 0.0:
        return 1.0  # rigid or decoupled bearings: the mesh mode is sqrt(Km / Me) itself
    from gearsim.dynamics import model as _m
    lin = params.with_(eps=0.0, xi=0.0, xi_py=0.0, xi_pz=0.0, xi_gy=0.0, xi_gz=0.0, friction=0.0,
                       var_ratio=0.0, mesh_damping_contact=0.0)
    p = lin.to_array()
    mode = np.ones(_m.N_MODE, dtype=np.int64)  # mesh and bearings in their loaded region (+1)
    y = np.zeros(2 * _m.N_STATE)
    dy = np.zeros(2 * _m.N_STATE)
    pos = (0, 2, 4, 6, 8)
    A = np.zeros((5, 5))
    for j, k in enumerate(pos):
        y[_m.N_STATE:] = 0.0
        y[_m.N_STATE + k] = 1.0
        _m.rhs(0.0, y, p, mode, dy, True)
        for i, kk in enumerate(pos):
            A[i, j] = -dy[_m.N_STATE + kk + 1]
    lam, vec = np.linalg.eig(A)
    stiff = np.array([1.0] + [getattr(params, f"kappa_{n}") / rho
                              for n, rho in zip(_m.BEARINGS, (params.rho_p, params.rho_p,
                                                              params.rho_g, params.rho_g),
                                                strict=True)])
    v = np.real(vec)
    share = stiff[0] * v[0] ** 2 / np.sum(stiff[:, None] * v**2, axis=0)
    k = int(np.argmax(share))
    return float(math.sqrt(float(np.real(lam[k]))))


def at_axis_w(params: ModelParameters, w_axis: float, frequency_scale: str = "mesh"
              ) -> ModelParameters:
    """Parameters at the axis value ``w_axis`` under a frequency-scale reading.

    ``"mesh"`` (the default): ``w = w_axis`` (``w_h / sqrt(Km / Me)``); ``"coupled"``: the axis is
    ``w_h / w_c`` and the model runs at ``w = mesh_mode_ratio(params) * w_axis``.
    """
    if frequency_scale not in FREQUENCY_SCALES:
        raise ParameterError(
            f"frequency_scale = {frequency_scale!r}; allowed: {', '.join(FREQUENCY_SCALES)}"
        )
    r = 1.0 if frequency_scale == "mesh" else mesh_mode_ratio(params)
    return params.with_(w=r * float(w_axis))
