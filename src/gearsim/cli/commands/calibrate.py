"""``gearsim calibrate``: fit the free parameters to the paper (the library:
:mod:`gearsim.calibration`).

Stages, each recorded in the output JSON (``--out``) or ``--forms-dir``:

``search``       differential evolution on the single-DOF model over a coarse w grid (the
                 landmark objective of :mod:`gearsim.calibration.calibrate`); every evaluation
                 is logged to ``--log-dir``.
``verify``       the winner (or ``--params``) on the 6-DOF DP5 model on a fine grid, with
                 bisection refinement of each landmark, the backlash threshold that sets ``Fm``
                 and the damping threshold.
``standard``     ``--standard-out`` from ``--out``'s record (:mod:`gearsim.calibration.standard`).
``forms``        each model form fitted with the same search (or, ``--no-search``, measured at
                 given points): ``<forms-dir>/<form>.json``
                 (:mod:`gearsim.calibration.form_search`).
``fit``          each model form fitted by CMA-ES with restarts, every population's sweeps in
                 the batched kernel's lanes, once per ``--seeds``; the best set measured
                 exactly (DP5): ``<forms-dir>/<form>.s<seed>.json``.
``fit-table``    the lane fits' records, the Pareto fronts and the evidence into ``--out``
                 (key ``fit``), the Pareto figure to ``--pareto-figure``.
``coexist``      the Figs 9-11 search: the motions at w x b around (0.82, 0.15) for the form's
                 start and each seed's best of ``--forms-dir`` (key ``coexist_scan`` of --out).
``forms-table``  the forms' records, Kmax readings and evidence into ``--out`` (key ``forms``).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from gearsim.errors import UsageError

NAME = "calibrate"
HELP = "fit Fe/Fm, eps, phi_e, xi, friction to the paper's landmarks (differential evolution)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--stage", choices=("search", "verify", "both", "standard", "forms",
                                        "fit", "fit-table", "coexist", "forms-table"),
                   default="both",
                   help="standard: write --standard-out from --out's result (or MODEL.md's set)")
    p.add_argument("--standard-out", default="config/standard_parameters.yaml",
                   help="standard-parameter file written by --stage standard")
    p.add_argument("--bearing-ratio", type=float, default=100.0,
                   help="bearing stiffness over mesh stiffness K_ij / Km (stage standard)")
    p.add_argument("--bearing-xi", type=float, default=0.03,
                   help="pinion bearing damping ratio (stage standard)")
    p.add_argument("--out", "-o", default="docs/calibration.json", help="result JSON")
    p.add_argument("--log-dir", default="results/calibration", help="per-evaluation logs")
    p.add_argument("--seed", type=int, default=20251122,
                   help="random seed of the differential evolution")
    p.add_argument("--popsize", type=int, default=6,
                   help="differential evolution population size (per parameter)")
    p.add_argument("--maxiter", type=int, default=40,
                   help="differential evolution generations")
    p.add_argument("--workers", type=int, default=1, help="processes for the DE map (<= 2 here)")
    p.add_argument("--time-budget", type=float, default=3000.0,
                   help="seconds for the search (stage fit: per form and seed and per call; a "
                   "seed stopped by it resumes from its checkpoint when run again)")
    p.add_argument("--dw", type=float, default=0.01, help="w step of the search grid")
    p.add_argument("--verify-dw", type=float, default=0.004, help="w step of the verification")
    p.add_argument("--verify-model", choices=("6dof", "1dof"), default="6dof",
                   help="model the verification stage simulates")
    p.add_argument("--params", help="standard-parameter YAML to verify (stage verify)")
    p.add_argument("--box", choices=("wide", "narrow"), default="narrow",
                   help="search bounds (gearsim.calibration.calibrate.BOXES)")
    p.add_argument("--no-start", action="store_true", help="do not seed DE with MODEL.md's set")
    p.add_argument("--forms", default="single_dof,fixed_start",
                   help="stage forms: comma-separated model forms "
                   "(gearsim.calibration.forms.FORMS)")
    p.add_argument("--generations", type=int, default=10,
                   help="stage forms: differential evolution generations (same for every form)")
    p.add_argument("--population", type=int, default=16,
                   help="stage forms: population (Sobol, seeded; same for every form)")
    p.add_argument("--refine-fev", type=int, default=16,
                   help="stage forms: Nelder-Mead evaluations of the exact objective")
    p.add_argument("--forms-dir", default="results/calibration/forms",
                   help="stage forms: one JSON per form and the evaluation logs")
    p.add_argument("--no-search", action="store_true",
                   help="stage forms: measure each form at the standard shape and at the "
                   "'single_dof' form's best (results of a previous search) without searching")
    p.add_argument("--seeds", default="1,2,3", help="stage fit: comma-separated seeds")
    p.add_argument("--max-evals", type=int, default=6000,
                   help="stage fit: most evaluations per form and seed")
    p.add_argument("--min-evals", type=int, default=3000,
                   help="stage fit: fewest evaluations before a flat curve may stop a search")
    p.add_argument("--flat-evals", type=int, default=600,
                   help="stage fit: a search stops when its best J fell by < 1 %% over this many "
                   "evaluations")
    p.add_argument("--no-final", action="store_true",
                   help="stage fit: skip the exact (DP5) measurement of each best set")
    p.add_argument("--pareto-figure", default="docs/calibration_pareto.png",
                   help="stage fit-table: the Pareto figure")
    p.add_argument("--adopt", default=None,
                   help="stage forms-table: the form adopted as the standard set")
    p.add_argument("--decision", default="", help="stage forms-table: why (one paragraph)")


def _search(args) -> dict:
    from gearsim.calibration.calibrate import BOXES, ObjectiveSettings, calibrate

    free = BOXES[args.box]
    x0 = None if args.no_start else [fp.start for fp in free]
    return calibrate(free=free, st=ObjectiveSettings(dw=args.dw), x0=x0, seed=args.seed,
                     popsize=args.popsize, maxiter=args.maxiter, workers=args.workers,
                     log_dir=args.log_dir, time_budget=args.time_budget)


def _form_names(args) -> list[str]:
    return [s.strip() for s in args.forms.split(",") if s.strip()]


def _known_form_names(args) -> list[str]:
    """``--forms``, each a form of :data:`gearsim.calibration.forms.FORMS` (else exit 2)."""
    from gearsim.calibration.forms import FORMS

    names = _form_names(args)
    unknown = [n for n in names if n not in FORMS]
    if unknown:
        raise UsageError(f"--forms: unknown form(s) {', '.join(unknown)}; known: "
                         f"{', '.join(FORMS)}")
    return names


def _forms(args) -> int:
    """Fit each model form with the same search and budget, or measure it unsearched."""
    from gearsim.calibration.form_search import run_forms

    names = _known_form_names(args)
    if args.generations < 0 or args.population < 5 or args.refine_fev < 0:
        raise UsageError("--generations >= 0, --population >= 5, --refine-fev >= 0 required")
    run_forms(names, args.forms_dir, search_forms=not args.no_search, seed=args.seed,
              generations=args.generations, population=args.population,
              refine_fev=args.refine_fev, workers=args.workers, time_budget=args.time_budget,
              log=lambda s: print(s, flush=True))
    return 0


def _fit(args) -> int:
    """CMA-ES of each form in lanes, once per seed."""
    from gearsim.calibration.lane_fit import run_forms_cmaes

    names = _known_form_names(args)
    try:
        seeds = [int(v) for v in args.seeds.split(",") if v.strip()]
    except ValueError:
        raise UsageError(f"--seeds {args.seeds!r}: comma-separated integers expected") from None
    if not seeds or args.max_evals < 1 or args.min_evals < 0 or args.flat_evals < 1:
        raise UsageError("--seeds: at least one; --max-evals >= 1, --min-evals >= 0, "
                         "--flat-evals >= 1 required")
    if args.time_budget <= 0:
        raise UsageError("--time-budget: seconds > 0 per form and seed")
    run_forms_cmaes(names, args.forms_dir, seeds=seeds, max_evals=args.max_evals,
                    min_evals=args.min_evals, flat_evals=args.flat_evals,
                    time_budget=args.time_budget, final=not args.no_final,
                    log=lambda s: print(s, flush=True))
    return 0


def _fit_table(args) -> int:
    """The lane fits' records and the Pareto fronts into --out (key ``fit``), the figure."""
    from gearsim.calibration.lane_fit import collect_fit
    from gearsim.calibration.pareto import pareto_figure

    fit = collect_fit(_form_names(args), args.forms_dir)
    if not fit["forms"]:
        raise UsageError(f"--forms-dir {args.forms_dir}: no <form>.s<seed>.json of --forms "
                         f"{args.forms} (run --stage fit first)")
    out = Path(args.out)
    record = json.loads(out.read_text()) if out.is_file() else {}
    record["fit"] = fit
    out.write_text(json.dumps(record, indent=1, default=float))
    for name, f in fit["forms"].items():
        print(f"{name}: {f['evaluations']} evaluations, {f['n_seeds']} seeds, best J (lanes) "
              f"{', '.join(f'{v:.4f}' for v in f['best_J_lanes'])}, spread {f['spread']:.1%}")
    print(f"wrote {out}, {pareto_figure(Path(args.forms_dir) / 'logs', args.pareto_figure)}")
    return 0


