"""Physical units: gear files, results in physical units, axes in rpm / N m / um.

The conversion itself (gear -> dimensionless set and back) is :class:`gearsim.physical.geometry.
GearGeometry`; this module is everything around it (docs/units.md):

* **gear files** (``config/gears/*.yaml``): a flat mapping of :class:`GearGeometry` fields (each
  name carries its unit) plus an optional ``description``; keys left out keep the standard
  gear's values (:func:`load_gear`);
* **physical columns** beside the dimensionless ones for a result row or DataFrame
  (:func:`physical_columns`; units and meanings in :data:`COLUMNS`);
* **physical axes**: a plane or sweep axis, or a fixed value, named ``speed_rpm``,
  ``mesh_frequency_Hz``, ``torque_Nm``, ``te_amplitude_um`` or ``half_backlash_um`` is converted
  to ``w``, ``Fm``, ``Fe`` or ``b`` (:func:`dimensionless_axis`, :func:`dimensionless_mapping`).
  Each is proportional to its dimensionless parameter for a given gear geometry, so a uniform
  grid in physical units is a uniform grid in the dimensionless one;
* the printed line of ``gearsim point --gear FILE --rpm N --torque T`` (its options are in
  :mod:`gearsim.cli.commands.gear`).

Scales (all fixed by the gear geometry and ``b_c``, independent of the loads)::

    time       1 / w_n          s       (tau = w_n t, w_n = sqrt(Km / Me))
    frequency  w_n / (2 pi)     Hz      (w = 2 pi f / w_n)
    length     b_c              m       (x = X_n / b_c, b = B / b_c, Fe = E_m / b_c)
    force      Km b_c           N       (Fm = T_p / (R_p Km b_c), F = mesh force / (Km b_c))
    speed      60 f_h / zp      rpm     (f_h = zp n_p / 60, mesh frequency of the pinion)
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.physical.geometry import GearGeometry, meaning, range_text

DEFAULT_GEAR = "config/gears/standard.yaml"

# ----------------------------------------------------------------------------- gear files


def gear_from_mapping(doc: Any, source: str = "gear") -> GearGeometry:
    """A :class:`GearGeometry` from a gear-file mapping (``description`` is ignored).

    Raises :class:`ParameterError` with one line naming the source, the key and its range.
    """
    if doc is None:
        doc = {}
    if not isinstance(doc, Mapping):
        raise ParameterError(f"{source}: expected a mapping of gear parameters, got "
                             f"{type(doc).__name__}")
    values = {k: v for k, v in doc.items() if k != "description"}
    if "description" in doc and not isinstance(doc["description"], str):
        raise ParameterError(f"{source}: key 'description' must be text")
    allowed = GearGeometry.names()
    for key in values:
        if key not in allowed:
            raise ParameterError(f"{source}: unknown key {key!r}; allowed: "
                                 f"{', '.join(allowed)}, description")
    try:
        return GearGeometry.from_mapping(values)
    except ParameterError as exc:
        raise ParameterError(f"{source}: {exc}") from None
    except TypeError as exc:  # pragma: no cover - from_mapping checks names first
        raise ParameterError(f"{source}: {exc}") from None


def load_gear(path: str | Path) -> GearGeometry:
    """Read a gear file (``config/gears/*.yaml``); one-line :class:`ParameterError` if bad."""
    from gearsim.safe_yaml import load_yaml

    return gear_from_mapping(load_yaml(path), f"gear file {path}")


def gear_yaml(gear: GearGeometry, description: str = "") -> str:
    """The gear as a gear file (fields in their units; ``None`` masses left out)."""
    import yaml

    doc: dict[str, Any] = {"description": description} if description else {}
    for name, value in gear.to_dict().items():
        if value is not None:
            doc[name] = float(f"{value:.12g}") if isinstance(value, float) else value
    return yaml.safe_dump(doc, sort_keys=False, width=100)


# ----------------------------------------------------------------------------- physical axes
#: physical axis name -> (dimensionless parameter, unit, meaning)
PHYSICAL_AXES: dict[str, tuple[str, str, str]] = {
    "speed_rpm": ("w", "rpm", "speed of the non-circular gear"),
    "mesh_frequency_Hz": ("w", "Hz", "mesh frequency zp n_p / 60"),
    "torque_Nm": ("Fm", "N m", "driving torque on the non-circular gear"),
    "te_amplitude_um": ("Fe", "um", "transmission-error amplitude"),
    "half_backlash_um": ("b", "um", "half backlash along the line of action"),
}


def axis_factor(name: str, gear: GearGeometry) -> tuple[str, float]:
    """``(parameter, k)`` with ``parameter = k * value`` for a physical axis ``name``.

    w = 2 pi f / w_n (f in Hz, f = zp n_p / 60); Fm = T_p / (R_p Km b_c); Fe = E_m / b_c;
    b = B / b_c (E_m, B in um).
    """
    if name not in PHYSICAL_AXES:
        raise ParameterError(f"unknown physical axis '{name}'; allowed: "
                             f"{', '.join(PHYSICAL_AXES)}")
    param = PHYSICAL_AXES[name][0]
    wn, bc = gear.natural_frequency, gear.nominal_length
    k = {
        "speed_rpm": 2.0 * math.pi * gear.zp / 60.0 / wn,
        "mesh_frequency_Hz": 2.0 * math.pi / wn,
        "torque_Nm": 1.0 / (gear.pitch_radius_p * gear.force_scale),
        "te_amplitude_um": 1e-6 / bc,
        "half_backlash_um": 1e-6 / bc,
    }[name]
    return param, k


def physical_factors(gear: GearGeometry | None, names) -> dict[str, dict[str, Any]]:
    """``{parameter: {name, unit, k}}`` (``physical = k * value``) for every parameter among
    ``names`` with a physical meaning on ``gear`` (w in rpm, Fm in N m, Fe and b in um); empty
    without a gear."""
    out: dict[str, dict[str, Any]] = {}
    if gear is None:
        return out
    for phys, (param, unit, _meaning) in PHYSICAL_AXES.items():
        if param in names and param not in out and phys != "mesh_frequency_Hz":
            out[param] = {"name": phys, "unit": unit, "k": to_physical(phys, 1.0, gear)}
    return out


def to_dimensionless(name: str, value: float, gear: GearGeometry) -> tuple[str, float]:
    """A value of a physical axis as ``(parameter, dimensionless value)``."""
    param, k = axis_factor(name, gear)
    return param, k * float(value)


def to_physical(name: str, value: float, gear: GearGeometry) -> float:
    """The inverse of :func:`to_dimensionless`: a dimensionless value in axis ``name``'s unit."""
    _, k = axis_factor(name, gear)
    return float(value) / k


def dimensionless_axis(spec: Mapping[str, Any], gear: GearGeometry | None,
                       where: str = "axis") -> dict[str, Any]:
    """A plane/sweep axis ``{name, min, max, ...}`` with a physical ``name`` converted.

    Axes that already name a dimensionless parameter are returned unchanged (copied). The
    conversion is linear and through zero, so ``min``/``max`` convert directly and the grid
    points ``v_i`` are the images of the physical grid points. A converted axis keeps its
    physical form under ``physical: {name, unit, min, max}`` (for labels in physical units).
    """
    out = dict(spec)
    name = out.get("name")
    if name not in PHYSICAL_AXES:
        return out
    if gear is None:
        raise ParameterError(f"config key '{where}.name': {name!r} is in physical units and "
                             "needs a gear file (config key 'gear')")
    param, k = axis_factor(name, gear)
    physical = {"name": name, "unit": PHYSICAL_AXES[name][1]}
    out["name"] = param
    for key in ("min", "max"):
        if key in out:
            v = out[key]
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ParameterError(f"config key '{where}.{key}' must be a number in {name}, "
                                     f"got {v!r}")
            physical[key] = v
            out[key] = k * float(v)
    out["physical"] = physical
    return out


def dimensionless_mapping(values: Mapping[str, Any], gear: GearGeometry | None,
                          where: str = "fixed") -> dict[str, Any]:
    """A mapping of parameter values (``fixed``, ``parameters``, a point) with physical names
    converted (``{torque_Nm: 20}`` -> ``{Fm: ...}``); list values convert element-wise."""
    out: dict[str, Any] = {}
    for name, v in values.items():
        if name not in PHYSICAL_AXES:
            out[name] = v
            continue
        if gear is None:
            raise ParameterError(f"config key '{where}.{name}': physical units need a gear file "
                                 "(config key 'gear')")
        param, k = axis_factor(name, gear)
        if param in out or param in values:
            raise ParameterError(f"config key '{where}.{name}': {param} is given twice")
        items = v if isinstance(v, list) else [v]
        for item in items:
            if isinstance(item, bool) or not isinstance(item, (int, float)):
                raise ParameterError(f"config key '{where}.{name}' must be a number, got {item!r}")
        conv = [k * float(item) for item in items]
        out[param] = conv if isinstance(v, list) else conv[0]
    return out


def axis_label_values(spec: Mapping[str, Any], values: Any) -> tuple[str, Any]:
    """``(label, values)`` to draw an axis converted by :func:`dimensionless_axis` in its
    physical unit, e.g. ``("torque_Nm [N m]", values in N m)``; a dimensionless axis gives
    ``(name, values)`` unchanged. Needs no gear: the conversion is proportional, so the factor
    is ``physical max / max`` (or min when max is 0)."""
    phys = spec.get("physical")
    if not isinstance(phys, Mapping):
        return str(spec.get("name")), values
    ref = "max" if float(spec.get("max", 0.0)) != 0.0 else "min"
    factor = float(phys[ref]) / float(spec[ref])
    return f"{phys['name']} [{phys['unit']}]", values * factor if not isinstance(
        values, (list, tuple)) else [v * factor for v in values]


def config_gear(config: Mapping[str, Any], root: str | Path = ".") -> GearGeometry | None:
    """The gear file named by the pipeline configuration's ``gear`` key (``None`` without)."""
    path = config.get("gear")
    if not path:
        return None
    try:
        return load_gear(Path(root) / path)
    except ParameterError as exc:
        raise ParameterError(f"config key 'gear': {exc}") from None


def dimensionless_config(config: dict[str, Any], root: str | Path = ".") -> dict[str, Any]:
    """Convert every physical name of a pipeline configuration, in place; returns ``config``.

    Plane and sweep axes, ``fixed`` values, ``parameters`` and mapping point sets may use the
    names of :data:`PHYSICAL_AXES`, with the gear file of the ``gear`` key. Idempotent (a
    converted configuration names only dimensionless parameters).
    """
    gear = config_gear(config, root)
    if config.get("parameters"):
        config["parameters"] = dimensionless_mapping(config["parameters"], gear, "parameters")
    for pname, plane in (config.get("planes") or {}).items():
        for ax in ("x", "y"):
            if isinstance(plane.get(ax), Mapping):
                plane[ax] = dimensionless_axis(plane[ax], gear, f"planes.{pname}.{ax}")
        if plane.get("fixed"):
            plane["fixed"] = dimensionless_mapping(plane["fixed"], gear,
                                                   f"planes.{pname}.fixed")
    for sname, sweep in (config.get("sweeps") or {}).items():
        if not isinstance(sweep, dict):
            continue
        fixed = sweep.get("fixed")
        sweep.update(dimensionless_axis(sweep, gear, f"sweeps.{sname}"))
        if fixed:
            sweep["fixed"] = dimensionless_mapping(fixed, gear, f"sweeps.{sname}.fixed")
    for fig, spec in (config.get("points") or {}).items():
        if isinstance(spec, Mapping):
            config["points"][fig] = dimensionless_mapping(spec, gear, f"points.{fig}")
    return config


# ----------------------------------------------------------------------------- result columns
#: physical column -> (unit, meaning); the dimensionless source columns are in brackets
COLUMNS: dict[str, tuple[str, str]] = {
    "speed_rpm": ("rpm", "speed of the non-circular gear n_p = 60 f_h / zp [w]"),
    "mesh_frequency_Hz": ("Hz", "mesh frequency f_h = w w_n / (2 pi) [w]"),
    "torque_Nm": ("N m", "driving torque T_p = Fm R_p Km b_c [Fm]"),
    "mean_mesh_force_N": ("N", "mean mesh force T_p / R_p = Fm Km b_c [Fm]"),
    "te_amplitude_um": ("um", "transmission-error amplitude E_m = Fe b_c [Fe]"),
    "half_backlash_um": ("um", "half backlash B = b b_c [b]"),
    "mesh_damping_Ns_per_m": ("N s/m", "mesh damping C_n = 2 xi sqrt(Km Me) [xi]"),
    "stiffness_fluctuation_N_per_m": ("N/m", "mesh-stiffness fluctuation Ka = eps Km [eps]"),
    "peak_mesh_force_N": ("N", "largest dynamic mesh force = kmax_peak_mean Fm Km b_c "
                          "[kmax_peak_mean, Fm]"),
    "min_mesh_force_N": ("N", "smallest dynamic mesh force = kmin_peak_mean Fm Km b_c "
                         "[kmin_peak_mean, Fm]"),
    "x_min_um": ("um", "smallest dynamic transmission error X_n = x b_c [x_min]"),
    "x_max_um": ("um", "largest dynamic transmission error X_n = x b_c [x_max]"),
    "dte_pp_um": ("um", "peak-to-peak dynamic transmission error (x_max - x_min) b_c "
                  "[x_min, x_max]"),
    "lyapunov_per_s": ("1/s", "largest Lyapunov exponent per second = lyapunov w_n [lyapunov]"),
    "time_s": ("s", "time t = tau / w_n [tau]"),
    "x_um": ("um", "dynamic transmission error X_n = x b_c [x]"),
    "xdot_m_per_s": ("m/s", "its rate dX_n/dt = x' b_c w_n [xdot]"),
    "mesh_force_N": ("N", "dynamic mesh force = F Km b_c [mesh_force]"),
    "frequency_Hz": ("Hz", "spectrum frequency (angular, in units of w_n) w_n / (2 pi) "
                     "[frequency]"),
}

#: parameters whose physical column is always produced (from the data or the fallback set)
_ALWAYS = ("w", "Fm", "b")


def _is_frame(data: Any) -> bool:
    try:
        import pandas as pd
    except ImportError:  # pragma: no cover - pandas is a dependency
        return False
    return isinstance(data, pd.DataFrame)


def physical_columns(data: Any, gear: GearGeometry,
                     params: ModelParameters | None = None) -> Any:
    """``data`` (a DataFrame or a result row mapping) with physical columns added beside it.

    Parameter columns ``w``, ``Fm``, ``b`` always give ``speed_rpm``, ``mesh_frequency_Hz``,
    ``torque_Nm``, ``mean_mesh_force_N`` and ``half_backlash_um``: from the column when present,
    otherwise from ``params`` (the set the results were computed with; default the gear's own
    dimensionless set; a sweep's ``value`` counts as the column of its ``parameter``).
    ``Fe``, ``xi``, ``eps`` and the result columns (``kmax_peak_mean``,
    ``kmin_peak_mean``, ``x_min``, ``x_max``, ``lyapunov``; a trajectory's ``tau``, ``x``,
    ``xdot``, ``mesh_force``, ``frequency``) convert when present. Units and meanings:
    :data:`COLUMNS`. Only the gear's geometry and ``b_c`` enter (not its loads).
    """
    frame = _is_frame(data)
    if not frame and not isinstance(data, Mapping):
        raise TypeError("physical_columns expects a pandas DataFrame or a mapping (one row)")
    base = params if params is not None else gear.to_model_parameters()
    cols = set(data.columns) if frame else set(data)
    swept = None  # a sweep's frame (gearsim.cell.sweep.orbit_diagram): 'value' of 'parameter'
    if {"parameter", "value"} <= cols:
        names = set(data["parameter"]) if frame else {data["parameter"]}
        if len(names) == 1 and next(iter(names)) not in cols:
            swept = next(iter(names))
            cols.add(swept)

    def get(name):
        if name in cols:
            v = data["value" if name == swept else name]
            return v.astype(float) if frame else float(v)
        return float(getattr(base, name))

    wn, bc, f0 = gear.natural_frequency, gear.nominal_length, gear.force_scale
    out: dict[str, Any] = {}
    w, fm, b = get("w"), get("Fm"), get("b")
    out["speed_rpm"] = w * wn / (2.0 * math.pi) * 60.0 / gear.zp
    out["mesh_frequency_Hz"] = w * wn / (2.0 * math.pi)
    out["torque_Nm"] = fm * gear.pitch_radius_p * f0
    out["mean_mesh_force_N"] = fm * f0
    out["half_backlash_um"] = b * bc * 1e6
    if "Fe" in cols:
        out["te_amplitude_um"] = get("Fe") * bc * 1e6
    if "xi" in cols:
        out["mesh_damping_Ns_per_m"] = (get("xi") * 2.0
                                        * math.sqrt(gear.mesh_stiffness * gear.equivalent_mass))
    if "eps" in cols:
        out["stiffness_fluctuation_N_per_m"] = get("eps") * gear.mesh_stiffness
    if "kmax_peak_mean" in cols:
        out["peak_mesh_force_N"] = get("kmax_peak_mean") * fm * f0
    if "kmin_peak_mean" in cols:
        out["min_mesh_force_N"] = get("kmin_peak_mean") * fm * f0
    for src in ("x_min", "x_max"):
        if src in cols:
            out[f"{src}_um"] = get(src) * bc * 1e6
    if "x_min" in cols and "x_max" in cols:
        out["dte_pp_um"] = (get("x_max") - get("x_min")) * bc * 1e6
    if "lyapunov" in cols:
        out["lyapunov_per_s"] = get("lyapunov") * wn
    if "tau" in cols:
        out["time_s"] = get("tau") / wn
    if "x" in cols and "tau" in cols:  # a trajectory (a plane's 'x' is its axis value)
        out["x_um"] = get("x") * bc * 1e6
    if "xdot" in cols:
        out["xdot_m_per_s"] = get("xdot") * bc * wn
    if "mesh_force" in cols:
        out["mesh_force_N"] = get("mesh_force") * f0
    if "frequency" in cols:
        out["frequency_Hz"] = get("frequency") * wn / (2.0 * math.pi)
    if frame:
        result = data.copy()
        for name, values in out.items():
            result[name] = values
        return result
    return {**data, **out}


def dte_rms_um(trajectory: Any, gear: GearGeometry) -> float:
    """RMS of the dynamic transmission error about its mean, um.

    ``trajectory``: a frame with ``tau`` and ``x`` (``gearsim point --out``; only its
    ``time_series`` rows when it has a ``kind`` column), integrated with the trapezoidal rule
    in ``tau`` (exact for a periodic motion sampled over whole periods); or an array of
    uniformly spaced ``x`` samples (plain mean). ``x = X_n / b_c``, so the result is
    ``b_c sqrt(mean((x - mean x)^2))``. The classification does not record it per cell.
    """
    import numpy as np

    if _is_frame(trajectory):
        df = trajectory
        if "kind" in df.columns:
            df = df[df["kind"] == "time_series"]
        tau, x = df["tau"].to_numpy(float), df["x"].to_numpy(float)
        span = tau[-1] - tau[0]
        if len(x) < 2 or not span > 0:
            raise ParameterError("dte_rms_um needs at least two samples of increasing tau")
        mean = np.trapezoid(x, tau) / span
        var = np.trapezoid((x - mean) ** 2, tau) / span
    else:
        x = np.asarray(trajectory, dtype=float)
        var = float(np.mean((x - x.mean()) ** 2))
    return float(np.sqrt(var)) * gear.nominal_length * 1e6


def dimensionless_columns(data: Any, gear: GearGeometry) -> dict[str, Any]:
    """The parameters ``w``, ``Fm``, ``Fe``, ``b`` recovered from physical columns (the inverse
    of :func:`physical_columns` for ``speed_rpm``, ``torque_Nm``, ``te_amplitude_um``,
    ``half_backlash_um``); returns a mapping of the parameters found."""
    cols = set(data.columns) if _is_frame(data) else set(data)
    out: dict[str, Any] = {}
    for name in ("speed_rpm", "torque_Nm", "te_amplitude_um", "half_backlash_um"):
        if name in cols:
            param, k = axis_factor(name, gear)
            out[param] = data[name] * k
    return out


# ----------------------------------------------------------------------------- reports
def describe(gear: GearGeometry, params: ModelParameters | None = None) -> str:
    """Text report: the gear (fields and derived values, units) and its dimensionless set.

    With ``params``, the physical meaning of that dimensionless set on this gear geometry
    (:meth:`GearGeometry.from_dimensionless`) and which of its values no gear of this
    geometry reproduces.
    """
    from gearsim.physical.geometry import DERIVED_UNITS

    lines = []
    if params is not None:
        target = params
        gear = GearGeometry.from_dimensionless(params, gear)
    else:
        target = gear.to_model_parameters()
    d = target.to_dict()
    phys = physical_columns({k: d[k] for k in ("w", "Fm", "Fe", "b", "xi", "eps")}, gear)
    notes = {
        "w": f"= {phys['speed_rpm']:.6g} rpm, mesh frequency {phys['mesh_frequency_Hz']:.6g} Hz",
        "Fm": f"= torque {phys['torque_Nm']:.6g} N m, mean mesh force "
              f"{phys['mean_mesh_force_N']:.6g} N",
        "Fe": f"= error amplitude {phys['te_amplitude_um']:.6g} um",
        "b": f"= half backlash {phys['half_backlash_um']:.6g} um",
        "xi": f"= mesh damping {phys['mesh_damping_Ns_per_m']:.6g} N s/m",
        "eps": f"= stiffness fluctuation {phys['stiffness_fluctuation_N_per_m']:.6g} N/m",
    }
    lines.append("dimensionless set (docs/model.md):")
    for name, value in d.items():
        if name == "model":
            lines.append(f"  {'model':28s} {value:>18s}")
            continue
        lines.append(f"  {name:28s} {value:18.10g}   {notes.get(name, '')}".rstrip())
    lines.append("gear (given or back-computed; units in the names):")
    for name, value in gear.to_dict().items():
        shown = "(from density)" if value is None else f"{value:.10g}"
        lines.append(f"  {name:28s} {shown:>18s}   {meaning(name)}")
    lines.append("derived (SI):")
    for name, value in gear.derived().items():
        lines.append(f"  {name:28s} {value:18.10g}   {DERIVED_UNITS.get(name, '')}")
    mine = gear.to_model_parameters(model=target.model, var_ratio=target.var_ratio)
    bad = gear.not_reproduced(target)
    if bad:
        got = ", ".join(f"{n} = {getattr(mine, n):.6g}" for n in bad)
        lines.append(f"not reproduced by a gear of this geometry (it gives {got}); the "
                     "geometry fixes the mass ratios, and one bearing stiffness and one "
                     "damping per gear serve both directions")
    return "\n".join(lines)


# ----------------------------------------------------------------------------- printing
def physical_line(row: Mapping[str, Any], gear_source: str = "") -> str:
    """One printed line of the physical columns of a result row (see :func:`physical_columns`)."""
    parts = [f"speed={row['speed_rpm']:.1f} rpm", f"f_mesh={row['mesh_frequency_Hz']:.1f} Hz",
             f"torque={row['torque_Nm']:.4g} N m", f"F_mean={row['mean_mesh_force_N']:.4g} N"]
    if "peak_mesh_force_N" in row:
        parts.append(f"F_peak={row['peak_mesh_force_N']:.4g} N")
    parts.append(f"B={row['half_backlash_um']:.4g} um")
    if "dte_pp_um" in row:
        parts.append(f"DTE_pp={row['dte_pp_um']:.4g} um")
    if "te_amplitude_um" in row:
        parts.append(f"E_m={row['te_amplitude_um']:.4g} um")
    head = f"physical ({gear_source}): " if gear_source else "physical: "
    return head + " ".join(parts)


__all__ = [
    "COLUMNS", "DEFAULT_GEAR", "PHYSICAL_AXES", "axis_factor", "axis_label_values",
    "config_gear", "describe", "dimensionless_axis", "dimensionless_columns",
    "dimensionless_config", "dimensionless_mapping", "dte_rms_um", "gear_from_mapping",
    "gear_yaml",
    "load_gear", "physical_columns", "physical_line", "range_text", "to_dimensionless",
    "to_physical",
]
