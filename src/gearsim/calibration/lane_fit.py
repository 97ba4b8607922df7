"""The fit stage: CMA-ES with restarts of each form (:func:`gearsim.calibration.search.run_cmaes`),
every population measured in the batched kernel's lanes (:data:`LANES`), the search state written
after every generation; the best set measured exactly (DP5) at the end; the records collected
into docs/calibration.json's ``fit`` entry (:func:`collect_fit`)."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gearsim.calibration.evidence import best_per_target
from gearsim.calibration.fidelity import FidelitySettings, measure_many
from gearsim.calibration.fit_record import Run, utc_now
from gearsim.calibration.forms import FINAL, FORMS, Form, final_measure
from gearsim.calibration.targets import score
from gearsim.study.config import Study


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


def checkpoint_path(log_dir: str | Path, form: str, seed: int) -> Path:
    """``<log_dir>/<form>-lanes.s<seed>.cma.pkl``: the whole search (cma's state included),
    from which an interrupted or budget-stopped fit resumes."""
    return Path(log_dir) / f"{form}-lanes.s{seed}.cma.pkl"


def fit_form_cmaes(form: Form, *, seed: int, log_dir: str | Path, max_evals: int = 3000,
                   min_evals: int = 0, flat_evals: int = 600, time_budget: float | None = None,
                   final: bool = True, log: Callable[[str], None] = print,
                   study: Study | None = None) -> dict[str, Any]:
    """CMA-ES with restarts (:func:`gearsim.calibration.search.run_cmaes`) of one form from its
    start, every population measured in lanes (:data:`LANES`); then, with ``final``, the best
    set and the start measured exactly (DP5, :func:`final_measure`) beside the best set's lane
    measurement. A JSON-able record with its run (wall, CPU, load), the best-J curve and why
    the search stopped. A fit with a checkpoint (:func:`checkpoint_path`) resumes from it:
    its evaluation log is kept (cut to the checkpoint's evaluations) and the search continues
    exactly where it stopped. ``study``: whose standard set and RK4 settings (default
    :meth:`Study.load`)."""
    from gearsim.calibration.search import (
        checkpoint_evaluations,
        compress_log,
        log_lines,
        run_cmaes,
    )

    if not form.available():
        return {"form": form.name, "skipped": f"needs parameters {form.requires}"}
    run = Run()
    Path(log_dir).mkdir(parents=True, exist_ok=True)
    logp = str(Path(log_dir) / f"{form.name}-lanes.s{seed}.jsonl")
    statep = state_path(log_dir, form.name, seed)
    ckp = checkpoint_path(log_dir, form.name, seed)
    gz = Path(logp + ".gz")  # a finished fit's log, compressed
    done = checkpoint_evaluations(ckp)
    if done is None:
        Path(logp).unlink(missing_ok=True)
        gz.unlink(missing_ok=True)
        statep.unlink(missing_ok=True)
    else:
        # the log as far as the checkpoint: a generation cut off after its log line was
        # written and before the checkpoint is evaluated again
        src = Path(logp) if Path(logp).is_file() else gz
        lines = log_lines(src) if src.is_file() else []
        Path(logp).write_text("".join(line + "\n" for line in lines[:done]))
        gz.unlink(missing_ok=True)
        log(f"[{form.name} s{seed}] resuming from {ckp} after {done} evaluations")
    study = study if study is not None else Study.load()
    lanes = LANES.with_study(study)
    batch = FormBatch(form, lanes, logp)
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
                 "updated": utc_now()}
        tmp = statep.with_suffix(".tmp")
        tmp.write_text(json.dumps(state, default=float))
        tmp.replace(statep)
        if info["nfev"] >= every["n"]:
            every["n"] = info["nfev"] + 200
            log(f"[{form.name} s{seed}] {info['nfev']} evaluations, best J {info['best_J']:.4f}, "
                f"{info['t']:.0f} s")

    res = run_cmaes(batch, bounds, seed=seed, x0=form.start, max_evals=max_evals,
                    min_evals=min_evals, flat_evals=flat_evals, time_budget=time_budget,
                    on_generation=gen, checkpoint=ckp)
    rec: dict[str, Any] = {
        "form": form.name, "text": form.text, "fixed": form.fixed,
        "continuation": form.continuation, "free": [asdict(f) for f in form.free],
        "seed": seed, "search": "cma-es, IPOP restarts",
        "lanes": lanes.to_dict(),
        "budget": {"max_evals": max_evals, "min_evals": min_evals, "flat_evals": flat_evals,
                   "time_budget_s": time_budget},
        "nfev": res["nfev"], "stopped_by": res["stopped_by"], "runs": res["runs"],
        "curve": res["curve"], "J_lanes": res["J"],
        "best": dict(zip(names, res["x"], strict=True)),
        "cpu_s_search": res["cpu_s"], "wall_s_search": res["wall_s"],
        "resumed": res["resumed"],
    }
    log(f"[{form.name} s{seed}] search: J (lanes) {res['J']:.4f} after {res['nfev']} "
        f"evaluations ({res['stopped_by']}), {res['wall_s']:.0f} s")
    if final:
        J, m, terms, b = final_measure(form, res["x"], FINAL.with_study(study))
        rec.update(J=J, terms=terms, measured=m.to_dict() if m else None, b_star_bisection=b)
        log(f"[{form.name} s{seed}] exact (DP5) J = {J:.4f}")
    rec["run"] = run.record()
    compress_log(logp)
    return rec


def run_forms_cmaes(names: Sequence[str], forms_dir: str | Path, *, seeds: Sequence[int],
                    max_evals: int, min_evals: int = 0, flat_evals: int = 600,
                    time_budget: float | None = None, final: bool = True,
                    log: Callable[[str], None] = print, study: Study | None = None) -> None:
    """``<forms_dir>/<form>.s<seed>.json`` for each form and seed (:func:`fit_form_cmaes`;
    evaluations logged to ``<forms_dir>/logs``), each written as soon as it is done."""
    d = Path(forms_dir)
    d.mkdir(parents=True, exist_ok=True)
    study = study if study is not None else Study.load()
    for name in names:
        for seed in seeds:
            rec = fit_form_cmaes(FORMS[name], seed=seed, log_dir=d / "logs",
                                 max_evals=max_evals, min_evals=min_evals,
                                 flat_evals=flat_evals, time_budget=time_budget, final=final,
                                 log=log, study=study)
            (d / f"{name}.s{seed}.json").write_text(json.dumps(rec, indent=1, default=float))
            log(f"wrote {d / f'{name}.s{seed}.json'}")


def superseded(rec: dict, forms_dir: Path, name: str) -> bool:
    """Whether a seed's record was resumed past (its state holds more evaluations): the seed is
    then its log and state, unfinished."""
    sp = state_path(forms_dir / "logs", name, int(rec["seed"]))
    return sp.is_file() and json.loads(sp.read_text())["nfev"] > rec["nfev"]


def seed_bests(forms_dir: str | Path, name: str) -> dict[str, tuple[dict, bool]]:
    """``"s<n>" -> (best set, finished)`` of a form's lane fit, with :func:`collect_fit`'s
    rule: a seed's record unless it was resumed past it, else its checkpoint state (a seed
    still running or cut off: its best so far)."""
    d = Path(forms_dir)
    out: dict[str, tuple[dict, bool]] = {}
    for f in sorted(d.glob(f"{name}.s*.json")):
        rec = json.loads(f.read_text())
        if rec.get("best") and not superseded(rec, d, name):
            out[f"s{int(rec['seed'])}"] = (rec["best"], True)
    for f in sorted(d.glob(f"logs/{name}-lanes.s*.state.json")):
        key = f.name.split(".")[1]
        best = json.loads(f.read_text()).get("best")
        if key not in out and best:
            out[key] = (best, False)
    return dict(sorted(out.items()))


def collect_fit(names: Sequence[str], forms_dir: str | Path, study: Study | None = None
                ) -> dict[str, Any]:
    """docs/calibration.json's ``fit`` entry from ``<forms_dir>/<form>.s<seed>.json``: per form
    its seeds' records (evaluations, why each stopped, best J in lanes and exact, the best-J
    curve, wall and CPU seconds, the run), the total evaluations, the seeds' best J and their
    spread ``(max - min) / min`` (a seed with a log but no record: ``unfinished``, its
    evaluations and curve from the log, no CPU time); the Pareto fronts of all logged evaluations
    (:func:`gearsim.calibration.pareto.pareto_record`) and the per-target evidence."""
    from gearsim.calibration.pareto import coexist_tally, pareto_record
    from gearsim.calibration.search import log_files, log_lines

    d = Path(forms_dir)
    out: dict[str, Any] = {}
    for name in names:
        seeds = {}
        for f in sorted(d.glob(f"{name}.s*.json")):
            rec = json.loads(f.read_text())
            if superseded(rec, d, name):
                continue  # resumed past its record and not finished again: its log and state
            seeds[str(rec["seed"])] = {k: rec[k] for k in (
                "seed", "search", "nfev", "stopped_by", "runs", "J_lanes", "J", "terms", "best",
                "measured", "cpu_s_search", "wall_s_search", "run", "budget", "curve")
                if k in rec}
        for f in log_files(d / "logs", f"{name}-lanes.s*"):
            seed = f.name.split(".")[1][1:]
            if seed in seeds:
                continue
            # a search still running or stopped before its record: its logged evaluations,
            # its wall and CPU seconds from its state (none without one: 0, "timed": False)
            Jl = [json.loads(line)["J"] for line in log_lines(f) if line]
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
    study = study if study is not None else Study.load()
    return {"forms": out, "lanes": LANES.with_study(study).to_dict(),
            "pareto": pareto_record(logs) if logs.is_dir() else {},
            "coexist": coexist_tally(logs) if logs.is_dir() else {},
            "evidence": best_per_target(logs) if logs.is_dir() else {}}
