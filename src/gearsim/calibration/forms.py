"""Model forms and their fits: the same search, budget and refinement for every form.

A model form (:class:`Form`) is a set of fixed :class:`~gearsim.dynamics.parameters.ModelParameters`
changes (the form's option keys, e.g. the error path or the damping placement; ``model`` for the
bearing DOFs), optional extra free parameters that only exist in that form, and the sweep method
(continuation, or the paper's fixed start at every w). Every form is searched over the same shared
box (:data:`SHARED_FREE`) plus its extras, from the same start (the calibrated single_dof shape), by
:func:`gearsim.calibration.search.search` (seeded differential evolution of :data:`POPULATION`
members for the same number of generations) scoring :func:`gearsim.calibration.fidelity.measure`
at the coarse level; then the same refinement: the best ``refine_top`` distinct candidates are
re-measured with exact (continued) landmarks, and Nelder-Mead runs ``refine_fev`` exact
evaluations from the best of them.

The search works at a fixed scale (``Fm = 0.1``, ``b = 1``) on the study's standard set; the
form's scale ``Fm`` follows from the backlash threshold. Each form's JSON record carries its own
run: start and end, load average at the start, git commit, wall and CPU seconds.
"""

from __future__ import annotations

import json
import math
import os
import resource
import subprocess
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from gearsim.calibration.fidelity import FidelitySettings, kmax_at_jump, measure, measure_many
from gearsim.calibration.search import (
    FreeParameter,
    LoggedObjective,
    logged_evaluations,
    params_from_vector,
    search,
)
from gearsim.calibration.sweeps import PLANE_W_GRID, backlash_threshold, w_sweep
from gearsim.calibration.tables import evidence_lines
from gearsim.calibration.targets import LANDMARK_KEYS, TARGETS, Measured, score, target_errors
from gearsim.dynamics.parameters import ModelParameters
from gearsim.study.config import Study

POPULATION = 16

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
        """The search-scale parameters at vector ``x``: the base is the study's standard set
        (:meth:`gearsim.study.config.Study.parameters`) with the form's fixed changes,
        ``Fm = st.Fm``, ``b = st.b0``."""
        return params_from_vector(x, self.free, Study.load().parameters().model, Fm=st.Fm, b=st.b0,
                                  **self.fixed)

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


# ============================================================================ the process record
def git_commit() -> str:
    """Short git commit of the package's checkout (``+dirty`` with uncommitted changes in it),
    ``unknown`` outside a git checkout."""
    here = str(Path(__file__).resolve().parents[1])
    try:
        head = subprocess.run(["git", "-C", here, "rev-parse", "--short", "HEAD"],
                              capture_output=True, text=True, timeout=10)
        if head.returncode != 0:
            return "unknown"
        dirty = subprocess.run(["git", "-C", here, "status", "--porcelain", "--", "."],
                               capture_output=True, text=True, timeout=10)
        return head.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def _utc() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def _user_s() -> float:
    """User CPU seconds of this process and its finished children (the search's workers)."""
    return (resource.getrusage(resource.RUSAGE_SELF).ru_utime
            + resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime)


class Run:
    """What a fit's process records of itself: start and end (UTC), load average at the start
    (1, 5, 15 min), git commit, wall and user CPU seconds (:meth:`record`)."""

    def __init__(self) -> None:
        self.t0 = time.time()
        self.u0 = _user_s()
        self.info = {"start": _utc(), "load": " ".join(f"{v:.2f}" for v in os.getloadavg()),
                     "code": git_commit()}

    def record(self) -> dict[str, Any]:
        return {**self.info, "wall_s": time.time() - self.t0, "user_s": _user_s() - self.u0,
                "end": _utc()}


# ============================================================================ one form
#: the backlash bisection grid
B_GRID = PLANE_W_GRID
#: the reported (final) measurement of a form: exact landmarks, the xi threshold to ~0.001;
#: one definition for :func:`fit_form` and :func:`evaluate_unsearched`
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


