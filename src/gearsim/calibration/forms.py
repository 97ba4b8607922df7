"""Model forms: what a fit varies, and a form's reported measurement.

A model form (:class:`Form`) is a set of fixed :class:`~gearsim.dynamics.parameters.ModelParameters`
changes (the form's option keys, e.g. the error path or the damping placement; ``model`` for the
bearing DOFs), optional extra free parameters that only exist in that form, and the sweep method
(continuation, or the paper's fixed start at every w). Every form is searched over the same shared
box (:data:`SHARED_FREE`) plus its extras, from the same start (the calibrated single_dof shape).
The searches: :mod:`gearsim.calibration.form_search` (differential evolution at the coarse level,
then Nelder-Mead on the exact objective) and :mod:`gearsim.calibration.lane_fit` (CMA-ES with
restarts, every population measured in the batched kernel's lanes). Both report a form's best set
by :func:`final_measure`.

The search works at a fixed scale (``Fm = 0.1``, ``b = 1``) on the study's standard set; the
form's scale ``Fm`` follows from the backlash threshold.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gearsim.calibration.fidelity import FidelitySettings, measure
from gearsim.calibration.search import FreeParameter, LoggedObjective, params_from_vector
from gearsim.calibration.sweeps import PLANE_W_GRID, backlash_threshold
from gearsim.calibration.targets import Measured, score
from gearsim.dynamics.parameters import ModelParameters

#: the shared box (every form): a window around the landmark fit and MODEL.md's feasibility
#: sets (a wider box, Fe/Fm 1.2-2.4, eps 0-0.6, phi -120..60 deg, gave 15 of 17 first Sobol
#: candidates with no usable landmark sequence: at this budget DE could not even leave the start)
SHARED_FREE: tuple[FreeParameter, ...] = (
    FreeParameter("Fe_over_Fm", 1.4, 2.1, 1.7854,
                  text="transmission-error amplitude over mean load"),
    FreeParameter("eps", 0.1, 0.55, 0.3175, text="mesh-stiffness fluctuation Ka/Km"),
    FreeParameter("phi_e_deg", -90.0, 0.0, -41.59, text="phase of the error, deg"),
    FreeParameter("xi", 0.04, 0.08, 0.0609, text="mesh damping ratio"),
    FreeParameter("friction", 0.0, 0.03, 0.0, text="friction factor gamma"),
)
#: the bearing forms' extra coordinates
BEARING_FREE: tuple[FreeParameter, ...] = (
    FreeParameter("kappa_ratio", 20.0, 200.0, 100.0, text="bearing stiffness K_brg / Km"),
    # the clearance's range ends at the cliff: 0.005 b_c already loses 10 of the 12 landmarks
    # (docs/calibration.md, "a cliff at zero clearance"), so a wider box is spent past it
    FreeParameter("b_brg", 0.0, 0.005, 0.0, text="bearing half clearance / b_c (search scale)"),
)


@dataclass(frozen=True)
class Form:
    """A model form: fixed parameter changes, extra free parameters, sweep method."""

    name: str
    text: str
    fixed: dict[str, Any] = field(default_factory=dict)
    extra: tuple[FreeParameter, ...] = ()
    continuation: bool = True
    requires: tuple[str, ...] = ()  # ModelParameters names the form needs (forms' option keys)
    freq_scale: str = "mesh"  # or "coupled": the paper's w is over the coupled mesh mode

    @property
    def free(self) -> tuple[FreeParameter, ...]:
        return SHARED_FREE + self.extra

    @property
    def start(self) -> list[float]:
        return [f.start for f in self.free]

    def available(self) -> bool:
        names = set(ModelParameters.names())
        return all(r in names for r in self.requires)

    def params(self, x: Sequence[float], st: FidelitySettings) -> ModelParameters:
        """The search-scale parameters at vector ``x``: the base is the standard set of the
        study ``st`` was given (:meth:`gearsim.study.config.Study.parameters`) with the form's
        fixed changes, ``Fm = st.Fm``, ``b = st.b0``."""
        return params_from_vector(x, self.free, st.the_study().parameters().model, Fm=st.Fm,
                                  b=st.b0, **self.fixed)

    def w_factor(self, params: ModelParameters) -> float:
        """``r`` of the frequency-scale mapping (1 on the mesh scale)."""
        if self.freq_scale != "coupled":
            return 1.0
        from gearsim.dynamics.parameters import mesh_mode_ratio

        return float(mesh_mode_ratio(params))


def _forms() -> dict[str, Form]:
    f = [
        Form("single_dof", "base form: error as inertial load Fe w^2, damping always on, "
             "rigid bearings (single-DOF), w over sqrt(Km/Me), mean friction arm, continuation "
             "sweep", {"model": "1dof"}),
        Form("fixed_start", "single_dof's equations; the paper's sweep method: every w starts from "
             "the same static state (no continuation)", {"model": "1dof"}, continuation=False),
        Form("bearings_6dof", "the single_dof mesh equations with the 6-DOF bearings as the paper "
             "describes them: pinion and gear masses from the geometry (rho_p 0.4, rho_g 0.1), "
             "bearing stiffness K/Km and radial clearance free, bearing damping 0.03",
             {"model": "6dof"}, extra=BEARING_FREE),
        Form("te_rate", "transmission error through the stiffness path, K(t) f(x - e) + "
             "C (x' - s e'): the damper follows the fraction s = te_damping of the TE rate (s = 1 "
             "is single_dof's inertial load Fe w^2 exactly, s = 0 the damper on x' alone; mixtures "
             "between)", {"model": "1dof"},
             extra=(FreeParameter("te_damping", 0.0, 1.0, 1.0,
                                  text="fraction of the TE rate the damper sees"),),
             requires=("te_damping",)),
        Form("contact_damping", "mesh damping acting only in contact (none in the backlash)",
             {"model": "1dof", "mesh_damping_contact": 1.0},
             requires=("mesh_damping_contact",)),
        Form("friction_arm", "friction with the time-varying arm L_p of Eq 9 (sawtooth over the "
             "mesh period) instead of its mean; its half range free",
             {"model": "1dof"},
             extra=(FreeParameter("friction_arm_var", 0.0, 1.5, 0.5,
                                  text="a: half range of L_p over its mean (0.38-1.24 from the "
                                  "geometry)"),),
             requires=("friction_arm_var",)),
        Form("coupled_scale", "the 6-DOF bearing form with the paper's w read over the coupled "
             "mesh-mode frequency w_c (bearing compliance in series): simulated at w = r w_paper, "
             "r = w_c / w_n", {"model": "6dof"}, extra=BEARING_FREE, freq_scale="coupled"),
    ]
    return {x.name: x for x in f}


FORMS: dict[str, Form] = _forms()


def register(form: Form) -> Form:
    FORMS[form.name] = form
    return form


@dataclass(frozen=True)
class FormPoint:
    """One evaluation of a form at a search vector (picklable for the search's workers):
    ``(J, {"J", "terms", "measured"})``."""

    form: Form
    st: FidelitySettings

    def __call__(self, x: np.ndarray) -> tuple[float, dict[str, Any]]:
        p = self.form.params(x, self.st)
        m = measure(p, self.st, continuation=self.form.continuation,
                    w_factor=self.form.w_factor(p))
        J, terms = score(m)
        return J, {"J": J, "terms": terms, "measured": m.to_dict()}


def form_objective(form: Form, st: FidelitySettings, log_dir: str | Path | None, level: str
                   ) -> LoggedObjective:
    """The logged objective of ``form`` at measurement ``st``; evaluations go to
    ``<log_dir>/<form>-<level>.<pid>.jsonl``."""
    pattern = None if not log_dir else str(Path(log_dir) / f"{form.name}-{level}") + ".{pid}.jsonl"
    return LoggedObjective(FormPoint(form, st), pattern)


# ================================================================ the reported measurement
#: the backlash bisection grid
B_GRID = PLANE_W_GRID
#: the reported (final) measurement of a form: exact landmarks, the xi threshold to ~0.001;
#: one definition for every search's report
FINAL = FidelitySettings(exact=True, xi_bisect=6, xi_dw=0.02)


def backlash_bisection(p: ModelParameters, st: FidelitySettings, *, continuation: bool = True,
                       tol: float = 0.002, w_factor: float = 1.0) -> float:
    """Smallest ``b`` above which no sweep over :data:`B_GRID` (with the form's sweep method)
    shows a double-sided impact; NaN if the sweep at ``st.b0`` already has one."""
    b = backlash_threshold(p, grid=B_GRID, settings=st.integration(), lo=0.0, hi=st.b0, tol=tol,
                           continuation=continuation, w_factor=w_factor)
    return b if math.isfinite(b) else math.nan


def final_measure(form: Form, x: Sequence[float], st: FidelitySettings
                  ) -> tuple[float, Measured | None, dict[str, float], float]:
    """Reported measurement of ``form`` at ``x``: the scale from a bisection of whole sweeps
    (:func:`backlash_bisection` on :data:`B_GRID`, tol 0.002), then
    :func:`gearsim.calibration.fidelity.measure` with exact landmarks."""
    p = form.params(x, st)
    try:
        b_star = backlash_bisection(p, st, continuation=form.continuation,
                                    w_factor=form.w_factor(p))
    except Exception:  # noqa: BLE001
        b_star = math.nan
    try:
        m = measure(p, st, continuation=form.continuation,
                    b_star=b_star if math.isfinite(b_star) else None, w_factor=form.w_factor(p))
        J, terms = score(m)
    except Exception:  # noqa: BLE001
        return 1e3, None, {}, b_star
    return J, m, terms, b_star
