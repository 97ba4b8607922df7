"""Dimensional description of the curve-face gear pair and its conversion to the model's units.

This is the one place where millimetres, kilograms and newtons meet the dimensionless model
(:class:`gearsim.parameters.ModelParameters`). Everything here is SI unless the field name says
otherwise (``module_mm``, ``face_width_mm``, ``pressure_angle_deg``).

Tooth stiffness (paper Eq 5-8, ISO 6336-1 / DIN 3990 "method B" draft formula)
-------------------------------------------------------------------------------
The minimum flexibility of one tooth pair per unit face width, for spur teeth (helix angle 0,
so the virtual tooth numbers are the tooth numbers) without profile shift (x1 = x2 = 0)::

    q' = C1 + C2 / zn1 + C3 / zn2 + C4 x1 + C5 x1 / zn1 + C6 x2 + C7 x2 / zn2 + C8 x1^2 + C9 x2^2
       [mm um / N],   C1..C9 = 0.04723, 0.15551, 0.25791, -0.00635, -0.11654, -0.00193,
                               -0.24188, 0.00529, 0.00182
    c'_th = 1 / q'                                  [N / (mm um)]  theoretical single stiffness
    c'    = c'_th C_M C_R C_B cos(beta)             (C_M = 0.8 theoretical-to-measured factor,
                                                     C_R = 1 solid blanks, C_B = 1 basic rack)
    k_s   = c' b_w                                  single-tooth-pair stiffness (tooth-width factor)
    K_m   = 1.5 k_s                                 mesh stiffness (Eq 8: 1.5 x single-tooth)

``zn1 = zp`` (non-circular gear) and ``zn2 = zg`` (curve-face gear), as the paper's prose states.

Dimensionless groups (docs/model.md, MODEL.md)::

    Me = Ip Ig / (Ip Rg^2 + Ig Rp^2)      w_n = sqrt(Km / Me)
    Fm = Tp / (Rp Km b_c)   Fe = Em / b_c   eps = Ka / Km   b = B / b_c   xi = Cn / (2 sqrt(Km Me))
    rho_i = Me / M_i   kappa_ij = (K_ij / Km) rho_i   xi_ij = C_ij / (2 M_i w_n)
    b_ij = B_ij / b_c  gamma = mu Lp / Rp

with ``Lp`` the mean friction arm, taken as a quarter of the length of contact ``eps_a p_b`` (the
mean distance of the contact point from the pitch point over a mesh cycle, an assumption).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

from .parameters import ModelParameters, ParameterError

#: ISO 6336-1 / DIN 3990 coefficients of q' (mm um / N)
ISO_C = (0.04723, 0.15551, 0.25791, -0.00635, -0.11654, -0.00193, -0.24188, 0.00529, 0.00182)

STEEL_DENSITY = 7850.0  # kg / m^3


def iso_flexibility(zn1: float, zn2: float, x1: float = 0.0, x2: float = 0.0) -> float:
    """ISO 6336 minimum flexibility ``q'`` of a tooth pair per unit width, mm um / N."""
    for name, z in (("zn1", zn1), ("zn2", zn2)):
        if not (isinstance(z, (int, float)) and math.isfinite(z) and z >= 5):
            raise ParameterError(f"parameter '{name}' (virtual tooth number) = {z!r} must be >= 5")
    c = ISO_C
    return (c[0] + c[1] / zn1 + c[2] / zn2 + c[3] * x1 + c[4] * x1 / zn1 + c[5] * x2
            + c[6] * x2 / zn2 + c[7] * x1**2 + c[8] * x2**2)


def iso_single_stiffness(
    zn1: float, zn2: float, x1: float = 0.0, x2: float = 0.0, *, beta_deg: float = 0.0,
    c_m: float = 0.8, c_r: float = 1.0, c_b: float = 1.0,
) -> float:
    """Single stiffness ``c'`` of a tooth pair per unit face width, N / (mm um) (= GPa)."""
    return c_m * c_r * c_b * math.cos(math.radians(beta_deg)) / iso_flexibility(zn1, zn2, x1, x2)


