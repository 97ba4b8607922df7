"""The batched kernel against the core's measured FMA peak, AVX2 and AVX-512 builds in one run.

For each build (``host``: this machine's ISA, e.g. AVX-512 on Zen 4; ``znver3``: the AVX2 code
of an AVX2-only Zen 3, ``NUMBA_CPU_NAME=znver3`` with the host's features but every AVX-512 one
off, ``gearsim.numerics.cache.avx2_features``, which runs here too) a fresh interpreter with
its own empty Numba cache (``inspect_asm`` needs code compiled in the process) measures:

* the peak: a pure-FMA loop of the kernel's own shape (the lane loop over ``batch.LANES``
  consecutive doubles, vectorised the same way), 12 independent FMA chains per lane so that the
  FMA latency is covered; flops/s = 2 x FMAs/s (its vector width is reported: it must be the
  kernel's);
* the kernel: batched RK4 cell-steps/s per core (CPU time) with and without the tangent vector,
  on the cells of ``bench_kernel`` (w in [0.6, 2.4], b in {0.15, 0.3, 1.0}, after a
  100-period transient; event redos included), and the flops of one cell-step counted in the
  compiled block step (:func:`arith_per_cell_step`: an FMA is 2 flops per lane);
* the share of peak = cell-steps/s x flops per cell-step / peak flops/s, and the vector width.

The builds run one after the other, each cold-compiled (its compile time is reported too).

Usage: python benchmarks/bench_peak.py [--quick] [--builds host,znver3]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

from _common import loadavg, machine, run_json_worker, save

from gearsim.numerics.cache import avx2_features

ROOT = Path(__file__).resolve().parents[1]
HERE = Path(__file__).resolve().parent

WORKER = r"""
import json, sys, time
t_import = time.perf_counter()
import numpy as np
from numba import njit
from gearsim.numerics import batch, kernel
from gearsim.numerics.steps import FASTMATH
from bench_kernel import cells, start_states
from bench_kernel_asm import native_body

L = batch.LANES
R = 32  # FMA rounds per block call


# the peak loop's body, straight-line like the kernel's lane loop: 12 independent chains
_src = ["def _fma_block_py(blk, b, c):", "    for q in range(L):"]
_src += [f"        a{i} = blk[q + {i} * L]" for i in range(12)]
_src += [f"        a{i} = a{i} * b + c" for r in range(R) for i in range(12)]
_src += [f"        blk[q + {i} * L] = a{i}" for i in range(12)]
exec("\n".join(_src))
_fma_block = njit(nogil=True, fastmath=FASTMATH)(_fma_block_py)


def arith_per_cell_step(asm_text):
    # flops per cell-step of a compiled block step: every arithmetic instruction's lanes (zmm 8,
    # ymm 4, packed xmm 2, scalar 1) times its flops (an FMA 2), over the lanes one pass of the
    # code handles: LANES when the lane loop is straight-line code, the vector width when it is
    # a loop over the lanes (a backward jump: AVX2, 2 passes of 4 lanes); stack spills/reloads
    # per cell-step alike
    import re
    lines = native_body(asm_text)
    ins = [x.strip() for x in lines if x.startswith("\t") and not x.strip().startswith(".")]
    flops = 0.0
    spills = 0
    widths = set()
    for s in ins:
        op = s.split()[0]
        w = 8 if "zmm" in s else 4 if "ymm" in s else (2 if op.endswith("pd") else 1)
        if "(%rsp)" in s and op.startswith("vmov"):
            spills += 1
        if op.startswith(("vfmadd", "vfmsub", "vfnm")):
            flops += 2 * w
        elif re.match(r"v(mul|add|sub|div|max|min|sqrt)(pd|sd)", op):
            flops += w
        if "zmm" in s or "ymm" in s:
            widths.add(8 if "zmm" in s else 4)
    width = max(widths or {1})
    labels = {}
    for k, x in enumerate(x for x in lines if x.startswith(("\t", "."))):
        m = re.match(r"^(\.LBB\w+):", x)
        if m:
            labels[m.group(1)] = k
    looped = False
    for k, x in enumerate(x for x in lines if x.startswith(("\t", "."))):
        m = re.match(r"\s*j\w+\s+(\.LBB\w+)", x)
        if m and labels.get(m.group(1), k + 1) <= k:
            looped = True
    per = width if looped else L
    return {"flops_per_cell_step": flops / per, "instructions": len(ins),
            "lane_loop": looped, "stack_spills_reloads_per_cell_step": spills / per,
            "vector_width": width}


@njit(nogil=True)
def fma_peak(blk, b, c, n):
    for i in range(n):
        _fma_block(blk, b, c)
    return blk[0]


