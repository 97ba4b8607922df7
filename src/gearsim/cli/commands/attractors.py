"""``gearsim attractors``: the coexisting attractors of one point with their basin fractions."""

from __future__ import annotations

import argparse
import json
import time

NAME = "attractors"
HELP = (
    "find the coexisting attractors of one point from many seeded starts: pattern, I, DC, Kmax, "
    "Lyapunov exponent and basin fraction of each"
)


def add_multistability_arguments(p: argparse.ArgumentParser) -> None:
    """``--params``, ``--set``, ``--transient``, ``--full`` (shared with ``gearsim basins``)."""
    p.add_argument("--omega", "-w", type=float, required=True,
                   help="dimensionless mesh frequency w")  # fmt: skip
    p.add_argument(
        "--params", metavar="YAML",
        help="standard parameters file (default: config/standard_parameters.yaml of the "
        "repository; the built-in defaults if it is absent)",
    )  # fmt: skip
    p.add_argument("--set", metavar="NAME=VALUE", action="append", default=[],
                   help="override a model parameter (repeatable), e.g. --set b=0.15")
    p.add_argument("--transient", type=int, default=150,
                   help="mesh periods of transient of a start before measuring (default 150)")
    p.add_argument("--full", action="store_true",
                   help="full-length run of every start (no early labelling by recurrence)")


def load_point(args: argparse.Namespace):
    """Parameters and settings of a multistability command: the standard parameters and the
    study's integration settings (RK4, the production path) with ``--transient``."""
    from gearsim.cli.commands._common import orbit_parameters
    from gearsim.dynamics.parameters import ParameterError
    from gearsim.study.config import study_settings

    if args.transient < 0:
        raise ParameterError(f"--transient = {args.transient} must be an integer >= 0")
    params, source = orbit_parameters(args.params, args.set, w=args.omega)
    # the study's settings (config/config.yaml: RK4, 192 steps per period), this transient
    settings = study_settings().with_(method="rk4",
                                                       transient=int(args.transient))
    return params, source, settings


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_multistability_arguments(p)
    p.add_argument("--starts", "-k", type=int, default=64,
                   help="number of seeded space-filling starts (default 64)")
    p.add_argument("--seed", type=int, default=0, help="seed of the Sobol starts (default 0)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")


def run(args: argparse.Namespace) -> int:
    from gearsim.analysis.attractors import find_attractors, summary_lines
    from gearsim.dynamics.parameters import ParameterError

    if args.starts < 1 or args.starts > 1_000_000:
        raise ParameterError(f"--starts = {args.starts} must be in [1, 1000000]")
    params, source, settings = load_point(args)
    t0 = time.perf_counter()
    ca = find_attractors(params, starts=args.starts, seed=args.seed, settings=settings,
                         early=not args.full)  # fmt: skip
    elapsed = time.perf_counter() - t0
    if args.json:
        out = {
            "w": params.w, "parameters_source": source, "starts": args.starts,
            "seed": args.seed, "elapsed_s": elapsed,
            "diverged_fraction": ca.diverged_fraction,
            "labelled_early": int(ca.early.sum()),
            "periods_integrated": int(ca.start_periods_run.sum()),
            "attractors": ca.records(),
        }  # fmt: skip
        print(json.dumps(out, default=float))
        return 0
    print(f"w={params.w:.4f} b={params.b:.4f} xi={params.xi:.4f}; {source}")
    print(f"{args.starts} starts (seed {args.seed}): {len(ca.attractors)} attractor(s), "
          f"{int(ca.early.sum())} starts labelled early by recurrence, "
          f"{int(ca.start_periods_run.sum())} periods integrated ({elapsed:.1f} s)")
    for line in summary_lines(ca):
        print("  " + line)
    return 0