def fit_form(form: Form, *, seed: int, generations: int, population: int = POPULATION,
             refine_top: int = 4, refine_fev: int = 16, workers: int = 1,
             coarse: FidelitySettings | None = None,
             exact: FidelitySettings | None = None, final: FidelitySettings | None = None,
             log_dir: str | None = None,
             time_budget: float | None = None, log: Callable[[str], None] = print
             ) -> dict[str, Any]:
    """Search, refine and measure one form; a JSON-able record with provenance."""
    from gearsim.study.provenance import code_version

    coarse = coarse or FidelitySettings()
    exact = exact or FidelitySettings(exact=True)
    if not form.available():
        return {"form": form.name, "skipped": f"needs parameters {form.requires}"}
    run = Run()
    bounds = [(f.lower, f.upper) for f in form.free]
    x0 = form.start
    if log_dir:
        Path(log_dir).mkdir(parents=True, exist_ok=True)
    obj = form_objective(form, coarse, log_dir, "coarse")
    J0 = obj(np.asarray(x0))
    log(f"[{form.name}] start J (coarse) = {J0:.4f}")
    res = search(obj, bounds, seed=seed, generations=generations, population=population, x0=x0,
                 workers=workers, time_budget=time_budget,
                 refine_fun=form_objective(form, exact, log_dir, "exact"),
                 refine_top=refine_top, refine_fev=refine_fev)
    de = res["de"]
    log(f"[{form.name}] DE: J = {de['J']:.4f} after {de['nfev']} evaluations, "
        f"{de['wall_s']:.0f} s")
    # final measurement: the backlash threshold by bisection of whole sweeps (the scale), the
    # xi threshold to ~0.001, exact landmarks
    final = final or FINAL
    J, m, terms, b_star = final_measure(form, res["x"], final)
    J_start, m_start, terms_start, b_star0 = final_measure(form, x0, final)
    names = [f.name for f in form.free]
    rec = {
        "form": form.name, "text": form.text, "fixed": form.fixed,
        "continuation": form.continuation,
        "free": [asdict(f) for f in form.free], "seed": seed,
        "budget": {"population": population, "generations": generations,
                   "refine_top": refine_top, "refine_fev": refine_fev,
                   "nfev_coarse": de["nfev"] + 1, "nfev_exact": res["nfev_refine"] + 2},
        "coarse": coarse.to_dict(), "exact": exact.to_dict(), "final": final.to_dict(),
        "b_star_bisection": b_star, "b_star_bisection_start": b_star0,
        "code_version": code_version("calibration"), "wall_s": time.time() - run.t0,
        "de": {k: v for k, v in de.items() if k not in ("population_final",)},
        "refine": res["refine"],
        "refine_candidates": [[float(s), [float(v) for v in c]] for s, c in res["candidates"]],
        "best": dict(zip(names, [float(v) for v in res["x"]], strict=True)),
        "J": J, "terms": terms, "measured": m.to_dict() if m else None,
        "start": {"J": J_start, "terms": terms_start,
                  "measured": m_start.to_dict() if m_start else None},
        "run": run.record(),
    }
    log(f"[{form.name}] refined exact J = {J:.4f} (start {J_start:.4f}); "
        f"{rec['wall_s']:.0f} s")
    return rec


def evaluate_unsearched(form: Form, points: dict[str, Sequence[float]],
                        final: FidelitySettings | None = None) -> dict[str, Any]:
    """A form measured (the fit's final measurement) at given points without a search, e.g. the
    standard shape and another form's best; the best point's values are the row."""
    from gearsim.study.provenance import code_version

    final = final or FINAL
    run = Run()
    rec: dict[str, Any] = {"form": form.name, "text": form.text, "fixed": form.fixed,
                           "continuation": form.continuation, "searched": False,
                           "code_version": code_version("calibration"), "final": final.to_dict(),
                           "points": {}}
    names = [f.name for f in form.free]
    for key, x in points.items():
        J, m, terms, b = final_measure(form, x, final)
        rec["points"][key] = {"x": dict(zip(names, [float(v) for v in x], strict=True)),
                              "J": J, "terms": terms, "measured": m.to_dict() if m else None,
                              "b_star_bisection": b}
    best = min(rec["points"], key=lambda k: rec["points"][k]["J"])
    p = rec["points"][best]
    rec.update(J=p["J"], terms=p["terms"], measured=p["measured"], best=p["x"],
               b_star_bisection=p["b_star_bisection"], best_point=best,
               wall_s=time.time() - run.t0, run=run.record())
    return rec