def _coexist(args) -> int:
    """The Figs 9-11 search around the paper's point at each form's start and seeds' bests."""
    import numpy as np

    from gearsim.calibration.fidelity import FidelitySettings, coexist_scan
    from gearsim.calibration.forms import FORMS
    from gearsim.calibration.lane_fit import seed_bests
    from gearsim.study.config import Study

    st = FidelitySettings(lanes=True).with_study(Study.load())
    ws = np.round(np.arange(0.76, 0.8801, 0.02), 4).tolist()
    bs = [0.11, 0.13, 0.15, 0.17, 0.19]
    out = Path(args.out)
    record = json.loads(out.read_text()) if out.is_file() else {}
    scan: dict = {"w": ws, "b": bs, "starts": 64, "forms": {}}
    old = record.get("coexist_scan") or {}
    if all(old.get(k) == scan[k] for k in ("w", "b", "starts")):
        scan["forms"] = dict(old.get("forms") or {})  # the same grid: other forms' scans kept
    for name in _known_form_names(args):
        form = FORMS[name]
        sets = {"start": form.start}
        unfinished = []
        for key, (best, done) in seed_bests(args.forms_dir, name).items():
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
        print(f"{name}: {len(rows)} points, {len(both)} with more than one motion")
    record["coexist_scan"] = scan
    out.write_text(json.dumps(record, indent=1, default=float))
    print(f"wrote {out}")
    return 0


