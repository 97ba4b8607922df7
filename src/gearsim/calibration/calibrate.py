"""Calibration of the free dimensionless parameters against the paper's landmark table.

What is fitted and why
----------------------
Without back contact the model is invariant under scaling ``x, Fm, Fe, b`` together, so the
w-sequence of the standard sweep depends on the *shape* parameters only: ``Fe/Fm``, ``eps``,
``xi``, ``phi_e`` and the friction factor (and, in the 6-DOF model, the bearing stiffness and mass
ratios). Those are fitted to the w of each landmark of
:data:`gearsim.analysis.landmarks.PAPER_LANDMARKS`.
The *scale* ``Fm`` then follows from the paper's backlash threshold: with ``Fm = 1`` we find the
backlash ``b*_1`` above which no double-sided impact occurs for w in [0.1, 2.5]
(:func:`backlash_threshold`); the threshold scales with ``Fm``, so ``Fm = 0.4125 / b*_1``.

Objective (:func:`objective`), smaller is better::

    J = sqrt(mean_k e_k^2)                       e_k = w_ours - w_paper (0 inside a paper range),
                                                 e_k = miss_penalty for a landmark not found
      + extra_penalty * (number of unmatched bifurcations in [w_lo, w_hi])   (pattern order)
      + xi_penalty * [subharmonics at xi_thr + dxi] + xi_penalty * [none at xi_thr - dxi]

The landmarks are matched to the paper in sweep order
(:func:`gearsim.analysis.landmarks.match_paper`), so
a wrong order shows up as missing landmarks. Nothing in the model is special-cased to hit a
number: the objective only reads the classified sweep.

The search uses :func:`scipy.optimize.differential_evolution` on the single-DOF model (rigid
bearings; the stiff-bearing 6-DOF model reproduces it) with a coarse w grid; the winner is then
verified with the 6-DOF DP5 model on a fine grid (:func:`evaluate` with ``model='6dof'``).
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from gearsim.analysis.landmarks import PAPER_LANDMARKS, find_landmarks, match_paper
from gearsim.cell.simulate import IntegrationSettings
from gearsim.cell.sweep import orbit_diagram
from gearsim.dynamics.parameters import ModelParameters
from gearsim.physical.geometry import DERIVED_UNITS as _GEOMETRY_DERIVED_UNITS

PAPER_B_THRESHOLD = 0.4125
PAPER_XI_THRESHOLD = 0.1436

#: the kinds whose unmatched occurrences count as pattern-order violations
_ORDER_KINDS = ("grazing", "period_doubling", "inverse_period_doubling", "chaos_onset",
                "period_one", "other")

#: MODEL.md's starting set (single-DOF fit at xi = 0.05)
START = {"Fe_over_Fm": 1.724, "eps": 0.371, "phi_e_deg": -45.0, "xi": 0.05, "friction": 0.0}


@dataclass(frozen=True)
class FreeParameter:
    """One coordinate of the search: a name, bounds and how it maps onto ModelParameters."""

    name: str
    lower: float
    upper: float
    unit: str = ""
    meaning: str = ""


#: Bounds: a window around MODEL.md's feasibility-study sets (Fe/Fm 1.56-1.72, eps 0.05-0.37,
#: phi -45..-19 deg, xi 0.05-0.084, friction fitted to 0), wide enough to leave them.
DEFAULT_FREE: tuple[FreeParameter, ...] = (
    FreeParameter("Fe_over_Fm", 1.2, 2.3, "", "transmission-error amplitude over mean load"),
    FreeParameter("eps", 0.0, 0.6, "", "mesh-stiffness fluctuation Ka/Km"),
    FreeParameter("phi_e_deg", -120.0, 60.0, "deg", "phase of the error forcing"),
    FreeParameter("xi", 0.04, 0.075, "", "mesh damping ratio"),
    FreeParameter("friction", 0.0, 0.1, "", "friction factor gamma = mu Lp / Rp"),
)

#: Local box around MODEL.md's best set (1.724, 0.371, -45 deg, 0.05, 0): a first wide DE run
#: (166 evaluations, results/calibration/search_wide_aborted) found nothing better than the
#: start, and the feasibility study had already searched globally.
NARROW_FREE: tuple[FreeParameter, ...] = (
    FreeParameter("Fe_over_Fm", 1.5, 2.0, "", "transmission-error amplitude over mean load"),
    FreeParameter("eps", 0.15, 0.55, "", "mesh-stiffness fluctuation Ka/Km"),
    FreeParameter("phi_e_deg", -80.0, -10.0, "deg", "phase of the error forcing"),
    FreeParameter("xi", 0.045, 0.065, "", "mesh damping ratio"),
    FreeParameter("friction", 0.0, 0.04, "", "friction factor gamma = mu Lp / Rp"),
)
BOXES = {"wide": DEFAULT_FREE, "narrow": NARROW_FREE}


@dataclass(frozen=True)
class SweepSettings:
    """The w grid and the integration of the calibration sweeps: the one definition that
    :class:`ObjectiveSettings` (round 1) and :class:`gearsim.calibration.fidelity.FidelitySettings`
    (the forms' objective) share."""

    w_min: float = 0.3
    w_max: float = 2.5
    dw: float = 0.01
    method: str = "dp5"
    rtol: float = 1e-7
    max_periods: int = 256
    transient_continuation: int = 40  # the core default (16) flips 1T/2T next to a PD
    chunk: int = 32
    Fm: float = 0.1  # scale of the search (the shape is scale-free; Fm is derived afterwards)
    xi_w_min: float = 0.6
    xi_dw: float = 0.03

    def grid(self, dw: float | None = None, lo: float | None = None) -> np.ndarray:
        """Cell centres of ``[lo, w_max]`` (``lo`` = ``w_min``) at step about ``dw``."""
        lo = self.w_min if lo is None else lo
        dw = self.dw if dw is None else dw
        n = int(round((self.w_max - lo) / dw))
        return lo + (np.arange(n) + 0.5) * (self.w_max - lo) / n

    def integration(self) -> IntegrationSettings:
        return IntegrationSettings(method=self.method, rtol=self.rtol,
                                   max_periods=self.max_periods,
                                   transient_continuation=self.transient_continuation,
                                   chunk=self.chunk)

    def to_dict(self) -> dict[str, Any]:
        from dataclasses import asdict

        return asdict(self)


@dataclass(frozen=True)
class ObjectiveSettings(SweepSettings):
    """Grid and weights of the calibration objective (recorded with every result)."""

    model: str = "1dof"
    miss_penalty: float = 0.2
    extra_penalty: float = 0.01
    extra_w_min: float = 0.3
    xi_check: bool = True
    xi_dxi: float = 0.01
    xi_w_max: float = 2.5
    xi_penalty: float = 0.02
    xi_gate: float = 0.08  # the xi check runs only when the landmark part is below this
    b: float = 1.0


def bisect_bool(pred, lo: float, hi: float, tol: float) -> float:
    """Midpoint of the final bracket of ``[lo, hi]`` where ``pred`` turns from true (at ``lo``)
    to false (at ``hi``), bisected to width ``tol``."""
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if pred(mid):
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def params_from_vector(
    x: Sequence[float],
    free: Sequence[FreeParameter] = DEFAULT_FREE,
    base: ModelParameters | None = None,
    *,
    Fm: float = 0.1,
    b: float = 1.0,
    model: str = "1dof",
) -> ModelParameters:
    """Map a search vector onto :class:`ModelParameters` (``Fe = Fe_over_Fm * Fm``)."""
    base = base or ModelParameters()
    kw: dict[str, Any] = {"Fm": Fm, "b": b, "model": model}
    for fp, v in zip(free, x, strict=True):
        if fp.name == "Fe_over_Fm":
            kw["Fe"] = float(v) * Fm
        elif fp.name == "phi_e_deg":
            kw["phi_e"] = math.radians(float(v))
        elif fp.name == "kappa":  # one stiffness for all four bearing directions
            kw.update(kappa_py=float(v), kappa_pz=float(v), kappa_gy=float(v),
                      kappa_gz=float(v))
        elif fp.name == "rho":
            kw.update(rho_p=float(v), rho_g=float(v))
        else:
            kw[fp.name] = float(v)
    return base.with_(**kw)


@dataclass
class Evaluation:
    """Everything one objective evaluation measured."""

    J: float
    rms: float
    worst: float
    n_found: int
    n_extra: int
    xi_flags: tuple[bool, bool] | None
    matched: pd.DataFrame = field(repr=False)
    landmarks: pd.DataFrame = field(repr=False)
    sweep: pd.DataFrame = field(repr=False)
    seconds: float = 0.0

    def summary(self) -> dict[str, Any]:
        return {
            "J": self.J,
            "rms": self.rms,
            "worst": self.worst,
            "n_found": self.n_found,
            "n_extra": self.n_extra,
            "xi_flags": list(self.xi_flags) if self.xi_flags is not None else None,
            "seconds": self.seconds,
            "landmarks": {
                r.key: (None if not r.found else round(float(r.ours), 5))
                for r in self.matched.itertuples()
            },
        }


def has_subharmonics(df: pd.DataFrame) -> bool:
    """Whether a sweep holds any motion other than period 1 (0/1T, 1/1T)."""
    periodic1 = (df["motion"] == "periodic") & (df["n"] == 1)
    return bool((~periodic1).any())


def score_landmarks(
    lms: pd.DataFrame, st: ObjectiveSettings
) -> tuple[float, float, float, int, int, pd.DataFrame]:
    """Landmark part of the objective: (J_landmarks, rms, worst, found, extra, matched)."""
    matched = match_paper(lms)
    errs = np.where(matched["found"], matched["error"].fillna(0.0), st.miss_penalty)
    rms = float(np.sqrt(np.mean(errs**2)))
    worst = float(np.max(np.abs(errs)))
    used = set()
    for r in matched.itertuples():
        if r.found:
            used.add(round(r.ours, 9))
    extra = 0
    for r in lms.itertuples():
        if r.kind in _ORDER_KINDS and r.value >= st.extra_w_min and round(r.value, 9) not in used:
            extra += 1
    J = rms + st.extra_penalty * extra
    return J, rms, worst, int(matched["found"].sum()), extra, matched


def evaluate(
    params: ModelParameters,
    st: ObjectiveSettings = ObjectiveSettings(),
    *,
    xi_check: bool | None = None,
) -> Evaluation:
    """Run the standard sweep for ``params`` and score it (see module docstring)."""
    t0 = time.perf_counter()
    settings = st.integration()
    df = orbit_diagram(params, "w", st.grid(), settings=settings)
    lms = find_landmarks(df)
    J, rms, worst, found, extra, matched = score_landmarks(lms, st)
    flags = None
    do_xi = st.xi_check if xi_check is None else xi_check
    if do_xi and J < st.xi_gate:
        n = int(round((st.xi_w_max - st.xi_w_min) / st.xi_dw))
        grid = st.xi_w_min + (np.arange(n) + 0.5) * (st.xi_w_max - st.xi_w_min) / n
        hi = orbit_diagram(params.with_(xi=PAPER_XI_THRESHOLD + st.xi_dxi), "w", grid,
                           settings=settings)
        lo = orbit_diagram(params.with_(xi=PAPER_XI_THRESHOLD - st.xi_dxi), "w", grid,
                           settings=settings)
        flags = (has_subharmonics(hi), not has_subharmonics(lo))
        J += st.xi_penalty * (int(flags[0]) + int(flags[1]))
    elif do_xi:
        J += 2 * st.xi_penalty  # not checked: assume the worst (keeps J monotone in quality)
    return Evaluation(J, rms, worst, found, extra, flags, matched, lms, df,
                      time.perf_counter() - t0)


# ----------------------------------------------------------------------------- search
class Objective:
    """Picklable objective for differential_evolution (``workers=`` map); logs every call."""

    def __init__(self, free: Sequence[FreeParameter], st: ObjectiveSettings,
                 base: ModelParameters, log_dir: str | None = None):
        self.free = tuple(free)
        self.st = st
        self.base = base
        self.log_dir = log_dir

    def __call__(self, x: np.ndarray) -> float:
        try:
            params = params_from_vector(x, self.free, self.base, Fm=self.st.Fm, b=self.st.b,
                                        model=self.st.model)
            ev = evaluate(params, self.st)
            J = ev.J
            rec = {"x": [float(v) for v in x], **ev.summary()}
        except Exception as exc:  # a failed evaluation is a bad point, not a crash
            J = 10.0
            rec = {"x": [float(v) for v in x], "J": J, "error": repr(exc)}
        if self.log_dir:
            path = Path(self.log_dir) / f"evals-{os.getpid()}.jsonl"
            with open(path, "a") as fh:
                fh.write(json.dumps(rec) + "\n")
        return float(J)


def calibrate(
    *,
    free: Sequence[FreeParameter] = DEFAULT_FREE,
    st: ObjectiveSettings = ObjectiveSettings(),
    base: ModelParameters | None = None,
    x0: Sequence[float] | None = None,
    seed: int = 20251122,
    popsize: int = 10,
    maxiter: int = 30,
    workers: int = 1,
    tol: float = 1e-3,
    log_dir: str | None = None,
    time_budget: float | None = None,
) -> dict[str, Any]:
    """Differential evolution over ``free``; returns a JSON-able record of the search.

    ``time_budget`` (seconds) stops the search after the generation that exceeds it (the best
    point so far is returned and the stop is recorded).
    """
    from scipy.optimize import differential_evolution

    base = base or ModelParameters()
    fun = Objective(free, st, base, log_dir)
    bounds = [(fp.lower, fp.upper) for fp in free]
    t0 = time.time()
    history: list[dict[str, Any]] = []
    stopped = {"by_budget": False}

    def callback(intermediate_result):
        history.append({"t": time.time() - t0, "J": float(intermediate_result.fun),
                        "x": [float(v) for v in intermediate_result.x]})
        if time_budget is not None and time.time() - t0 > time_budget:
            stopped["by_budget"] = True
            return True
        return False

    if log_dir:
        Path(log_dir).mkdir(parents=True, exist_ok=True)
    res = differential_evolution(
        fun,
        bounds,
        x0=None if x0 is None else np.asarray(x0, dtype=float),
        seed=seed,
        popsize=popsize,
        maxiter=maxiter,
        tol=tol,
        polish=False,
        init="sobol",
        updating="deferred" if workers != 1 else "immediate",
        workers=workers,
        callback=callback,
    )
    return {
        "method": "scipy.optimize.differential_evolution",
        "objective": "rms(w_ours - w_paper over PAPER_LANDMARKS, miss_penalty for missing) "
                     "+ extra_penalty * unmatched bifurcations + xi_penalty * xi-threshold flags",
        "free": [fp.__dict__ for fp in free],
        "bounds": bounds,
        "seed": seed,
        "popsize": popsize,
        "maxiter": maxiter,
        "tol": tol,
        "workers": workers,
        "x0": None if x0 is None else [float(v) for v in x0],
        "settings": st.to_dict(),
        "base": base.to_dict(),
        "nfev": int(res.nfev),
        "nit": int(res.nit),
        "message": str(res.message),
        "stopped_by_time_budget": stopped["by_budget"],
        "wall_seconds": time.time() - t0,
        "x": [float(v) for v in res.x],
        "J": float(res.fun),
        "best": dict(zip([fp.name for fp in free], [float(v) for v in res.x], strict=True)),
        "history": history,
        "paper_landmarks": [pl.__dict__ for pl in PAPER_LANDMARKS],
    }


# ----------------------------------------------------------------------------- thresholds
def double_sided_anywhere(params: ModelParameters, grid: np.ndarray,
                          settings: IntegrationSettings) -> bool:
    """Whether a forward sweep over ``grid`` shows any back impact (I = 2 or -1, q > 0)."""
    df = orbit_diagram(params, "w", grid, settings=settings)
    q = df["q"].fillna(0).astype(int)
    return bool(((df["I"] == 2) | (df["I"] == -1) | (q > 0)).any())


def backlash_threshold(
    params: ModelParameters,
    *,
    grid: np.ndarray | None = None,
    settings: IntegrationSettings | None = None,
    lo: float = 0.0,
    hi: float | None = None,
    tol: float = 0.002,
) -> float:
    """Smallest ``b`` above which no double-sided impact occurs over ``grid`` (bisection).

    Assumes monotonicity in ``b`` (checked at the bracket ends). ``hi`` defaults to
    ``10 (Fm + Fe)`` which is far above the motion amplitude.
    """
    grid = np.linspace(0.1, 2.5, 241) if grid is None else grid
    settings = settings or ObjectiveSettings().integration()
    hi = 10.0 * (params.Fm + params.Fe) if hi is None else hi
    if double_sided_anywhere(params.with_(b=hi), grid, settings):
        return float("inf")
    if lo > 0 and not double_sided_anywhere(params.with_(b=lo), grid, settings):
        return lo
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if double_sided_anywhere(params.with_(b=mid), grid, settings):
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def damping_threshold(
    params: ModelParameters,
    *,
    grid: np.ndarray | None = None,
    settings: IntegrationSettings | None = None,
    lo: float = 0.04,
    hi: float = 0.3,
    tol: float = 0.001,
) -> float:
    """Smallest ``xi`` above which only period-1 motion (0/1T, 1/1T) remains (bisection)."""
    grid = np.linspace(0.1, 2.5, 241) if grid is None else grid
    settings = settings or ObjectiveSettings().integration()

    def sub(x):
        return has_subharmonics(orbit_diagram(params.with_(xi=x), "w", grid, settings=settings))

    if sub(hi):
        return float("inf")
    if not sub(lo):
        return lo
    return bisect_bool(sub, lo, hi, tol)


# ----------------------------------------------------------------------------- standard file
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
