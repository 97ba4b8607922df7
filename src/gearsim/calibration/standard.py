"""The standard-parameter file (``config/standard_parameters.yaml``, the reconstructed Table 1):
the document with every value's provenance, built from a calibration record, and its writer."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from gearsim.analysis.paper import PAPER_B_THRESHOLD
from gearsim.calibration.calibrate import DEFAULT_FREE, START, search_params
from gearsim.dynamics.parameters import ModelParameters
from gearsim.physical.geometry import DERIVED_UNITS as _GEOMETRY_DERIVED_UNITS
from gearsim.physical.geometry import GearGeometry

#: units and meaning of the dimensional fields (for the YAML and Table 1)
DIMENSIONAL_UNITS = {
    "module_mm": "mm", "zp": "-", "zg": "-", "n1": "-", "n2": "-", "pressure_angle_deg": "deg",
    "face_width_mm": "mm", "c_m": "-", "mesh_factor": "-", "eps_stiffness": "-",
    "density_kg_per_m3": "kg/m^3", "mass_p_kg": "kg", "mass_g_kg": "kg",
    "inertia_p_kg_m2": "kg m^2", "inertia_g_kg_m2": "kg m^2", "bearing_stiffness_N_per_m": "N/m",
    "bearing_damping_p_Ns_per_m": "N s/m", "bearing_damping_g_Ns_per_m": "N s/m",
    "bearing_clearance_um": "um", "mesh_damping_ratio": "-", "torque_Nm": "N m",
    "speed_rpm": "rpm", "te_amplitude_um": "um", "te_phase_deg": "deg", "friction_mu": "-",
    "half_backlash_um": "um", "nominal_length_um": "um",
}
DERIVED_UNITS = _GEOMETRY_DERIVED_UNITS


def standard_document(
    params: ModelParameters,
    geometry,
    provenance: dict[str, tuple[str, str]],
    *,
    header: str = "",
) -> dict[str, Any]:
    """The ``config/standard_parameters.yaml`` document (format of :mod:`gearsim.study.config_io`).

    ``provenance`` maps a parameter name (dimensionless or dimensional) to ``(provenance, note)``;
    names not listed get ``derived`` (dimensional values back-computed from the dimensionless set)
    or ``assumed``.
    """
    from gearsim.study.config_io import PROVENANCES

    def entry(name, value, default):
        prov, note = provenance.get(name, default)
        if prov not in PROVENANCES:
            raise ValueError(f"provenance {prov!r} of {name} not in {PROVENANCES}")
        v = value if isinstance(value, str) else (int(value) if isinstance(value, int)
                                                  else float(f"{float(value):.10g}"))
        e: dict[str, Any] = {"value": v, "provenance": prov}
        if note:
            e["note"] = note
        return e

    dimless = {k: entry(k, v, ("assumed", "")) for k, v in params.to_dict().items()}
    dims = {}
    for k, v in geometry.to_dict().items():
        if v is None:  # masses / inertias computed from the density: listed under derived
            continue
        e = entry(k, v, ("derived", "back-computed from the dimensionless set"))
        e["unit"] = DIMENSIONAL_UNITS.get(k, "")
        dims[k] = e
    derived = {}
    for k, v in geometry.derived().items():
        e = entry(k, v, ("derived", ""))
        e["unit"] = DERIVED_UNITS.get(k, "")
        derived[k] = e
    doc: dict[str, Any] = {"dimensionless": dimless, "dimensional": dims, "derived": derived}
    if header:
        doc = {"description": header, **doc}
    return doc


def write_standard_parameters(path, doc: dict[str, Any]) -> None:
    import yaml

    path = Path(path)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(yaml.safe_dump(doc, sort_keys=False, width=100))
    tmp.replace(path)


#: provenance and note of every value the calibration does not set, by provenance
FIXED_PROVENANCE: dict[str, dict[str, str]] = {
    "paper": {
        "module_mm": "paper: m = 4 mm", "zp": "paper", "zg": "paper", "n1": "paper", "n2": "paper",
        "pressure_angle_deg": "paper: 20 deg", "mesh_factor": "paper Eq 8: 1.5 x single-tooth",
        "alpha": "normal pressure angle 20 deg, rad",
    },
    "ISO formula": {
        "c_m": "ISO 6336-1 C_M = 0.8",
        "iso_flexibility_q": "q' = C1 + C2/zp + C3/zg (beta = 0, x = 0)",
        "single_stiffness_per_width": "c' = C_M / q'",
        "single_tooth_stiffness": "k_s = c' b_w (tooth-width factor)",
        "mesh_stiffness": "Km = 1.5 k_s (Eq 8)",
    },
    "assumed": {
        "w": "sweep variable; every sweep overrides it",
        "b": f"standard backlash: any b above {PAPER_B_THRESHOLD} gives the same patterns (paper "
             "Sect 3.2); Table 1's value is lost",
        "var_ratio": "variable-ratio inertial term off: its 9-mesh-period cycle would turn the "
                     "paper's 1T motions into 9T (MODEL.md)",
        "model": "6-DOF bending-torsional model",
        "face_width_mm": "Table 1 lost; 20 mm = 5 modules",
        "density_kg_per_m3": "steel blanks",
        "mass_p": "solid steel disk, pitch radius x face width",
        "mass_g": "solid steel disk, pitch radius x face width",
        "inertia_p": "solid steel disk M R^2 / 2",
        "inertia_g": "solid steel disk M R^2 / 2",
        "bearing_clearance_um": "no clearance",
        "nominal_length_um": "b_c = 10 um",
        **{f"b_{g}{j}": "no bearing clearance" for j in ("y", "z") for g in ("p", "g")},
    },
    "derived": {
        "var_ratio_order": "n1 / zp",
        "rho_p": "Me / M_p with solid steel disks on the pitch radii (assumed)",
        "rho_g": "Me / M_g with solid steel disks on the pitch radii (assumed)",
        "bearing_damping_p_Ns_per_m": "C = 2 xi_pj M_p w_n",
        "bearing_damping_g_Ns_per_m": "C = 2 xi_gj M_g w_n",
    },
}


def standard_from_record(record: Mapping[str, Any], *, bearing_ratio: float,
                         bearing_xi: float) -> dict[str, Any]:
    """The standard-parameter document from a calibration record (docs/calibration.json: the
    landmark search's vector, the scale ``Fm`` from the backlash threshold), or MODEL.md's set
    when the record has no search; bearings ``K_ij = bearing_ratio Km`` with damping ratio
    ``bearing_xi``."""
    geo = GearGeometry()
    rho_p = geo.equivalent_mass / geo.mass_p
    rho_g = geo.equivalent_mass / geo.mass_g
    verify_ = record.get("verify")
    if "search" in record:
        x = record["search"]["x"]
        src = f"calibrated (differential evolution, seed {record['search']['seed']}, " \
              f"{record['search']['nfev']} evaluations, docs/calibration.json)"
    else:
        x = [START[fp.name] for fp in DEFAULT_FREE]
        src = "MODEL.md feasibility-study single-DOF fit (starting set, not yet recalibrated)"
    Fm = 0.1
    fm_prov = ("assumed", "scale of the starting set; will follow from the b = "
               f"{PAPER_B_THRESHOLD} threshold")
    fine = record.get("b_threshold_fine")
    if fine and math.isfinite(fine.get("b_threshold_at_Fm1", float("nan"))):
        Fm = PAPER_B_THRESHOLD / float(fine["b_threshold_at_Fm1"])
        fm_prov = ("derived", f"Fm = {PAPER_B_THRESHOLD} / b*(Fm=1), b*(Fm=1) = "
                   f"{fine['b_threshold_at_Fm1']:.4f} on the paper's 400-cell w grid (6-DOF)")
    elif verify_ and math.isfinite(verify_.get("Fm_from_b_threshold", float("nan"))):
        Fm = float(verify_["Fm_from_b_threshold"])
        fm_prov = ("derived", f"Fm = {PAPER_B_THRESHOLD} / b*(Fm=1), b*(Fm=1) = "
                   f"{verify_['b_threshold_at_Fm1']:.4f} (gearsim calibrate --stage verify)")
    params = search_params(x, DEFAULT_FREE, Fm=Fm, b=1.0, model="6dof")
    kw: dict[str, Any] = {"rho_p": rho_p, "rho_g": rho_g}
    for j in ("y", "z"):
        kw[f"kappa_p{j}"] = bearing_ratio * rho_p
        kw[f"kappa_g{j}"] = bearing_ratio * rho_g
        kw[f"xi_p{j}"] = kw[f"xi_g{j}"] = bearing_xi
    params = params.with_(**kw)
    geo = GearGeometry.from_dimensionless(params, geo)
    prov = {k: (kind, note) for kind, notes in FIXED_PROVENANCE.items()
            for k, note in notes.items()}
    cal = ("calibrated", src)
    prov.update({k: cal for k in ("eps", "xi", "friction", "mesh_damping_ratio",
                                  "te_phase_deg")})
    prov.update(Fm=fm_prov, Fe=("calibrated", f"Fe/Fm = {params.Fe / params.Fm:.4f}; " + src),
                phi_e=("calibrated", "rad; " + src),
                eps_stiffness=("calibrated", "Ka / Km = eps"),
                bearing_stiffness_N_per_m=("assumed", f"stiff bearings, {bearing_ratio:g} Km "
                                           "(MODEL.md: soft bearings put bearing modes inside "
                                           "the w range)"))
    for j in ("y", "z"):
        for g in ("p", "g"):
            prov[f"kappa_{g}{j}"] = ("derived", f"(K_ij / Km) rho_{g} with K_ij = "
                                     f"{bearing_ratio:g} Km (assumed stiff bearings)")
            prov[f"xi_{g}{j}"] = ("assumed", f"bearing damping ratio {bearing_xi:g} on both gears: "
                                  "with one C_ij for both the gear's lighter-damped bearing mode "
                                  "(0.0075) rings and breaks the sequence (docs/calibration.md)")
    header = ("Reconstructed Table 1 of Liu et al. (PLOS ONE 2025). Written by "
              "`gearsim calibrate --stage standard`; provenance per value: paper / ISO formula / "
              "calibrated / assumed / derived. See docs/calibration.md.")
    return standard_document(params, geo, prov, header=header)
