"""The calibration's stages, one call each (``gearsim calibrate --stage``): what a stage reads,
runs and writes into its record (the JSON of ``out``, one key per stage, or the form records of
``forms_dir``). :func:`run_stage` checks the options a stage uses (one line, exit 2) and runs it.

``search``       differential evolution on the single-DOF model (:mod:`.calibrate`);
``verify``       the winner (or ``params``) on the 6-DOF DP5 model on a fine grid;
``both``         the two above;
``standard``     the standard-parameter file from the record (:mod:`.standard`);
``forms``        each model form fitted with the same search, or measured (:mod:`.form_search`);
``fit``          CMA-ES of each form in lanes, once per seed (:mod:`.lane_fit`);
``fit-table``    the lane fits' records and Pareto fronts into the record, the Pareto figure;
``coexist``      the Figs 9-11 search around (0.82, 0.15) at each form's start and seeds' bests;
``forms-table``  the forms' records, Kmax readings and evidence into the record.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from gearsim.errors import UsageError

STAGES = ("search", "verify", "both", "standard", "forms", "fit", "fit-table", "coexist",
          "forms-table")

Log = Callable[[str], None]


@dataclass(frozen=True)
class StageOptions:
    """The options of every stage (the command's, by name; each stage reads its own)."""

    stage: str = "both"
    out: str = "docs/calibration.json"
    standard_out: str = "config/standard_parameters.yaml"
    bearing_ratio: float = 100.0
    bearing_xi: float = 0.03
    log_dir: str = "results/calibration"
    seed: int = 20251122
    popsize: int = 6
    maxiter: int = 40
    workers: int = 1
    time_budget: float = 3000.0
    dw: float = 0.01
    verify_dw: float = 0.004
    verify_model: str = "6dof"
    params: str | None = None
    box: str = "narrow"
    no_start: bool = False
    forms: str = "single_dof,fixed_start"
    generations: int = 10
    population: int = 16
    refine_fev: int = 16
    forms_dir: str = "results/calibration/forms"
    no_search: bool = False
    seeds: str = "1,2,3"
    max_evals: int = 6000
    min_evals: int = 3000
    flat_evals: int = 600
    no_final: bool = False
    pareto_figure: str = "docs/calibration_pareto.png"
    adopt: str | None = None
    decision: str = ""


def run_stage(o: StageOptions, log: Log = print) -> None:
    """Check ``o`` for its stage and run the stage."""
    if o.stage == "standard":
        _standard(o, log)
        return
    if o.workers < 1:
        raise UsageError("--workers must be >= 1")
    {"forms": _forms, "fit": _fit, "fit-table": _fit_table, "coexist": _coexist,
     "forms-table": _forms_table}.get(o.stage, _search_verify)(o, log)


def read_record(out: str | Path) -> dict:
    """The calibration record of ``out`` (empty when there is none yet)."""
    out = Path(out)
    return json.loads(out.read_text()) if out.is_file() else {}


def write_record(out: str | Path, record: dict) -> None:
    Path(out).write_text(json.dumps(record, indent=1, default=float))


def _update(out: str, key: str, value) -> None:
    record = read_record(out)
    record[key] = value
    write_record(out, record)


def form_names(o: StageOptions) -> list[str]:
    return [s.strip() for s in o.forms.split(",") if s.strip()]


def known_form_names(o: StageOptions) -> list[str]:
    """``forms``, each a form of :data:`gearsim.calibration.forms.FORMS` (else one line)."""
    from gearsim.calibration.forms import FORMS

    names = form_names(o)
    unknown = [n for n in names if n not in FORMS]
    if unknown:
        raise UsageError(f"--forms: unknown form(s) {', '.join(unknown)}; known: "
                         f"{', '.join(FORMS)}")
    return names


def _standard(o: StageOptions, log: Log) -> None:
    from gearsim.calibration.standard import standard_from_record, write_standard_parameters

    doc = standard_from_record(read_record(o.out), bearing_ratio=o.bearing_ratio,
                               bearing_xi=o.bearing_xi)
    write_standard_parameters(o.standard_out, doc)
    log(f"wrote {o.standard_out}")


def _forms(o: StageOptions, log: Log) -> None:
    """Fit each model form with the same search and budget, or measure it unsearched."""
    from gearsim.calibration.form_search import run_forms

    names = known_form_names(o)
    if o.generations < 0 or o.population < 5 or o.refine_fev < 0:
        raise UsageError("--generations >= 0, --population >= 5, --refine-fev >= 0 required")
    run_forms(names, o.forms_dir, search_forms=not o.no_search, seed=o.seed,
              generations=o.generations, population=o.population, refine_fev=o.refine_fev,
              workers=o.workers, time_budget=o.time_budget, log=log)


def _fit(o: StageOptions, log: Log) -> None:
    """CMA-ES of each form in lanes, once per seed."""
    from gearsim.calibration.lane_fit import run_forms_cmaes

    names = known_form_names(o)
    try:
        seeds = [int(v) for v in o.seeds.split(",") if v.strip()]
    except ValueError:
        raise UsageError(f"--seeds {o.seeds!r}: comma-separated integers expected") from None
    if not seeds or o.max_evals < 1 or o.min_evals < 0 or o.flat_evals < 1:
        raise UsageError("--seeds: at least one; --max-evals >= 1, --min-evals >= 0, "
                         "--flat-evals >= 1 required")
    if o.time_budget <= 0:
        raise UsageError("--time-budget: seconds > 0 per form and seed")
    run_forms_cmaes(names, o.forms_dir, seeds=seeds, max_evals=o.max_evals,
                    min_evals=o.min_evals, flat_evals=o.flat_evals, time_budget=o.time_budget,
                    final=not o.no_final, log=log)


def _fit_table(o: StageOptions, log: Log) -> None:
    """The lane fits' records and the Pareto fronts into the record (key ``fit``), the figure."""
    from gearsim.calibration.lane_fit import collect_fit
    from gearsim.calibration.pareto import pareto_figure

    fit = collect_fit(form_names(o), o.forms_dir)
    if not fit["forms"]:
        raise UsageError(f"--forms-dir {o.forms_dir}: no <form>.s<seed>.json of --forms "
                         f"{o.forms} (run --stage fit first)")
    _update(o.out, "fit", fit)
    for name, f in fit["forms"].items():
        log(f"{name}: {f['evaluations']} evaluations, {f['n_seeds']} seeds, best J (lanes) "
            f"{', '.join(f'{v:.4f}' for v in f['best_J_lanes'])}, spread {f['spread']:.1%}")
    log(f"wrote {o.out}, {pareto_figure(Path(o.forms_dir) / 'logs', o.pareto_figure)}")


def _coexist(o: StageOptions, log: Log) -> None:
    """The Figs 9-11 search around the paper's point at each form's start and seeds' bests."""
    import numpy as np

    from gearsim.calibration.fidelity import FidelitySettings, coexist_scan
    from gearsim.calibration.forms import FORMS
    from gearsim.calibration.lane_fit import seed_bests
    from gearsim.study.config import Study

    st = FidelitySettings(lanes=True).with_study(Study.load())
    ws = np.round(np.arange(0.76, 0.8801, 0.02), 4).tolist()
    bs = [0.11, 0.13, 0.15, 0.17, 0.19]
    record = read_record(o.out)
    scan: dict = {"w": ws, "b": bs, "starts": 64, "forms": {}}
    old = record.get("coexist_scan") or {}
    if all(old.get(k) == scan[k] for k in ("w", "b", "starts")):
        scan["forms"] = dict(old.get("forms") or {})  # the same grid: other forms' scans kept
    for name in known_form_names(o):
        form = FORMS[name]
        sets = {"start": form.start}
        unfinished = []
        for key, (best, done) in seed_bests(o.forms_dir, name).items():
            sets[key] = [best[q.name] for q in form.free]
            if not done:
                unfinished.append(key)
        ps = [form.params(x, st) for x in sets.values()]
        rows = coexist_scan(ps, ws, bs, st, continuation=form.continuation,
                            w_factors=[form.w_factor(p) for p in ps])
        keys = list(sets)
        for r in rows:
            r["set"] = keys[r["set"]]
        scan["forms"][name] = {"sets": {k: [float(v) for v in x] for k, x in sets.items()},
                               "unfinished": unfinished, "rows": rows}
        both = [r for r in rows if r.get("motions") and len(r["motions"]) > 1]
        log(f"{name}: {len(rows)} points, {len(both)} with more than one motion")
    record["coexist_scan"] = scan
    write_record(o.out, record)
    log(f"wrote {o.out}")


def _forms_table(o: StageOptions, log: Log) -> None:
    """Collect the per-form records into the record (key ``forms``) and log the table."""
    from gearsim.calibration.form_search import collect_forms
    from gearsim.calibration.tables import form_report_lines

    names = form_names(o)
    if o.adopt is not None and o.adopt not in names:
        raise UsageError(f"--adopt {o.adopt!r} is not among --forms {', '.join(names)}")
    try:
        forms = collect_forms(names, o.forms_dir, adopt=o.adopt, decision=o.decision)
    except KeyError as exc:
        raise UsageError(f"--forms: no record {Path(o.forms_dir) / (exc.args[0] + '.json')} "
                         f"and no logged evaluation of {exc.args[0]} (run --stage forms first)"
                         ) from None
    _update(o.out, "forms", forms)
    log("\n".join(form_report_lines(forms)))
    log(f"wrote {o.out}")


def _search_verify(o: StageOptions, log: Log) -> None:
    """Stages ``search``, ``verify`` and ``both``."""
    from gearsim.calibration.calibrate import BOXES, ObjectiveSettings, calibrate

    out = Path(o.out)
    record = read_record(out)
    if o.stage in ("search", "both"):
        free = BOXES[o.box]
        x0 = None if o.no_start else [fp.start for fp in free]
        record["search"] = calibrate(
            free=free, st=ObjectiveSettings(dw=o.dw), x0=x0, seed=o.seed, popsize=o.popsize,
            maxiter=o.maxiter, workers=o.workers, log_dir=o.log_dir, time_budget=o.time_budget)
        out.parent.mkdir(parents=True, exist_ok=True)
        write_record(out, record)
        log(f"search: J={record['search']['J']:.4f} nfev={record['search']['nfev']} "
            f"best={record['search']['best']}")
    if o.stage in ("verify", "both"):
        from gearsim.calibration.calibrate import search_params, verify

        if o.params:
            from gearsim.dynamics.parameters import ModelParameters
            from gearsim.study.config_io import load_standard_parameters

            params = ModelParameters.from_mapping(load_standard_parameters(o.params))
        elif "search" in record:
            params = search_params(record["search"]["x"])
        else:
            raise UsageError("stage verify needs --params or a previous search in --out")
        record["verify"] = verify(params, dw=o.verify_dw, model=o.verify_model)
        write_record(out, record)
        log(f"verify: rms={record['verify']['rms_found']:.4f} "
            f"Fm={record['verify']['Fm_from_b_threshold']:.5f} "
            f"xi*={record['verify']['xi_threshold']:.4f}")
    log(f"wrote {out}")
