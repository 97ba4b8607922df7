"""Cost of one calibration evaluation before and after the lanes, side by side in one run.

Before: the scalar DP5 measurement (:func:`gearsim.calibration.fidelity.measure`, the search's
coarse level), one candidate after another. After: the same candidates as one population
(:func:`gearsim.calibration.fidelity.measure_many` with ``lanes``: every stage's sweeps the
chains of one batched-kernel call, the study's RK4 settings). CPU seconds (user + sys) per
evaluation, the ratio, and each candidate's J both ways (where they differ, the labels did).

    python benchmarks/bench_calibration_lanes.py [--n 8] [--form single_dof] [--seed 0]

Run after `gearsim compile` (the first kernel calls then load, not compile).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import time

import numpy as np

from gearsim.calibration.fidelity import FidelitySettings, measure, measure_many
from gearsim.calibration.forms import FORMS
from gearsim.calibration.targets import score


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=8, help="candidates (one population)")
    ap.add_argument("--form", default="single_dof")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    form = FORMS[a.form]
    rng = np.random.default_rng(a.seed)
    lo = np.array([f.lower for f in form.free])
    hi = np.array([f.upper for f in form.free])
    x0 = np.asarray(form.start)
    # a population as CMA-ES draws it around the start (sigma 0.1 of the box)
    xs = [x0] + [np.clip(x0 + 0.1 * (hi - lo) * rng.standard_normal(len(x0)), lo, hi)
                 for _ in range(a.n - 1)]
    load0 = os.getloadavg()
    lanes = FidelitySettings(lanes=True)
    dp5 = FidelitySettings()
    measure_many([form.params(x0, lanes)], lanes, continuation=form.continuation)  # warm
    c, w = _cpu(), time.time()
    got = measure_many([form.params(x, lanes) for x in xs], lanes,
                       continuation=form.continuation)
    c_l, w_l = _cpu() - c, time.time() - w
    c, w = _cpu(), time.time()
    ref = [measure(form.params(x, dp5), dp5, continuation=form.continuation) for x in xs]
    c_d, w_d = _cpu() - c, time.time() - w
    out = {"cpu": platform.processor() or platform.machine(), "load_start": load0,
           "load_end": os.getloadavg(), "n": a.n, "form": a.form,
           "dp5_cpu_s_per_eval": c_d / a.n, "lanes_cpu_s_per_eval": c_l / a.n,
           "ratio_cpu": c_d / c_l, "dp5_wall_s_per_eval": w_d / a.n,
           "lanes_wall_s_per_eval": w_l / a.n,
           "J_dp5": [round(score(m)[0], 4) for m in ref],
           "J_lanes": [round(score(m)[0], 4) for m in got],
           "gated_dp5": [m.gated for m in ref], "gated_lanes": [m.gated for m in got]}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
