"""``gearsim calibrate``: fit the free parameters to the paper, one stage a call. The stages and
what each writes: :mod:`gearsim.calibration.stages` (the library: :mod:`gearsim.calibration`).
"""

from __future__ import annotations

import argparse
from dataclasses import fields

from gearsim.calibration.stages import STAGES, StageOptions, run_stage

NAME = "calibrate"
HELP = "fit Fe/Fm, eps, phi_e, xi, friction to the paper's landmarks (differential evolution)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--stage", choices=STAGES, default="both",
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


def run(args: argparse.Namespace) -> int:
    options = StageOptions(**{f.name: getattr(args, f.name) for f in fields(StageOptions)})
    run_stage(options, log=lambda line: print(line, flush=True))
    return 0