def _forms_table(args) -> int:
    """Collect the per-form records into --out (key ``forms``) and print the table."""
    from gearsim.calibration.form_search import collect_forms
    from gearsim.calibration.tables import form_report_lines

    names = _form_names(args)
    if args.adopt is not None and args.adopt not in names:
        raise UsageError(f"--adopt {args.adopt!r} is not among --forms {', '.join(names)}")
    try:
        forms = collect_forms(names, args.forms_dir, adopt=args.adopt, decision=args.decision)
    except KeyError as exc:
        raise UsageError(f"--forms: no record {Path(args.forms_dir) / (exc.args[0] + '.json')} "
                         f"and no logged evaluation of {exc.args[0]} (run --stage forms first)"
                         ) from None
    out = Path(args.out)
    record = json.loads(out.read_text()) if out.is_file() else {}
    record["forms"] = forms
    out.write_text(json.dumps(record, indent=1, default=float))
    print("\n".join(form_report_lines(forms)))
    print(f"wrote {out}")
    return 0


def run(args: argparse.Namespace) -> int:
    if args.stage == "standard":
        from gearsim.calibration.standard import standard_from_record, write_standard_parameters

        out = Path(args.out)
        record = json.loads(out.read_text()) if out.is_file() else {}
        doc = standard_from_record(record, bearing_ratio=args.bearing_ratio,
                                   bearing_xi=args.bearing_xi)
        write_standard_parameters(args.standard_out, doc)
        print(f"wrote {args.standard_out}")
        return 0
    if args.workers < 1:
        raise UsageError("--workers must be >= 1")
    if args.stage == "forms":
        return _forms(args)
    if args.stage == "fit":
        return _fit(args)
    if args.stage == "fit-table":
        return _fit_table(args)
    if args.stage == "coexist":
        return _coexist(args)
    if args.stage == "forms-table":
        return _forms_table(args)
    out = Path(args.out)
    record: dict = json.loads(out.read_text()) if out.is_file() else {}
    if args.stage in ("search", "both"):
        record["search"] = _search(args)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(record, indent=1, default=float))
        print(f"search: J={record['search']['J']:.4f} nfev={record['search']['nfev']} "
              f"best={record['search']['best']}")
    if args.stage in ("verify", "both"):
        from gearsim.calibration.calibrate import search_params, verify

        if args.params:
            from gearsim.dynamics.parameters import ModelParameters
            from gearsim.study.config_io import load_standard_parameters

            params = ModelParameters.from_mapping(load_standard_parameters(args.params))
        elif "search" in record:
            params = search_params(record["search"]["x"])
        else:
            raise UsageError("stage verify needs --params or a previous search in --out")
        record["verify"] = verify(params, dw=args.verify_dw, model=args.verify_model)
        out.write_text(json.dumps(record, indent=1, default=float))
        print(f"verify: rms={record['verify']['rms_found']:.4f} "
              f"Fm={record['verify']['Fm_from_b_threshold']:.5f} "
              f"xi*={record['verify']['xi_threshold']:.4f}")
    print(f"wrote {out}")
    return 0
