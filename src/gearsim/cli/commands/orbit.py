"""``gearsim orbit``: a periodic orbit by Newton shooting, its Floquet multipliers and margins."""

from __future__ import annotations

import argparse
import json
import time

from gearsim.analysis.orbits import SEEDING, find_periodic_orbit, shooting_settings
from gearsim.cell.simulate import simulate_cell
from gearsim.cli.commands._common import (
    add_device_argument,
    add_parameter_arguments,
    command_parameters,
    select_device,
)

NAME = "orbit"
HELP = (
    "find a periodic orbit by Newton shooting: section state, Floquet multipliers, stability, "
    "grazing margin"
)


def add_orbit_parameter_arguments(p: argparse.ArgumentParser) -> None:
    """The shared parameter options (:func:`add_parameter_arguments`) and the shooting
    integrator's ``--rtol`` (``orbit``, ``continue``)."""
    add_parameter_arguments(p, integration=False)
    p.add_argument("--rtol", type=float, default=None,
                   help="DP5 relative tolerance of the shooting integrator (default 1e-12)")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--omega", "-w", type=float, default=None,
                   help="dimensionless mesh frequency w (or --set w=W, or --gear with --rpm)")
    p.add_argument("--period", "-n", type=int, default=None,
                   help="period in mesh periods (default: the period simulated from rest)")
    add_orbit_parameter_arguments(p)
    add_device_argument(p)
    p.add_argument("--json", action="store_true", help="print the result as JSON")


def resolve(args: argparse.Namespace):
    """The orbit's parameters (:func:`gearsim.cli.commands._common.command_parameters`)."""
    return command_parameters(args, omega_required=True, w=args.omega)


def run(args: argparse.Namespace) -> int:
    r = resolve(args)
    select_device(args, r.study)  # a device that cannot run is one line; one orbit's lanes: CPU
    params, source = r.params, r.source
    st = shooting_settings(args.rtol)
    t0 = time.perf_counter()
    sim = simulate_cell(params, settings=SEEDING)
    n = args.period if args.period is not None else max(sim.classification.n, 1)
    if args.period is None and sim.classification.n < 1:
        print(f"note: the simulation from rest found no period ({sim.classification.label});"
              " shooting for period 1")
    orbit = find_periodic_orbit(params, n, sim.final_state, st)
    elapsed = time.perf_counter() - t0
    d = orbit.to_dict()
    d.update(parameters_source=source, simulated_label=sim.classification.label,
             elapsed_s=elapsed)
    if args.json:
        print(json.dumps(d, default=float))
        return 0
    print(f"parameters: {source} (model {params.model}), w = {params.w:g}")
    print(f"period-{n} orbit (minimal period {orbit.minimal_period}; simulated from rest: "
          f"{sim.classification.label}), Newton {orbit.iterations} iterations, "
          f"residual {orbit.residual:.2e}")
    print("section state (tau = 0): x = {:.10f}, x' = {:.10f}".format(*orbit.state[:2]))
    print(f"Floquet multipliers (per {n} mesh periods):")
    for m in orbit.multipliers:
        print(f"  {m.real:+.8f} {m.imag:+.8f}i   |mu| = {abs(m):.8f}")
    print(f"{'stable' if orbit.stable else 'UNSTABLE'}: |mu|max = {orbit.mu_max:.8f}, critical "
          f"multiplier kind: {orbit.critical_kind}")
    g = orbit.grazing
    margins = ", ".join(f"{k}: {v:.6g}" for k, v in g.margins.items())
    print(f"grazing margin {g.smallest:.6g} (turning point to boundary, units of b_c; {margins});"
          f" {g.switches} contact switches per orbit")
    print(f"({elapsed * 1e3:.0f} ms including the simulation from rest)")
    return 0