def run_forms(names: Sequence[str], forms_dir: str | Path, *, search_forms: bool = True,
              seed: int, generations: int, population: int, refine_fev: int, workers: int = 1,
              time_budget: float | None = None, log: Callable[[str], None] = print) -> None:
    """``<forms_dir>/<form>.json`` for each form of ``names``: its fit (:func:`fit_form`,
    evaluations logged to ``<forms_dir>/logs``) or, without ``search_forms``, its measurement
    at the standard shape and at the ``single_dof`` form's best of an earlier fit
    (``<forms_dir>/single_dof.json``, if there) (:func:`evaluate_unsearched`)."""
    d = Path(forms_dir)
    d.mkdir(parents=True, exist_ok=True)
    for name in names:
        form = FORMS[name]
        if not search_forms:
            pts = {"start": form.start}
            tb = d / "single_dof.json"
            if tb.is_file():
                best = json.loads(tb.read_text()).get("best", {})
                pts["single_dof_best"] = [best.get(f.name, f.start) for f in form.free]
            rec = evaluate_unsearched(form, pts)
            (d / f"{name}.json").write_text(json.dumps(rec, indent=1, default=float))
            log(f"{name}: J = {rec['J']:.4f} at {rec['best_point']} (not searched)")
            continue
        rec = fit_form(form, seed=seed, generations=generations, population=population,
                       refine_fev=refine_fev, workers=workers, log_dir=str(d / "logs"),
                       time_budget=time_budget, log=log)
        (d / f"{name}.json").write_text(json.dumps(rec, indent=1, default=float))
        log(f"wrote {d / (name + '.json')}")


# ============================================================================ CMA-ES in lanes
#: the search-level measurement of the lane fits: every sweep a chain in the batched kernel's
def state_path(log_dir: str | Path, form: str, seed: int) -> Path:
    """``<log_dir>/<form>-lanes.s<seed>.state.json``: a lane fit's search so far (evaluations,
    best J and set, curve, runs, wall and CPU seconds), rewritten after every generation."""
    return Path(log_dir) / f"{form}-lanes.s{seed}.state.json"


#: lanes with the study's RK4 settings, landmarks read off the grid (DP5 stays for the final)
LANES = FidelitySettings(lanes=True)


@dataclass(frozen=True)
class FormBatch:
    """A whole population of ``form`` measured at once (:func:`measure_many`); every
    evaluation appended as one JSON line to ``log_path`` (if given)."""

    form: Form
    st: FidelitySettings
    log_path: str | None = None

    def __call__(self, xs: Sequence[np.ndarray]) -> list[float]:
        ps = [self.form.params(x, self.st) for x in xs]
        try:
            ms = measure_many(ps, self.st, continuation=self.form.continuation,
                              w_factors=[self.form.w_factor(p) for p in ps])
        except Exception:  # noqa: BLE001 - one failing set: measure them one by one
            ms = []
            for p in ps:
                try:
                    ms.append(measure_many([p], self.st, continuation=self.form.continuation,
                                           w_factors=[self.form.w_factor(p)])[0])
                except Exception:  # noqa: BLE001 - a failed evaluation is a bad point
                    ms.append(None)
        Js = []
        lines = []
        for x, m in zip(xs, ms, strict=True):
            if m is None:
                J, terms, md = 1e3, {}, None
            else:
                J, terms = score(m)
                md = m.to_dict()
            Js.append(J)
            lines.append(json.dumps({"x": [float(v) for v in x], "J": J, "terms": terms,
                                     "measured": md}, default=float))
        if self.log_path:
            with open(self.log_path, "a") as fh:
                fh.write("\n".join(lines) + "\n")
        return Js


