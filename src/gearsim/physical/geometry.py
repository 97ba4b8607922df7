"""Dimensional description of the curve-face gear pair and its conversion to the model's units.

This is the one place where millimetres, kilograms, newtons and rpm meet the dimensionless model
(:class:`gearsim.dynamics.parameters.ModelParameters`). Every field of :class:`GearGeometry` names
its
unit (``module_mm``, ``torque_Nm``, ``speed_rpm``, ``half_backlash_um``, ...); its properties are
SI (m, kg, N/m, rad/s). Gear files (``config/gears/*.yaml``), the columns in physical units and
axes given in rpm / N m / um are in :mod:`gearsim.physical.units`; the assumptions in docs/units.md.

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

    Me = Ip Ig / (Ip Rg^2 + Ig Rp^2)      w_n = sqrt(Km / Me)                 [rad/s]
    w  = 2 pi f_h / w_n,   f_h = zp n_p / 60 [Hz]   (n_p: speed of the non-circular gear, rpm)
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

from gearsim.dynamics.parameters import (
    ModelParameters,
    ParameterError,
    check_number,
    interval_text,
)
from gearsim.errors import reject_unknown

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
    "zp": (5, 1000, True, True, "teeth of the non-circular gear (pinion)"),
    "zg": (5, 1000, True, True, "teeth of the curve-face gear"),
    "n1": (1, 20, True, True, "order of the non-circular gear"),
    "n2": (1, 40, True, True, "order of the curve-face gear"),
    "pressure_angle_deg": (0.0, 45.0, False, False, "normal pressure angle, deg"),
    "face_width_mm": (0.0, 1000.0, False, True, "face width, mm"),
    "c_m": (0.0, 1.0, False, True, "ISO theoretical-to-measured stiffness factor C_M"),
    "mesh_factor": (1.0, 2.0, True, True, "mesh stiffness over single-tooth stiffness (Eq 8)"),
    "eps_stiffness": (0.0, 1.0, True, False, "stiffness fluctuation Ka / Km"),
    "density_kg_per_m3": (0.0, 1e5, False, True, "density of the gear blanks, kg/m^3"),
    "mass_p_kg": (0.0, 1e4, False, True, "mass of the non-circular gear M_p, kg"),
    "mass_g_kg": (0.0, 1e4, False, True, "mass of the curve-face gear M_g, kg"),
    "inertia_p_kg_m2": (0.0, 1e3, False, True, "moment of inertia I_p, kg m^2"),
    "inertia_g_kg_m2": (0.0, 1e3, False, True, "moment of inertia I_g, kg m^2"),
    "bearing_stiffness_N_per_m": (0.0, 1e14, False, True,
                                  "bearing stiffness K_ij (all four directions), N/m"),
    "bearing_damping_p_Ns_per_m": (0.0, 1e8, True, True,
                                   "pinion bearing damping C_pj (Y and Z), N s/m"),
    "bearing_damping_g_Ns_per_m": (0.0, 1e8, True, True,
                                   "gear bearing damping C_gj (Y and Z), N s/m"),
    "bearing_clearance_um": (0.0, 1e4, True, True, "bearing half radial clearance B_ij, um"),
    "mesh_damping_ratio": (0.0, 10.0, True, True, "mesh damping ratio xi = C_n / (2 sqrt(Km Me))"),
    "torque_Nm": (0.0, 1e6, True, True, "driving torque on the non-circular gear T_p, N m"),
    "speed_rpm": (0.0, 1e6, False, True, "speed of the non-circular gear n_p, rpm"),
    "te_amplitude_um": (0.0, 1e4, True, True, "transmission-error amplitude E_m, um"),
    "te_phase_deg": (-360.0, 360.0, True, True, "phase of the error forcing phi_e, deg"),
    "friction_mu": (0.0, 1.0, True, False, "sliding friction coefficient mu"),
    "half_backlash_um": (0.0, 1e4, True, True,
                         "half backlash B along the line of action, um (total 2B)"),
    "nominal_length_um": (0.0, 1e6, False, True, "nominal length b_c of the scaling, um"),
}

#: fields that are computed from the geometry and the density when left out (``None``)
OPTIONAL = ("mass_p_kg", "mass_g_kg", "inertia_p_kg_m2", "inertia_g_kg_m2")
INTEGERS = ("zp", "zg", "n1", "n2")


def range_text(name: str) -> str:
    """The allowed range of a gear field, e.g. ``(0, 1e+06]``."""
    return interval_text(_RANGES[name])


def meaning(name: str) -> str:
    """The meaning and unit of a gear field."""
    return _RANGES[name][4]


def _check(name: str, value: Any) -> float:
    return check_number(name, value, _RANGES[name], "gear parameter")


@dataclass(frozen=True)
class GearGeometry:
    """Dimensional curve-face gear pair (immutable, validated on construction).

    Every field name carries its unit (mm, um, deg, kg, N m, rpm, N/m, N s/m); the properties
    return SI values (m, kg, N/m, rad/s). The defaults are the study's standard gear,
    ``config/gears/standard.yaml``: the paper's design (module 4 mm, zp 18, zg 36, n1 2, n2 4,
    20 deg), the assumed values for what the lost Table 1 held (face width 20 mm, solid steel
    disks on the pitch radii, b_c = 10 um, bearings 100 Km) and the load-like values that
    reproduce the calibrated dimensionless set of ``config/standard_parameters.yaml``
    (``speed_rpm`` gives its w = 1). ``tests/unit/test_units.py`` checks that the three agree.

    ``mass_*_kg`` and ``inertia_*_kg_m2`` left at ``None`` are those of solid disks of density
    ``density_kg_per_m3`` on the pitch radii and the face width (an inertia alone: ``M R^2 / 2``
    of the given or computed mass).
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
    eps_stiffness: float = 0.3175445853
    density_kg_per_m3: float = STEEL_DENSITY
    mass_p_kg: float | None = None
    mass_g_kg: float | None = None
    inertia_p_kg_m2: float | None = None
    inertia_g_kg_m2: float | None = None
    bearing_stiffness_N_per_m: float = 38074924753.5
    bearing_damping_p_Ns_per_m: float = 1480.02157001
    bearing_damping_g_Ns_per_m: float = 5920.08628005
    bearing_clearance_um: float = 0.0
    mesh_damping_ratio: float = 0.06086822568
    torque_Nm: float = 16.2376037872
    speed_rpm: float = 20472.0411012
    te_amplitude_um: float = 2.115055312
    te_phase_deg: float = -41.5865828966
    friction_mu: float = 0.000604607663387
    half_backlash_um: float = 10.0
    nominal_length_um: float = 10.0

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in OPTIONAL and v is None:
                continue
            if f.name in INTEGERS:
                if isinstance(v, bool) or not isinstance(v, int):
                    if isinstance(v, float) and v.is_integer():
                        v = int(v)
                    else:
                        raise ParameterError(f"gear parameter '{f.name}' ({meaning(f.name)}) "
                                             f"must be an integer in {range_text(f.name)}, "
                                             f"got {v!r}")
                _check(f.name, v)
                object.__setattr__(self, f.name, int(v))
            else:
                object.__setattr__(self, f.name, _check(f.name, v))
        if self.zg * self.n1 != self.zp * self.n2:
            raise ParameterError(
                f"gear parameters 'zg' / 'zp' = {self.zg}/{self.zp} must equal n2 / n1 = "
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
        """Pressure angle, rad."""
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

    def _disk_mass(self, radius: float) -> float:
        return self.density_kg_per_m3 * math.pi * radius**2 * self.face_width_mm * 1e-3

    @property
    def mass_p(self) -> float:
        """M_p, kg (given, or a solid disk on R_p)."""
        m = self.mass_p_kg
        return self._disk_mass(self.pitch_radius_p) if m is None else m

    @property
    def mass_g(self) -> float:
        """M_g, kg (given, or a solid disk on R_g)."""
        m = self.mass_g_kg
        return self._disk_mass(self.pitch_radius_g) if m is None else m

    @property
    def inertia_p(self) -> float:
        """I_p, kg m^2 (given, or M_p R_p^2 / 2)."""
        i = self.inertia_p_kg_m2
        return 0.5 * self.mass_p * self.pitch_radius_p**2 if i is None else i

    @property
    def inertia_g(self) -> float:
        """I_g, kg m^2 (given, or M_g R_g^2 / 2)."""
        i = self.inertia_g_kg_m2
        return 0.5 * self.mass_g * self.pitch_radius_g**2 if i is None else i

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
        """w_n = sqrt(Km / Me), rad/s (the unit of the dimensionless frequency w)."""
        return math.sqrt(self.mesh_stiffness / self.equivalent_mass)

    @property
    def nominal_length(self) -> float:
        """b_c, m (the unit of the dimensionless lengths x, b, Fe)."""
        return self.nominal_length_um * 1e-6

    @property
    def force_scale(self) -> float:
        """Km b_c, N (the unit of the dimensionless forces Fm, F)."""
        return self.mesh_stiffness * self.nominal_length

    @property
    def mesh_damping(self) -> float:
        """C_n = 2 xi sqrt(Km Me), N s/m."""
        return 2.0 * self.mesh_damping_ratio * math.sqrt(self.mesh_stiffness
                                                           * self.equivalent_mass)

    @property
    def mesh_frequency_hz(self) -> float:
        """Mesh frequency f_h = zp n_p / 60, Hz."""
        return self.zp * self.speed_rpm / 60.0

    @property
    def mean_mesh_force(self) -> float:
        """Mean mesh force T_p / R_p, N (the model's convention for Fm, see docs/units.md)."""
        return self.torque_Nm / self.pitch_radius_p

    # ---------------------------------------------------------------- conversion
    def to_model_parameters(self, **overrides: Any) -> ModelParameters:
        """The dimensionless parameter set (the one conversion; see the module docstring).

        ``overrides`` are dimensionless values set afterwards (e.g. ``model="1dof"``,
        ``var_ratio=...``, which has no dimensional counterpart here).
        """
        km, bc = self.mesh_stiffness, self.nominal_length
        wn = self.natural_frequency
        rho_p, rho_g = self.equivalent_mass / self.mass_p, self.equivalent_mass / self.mass_g
        kw: dict[str, Any] = {
            "w": 2.0 * math.pi * self.mesh_frequency_hz / wn,
            "Fm": self.torque_Nm / (self.pitch_radius_p * km * bc),
            "Fe": self.te_amplitude_um * 1e-6 / bc,
            "eps": self.eps_stiffness,
            "xi": self.mesh_damping_ratio,
            "b": self.half_backlash_um * 1e-6 / bc,
            "phi_e": math.radians(self.te_phase_deg),
            "friction": self.friction_mu * self.friction_arm / self.pitch_radius_p,
            "alpha": self.alpha,
            "var_ratio_order": self.n1 / self.zp,
            "rho_p": rho_p,
            "rho_g": rho_g,
        }
        for j in ("y", "z"):
            kw[f"kappa_p{j}"] = self.bearing_stiffness_N_per_m / km * rho_p
            kw[f"kappa_g{j}"] = self.bearing_stiffness_N_per_m / km * rho_g
            kw[f"xi_p{j}"] = self.bearing_damping_p_Ns_per_m / (2.0 * self.mass_p * wn)
            kw[f"xi_g{j}"] = self.bearing_damping_g_Ns_per_m / (2.0 * self.mass_g * wn)
            kw[f"b_p{j}"] = self.bearing_clearance_um * 1e-6 / bc
            kw[f"b_g{j}"] = self.bearing_clearance_um * 1e-6 / bc
        kw.update(overrides)
        return ModelParameters.from_mapping(kw)

    @classmethod
    def from_dimensionless(cls, params: ModelParameters, base: GearGeometry | None = None
                           ) -> GearGeometry:
        """The gear whose load-like quantities reproduce ``params`` (inverse conversion).

        Keeps ``base``'s geometry, masses and ``b_c`` (default: the standard gear) and
        back-computes speed, torque, error amplitude and phase, stiffness fluctuation, damping
        ratio, half backlash, friction coefficient, bearing stiffness and clearance (from the
        pinion's Y values: the gear has one value for all four bearing directions) and each
        gear's bearing damping (Y values). :meth:`not_reproduced` names what is then lost.
        """
        g = base or cls()
        km, bc = g.mesh_stiffness, g.nominal_length
        wn = g.natural_frequency
        rho_p = g.equivalent_mass / g.mass_p
        return replace(
            g,
            speed_rpm=params.w * wn / (2.0 * math.pi) * 60.0 / g.zp,
            torque_Nm=params.Fm * g.pitch_radius_p * km * bc,
            te_amplitude_um=params.Fe * bc * 1e6,
            te_phase_deg=math.degrees(params.phi_e),
            eps_stiffness=params.eps,
            mesh_damping_ratio=params.xi,
            half_backlash_um=params.b * bc * 1e6,
            friction_mu=params.friction * g.pitch_radius_p / g.friction_arm,
            bearing_stiffness_N_per_m=params.kappa_py / rho_p * km,
            bearing_damping_p_Ns_per_m=params.xi_py * 2.0 * g.mass_p * wn,
            bearing_damping_g_Ns_per_m=params.xi_gy * 2.0 * g.mass_g * wn,
            bearing_clearance_um=params.b_py * bc * 1e6,
        )

    def not_reproduced(self, params: ModelParameters, rtol: float = 1e-9) -> list[str]:
        """Dimensionless parameters of ``params`` that this gear does not give (to ``rtol``).

        Non-empty when ``params`` is not the image of any gear with this geometry, e.g. mass
        ratios other than the geometry's, or bearing values that differ between directions.
        """
        mine = self.to_model_parameters(model=params.model, var_ratio=params.var_ratio).to_dict()
        bad = []
        for name, v in params.to_dict().items():
            if name == "model":
                continue
            if not math.isclose(mine[name], v, rel_tol=rtol, abs_tol=1e-300):
                bad.append(name)
        return bad

    def derived(self) -> dict[str, float]:
        """Derived dimensional quantities (for Table 1 and ``gearsim gear``), SI units."""
        return {
            "pitch_radius_p": self.pitch_radius_p,
            "pitch_radius_g": self.pitch_radius_g,
            "base_pitch": self.base_pitch,
            "contact_ratio": self.contact_ratio,
            "friction_arm": self.friction_arm,
            "mass_p": self.mass_p,
            "mass_g": self.mass_g,
            "inertia_p": self.inertia_p,
            "inertia_g": self.inertia_g,
            "iso_flexibility_q": iso_flexibility(self.zp, self.zg),
            "single_stiffness_per_width": self.single_stiffness_per_width,
            "single_tooth_stiffness": self.single_tooth_stiffness,
            "mesh_stiffness": self.mesh_stiffness,
            "stiffness_fluctuation": self.eps_stiffness * self.mesh_stiffness,
            "equivalent_mass": self.equivalent_mass,
            "natural_frequency": self.natural_frequency,
            "mesh_damping": self.mesh_damping,
            "mesh_frequency": self.mesh_frequency_hz,
            "mean_mesh_force": self.mean_mesh_force,
        }

    def to_dict(self) -> dict[str, Any]:
        """The fields as given (``None`` for masses and inertias computed from the density)."""
        return asdict(self)

    @classmethod
    def from_mapping(cls, values: dict[str, Any]) -> GearGeometry:
        """Build from a mapping of field names; unspecified fields keep the standard gear's."""
        reject_unknown(values, cls.names(), "gear parameter")
        return cls(**values)

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """Field names, in the order of the dataclass (and of the gear files)."""
        return tuple(f.name for f in fields(cls))


#: units of :meth:`GearGeometry.derived`
DERIVED_UNITS = {
    "pitch_radius_p": "m", "pitch_radius_g": "m", "base_pitch": "m", "contact_ratio": "-",
    "friction_arm": "m", "mass_p": "kg", "mass_g": "kg", "inertia_p": "kg m^2",
    "inertia_g": "kg m^2", "iso_flexibility_q": "mm um/N",
    "single_stiffness_per_width": "N/(mm um)", "single_tooth_stiffness": "N/m",
    "mesh_stiffness": "N/m", "stiffness_fluctuation": "N/m", "equivalent_mass": "kg",
    "natural_frequency": "rad/s", "mesh_damping": "N s/m", "mesh_frequency": "Hz",
    "mean_mesh_force": "N",
}
