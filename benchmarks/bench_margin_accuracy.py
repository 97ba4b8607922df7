"""The Floquet margin of the study's RK4 map against the flow's (docs/decisions.md, "Floquet
margin of every cell").

For each cell (``w,b`` pairs of the wb plane, standard parameters, period ``n``): the largest
multiplier moduli of the Newton orbit of the RK4 map at 1x, 2x, 4x and 8x the study's steps
per period, and of DP5 shooting at 1e-12 (``gearsim orbit``'s solver), each from the cell's
settled state.

Usage: python benchmarks/bench_margin_accuracy.py [w:b[:n] ...]
"""

from __future__ import annotations

import sys

import numpy as np
from _common import setup_env

#: periodic wb cells of the default catalogue below w = 0.6 (period 1)
CELLS = ("0.103:0.33875", "0.127:0.20375", "0.151:0.06875", "0.319:0.88625", "0.385:0.86125")


def main(argv: list[str]) -> None:
    setup_env()
    from gearsim.cell.simulate import simulate_cell
    from gearsim.numerics.batch import steps_per_period
    from gearsim.numerics.shooting import SHOOTING, newton_orbit, sorted_eigs
    from gearsim.study.config import Study

    st = Study.load().settings
    for spec in argv or CELLS:
        parts = spec.split(":")
        w, b = float(parts[0]), float(parts[1])
        n = int(parts[2]) if len(parts) > 2 else 1
        p = Study.load().parameters(w=w, b=b).model
        y = simulate_cell(p, settings=st).final_state
        row = [f"w={w:g} b={b:g} n={n} N={steps_per_period(p, st)}"]
        for k in (1, 2, 4, 8):
            s = st.with_(steps_per_period=k * st.steps_per_period)
            M = newton_orbit(p, n, y, s, tol=1e-11, max_iter=8)[2]
            row.append(f"{k}x {np.abs(sorted_eigs(M))[0]:.7f}")
        M = newton_orbit(p, n, y, SHOOTING, tol=1e-11, max_iter=8)[2]
        row.append(f"DP5 {np.abs(sorted_eigs(M))[0]:.7f}")
        print("  ".join(row), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
