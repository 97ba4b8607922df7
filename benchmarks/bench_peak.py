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
With ``--rev REV`` the package at that git revision (``git archive``) runs beside this checkout:
for each build, old and new alternate (the order swapped every round) for ``--rounds`` rounds,
the first round cold-compiled (machine code and flops counted), the later ones from that
round's cache; reported per version and build: the median of the rounds' rates and the best.

Usage: python benchmarks/bench_peak.py [--quick] [--builds host,znver3] [--rev REV --rounds 2]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
from pathlib import Path

from _common import loadavg, machine, run_json_worker, save

from gearsim.numerics.cache import avx2_features, host_features

ROOT = Path(__file__).resolve().parents[1]
HERE = Path(__file__).resolve().parent

WORKER = r"""
import json, sys, time
t_import = time.perf_counter()
import numpy as np
from numba import njit
from gearsim.numerics import batch, kernel
from gearsim.numerics.steps import FASTMATH
from bench_kernel import cells, load_lanes, start_states
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


n, periods, repeats, cold = (int(a) for a in sys.argv[1:5])
out = {"lanes": L}
blk = np.ones(12 * L)
t0 = time.perf_counter(); c0 = time.process_time()
fma_peak(blk, 0.999999, 1e-6, 1)
cs = cells(n)  # the cells of bench_kernel, after its 100-period transient
y0 = start_states(cs)
lanes = batch.Lanes(n, periods)
N = 256
def setup():
    load_lanes(lanes, cs, y0, N)
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
for sig, asm in (kernel._block_step.inspect_asm().items() if cold else ()):
    t, general = (str(x) for x in sig[-2:])
    if "False" in general:  # the base loop
        out["tangent" if "True" in t else "state"].update(arith_per_cell_step(asm))
for kind in ("state", "tangent"):
    o = out[kind]
    o["gflops"] = o["cell_steps_per_s"] * o.get("flops_per_cell_step", float("nan")) / 1e9
    o["share_of_peak"] = o["gflops"] / out["peak_gflops"]
print(json.dumps(out))
"""


def run_build(cpu: str, n: int, periods: int, repeats: int, src: Path = ROOT / "src",
              cache: Path | None = None) -> dict:
    """One build of the package at ``src`` in a fresh interpreter; cold unless ``cache`` holds
    that build's kernels already (then no machine code is counted)."""
    with tempfile.TemporaryDirectory(prefix="gearsim_peak_") as tmp:
        cache = cache or Path(tmp)
        cold = not any(cache.rglob("*.nbi"))
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(src), str(HERE)]),
                   NUMBA_CACHE_DIR=str(cache), NUMBA_NUM_THREADS="1")
        env.pop("NUMBA_CPU_NAME", None)
        env.pop("NUMBA_CPU_FEATURES", None)
        if cpu == "host512":
            # the host's ISA with LLVM's 256-bit preference off (an Intel AVX-512 core tunes for
            # ymm; Zen 4 is zmm already)
            env["NUMBA_CPU_FEATURES"] = host_features() + ",-prefer-256-bit"
        elif cpu != "host":
            env["NUMBA_CPU_NAME"] = cpu
            env["NUMBA_CPU_FEATURES"] = avx2_features()
        return run_json_worker(WORKER, [n, periods, repeats, int(cold)], env)


def _line(name: str, r: dict) -> str:
    return (f"{name:12s} peak width {r['peak_vector_width']}, kernel width "
            f"{r['tangent'].get('vector_width')}: peak {r['peak_gflops']:.1f} GFLOP/s; "
            + "; ".join(f"{k} {r[k]['cell_steps_per_s'] / 1e6:.1f} M cell-steps/s x "
                        f"{r[k].get('flops_per_cell_step', 0):.0f} flops = {r[k]['gflops']:.1f} "
                        f"GFLOP/s ({100 * r[k]['share_of_peak']:.0f} % of peak, "
                        f"{r[k].get('stack_spills_reloads_per_cell_step', 0):.0f} stack "
                        "accesses per cell-step)"
                        for k in ("state", "tangent"))
            + f"; compile {r['compile_cpu_s']:.0f} CPU-s; load {r['load_end']}")


