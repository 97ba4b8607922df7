"""Seeded search per model form: the same space handling, the same budget, then a refinement.

A model form (:class:`Form`) is a set of fixed :class:`~gearsim.dynamics.parameters.ModelParameters`
changes (the form's option keys, e.g. the error path or the damping placement; ``model`` for the
bearing DOFs), optional extra free parameters that only exist in that form, and the sweep method
(continuation, or the paper's fixed start at every w). Every form is searched over the same shared
box (:data:`SHARED_FREE`) plus its extras, from the same start (today's calibrated shape), with
:func:`differential_evolution` (scipy, seeded Sobol initial population of :data:`POPULATION`
members, ``updating='deferred'``, no polish) for the same number of generations, scoring
:func:`gearsim.calibration.fidelity.measure` at the coarse level; then the same refinement: the best
``refine_top`` distinct candidates of the search are re-measured with exact (continued)
landmarks, and Nelder-Mead runs ``refine_fev`` exact evaluations from the best of them.

The search works at a fixed scale (``Fm = 0.1``, ``b = 1``); the form's scale ``Fm`` follows from
the backlash threshold (:func:`gearsim.calibration.fidelity.backlash_from_sweep`).
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gearsim.calibration.calibrate import bisect_bool
from gearsim.calibration.fidelity import LANDMARK_KEYS, FidelitySettings, Measured, measure, score
from gearsim.dynamics.parameters import ModelParameters
from gearsim.study.config import standard_parameters

POPULATION = 16


@dataclass(frozen=True)
class Free:
    """One search coordinate: name (a ModelParameters name or a derived one), bounds, start."""

    name: str
    lower: float
    upper: float
    start: float
    text: str = ""


#: the shared box (every form): a window around the round-1 fit and MODEL.md's feasibility
#: sets (a wider box, Fe/Fm 1.2-2.4, eps 0-0.6, phi -120..60 deg, gave 15 of 17 first Sobol
#: candidates with no usable landmark sequence: at this budget DE could not even leave the start)
SHARED_FREE: tuple[Free, ...] = (
    Free("Fe_over_Fm", 1.4, 2.1, 1.7854, "transmission-error amplitude over mean load"),
    Free("eps", 0.1, 0.55, 0.3175, "mesh-stiffness fluctuation Ka/Km"),
    Free("phi_e_deg", -90.0, 0.0, -41.59, "phase of the error, deg"),
    Free("xi", 0.04, 0.08, 0.0609, "mesh damping ratio"),
    Free("friction", 0.0, 0.03, 0.0, "friction factor gamma"),
)


@dataclass(frozen=True)
class Form:
    """A model form: fixed parameter changes, extra free parameters, sweep method."""

    name: str
    text: str
    fixed: dict[str, Any] = field(default_factory=dict)
    extra: tuple[Free, ...] = ()
    continuation: bool = True
    requires: tuple[str, ...] = ()  # ModelParameters names the form needs (forms' option keys)
    freq_scale: str = "mesh"  # or "coupled": the paper's w is over the coupled mesh mode

    @property
    def free(self) -> tuple[Free, ...]:
        return SHARED_FREE + self.extra

    def available(self) -> bool:
        names = set(ModelParameters.names())
        if self.freq_scale == "coupled":
            from gearsim.dynamics import parameters

            if not hasattr(parameters, "mesh_mode_ratio"):
                return False
        return all(r in names for r in self.requires)

    def w_factor(self, params: ModelParameters) -> float:
        """``r`` of the frequency-scale mapping (1 on the mesh scale)."""
        if self.freq_scale != "coupled":
            return 1.0
        from gearsim.dynamics.parameters import mesh_mode_ratio

        return float(mesh_mode_ratio(params))


def _forms() -> dict[str, Form]:
    f = [
        Form("today", "round-1 form: error as inertial load Fe w^2, damping always on, "
             "rigid bearings (single-DOF), w over sqrt(Km/Me), mean friction arm, continuation "
             "sweep", {"model": "1dof"}),
        Form("fixed_start", "today's equations; the paper's sweep method: every w starts from "
             "the same static state (no continuation)", {"model": "1dof"}, continuation=False),
        Form("bearings_6dof", "today's mesh equations with the 6-DOF bearings as the paper "
             "describes them: pinion and gear masses from the geometry (rho_p 0.4, rho_g 0.1), "
             "bearing stiffness K/Km and radial clearance free, bearing damping 0.03",
             {"model": "6dof"},
             extra=(Free("kappa_ratio", 20.0, 200.0, 100.0, "bearing stiffness K_brg / Km"),
                    Free("b_brg", 0.0, 0.2, 0.0, "bearing half clearance / b_c (search scale)"))),
        Form("te_rate", "transmission error through the stiffness path, K(t) f(x - e) + "
             "C (x' - s e'): the damper follows the fraction s = te_damping of the TE rate (s = 1 "
             "is today's inertial load Fe w^2 exactly, s = 0 the damper on x' alone; mixtures "
             "between)", {"model": "1dof"},
             extra=(Free("te_damping", 0.0, 1.0, 1.0, "fraction of the TE rate the damper sees"),),
             requires=("te_damping",)),
        Form("contact_damping", "mesh damping acting only in contact (none in the backlash)",
             {"model": "1dof", "mesh_damping_contact": 1.0},
             requires=("mesh_damping_contact",)),
        Form("friction_arm", "friction with the time-varying arm L_p of Eq 9 (sawtooth over the "
             "mesh period) instead of its mean; its half range free",
             {"model": "1dof"},
             extra=(Free("friction_arm_var", 0.0, 1.5, 0.5,
                         "a: half range of L_p over its mean (0.38-1.24 from the geometry)"),),
             requires=("friction_arm_var",)),
        Form("coupled_scale", "the 6-DOF bearing form with the paper's w read over the coupled "
             "mesh-mode frequency w_c (bearing compliance in series): simulated at w = r w_paper, "
             "r = w_c / w_n", {"model": "6dof"},
             extra=(Free("kappa_ratio", 20.0, 200.0, 100.0, "bearing stiffness K_brg / Km"),
                    Free("b_brg", 0.0, 0.2, 0.0, "bearing half clearance / b_c (search scale)")),
             freq_scale="coupled"),
    ]
    return {x.name: x for x in f}


FORMS: dict[str, Form] = _forms()


def register(form: Form) -> Form:
    FORMS[form.name] = form
    return form


def params_from_vector(x: Sequence[float], form: Form, *, Fm: float = 0.1, b: float = 1.0,
                       base: ModelParameters | None = None) -> ModelParameters:
    """The search-scale parameters of ``form`` at search vector ``x``."""
    base = base or standard_parameters()
    kw: dict[str, Any] = dict(form.fixed)
    kw.update(Fm=Fm, b=b)
    for fp, v in zip(form.free, x, strict=True):
        v = float(v)
        if fp.name == "Fe_over_Fm":
            kw["Fe"] = v * Fm
        elif fp.name == "phi_e_deg":
            kw["phi_e"] = math.radians(v)
        elif fp.name == "kappa_ratio":  # K_brg / Km, one value for the four directions
            kw.update(kappa_py=v * base.rho_p, kappa_pz=v * base.rho_p,
                      kappa_gy=v * base.rho_g, kappa_gz=v * base.rho_g)
        elif fp.name == "b_brg":
            kw.update(b_py=v, b_pz=v, b_gy=v, b_gz=v)
        else:
            kw[fp.name] = v
    return base.with_(**kw)


class FormObjective:
    """Picklable objective of one form (``workers=`` map); logs every evaluation as JSON."""

    def __init__(self, form: Form, st: FidelitySettings, log_path: str | None = None):
        self.form = form
        self.st = st
        self.log_path = log_path

    def evaluate(self, x: np.ndarray) -> tuple[float, Measured | None, dict[str, float]]:
        try:
            p = params_from_vector(x, self.form, Fm=self.st.Fm, b=self.st.b0)
            m = measure(p, self.st, continuation=self.form.continuation,
                        w_factor=self.form.w_factor(p))
            J, terms = score(m)
            rec = {"x": [float(v) for v in x], "J": J, "terms": terms, "measured": m.to_dict()}
        except Exception as exc:  # noqa: BLE001 - a failed evaluation is a bad point
            J, m, terms = 1e3, None, {}
            rec = {"x": [float(v) for v in x], "J": J, "error": repr(exc)}
        if self.log_path:
            with open(f"{self.log_path}.{os.getpid()}.jsonl", "a") as fh:
                fh.write(json.dumps(rec, default=float) + "\n")
        return J, m, terms

    def __call__(self, x: np.ndarray) -> float:
        return float(self.evaluate(x)[0])


# ============================================================================ the DE harness
def sobol_population(bounds: Sequence[tuple[float, float]], size: int, seed: int,
                     x0: Sequence[float] | None = None) -> np.ndarray:
    """Scrambled-Sobol initial population in ``bounds`` (seeded); row 0 is ``x0`` if given."""
    from scipy.stats import qmc

    d = len(bounds)
    u = qmc.Sobol(d, scramble=True, seed=seed).random(size)
    lo = np.array([b[0] for b in bounds])
    hi = np.array([b[1] for b in bounds])
    pop = lo + u * (hi - lo)
    if x0 is not None:
        pop[0] = np.clip(np.asarray(x0, dtype=float), lo, hi)
    return pop


def run_de(fun: Callable[[np.ndarray], float], bounds: Sequence[tuple[float, float]], *,
           seed: int, generations: int, population: int = POPULATION,
           x0: Sequence[float] | None = None, workers: int = 1,
           time_budget: float | None = None) -> dict[str, Any]:
    """Seeded differential evolution (the harness every form uses). Reproducible: the same
    seed, bounds, population and generations give the same result (``workers`` only changes
    where the evaluations run, ``updating='deferred'`` keeps the order)."""
    from scipy.optimize import differential_evolution

    t0 = time.time()
    c0 = time.process_time()
    history: list[dict[str, Any]] = []
    stopped = {"time": False}

    def cb(intermediate_result):
        history.append({"t": time.time() - t0, "J": float(intermediate_result.fun)})
        if time_budget is not None and time.time() - t0 > time_budget:
            stopped["time"] = True
            return True
        return False

    init = sobol_population(bounds, population, seed, x0)
    res = differential_evolution(fun, bounds, init=init, seed=seed, maxiter=generations,
                                 tol=0.0, atol=0.0, polish=False, updating="deferred",
                                 workers=workers, callback=cb)
    return {"x": [float(v) for v in res.x], "J": float(res.fun), "nfev": int(res.nfev),
            "nit": int(res.nit), "message": str(res.message), "seed": seed,
            "population": population, "generations": generations, "workers": workers,
            "stopped_by_time": stopped["time"], "wall_s": time.time() - t0,
            "cpu_s_main": time.process_time() - c0, "history": history,
            "population_final": [[float(v) for v in r] for r in res.population],
            "population_energies": [float(v) for v in res.population_energies]}


def refine(fun: Callable[[np.ndarray], float], x0: Sequence[float],
           bounds: Sequence[tuple[float, float]], *, maxfev: int, step: float = 0.05
           ) -> dict[str, Any]:
    """Bounded Nelder-Mead from ``x0`` (initial simplex ``step`` of each box width)."""
    from scipy.optimize import minimize

    x0 = np.asarray(x0, dtype=float)
    lo = np.array([b[0] for b in bounds])
    hi = np.array([b[1] for b in bounds])
    d = len(x0)
    simplex = np.repeat(x0[None, :], d + 1, axis=0)
    for k in range(d):
        h = step * (hi[k] - lo[k])
        simplex[k + 1, k] = x0[k] + h if x0[k] + h <= hi[k] else x0[k] - h
    res = minimize(fun, x0, method="Nelder-Mead", bounds=list(zip(lo, hi, strict=True)),
                   options={"maxfev": maxfev, "initial_simplex": simplex, "xatol": 1e-6,
                            "fatol": 1e-6})
    return {"x": [float(v) for v in res.x], "J": float(res.fun), "nfev": int(res.nfev)}


# ============================================================================ one form
#: the backlash bisection grid: the paper's plane grid (400 cell centres on [0.1, 2.5])
B_GRID = 0.1 + (np.arange(400) + 0.5) * 2.4 / 400
#: the reported (final) measurement of a form: exact landmarks, the xi threshold to ~0.001;
#: one definition for :func:`fit_form` and :func:`evaluate_unsearched`
FINAL = FidelitySettings(exact=True, xi_bisect=6, xi_dw=0.02)


def backlash_bisection(p: ModelParameters, st: FidelitySettings, *, continuation: bool = True,
                       tol: float = 0.002, w_factor: float = 1.0) -> float:
    """Smallest ``b`` above which no sweep over :data:`B_GRID` (with the form's sweep method)
    shows a double-sided impact; NaN if the sweep at ``st.b0`` already has one."""
    from gearsim.calibration.fidelity import sweep

    def double(b: float) -> bool:
        df = sweep(p.with_(b=b), B_GRID, st.integration(), continuation=continuation,
                   w_factor=w_factor)
        q = df["q"].fillna(0).astype(int)
        return bool(((df["I"] == 2) | (df["I"] == -1) | (q > 0)).any())

    if double(st.b0):
        return math.nan
    return bisect_bool(double, 0.0, st.b0, tol)


def final_measure(form: Form, x: Sequence[float], st: FidelitySettings
                  ) -> tuple[float, Measured | None, dict[str, float], float]:
    """Reported measurement of ``form`` at ``x``: the scale from a bisection of whole sweeps
    (:func:`backlash_bisection` on :data:`B_GRID`, tol 0.002), then
    :func:`gearsim.calibration.fidelity.measure` with exact landmarks."""
    p = params_from_vector(x, form, Fm=st.Fm, b=st.b0)
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
    bounds = [(f.lower, f.upper) for f in form.free]
    x0 = [f.start for f in form.free]
    log_path = None
    if log_dir:
        Path(log_dir).mkdir(parents=True, exist_ok=True)
        log_path = str(Path(log_dir) / f"{form.name}-coarse")
    obj = FormObjective(form, coarse, log_path)
    t0 = time.time()
    J0, m0, _ = obj.evaluate(np.asarray(x0))
    log(f"[{form.name}] start J (coarse) = {J0:.4f}")
    de = run_de(obj, bounds, seed=seed, generations=generations, population=population,
                x0=x0, workers=workers, time_budget=time_budget)
    log(f"[{form.name}] DE: J = {de['J']:.4f} after {de['nfev']} evaluations, "
        f"{de['wall_s']:.0f} s")
    # refinement: top distinct candidates with exact landmarks, then Nelder-Mead
    pop = np.asarray(de["population_final"])
    en = np.asarray(de["population_energies"])
    order = np.argsort(en)
    cand: list[np.ndarray] = []
    for i in order:
        if not any(np.allclose(pop[i], c) for c in cand):
            cand.append(pop[i])
        if len(cand) >= refine_top:
            break
    exobj = FormObjective(form, exact,
                          None if not log_dir else str(Path(log_dir) / f"{form.name}-exact"))
    scored = [(exobj(c), c) for c in cand]
    Jbest, xbest = min(scored, key=lambda t: t[0])
    nm = refine(exobj, xbest, bounds, maxfev=refine_fev)
    if nm["J"] < Jbest:
        xbest, Jbest = np.asarray(nm["x"]), nm["J"]
    # final measurement: the backlash threshold by bisection of whole sweeps (the scale), the
    # xi threshold to ~0.001, exact landmarks
    final = final or FINAL
    J, m, terms, b_star = final_measure(form, xbest, final)
    J_start, m_start, terms_start, b_star0 = final_measure(form, x0, final)
    names = [f.name for f in form.free]
    rec = {
        "form": form.name, "text": form.text, "fixed": form.fixed,
        "continuation": form.continuation,
        "free": [f.__dict__ for f in form.free], "seed": seed,
        "budget": {"population": population, "generations": generations,
                   "refine_top": refine_top, "refine_fev": refine_fev,
                   "nfev_coarse": de["nfev"] + 1, "nfev_exact": len(scored) + nm["nfev"] + 2},
        "coarse": coarse.to_dict(), "exact": exact.to_dict(), "final": final.to_dict(),
        "b_star_bisection": b_star, "b_star_bisection_start": b_star0,
        "code_version": code_version(), "wall_s": time.time() - t0,
        "de": {k: v for k, v in de.items() if k not in ("population_final",)},
        "refine": nm, "refine_candidates": [[float(s), [float(v) for v in c]] for s, c in scored],
        "best": dict(zip(names, [float(v) for v in xbest], strict=True)),
        "J": J, "terms": terms, "measured": m.to_dict() if m else None,
        "start": {"J": J_start, "terms": terms_start,
                  "measured": m_start.to_dict() if m_start else None},
    }
    log(f"[{form.name}] refined exact J = {J:.4f} (start {J_start:.4f}); "
        f"{time.time() - t0:.0f} s")
    return rec


# ============================================================================ evidence
def best_per_target(log_dir: str | Path) -> dict[str, dict[str, Any]]:
    """For every target: the smallest error any logged evaluation of any form reached, with
    that evaluation's form, level (coarse grid read / exact), J and how many evaluations
    measured the target. Evidence for a miss: no tested form got closer within its search."""
    from gearsim.calibration.fidelity import TARGETS, Measured, target_errors

    tol = {t.key: t.tol for t in TARGETS}
    best: dict[str, dict[str, Any]] = {}
    for f in sorted(Path(log_dir).glob("*.jsonl")):
        form, level = f.name.split(".")[0].rsplit("-", 1)
        for line in f.read_text().splitlines():
            rec = json.loads(line)
            md = rec.get("measured")
            if not md:
                continue
            m = Measured(**{k: v for k, v in md.items() if k in Measured.__dataclass_fields__})
            errs = target_errors(m)
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
    """Per form, from the fit streams' logs (``stream*.log`` in ``forms_dir``, written by the
    lead's fitstream.sh): start and end time, load average at the start, code version, wall
    and user seconds of the process (``/usr/bin/time``)."""
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
    from gearsim.calibration.fidelity import kmax_at_jump, sweep

    st = st or FidelitySettings(exact=True)
    p = params_from_vector(x, form, Fm=st.Fm, b=st.b0)
    grid = np.arange(w_lo, w_hi + 1e-12, dw)
    df = sweep(p, grid, st.integration(), continuation=form.continuation,
               w_factor=form.w_factor(p))
    return kmax_at_jump(p, df, st)


def evidence_lines(best: dict[str, dict[str, Any]]) -> list[str]:
    """Markdown: per target the closest any evaluation came, and what that evaluation's J was
    (a target met only by sets with a large J is a trade-off, not a fit)."""
    from gearsim.calibration.fidelity import SHORT_HEAD, TARGETS

    lines = ["| target | tol | closest error any evaluation reached | form | level | J of that "
             "evaluation | evaluations measuring it | within tol | lowest J within tol "
             "(form, level): landmarks then missing 0.02 |",
             "|---|---|---|---|---|---|---|---|---|"]
    for t in TARGETS:
        b = best.get(t.key)
        if not b or "error" not in b:
            lines.append(f"| {SHORT_HEAD[t.key]} | {t.tol:g} | never measured | | | | 0 | 0 | |")
            continue
        hit = ""
        if b.get("n_hit"):
            miss = b.get("hit_misses") or {}
            ms = ", ".join(f"{SHORT_HEAD[k]} {'miss' if v is None else format(v, '+.3f')}"
                           for k, v in miss.items()) or "none"
            hit = f"{b['hit_J']:.2f} ({b['hit_form']}, {b['hit_level']}): {ms}"
        lines.append(f"| {SHORT_HEAD[t.key]} | {t.tol:g} | {b['error']:+.4g} | {b['form']} | "
                     f"{b['level']} | {b['J']:.2f} | {b['n']} | {b.get('n_hit', 0)} | {hit} |")
    return lines


def evaluate_unsearched(form: Form, points: dict[str, Sequence[float]],
                        final: FidelitySettings | None = None) -> dict[str, Any]:
    """A form measured (the fit's final measurement) at given points without a search, e.g. the
    standard shape and another form's best; the best point's values are the row."""
    from gearsim.study.provenance import code_version

    final = final or FINAL
    rec: dict[str, Any] = {"form": form.name, "text": form.text, "fixed": form.fixed,
                           "continuation": form.continuation, "searched": False,
                           "code_version": code_version(), "final": final.to_dict(),
                           "points": {}}
    t0 = time.time()
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
               wall_s=time.time() - t0)
    return rec
