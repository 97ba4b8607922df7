"""(a) Cell-steps per second per core of the 6-DOF kernels.

* scalar ``integrate_periods`` (gearsim.numerics.integrate): fixed-step RK4 (the study's steps per
  period, 192)
and
  adaptive DP5 (rtol 1e-9, atol 1e-12), with and without the tangent vector;
* batched RK4 (gearsim.numerics.kernel.advance) with 8 ... 64 lanes.

Cells: ModelParameters defaults at w in [0.6, 2.4], b in {0.15, 0.3, 1.0} (impacting, some
double-sided, some chaotic), started after a 100-period transient. A cell-step is one accepted
RK4/DP5 step of one cell (fix-up sub-steps and rejected steps are not counted as extra work, they
are included in the time). Throughput uses CPU time (``process_time``: per core, robust to the
other jobs on the machine); wall time and load average are recorded too.

Usage: python benchmarks/bench_kernel.py [--quick]
"""

from __future__ import annotations

import argparse
import sys

from _common import measure, save, setup_env

setup_env()

import numpy as np  # noqa: E402

from gearsim.cell.simulate import IntegrationSettings, initial_tangent, run_periods  # noqa: E402
from gearsim.dynamics.model import static_state  # noqa: E402
from gearsim.dynamics.parameters import ModelParameters  # noqa: E402
from gearsim.numerics import batch, lanes_layout  # noqa: E402
from gearsim.numerics.integrate import METHODS, integrate_periods  # noqa: E402
from gearsim.numerics.steps import phase_tables, rk4_steps_per_period  # noqa: E402


def cells(n: int) -> list[ModelParameters]:
    ws = np.linspace(0.6, 2.4, n)
    return [ModelParameters(w=float(w), b=(0.15, 0.3, 1.0)[i % 3]) for i, w in enumerate(ws)]


def start_states(cs, periods=100):
    st = IntegrationSettings(method="rk4")
    out = []
    for p in cs:
        r = run_periods(p, static_state(p.to_array()), periods, st)
        out.append(np.concatenate([r.state, initial_tangent(p)]))
    return np.array(out)


def load_lanes(lanes, cs, y0, N):
    """Set-up of a timed batched run: counters reset (start at period 100), the cells'
    parameters and start states loaded into ``lanes`` (a ``batch.Lanes``)."""
    lanes.ist[:] = 0
    lanes.ist[lanes_layout.IST_POS] = 0
    lanes.ist[lanes_layout.IST_K] = 100
    for lane, p in enumerate(cs):
        lanes.load_params(lane, p, N)
        lanes.load_state(lane, y0[lane])


def scalar(cs, y0, method, tangent, periods):
    """Steps/s of integrate_periods over the cells one by one."""
    st = IntegrationSettings(method=method)
    m = periods
    steps = [0]

    def run():
        steps[0] = 0
        for p, y in zip(cs, y0, strict=True):
            yy = np.zeros(20)
            yy[:] = y
            sec = np.zeros((m, 10))
            ints = [np.zeros(m, dtype=np.int64) for _ in range(2)]
            fl = [np.zeros(m) for _ in range(6)]
            n_rk = rk4_steps_per_period(p, st)
            out = integrate_periods(
                yy, 100, p.to_array(), METHODS[method], st.rtol, st.atol, st.hmax,
                n_rk, m, 1, tangent, 0.0, sec, *ints, *fl,
                np.zeros((0, 10)), np.zeros(0), np.zeros(0, dtype=np.int64), 1e6,
                *phase_tables(n_rk),
            )  # fmt: skip
            steps[0] += out[4]

    run()
    res = measure(run)
    res["cell_steps"] = steps[0]
    res["cell_steps_per_s_cpu"] = steps[0] / res["cpu_median_s"]
    res["cell_steps_per_s_wall"] = steps[0] / res["wall_median_s"]
    return res


def batched(cs, y0, periods):
    st = IntegrationSettings(method="rk4")
    n = len(cs)
    # the steps the lanes took (the study's steps per period, raised where hmax asks for more)
    taken = [0]

    def run():
        _, _, status, steps = batch.run_periods_batched(
            cs, y0, periods, st, start_periods=[100] * n
        )
        taken[0] = int(steps.sum())

    run()
    res = measure(run)
    res["cell_steps"] = taken[0]
    res["steps_per_period"] = taken[0] / (n * periods)
    res["cell_steps_per_s_cpu"] = taken[0] / res["cpu_median_s"]
    res["cell_steps_per_s_wall"] = taken[0] / res["wall_median_s"]
    return res


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--name", default="kernel")
    args = ap.parse_args(argv)
    periods = 10 if args.quick else 40
    out = {
        "lanes_per_block": batch.LANES,
        "steps_per_period": IntegrationSettings().steps_per_period,
        "periods": periods,
        "scalar": {},
        "batched": {},
    }
    cs = cells(24)
    y0 = start_states(cs)
    for method in ("rk4", "dp5"):
        for tangent in (False, True):
            key = f"{method}_{'tangent' if tangent else 'state'}"
            r = scalar(cs[:12], y0[:12], method, tangent, periods)
            out["scalar"][key] = r
            print(
                f"scalar {key:14s} {r['cell_steps_per_s_cpu'] / 1e6:6.2f} M cell-steps/s (cpu)"
                f"  load {r['load_after']}",
                flush=True,
            )
    for n in (8, 16, 32, 64):
        cs = cells(n)
        y0 = start_states(cs)
        r = batched(cs, y0, periods)
        out["batched"][str(n)] = r
        print(
            f"batched lanes={n:3d}     {r['cell_steps_per_s_cpu'] / 1e6:6.2f} M cell-steps/s (cpu)"
            f"  wall {r['cell_steps_per_s_wall'] / 1e6:6.2f}  load {r['load_after']}",
            flush=True,
        )
    print(save(args.name, out))


if __name__ == "__main__":
    sys.exit(main())