def fit_form_cmaes(form: Form, *, seed: int, log_dir: str | Path, max_evals: int = 3000,
                   min_evals: int = 0, flat_evals: int = 600, time_budget: float | None = None,
                   final: bool = True, log: Callable[[str], None] = print) -> dict[str, Any]:
    """CMA-ES with restarts (:func:`gearsim.calibration.search.run_cmaes`) of one form from its
    start, every population measured in lanes (:data:`LANES`); then, with ``final``, the best
    set and the start measured exactly (DP5, :func:`final_measure`) beside the best set's lane
    measurement. A JSON-able record with its run (wall, CPU, load), the best-J curve and why
    the search stopped."""
    from gearsim.calibration.search import run_cmaes

    if not form.available():
        return {"form": form.name, "skipped": f"needs parameters {form.requires}"}
    run = Run()
    Path(log_dir).mkdir(parents=True, exist_ok=True)
    logp = str(Path(log_dir) / f"{form.name}-lanes.s{seed}.jsonl")
    statep = state_path(log_dir, form.name, seed)
    Path(logp).unlink(missing_ok=True)
    statep.unlink(missing_ok=True)
    batch = FormBatch(form, LANES, logp)
    bounds = [(f.lower, f.upper) for f in form.free]
    names = [f.name for f in form.free]
    every = {"n": 0}

    def gen(info: dict[str, Any]) -> None:
        # the search so far, rewritten after every generation: an interrupted fit keeps it
        state = {"form": form.name, "seed": seed, "nfev": info["nfev"],
                 "J_lanes": info["best_J"], "best": dict(zip(names, info["x"], strict=True)),
                 "run_index": info["run"], "runs": info["runs"], "curve": info["curve"],
                 "cpu_s_search": info["cpu_s"], "wall_s_search": info["t"],
                 "start": run.info["start"], "load": run.info["load"], "code": run.info["code"],
                 "updated": _utc()}
        tmp = statep.with_suffix(".tmp")
        tmp.write_text(json.dumps(state, default=float))
        tmp.replace(statep)
        if info["nfev"] >= every["n"]:
            every["n"] = info["nfev"] + 200
            log(f"[{form.name} s{seed}] {info['nfev']} evaluations, best J {info['best_J']:.4f}, "
                f"{info['t']:.0f} s")

    res = run_cmaes(batch, bounds, seed=seed, x0=form.start, max_evals=max_evals,
                    min_evals=min_evals, flat_evals=flat_evals, time_budget=time_budget,
                    on_generation=gen)
    rec: dict[str, Any] = {
        "form": form.name, "text": form.text, "fixed": form.fixed,
        "continuation": form.continuation, "free": [asdict(f) for f in form.free],
        "seed": seed, "search": "cma-es, IPOP restarts",
        "lanes": LANES.to_dict(),
        "budget": {"max_evals": max_evals, "min_evals": min_evals, "flat_evals": flat_evals,
                   "time_budget_s": time_budget},
        "nfev": res["nfev"], "stopped_by": res["stopped_by"], "runs": res["runs"],
        "curve": res["curve"], "J_lanes": res["J"],
        "best": dict(zip(names, res["x"], strict=True)),
        "cpu_s_search": res["cpu_s"], "wall_s_search": res["wall_s"],
    }
    log(f"[{form.name} s{seed}] search: J (lanes) {res['J']:.4f} after {res['nfev']} "
        f"evaluations ({res['stopped_by']}), {res['wall_s']:.0f} s")
    if final:
        J, m, terms, b = final_measure(form, res["x"], FINAL)
        rec.update(J=J, terms=terms, measured=m.to_dict() if m else None, b_star_bisection=b)
        log(f"[{form.name} s{seed}] exact (DP5) J = {J:.4f}")
    rec["run"] = run.record()
    return rec