# name -> (lower, upper, lower inclusive, upper inclusive, meaning with unit)
_RANGES: dict[str, tuple[float, float, bool, bool, str]] = {
    "module_mm": (0.1, 100.0, True, True, "module, mm"),
    "zp": (5, 1000, True, True, "teeth of the non-circular gear"),
    "zg": (5, 1000, True, True, "teeth of the curve-face gear"),
    "n1": (1, 20, True, True, "order of the non-circular gear"),
    "n2": (1, 40, True, True, "order of the curve-face gear"),
    "pressure_angle_deg": (0.0, 45.0, False, False, "normal pressure angle, deg"),
    "face_width_mm": (0.0, 1000.0, False, True, "face width, mm"),
    "c_m": (0.0, 1.0, False, True, "ISO theoretical-to-measured stiffness factor C_M"),
    "mesh_factor": (1.0, 2.0, True, True, "mesh stiffness over single-tooth stiffness (Eq 8)"),
    "eps_stiffness": (0.0, 1.0, True, False, "stiffness fluctuation Ka / Km"),
    "mass_p": (0.0, 1e4, False, True, "mass of the non-circular gear M_p, kg"),
    "mass_g": (0.0, 1e4, False, True, "mass of the curve-face gear M_g, kg"),
    "inertia_p": (0.0, 1e3, False, True, "moment of inertia I_p, kg m^2"),
    "inertia_g": (0.0, 1e3, False, True, "moment of inertia I_g, kg m^2"),
    "bearing_k": (0.0, 1e14, False, True, "bearing stiffness K_ij (all four), N/m"),
    "bearing_c_p": (0.0, 1e8, True, True, "pinion bearing damping C_pj (Y and Z), N s/m"),
    "bearing_c_g": (0.0, 1e8, True, True, "gear bearing damping C_gj (Y and Z), N s/m"),
    "bearing_clearance_m": (0.0, 1e-2, True, True, "bearing half radial clearance B_ij, m"),
    "mesh_damping_ratio": (0.0, 10.0, True, True, "mesh damping ratio xi"),
    "torque_p": (0.0, 1e6, True, True, "driving torque T_p, N m"),
    "te_amplitude_m": (0.0, 1e-2, True, True, "transmission-error amplitude E_m, m"),
    "te_phase_deg": (-360.0, 360.0, True, True, "phase of the error forcing, deg"),
    "friction_mu": (0.0, 1.0, True, False, "sliding friction coefficient mu"),
    "backlash_half_m": (0.0, 1e-2, True, True, "half backlash B, m"),
    "nominal_length_m": (0.0, 1.0, False, True, "nominal length b_c, m"),
}


def _check(name: str, value: Any) -> float:
    lo, hi, lo_in, hi_in, meaning = _RANGES[name]
    rng = f"{'[' if lo_in else '('}{lo:g}, {hi:g}{']' if hi_in else ')'}"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ParameterError(f"geometry parameter '{name}' ({meaning}) must be a number in {rng},"
                             f" got {value!r}")
    v = float(value)
    ok = math.isfinite(v) and (v >= lo if lo_in else v > lo) and (v <= hi if hi_in else v < hi)
    if not ok:
        raise ParameterError(f"geometry parameter '{name}' ({meaning}) = {value!r} is outside the"
                             f" allowed range {rng}")
    return v


def _disk(radius: float, width: float) -> tuple[float, float]:
    m = STEEL_DENSITY * math.pi * radius**2 * width
    return m, 0.5 * m * radius**2


