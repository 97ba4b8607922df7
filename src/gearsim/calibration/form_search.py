"""The forms stage: each form searched by seeded differential evolution of :data:`POPULATION`
members for the same number of generations (:func:`gearsim.calibration.search.search`), scoring
:func:`gearsim.calibration.fidelity.measure` at the coarse level; then the same refinement for
every form: the best ``refine_top`` distinct candidates re-measured with exact (continued)
landmarks, and Nelder-Mead for ``refine_fev`` exact evaluations from the best of them. Each form's
JSON record carries its own run (:class:`gearsim.calibration.fit_record.Run`)."""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from gearsim.calibration.evidence import best_per_target
from gearsim.calibration.fidelity import FidelitySettings, kmax_at_jump
from gearsim.calibration.fit_record import Run
from gearsim.calibration.forms import FINAL, FORMS, Form, final_measure, form_objective
from gearsim.calibration.search import search
from gearsim.calibration.sweeps import w_sweep
from gearsim.calibration.tables import evidence_lines
from gearsim.study.config import Study

POPULATION = 16


def fit_form(form: Form, *, seed: int, generations: int, population: int = POPULATION,
             refine_top: int = 4, refine_fev: int = 16, workers: int = 1,
             coarse: FidelitySettings | None = None,
             exact: FidelitySettings | None = None, final: FidelitySettings | None = None,
             log_dir: str | None = None,
             time_budget: float | None = None, log: Callable[[str], None] = print,
             study: Study | None = None) -> dict[str, Any]:
    """Search, refine and measure one form; a JSON-able record with provenance. ``study``:
    whose standard set is the forms' base (default :meth:`Study.load`)."""
    from gearsim.study.provenance import code_version

    study = study if study is not None else Study.load()
    coarse = (coarse or FidelitySettings()).with_study(study)
    exact = (exact or FidelitySettings(exact=True)).with_study(study)
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
    final = (final or FINAL).with_study(study)
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
                        final: FidelitySettings | None = None, study: Study | None = None
                        ) -> dict[str, Any]:
    """A form measured (the fit's final measurement) at given points without a search, e.g. the
    standard shape and another form's best; the best point's values are the row."""
    from gearsim.study.provenance import code_version

    final = (final or FINAL).with_study(study if study is not None else Study.load())
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
              time_budget: float | None = None, log: Callable[[str], None] = print,
              study: Study | None = None) -> None:
    """``<forms_dir>/<form>.json`` for each form of ``names``: its fit (:func:`fit_form`,
    evaluations logged to ``<forms_dir>/logs``) or, without ``search_forms``, its measurement
    at the standard shape and at the ``single_dof`` form's best of an earlier fit
    (``<forms_dir>/single_dof.json``, if there) (:func:`evaluate_unsearched`)."""
    d = Path(forms_dir)
    d.mkdir(parents=True, exist_ok=True)
    study = study if study is not None else Study.load()
    for name in names:
        form = FORMS[name]
        if not search_forms:
            pts = {"start": form.start}
            tb = d / "single_dof.json"
            if tb.is_file():
                best = json.loads(tb.read_text()).get("best", {})
                pts["single_dof_best"] = [best.get(f.name, f.start) for f in form.free]
            rec = evaluate_unsearched(form, pts, study=study)
            (d / f"{name}.json").write_text(json.dumps(rec, indent=1, default=float))
            log(f"{name}: J = {rec['J']:.4f} at {rec['best_point']} (not searched)")
            continue
        rec = fit_form(form, seed=seed, generations=generations, population=population,
                       refine_fev=refine_fev, workers=workers, log_dir=str(d / "logs"),
                       time_budget=time_budget, log=log, study=study)
        (d / f"{name}.json").write_text(json.dumps(rec, indent=1, default=float))
        log(f"wrote {d / (name + '.json')}")


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
             w_lo: float = 0.3, w_hi: float = 1.0, dw: float = 0.002,
             study: Study | None = None) -> dict[str, Any]:
    """Kmax readings on both sides of the jump of ``form`` at ``x``, the jump resolved on a
    fine forward sweep (``dw``) with the form's sweep method (the readings are ratios: the
    scale does not enter)."""
    st = (st or FidelitySettings(exact=True)).with_study(
        study if study is not None else Study.load())
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
                  decision: str = "", study: Study | None = None) -> dict[str, Any]:
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
        study = study if study is not None else Study.load()
        kmax = kmax_for(form, form.start, study=study)
        kmax.update(form=kform, x={f.name: f.start for f in form.free},
                    at="standard (the search's start)")
        kb = kmax_for(form, [best[f.name] for f in form.free], study=study)
        kmax["best"] = {**kb, "x": best}
    evidence = best_per_target(d / "logs") if (d / "logs").is_dir() else {}
    return {"records": recs, "adopted": adopt, "decision": decision, "kmax_form": kform,
            "kmax": kmax, "evidence": evidence,
            "evidence_lines": evidence_lines(evidence) if evidence else [],
            "known_forms": {n: f.text for n, f in FORMS.items()}}