def run_forms_cmaes(names: Sequence[str], forms_dir: str | Path, *, seeds: Sequence[int],
                    max_evals: int, min_evals: int = 0, flat_evals: int = 600,
                    time_budget: float | None = None, final: bool = True,
                    log: Callable[[str], None] = print) -> None:
    """``<forms_dir>/<form>.s<seed>.json`` for each form and seed (:func:`fit_form_cmaes`;
    evaluations logged to ``<forms_dir>/logs``), each written as soon as it is done."""
    d = Path(forms_dir)
    d.mkdir(parents=True, exist_ok=True)
    for name in names:
        for seed in seeds:
            rec = fit_form_cmaes(FORMS[name], seed=seed, log_dir=d / "logs",
                                 max_evals=max_evals, min_evals=min_evals,
                                 flat_evals=flat_evals, time_budget=time_budget, final=final,
                                 log=log)
            (d / f"{name}.s{seed}.json").write_text(json.dumps(rec, indent=1, default=float))
            log(f"wrote {d / f'{name}.s{seed}.json'}")


def collect_fit(names: Sequence[str], forms_dir: str | Path) -> dict[str, Any]:
    """docs/calibration.json's ``fit`` entry from ``<forms_dir>/<form>.s<seed>.json``: per form
    its seeds' records (evaluations, why each stopped, best J in lanes and exact, the best-J
    curve, wall and CPU seconds, the run), the total evaluations, the seeds' best J and their
    spread ``(max - min) / min`` (a seed with a log but no record: ``unfinished``, its
    evaluations and curve from the log, no CPU time); the Pareto fronts of all logged evaluations
    (:func:`gearsim.calibration.pareto.pareto_record`) and the per-target evidence."""
    from gearsim.calibration.pareto import coexist_tally, pareto_record

    d = Path(forms_dir)
    out: dict[str, Any] = {}
    for name in names:
        seeds = {}
        for f in sorted(d.glob(f"{name}.s*.json")):
            rec = json.loads(f.read_text())
            seeds[str(rec["seed"])] = {k: rec[k] for k in (
                "seed", "search", "nfev", "stopped_by", "runs", "J_lanes", "J", "terms", "best",
                "measured", "cpu_s_search", "wall_s_search", "run", "budget", "curve")
                if k in rec}
        for f in sorted((d / "logs").glob(f"{name}-lanes.s*.jsonl")):
            seed = f.name.split(".")[1][1:]
            if seed in seeds:
                continue
            # a search still running or stopped before its record: its logged evaluations,
            # its wall and CPU seconds from its state (none without one: 0, "timed": False)
            Jl = [json.loads(line)["J"] for line in f.read_text().splitlines() if line]
            if Jl:
                curve = np.minimum.accumulate(Jl)
                seeds[seed] = {"seed": int(seed), "nfev": len(Jl), "stopped_by": "unfinished",
                               "J_lanes": float(curve[-1]), "cpu_s_search": 0.0,
                               "wall_s_search": 0.0, "timed": False,
                               "curve": [[i + 1, float(v)] for i, v in enumerate(curve)
                                         if i == len(Jl) - 1 or curve[i + 1] < v]}
                sp = state_path(d / "logs", name, int(seed))
                if sp.is_file():
                    state = json.loads(sp.read_text())
                    seeds[seed].update({k: state[k] for k in (
                        "best", "runs", "cpu_s_search", "wall_s_search", "start", "load",
                        "code", "updated") if k in state}, timed=True)
        if not seeds:
            continue
        Js = [v["J_lanes"] for v in seeds.values()]
        out[name] = {"text": FORMS[name].text if name in FORMS else "",
                     "seeds": seeds, "n_seeds": len(seeds),
                     "evaluations": int(sum(v["nfev"] for v in seeds.values())),
                     "best_J_lanes": Js, "spread": (max(Js) - min(Js)) / min(Js),
                     "cpu_s": float(sum(v["cpu_s_search"] for v in seeds.values())),
                     "wall_s": float(sum(v["wall_s_search"] for v in seeds.values()))}
    logs = d / "logs"
    return {"forms": out, "lanes": LANES.to_dict(),
            "pareto": pareto_record(logs) if logs.is_dir() else {},
            "coexist": coexist_tally(logs) if logs.is_dir() else {},
            "evidence": best_per_target(logs) if logs.is_dir() else {}}