n, periods, repeats = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
out = {"lanes": L}
blk = np.ones(12 * L)
t0 = time.perf_counter(); c0 = time.process_time()
fma_peak(blk, 0.999999, 1e-6, 1)
cs = cells(n)  # the cells of bench_kernel, after its 100-period transient
y0 = start_states(cs)
lanes = batch.Lanes(n, periods)
N = 256
def setup():
    lanes.ist[:] = 0
    lanes.ist[batch._POS] = 0
    lanes.ist[batch._K] = 100
    for l, p in enumerate(cs):
        lanes.load_params(l, p, N)
        lanes.load_state(l, y0[l])
for tangent in (False, True):
    setup()
    lanes.run(N, 1, 0.0, 1e6, tangent)  # compile
out["compile_wall_s"] = time.perf_counter() - t0
out["compile_cpu_s"] = time.process_time() - c0
# ---- the peak
iters = 200_000
best = 1e9
for _ in range(repeats):
    blk[:] = 1.0
    c0 = time.process_time()
    fma_peak(blk, 0.999999, 1e-6, iters)
    best = min(best, time.process_time() - c0)
out["peak_gflops"] = 2.0 * 12 * R * L * iters / best / 1e9
asm = next(iter(_fma_block.inspect_asm().values()))
out["peak_vector_width"] = 8 if "zmm" in asm else 4 if "ymm" in asm else 2
out["peak_fma_instructions"] = sum(1 for s in asm.splitlines() if s.strip().startswith("vfmadd"))
out["peak_stack_accesses"] = sum(1 for s in asm.splitlines() if "(%rsp)" in s)
# ---- the kernel
for tangent in (False, True):
    cpu = []
    for _ in range(repeats):
        setup()
        c0 = time.process_time()
        lanes.run(N, periods, 0.0, 1e6, tangent)
        cpu.append(time.process_time() - c0)
    rate = n * periods * N / sorted(cpu)[len(cpu) // 2]
    out["tangent" if tangent else "state"] = {"cell_steps_per_s": rate}
for sig, asm in kernel._block_step.inspect_asm().items():
    t, general = (str(x) for x in sig[-2:])
    if "False" in general:  # the base loop
        out["tangent" if "True" in t else "state"].update(arith_per_cell_step(asm))
for kind in ("state", "tangent"):
    o = out[kind]
    o["gflops"] = o["cell_steps_per_s"] * o.get("flops_per_cell_step", float("nan")) / 1e9
    o["share_of_peak"] = o["gflops"] / out["peak_gflops"]
print(json.dumps(out))
"""


def run_build(cpu: str, n: int, periods: int, repeats: int) -> dict:
    with tempfile.TemporaryDirectory(prefix="gearsim_peak_") as cache:
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT / "src"), str(HERE)]),
                   NUMBA_CACHE_DIR=cache, NUMBA_NUM_THREADS="1")
        env.pop("NUMBA_CPU_NAME", None)
        env.pop("NUMBA_CPU_FEATURES", None)
        if cpu != "host":
            env["NUMBA_CPU_NAME"] = cpu
            env["NUMBA_CPU_FEATURES"] = avx2_features()
        return run_json_worker(WORKER, [n, periods, repeats], env)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer periods")
    ap.add_argument("--builds", default="host,znver3", help="NUMBA_CPU_NAME values (host: none)")
    args = ap.parse_args(argv)
    n, periods, repeats = 32, (40 if args.quick else 200), (3 if args.quick else 7)
    builds = {}
    for cpu in args.builds.split(","):
        load0 = loadavg()
        r = run_build(cpu, n, periods, repeats)
        r["load_start"], r["load_end"] = load0, loadavg()
        builds[cpu] = r
        print(f"{cpu:8s} peak width {r['peak_vector_width']}, kernel width "
              f"{r['tangent'].get('vector_width')}: peak {r['peak_gflops']:.1f} GFLOP/s; "
              + "; ".join(f"{k} {r[k]['cell_steps_per_s'] / 1e6:.1f} M cell-steps/s x "
                          f"{r[k].get('flops_per_cell_step', 0):.0f} flops = {r[k]['gflops']:.1f} "
                          f"GFLOP/s ({100 * r[k]['share_of_peak']:.0f} % of peak, "
                          f"{r[k].get('stack_spills_reloads_per_cell_step'):.0f} stack "
                          "accesses per cell-step)"
                          for k in ("state", "tangent"))
              + f"; cold compile {r['compile_cpu_s']:.0f} CPU-s; load {r['load_end']}",
              flush=True)
    path = save("peak", {"machine": machine(), "lanes": n, "periods": periods,
                         "builds": builds})
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
