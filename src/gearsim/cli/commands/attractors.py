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
    """``--omega``, the shared parameter options, ``--device``, ``--transient``, ``--full``
    (shared with ``gearsim basins``)."""
    from gearsim.cli.commands._common import add_device_argument, add_parameter_arguments

    p.add_argument("--omega", "-w", type=float, default=None,
                   help="dimensionless mesh frequency w (or --set w=W, or --gear with --rpm)")
    add_parameter_arguments(p, integration=False)
    add_device_argument(p)
    p.add_argument("--transient", type=int, default=150,
                   help="mesh periods of transient of a start before measuring (default 150)")
    p.add_argument("--full", action="store_true",
                   help="full-length run of every start (no early labels: neither certified "
                        "ellipsoids nor recurrence)")


def resolve(args: argparse.Namespace):
    """The point's parameters (:func:`gearsim.cli.commands._common.command_parameters`)."""
    from gearsim.cli.commands._common import command_parameters

    return command_parameters(args, omega_required=True, w=args.omega)


def load_point(args: argparse.Namespace):
    """Parameters, their source, settings and lanes backend of a multistability command: the
    shared parameter resolution, the study's integration settings (RK4, the production path)
    with ``--transient``, and the starts' device (``--device`` or ``execution.device``)."""
    from gearsim.cli.commands._common import select_device
    from gearsim.dynamics.parameters import ParameterError

    if args.transient < 0:
        raise ParameterError(f"--transient = {args.transient} must be an integer >= 0")
    r = resolve(args)
    # the study's settings (config/config.yaml: RK4, 192 steps per period), this transient
    settings = r.study.settings.with_(method="rk4", transient=int(args.transient))
    return r.params, r.source, settings, select_device(args, r.study)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_multistability_arguments(p)
    p.add_argument("--starts", "-k", type=int, default=64,
                   help="number of seeded space-filling starts (default 64)")
    p.add_argument("--seed", type=int, default=0, help="seed of the Sobol starts (default 0)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")


def run(args: argparse.Namespace) -> int:
    from gearsim.analysis.attractors import FinderOptions, find_attractors, summary_lines
    from gearsim.dynamics.parameters import ParameterError

    if args.starts < 1 or args.starts > 1_000_000:
        raise ParameterError(f"--starts = {args.starts} must be in [1, 1000000]")
    params, source, settings, backend = load_point(args)
    t0 = time.perf_counter()
    options = FinderOptions(starts=args.starts, seed=args.seed, early=not args.full)
    ca = find_attractors(params, options, settings=settings, backend=backend)
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
          f"{int(ca.early.sum())} starts labelled early (certified ellipsoid or recurrence), "
          f"{int(ca.start_periods_run.sum())} periods integrated ({elapsed:.1f} s)")
    for line in summary_lines(ca):
        print("  " + line)
    return 0