# ============================================================================ evidence
def best_per_target(log_dir: str | Path) -> dict[str, dict[str, Any]]:
    """For every target: the smallest error any logged evaluation of any form reached, with
    that evaluation's form, level (coarse grid read / exact), J and how many evaluations
    measured the target. Evidence for a miss: no tested form got closer within its search."""
    tol = {t.key: t.tol for t in TARGETS}
    best: dict[str, dict[str, Any]] = {}
    for form, level, rec in logged_evaluations(log_dir):
        errs = target_errors(Measured.from_dict(rec["measured"]))
        for k, e in errs.items():
            if not np.isfinite(e):
                continue
            b = best.setdefault(k, {"n": 0, "n_hit": 0})
            b["n"] += 1
            if "error" not in b or abs(e) < abs(b["error"]):
                b.update(error=float(e), form=form, level=level, J=float(rec["J"]),
                         x=rec["x"])
            if abs(e) <= tol[k] * (1 + 1e-9):
                # the trade-off: of the evaluations that hit this target, the lowest J and
                # which landmarks miss 0.02 there
                b["n_hit"] += 1
                if "hit_J" not in b or rec["J"] < b["hit_J"]:
                    b.update(hit_J=float(rec["J"]), hit_form=form, hit_level=level,
                             hit_x=rec["x"],
                             hit_misses={q: (None if not np.isfinite(v) else float(v))
                                         for q, v in errs.items()
                                         if q != k and q in LANDMARK_KEYS and
                                         not (np.isfinite(v) and abs(v) <= tol[q])})
    return best


def partial_record(form: Form, log_dir: str | Path) -> dict[str, Any] | None:
    """A form whose fit did not finish: its evaluations so far and the best logged one (an
    exact evaluation if any, else the best coarse one), marked ``unfinished``; None if nothing
    was logged. The row is comparable with the finished ones only at the same level."""
    n = {"coarse": 0, "exact": 0}
    best: dict[str, Any] = {}
    for level in ("coarse", "exact"):
        for f in sorted(Path(log_dir).glob(f"{form.name}-{level}.*.jsonl")):
            for line in f.read_text().splitlines():
                rec = json.loads(line)
                n[level] += 1
                if not rec.get("measured"):
                    continue
                b = best.get(level)
                if b is None or rec["J"] < b["J"]:
                    best[level] = rec
    if not n["coarse"] and not n["exact"]:
        return None
    level = "exact" if "exact" in best else "coarse"
    rec = best.get(level)
    names = [f.name for f in form.free]
    out: dict[str, Any] = {"form": form.name, "text": form.text, "fixed": form.fixed,
                           "continuation": form.continuation,
                           "unfinished": {"n_coarse": n["coarse"], "n_exact": n["exact"],
                                          "level": level}}
    if rec is not None:
        out.update(J=rec["J"], terms=rec.get("terms", {}), measured=rec["measured"],
                   best=dict(zip(names, rec["x"], strict=True)))
    return out


def stream_runs(forms_dir: str | Path) -> dict[str, dict[str, Any]]:
    """Per form, the run record of fits made before the records carried their own (``run`` of
    :func:`fit_form`): read from the logs of the processes that ran them (``stream*.log`` in
    ``forms_dir``: a line ``=== <form> start <time> load <1 5 15 min> code <commit>``, the
    ``/usr/bin/time`` line ``<s> s wall <s> s user`` and ``=== <form> end <time>``)."""
    import re

    runs: dict[str, dict[str, Any]] = {}
    for f in sorted(Path(forms_dir).glob("stream*.log")):
        cur = None
        for line in f.read_text().splitlines():
            mo = re.match(r"=== (\S+) start (\S+) load (\S+) (\S+) (\S+) code (\S+)", line)
            if mo:
                cur = mo.group(1)
                runs[cur] = {"stream": f.stem, "start": mo.group(2),
                             "load": " ".join(mo.group(3, 4, 5)), "code": mo.group(6)}
                continue
            mo = re.match(r"([0-9.]+) s wall ([0-9.]+) s user", line)
            if mo and cur:
                runs[cur].update(wall_s=float(mo.group(1)), user_s=float(mo.group(2)))
                continue
            mo = re.match(r"=== (\S+) end (\S+)", line)
            if mo and mo.group(1) in runs:
                runs[mo.group(1)]["end"] = mo.group(2)
    return runs