def side_by_side(rev: str, builds: list[str], rounds: int, n: int, periods: int,
                 repeats: int) -> dict:
    """Old (``rev``) and new alternating per build; the counted flops of the cold round."""
    from bench_kernel_ab import export

    out: dict = {}
    with tempfile.TemporaryDirectory(prefix="gearsim_peak_ab_") as tmp:
        tmp = Path(tmp)
        srcs = {"old": export(rev, tmp / "old"), "new": ROOT / "src"}
        for cpu in builds:
            runs: dict[str, list[dict]] = {"old": [], "new": []}
            for r in range(rounds):
                for v in (("old", "new") if r % 2 == 0 else ("new", "old")):
                    cache = tmp / f"cache_{v}_{cpu}"
                    cache.mkdir(exist_ok=True)
                    load0 = loadavg()
                    res = run_build(cpu, n, periods, repeats, srcs[v], cache)
                    res["load_start"], res["load_end"] = load0, loadavg()
                    for k in ("state", "tangent"):  # the cold round's machine code
                        for key, val in (runs[v][0] if runs[v] else res)[k].items():
                            res[k].setdefault(key, val)
                        flops = res[k]["flops_per_cell_step"]
                        res[k]["gflops"] = res[k]["cell_steps_per_s"] * flops / 1e9
                        res[k]["share_of_peak"] = res[k]["gflops"] / res["peak_gflops"]
                    runs[v].append(res)
                    print(_line(f"{cpu} {v} r{r}", res), flush=True)
            summ = {}
            for v in ("old", "new"):
                for k in ("state", "tangent"):
                    rates = [x[k]["cell_steps_per_s"] for x in runs[v]]
                    shares = [x[k]["share_of_peak"] for x in runs[v]]
                    summ[f"{v}_{k}"] = {"median_cell_steps_per_s": statistics.median(rates),
                                        "best_cell_steps_per_s": max(rates),
                                        "median_share": statistics.median(shares),
                                        "best_share": max(shares)}
            for k in ("state", "tangent"):
                o, nw = summ[f"old_{k}"], summ[f"new_{k}"]
                print(f"{cpu:7s} {k:7s} old {o['median_cell_steps_per_s'] / 1e6:.1f} M "
                      f"({100 * o['median_share']:.0f} %; best {100 * o['best_share']:.0f} %)"
                      f"  new {nw['median_cell_steps_per_s'] / 1e6:.1f} M "
                      f"({100 * nw['median_share']:.0f} %; best {100 * nw['best_share']:.0f} %)"
                      f"  new/old "
                      f"x{nw['median_cell_steps_per_s'] / o['median_cell_steps_per_s']:.2f}"
                      f" (best x{nw['best_cell_steps_per_s'] / o['best_cell_steps_per_s']:.2f})",
                      flush=True)
            out[cpu] = {"runs": runs, "summary": summ}
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer periods")
    ap.add_argument("--builds", default="host,znver3",
                    help="NUMBA_CPU_NAME values (host: none; host512: the host without LLVM's "
                    "256-bit preference)")
    ap.add_argument("--rev", help="git revision to run beside this checkout (alternating)")
    ap.add_argument("--rounds", type=int, default=2, help="alternating rounds with --rev")
    args = ap.parse_args(argv)
    n, periods, repeats = 32, (40 if args.quick else 200), (3 if args.quick else 7)
    if args.rev:
        res = side_by_side(args.rev, args.builds.split(","), args.rounds, n, periods, repeats)
        print(save("peak_ab", {"machine": machine(), "rev_old": args.rev, "lanes": n,
                               "periods": periods, "builds": res}))
        return 0
    builds = {}
    for cpu in args.builds.split(","):
        load0 = loadavg()
        r = run_build(cpu, n, periods, repeats)
        r["load_start"], r["load_end"] = load0, loadavg()
        builds[cpu] = r
        print(_line(cpu, r), flush=True)
    path = save("peak", {"machine": machine(), "lanes": n, "periods": periods,
                         "builds": builds})
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
