"""Reproducer: scalar integrate_periods (RK4) stalls at a large absolute time.

Found by the default-configuration run (batched tiles, audit with the scalar path): the audit of
plane wb cell (i=285, j=6) never finished. One mesh period of RK4 (512 steps, hmax 0.1: the
``tightened()`` settings) from the left neighbour's final state at start_period 19518
(tau = 6.8e4, ulp(tau) = 1.5e-11) does not return; the same state at start_period 0 takes
0.3 s, DP5 at 19518 0.3 s, and the batched kernel (time relative to the period start) 0.3 s.

Likely cause: ``t`` is absolute in the RK4 grid/event loop; a switch located a few 1e-12 after
``t`` lands with ``t + th == t`` (no progress) while the region flips, so the loop chatters.
Proposed fix (integrate.py): keep the loop time relative to the period start
(``t_rel`` in [0, T]: grid points ``j * h_rk``, switch landings ``t_rel + th``) and pass
``t_start + t_rel`` (or better the phase) only to ``rhs``; gearsim.batch does this.

Run: timeout 60 python benchmarks/proposed/rk4_large_time_stall.py
"""

import time

import numpy as np

from gearsim import batch
from gearsim.parameters import ModelParameters
from gearsim.simulate import IntegrationSettings, run_periods

p = ModelParameters(
    w=1.813, b=0.01625, rho_p=0.4, rho_g=0.1, kappa_py=40.0, kappa_pz=40.0, kappa_gy=10.0,
    kappa_gz=10.0, xi_gy=0.0075, xi_gz=0.0075,
)  # fmt: skip
u0 = np.array([
    -0.4549628796441339, 1.172058567753086, 0.004264165539223804, -0.027711671070399988,
    0.0015520293302666245, -0.010086223411437, -0.006157172126949306, 0.04117271081464423,
    -0.002241027381470986, 0.014985641200633485,
])  # fmt: skip
K = 19518
tight = IntegrationSettings(method="rk4").tightened()

t = time.process_time()
r = batch.simulate_cells([p], settings=tight, u0=[u0], start_periods=[K])[0]
print(f"batched, start period {K}: {r.classification.label}, {time.process_time() - t:.2f} s")
t = time.process_time()
run_periods(p, u0, 1, tight, start_period=0)
print(f"scalar RK4, 1 period from start period 0: {time.process_time() - t:.2f} s")
t = time.process_time()
run_periods(p, u0, 1, tight.with_(method="dp5"), start_period=K)
print(f"scalar DP5, 1 period from start period {K}: {time.process_time() - t:.2f} s")
print(f"scalar RK4, 1 period from start period {K}: ... (does not return)", flush=True)
run_periods(p, u0, 1, tight, start_period=K)
print("returned")