def kmax_for(form: Form, x: Sequence[float], st: FidelitySettings | None = None, *,
             w_lo: float = 0.3, w_hi: float = 1.0, dw: float = 0.002) -> dict[str, Any]:
    """Kmax readings on both sides of the jump of ``form`` at ``x``, the jump resolved on a
    fine forward sweep (``dw``) with the form's sweep method (the readings are ratios: the
    scale does not enter)."""
    st = st or FidelitySettings(exact=True)
    p = form.params(x, st)
    grid = np.arange(w_lo, w_hi + 1e-12, dw)
    df = w_sweep(p, grid, st.integration(), continuation=form.continuation,
                 w_factor=form.w_factor(p))
    return kmax_at_jump(p, df, st)


def compact_record(rec: Mapping[str, Any]) -> dict[str, Any]:
    """The part of a :func:`fit_form` record kept in docs/calibration.json."""
    keep = ("form", "text", "fixed", "continuation", "seed", "budget", "code_version", "wall_s",
            "best", "J", "terms", "measured", "b_star_bisection", "skipped", "searched",
            "best_point", "unfinished", "run")
    out = {k: rec[k] for k in keep if k in rec}
    if "de" in rec:
        out["de"] = {k: rec["de"][k] for k in ("J", "nfev", "nit", "stopped_by_time", "wall_s",
                                               "cpu_s_main") if k in rec["de"]}
    if "start" in rec:
        out["start"] = {"J": rec["start"]["J"], "measured": rec["start"]["measured"]}
    return out


def collect_forms(names: Sequence[str], forms_dir: str | Path, *, adopt: str | None = None,
                  decision: str = "") -> dict[str, Any]:
    """docs/calibration.json's ``forms`` entry from ``<forms_dir>``: each form's record
    (:func:`compact_record`; an unfinished fit: :func:`partial_record`), the run of records
    made before they carried their own (:func:`stream_runs`), the Kmax readings of the adopted
    form (else the first) at the standard shape and at its best set, and the per-target evidence
    of every logged evaluation (:func:`best_per_target`).

    Raises ``KeyError`` naming a form with no record and no logged evaluation."""
    d = Path(forms_dir)
    runs = stream_runs(d)
    recs = {}
    for name in names:
        f = d / f"{name}.json"
        if f.is_file():
            rec = json.loads(f.read_text())
        elif name in FORMS and (part := partial_record(FORMS[name], d / "logs")) is not None:
            rec = part  # the fit did not finish: its evaluations so far, marked unfinished
        else:
            raise KeyError(name)
        if "run" not in rec and name in runs:
            rec["run"] = runs[name]
        recs[name] = compact_record(rec)
    kform = adopt or next(iter(recs))
    best = recs[kform].get("best") or {}
    kmax: dict[str, Any] = {}
    if best and kform in FORMS:
        form = FORMS[kform]
        # the kept standard shape (the search's start) and the form's own best set
        kmax = kmax_for(form, form.start)
        kmax.update(form=kform, x={f.name: f.start for f in form.free},
                    at="standard (the search's start)")
        kb = kmax_for(form, [best[f.name] for f in form.free])
        kmax["best"] = {**kb, "x": best}
    evidence = best_per_target(d / "logs") if (d / "logs").is_dir() else {}
    return {"records": recs, "adopted": adopt, "decision": decision, "kmax_form": kform,
            "kmax": kmax, "evidence": evidence,
            "evidence_lines": evidence_lines(evidence) if evidence else [],
            "known_forms": {n: f.text for n, f in FORMS.items()}}
