"""``gearsim compile``: warm the Numba cache once, before many workers start."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

NAME = "compile"
HELP = "compile the Numba kernels into NUMBA_CACHE_DIR (run once before workers start)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--stamp", default=None, help="file to write when done (the rule's output)")


def _scalar_kernels() -> None:
    """The scalar integrators (DP5 and RK4) and the dense trajectory."""
    from gearsim.cell.simulate import IntegrationSettings, simulate_cell, trajectory
    from gearsim.dynamics.parameters import ModelParameters

    p = ModelParameters(w=1.0)
    for method in ("dp5", "rk4"):
        st = IntegrationSettings(
            method=method, transient=2, transient_continuation=1, chunk=4, max_periods=8, n_max=2
        )
        simulate_cell(p, settings=st)
        trajectory(p, periods=1, samples_per_period=4, settings=st)


def run(args: argparse.Namespace) -> int:
    import os

    from gearsim.cell.chains import warm_up
    from gearsim.study.provenance import code_version

    t0 = time.perf_counter()
    # one process: the batched kernel's warm-up verifies its cells with the scalar RK4 path and
    # the tangent lanes, so a second process compiling the scalar kernels would compile most of
    # the same functions again (and Numba's per-function cache index is not safe for two
    # processes adding different specialisations at once)
    warm_up()  # the batched RK4 kernel (tiles, sweeps, attractors) and the RK4 verification
    _scalar_kernels()  # DP5, the dense trajectory
    dt = time.perf_counter() - t0
    cache = os.environ.get("NUMBA_CACHE_DIR", "(numba default)")
    msg = f"kernels ready in {dt:.1f} s; NUMBA_CACHE_DIR={cache}; code_version={code_version()}"
    print(msg, file=sys.stderr)
    if args.stamp:
        Path(args.stamp).parent.mkdir(parents=True, exist_ok=True)
        Path(args.stamp).write_text(msg + "\n")
    return 0