@dataclass(frozen=True)
class GearGeometry:
    """Dimensional gear pair (immutable, validated on construction).

    Defaults: the paper's design parameters (module 4 mm, zp 18, zg 36, n1 2, n2 4, 20 deg) and
    assumed values for what the lost Table 1 held (face width 20 mm, solid steel disks on the
    pitch radii for masses and inertias, b_c = 10 um). Load-like quantities (torque, error
    amplitude, bearing stiffness and damping, backlash) are usually back-computed from the
    calibrated dimensionless set with :meth:`from_dimensionless`.
    """

    module_mm: float = 4.0
    zp: int = 18
    zg: int = 36
    n1: int = 2
    n2: int = 4
    pressure_angle_deg: float = 20.0
    face_width_mm: float = 20.0
    c_m: float = 0.8
    mesh_factor: float = 1.5
    eps_stiffness: float = 0.371
    mass_p: float = 0.0  # 0 -> solid steel disk on the pitch radius
    mass_g: float = 0.0
    inertia_p: float = 0.0
    inertia_g: float = 0.0
    bearing_k: float = 1.0e10
    bearing_c_p: float = 0.0
    bearing_c_g: float = 0.0
    bearing_clearance_m: float = 0.0
    mesh_damping_ratio: float = 0.05
    torque_p: float = 10.0
    te_amplitude_m: float = 1.0e-6
    te_phase_deg: float = -45.0
    friction_mu: float = 0.0
    backlash_half_m: float = 1.0e-5
    nominal_length_m: float = 1.0e-5

    def __post_init__(self) -> None:
        w = self.face_width_mm * 1e-3
        defaults = {
            "mass_p": _disk(self.pitch_radius_p, w)[0] if self.module_mm > 0 else 0,
            "inertia_p": _disk(self.pitch_radius_p, w)[1] if self.module_mm > 0 else 0,
            "mass_g": _disk(self.pitch_radius_g, w)[0] if self.module_mm > 0 else 0,
            "inertia_g": _disk(self.pitch_radius_g, w)[1] if self.module_mm > 0 else 0,
        }
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in defaults and isinstance(v, (int, float)) and v == 0:
                v = defaults[f.name]
            if f.name in ("zp", "zg", "n1", "n2"):
                if isinstance(v, bool) or not isinstance(v, int):
                    if isinstance(v, float) and v.is_integer():
                        v = int(v)
                    else:
                        raise ParameterError(f"geometry parameter '{f.name}' must be an integer,"
                                             f" got {v!r}")
                _check(f.name, v)
                object.__setattr__(self, f.name, int(v))
            else:
                object.__setattr__(self, f.name, _check(f.name, v))
        if self.zg * self.n1 != self.zp * self.n2:
            raise ParameterError(
                f"geometry parameters 'zg' / 'zp' = {self.zg}/{self.zp} must equal n2 / n1 = "
                f"{self.n2}/{self.n1} (closed pitch curves)")

    # ---------------------------------------------------------------- derived geometry
    @property
    def pitch_radius_p(self) -> float:
        """Mean pitch radius of the non-circular gear R_p = m zp / 2, m."""
        return 0.5 * self.module_mm * 1e-3 * self.zp

    @property
    def pitch_radius_g(self) -> float:
        """Equivalent pitch radius of the curve-face gear R_g = m zg / 2, m."""
        return 0.5 * self.module_mm * 1e-3 * self.zg

    @property
    def alpha(self) -> float:
        return math.radians(self.pressure_angle_deg)

    @property
    def base_pitch(self) -> float:
        """Base pitch p_b = pi m cos(alpha), m."""
        return math.pi * self.module_mm * 1e-3 * math.cos(self.alpha)

    @property
    def contact_ratio(self) -> float:
        """Transverse contact ratio of the equivalent spur pair (addendum = m)."""
        m = self.module_mm * 1e-3
        rp, rg = self.pitch_radius_p, self.pitch_radius_g
        rbp, rbg = rp * math.cos(self.alpha), rg * math.cos(self.alpha)
        rap, rag = rp + m, rg + m
        length = (math.sqrt(rap**2 - rbp**2) + math.sqrt(rag**2 - rbg**2)
                  - (rp + rg) * math.sin(self.alpha))
        return length / self.base_pitch

    @property
    def friction_arm(self) -> float:
        """Mean friction arm L_p = contact_ratio p_b / 4, m (assumption, see module doc)."""
        return 0.25 * self.contact_ratio * self.base_pitch

    @property
    def single_stiffness_per_width(self) -> float:
        """ISO single stiffness c', N / (mm um)."""
        return iso_single_stiffness(self.zp, self.zg, c_m=self.c_m)

    @property
    def single_tooth_stiffness(self) -> float:
        """k_s = c' b_w, N/m."""
        return self.single_stiffness_per_width * self.face_width_mm * 1e9 * 1e-3

    @property
    def mesh_stiffness(self) -> float:
        """K_m = mesh_factor k_s (Eq 8), N/m."""
        return self.mesh_factor * self.single_tooth_stiffness

    @property
    def equivalent_mass(self) -> float:
        """Me = Ip Ig / (Ip Rg^2 + Ig Rp^2), kg."""
        ip, ig = self.inertia_p, self.inertia_g
        return ip * ig / (ip * self.pitch_radius_g**2 + ig * self.pitch_radius_p**2)

    @property
    def natural_frequency(self) -> float:
        """w_n = sqrt(Km / Me), rad/s."""
        return math.sqrt(self.mesh_stiffness / self.equivalent_mass)

    @property
    def mesh_damping(self) -> float:
        """C_n = 2 xi sqrt(Km Me), N s/m."""
        return 2.0 * self.mesh_damping_ratio * math.sqrt(self.mesh_stiffness
                                                           * self.equivalent_mass)

    # ---------------------------------------------------------------- conversion
    def to_model_parameters(self, **overrides: Any) -> ModelParameters:
        """The dimensionless parameter set (the one conversion; see the module docstring)."""
        km, me, bc = self.mesh_stiffness, self.equivalent_mass, self.nominal_length_m
        wn = self.natural_frequency
        rho_p, rho_g = me / self.mass_p, me / self.mass_g
        kw: dict[str, Any] = {
            "Fm": self.torque_p / (self.pitch_radius_p * km * bc),
            "Fe": self.te_amplitude_m / bc,
            "eps": self.eps_stiffness,
            "xi": self.mesh_damping_ratio,
            "b": self.backlash_half_m / bc,
            "phi_e": math.radians(self.te_phase_deg),
            "friction": self.friction_mu * self.friction_arm / self.pitch_radius_p,
            "alpha": self.alpha,
            "var_ratio_order": self.n1 / self.zp,
            "rho_p": rho_p,
            "rho_g": rho_g,
        }
        for j in ("y", "z"):
            kw[f"kappa_p{j}"] = self.bearing_k / km * rho_p
            kw[f"kappa_g{j}"] = self.bearing_k / km * rho_g
            kw[f"xi_p{j}"] = self.bearing_c_p / (2.0 * self.mass_p * wn)
            kw[f"xi_g{j}"] = self.bearing_c_g / (2.0 * self.mass_g * wn)
            kw[f"b_p{j}"] = self.bearing_clearance_m / bc
            kw[f"b_g{j}"] = self.bearing_clearance_m / bc
        kw.update(overrides)
        return ModelParameters.from_mapping(kw)

    @classmethod
    def from_dimensionless(cls, params: ModelParameters, base: GearGeometry | None = None
                           ) -> GearGeometry:
        """The geometry whose load-like quantities reproduce ``params`` (inverse conversion).

        Keeps ``base``'s gear geometry, masses and ``b_c``; back-computes torque, error amplitude
        and phase, stiffness fluctuation, damping ratio, half backlash, friction coefficient, and
        bearing stiffness and clearance (from the pinion's Y values; the conversion uses one
        value for all four bearing directions) and the bearing damping of each gear (Y values).
        """
        g = base or cls()
        km, bc = g.mesh_stiffness, g.nominal_length_m
        rho_p = g.equivalent_mass / g.mass_p
        return replace(
            g,
            torque_p=params.Fm * g.pitch_radius_p * km * bc,
            te_amplitude_m=params.Fe * bc,
            te_phase_deg=math.degrees(params.phi_e),
            eps_stiffness=params.eps,
            mesh_damping_ratio=params.xi,
            backlash_half_m=params.b * bc,
            friction_mu=params.friction * g.pitch_radius_p / g.friction_arm,
            bearing_k=params.kappa_py / rho_p * km,
            bearing_c_p=params.xi_py * 2.0 * g.mass_p * g.natural_frequency,
            bearing_c_g=params.xi_gy * 2.0 * g.mass_g * g.natural_frequency,
            bearing_clearance_m=params.b_py * bc,
        )

    def derived(self) -> dict[str, float]:
        """Derived dimensional quantities (for Table 1), SI units."""
        return {
            "pitch_radius_p": self.pitch_radius_p,
            "pitch_radius_g": self.pitch_radius_g,
            "base_pitch": self.base_pitch,
            "contact_ratio": self.contact_ratio,
            "friction_arm": self.friction_arm,
            "iso_flexibility_q": iso_flexibility(self.zp, self.zg),
            "single_stiffness_per_width": self.single_stiffness_per_width,
            "single_tooth_stiffness": self.single_tooth_stiffness,
            "mesh_stiffness": self.mesh_stiffness,
            "stiffness_fluctuation": self.eps_stiffness * self.mesh_stiffness,
            "equivalent_mass": self.equivalent_mass,
            "natural_frequency": self.natural_frequency,
            "mesh_damping": self.mesh_damping,
        }

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_mapping(cls, values: dict[str, Any]) -> GearGeometry:
        known = {f.name for f in fields(cls)}
        for key in values:
            if key not in known:
                raise ParameterError(f"unknown geometry parameter '{key}'; allowed: "
                                     f"{', '.join(sorted(known))}")
        return cls(**values)
