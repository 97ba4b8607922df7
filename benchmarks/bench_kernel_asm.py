"""The generated machine code of the batched kernel's vector step: what bounds its speed.

Compiles the kernel in a fresh Numba cache (``inspect_asm`` is disabled for cached code), runs
it once with and without the tangent vector, and counts, in the lane loop of each compiled
``kernel._block_step*`` (one loop iteration = one SIMD vector of lanes):

* instructions, and among them vector arithmetic (FMA, mul, add/sub, div, compares), loads and
  stores of vectors (from the block or the stack), stack spills/reloads, masks and selects;
* the vector width (ymm = 4 doubles, zmm = 8) and the lanes per iteration;
* flops per cell-step (an FMA counts 2), instructions per cell-step.

With a measured vector-only rate (``--rate``, cell-steps/s per core, e.g. from a run with the
flagged-lane redo disabled) it also reports cycles and instructions per cycle at the nominal clock.

Usage: python benchmarks/bench_kernel_asm.py [--rate 7.4e7]
"""

from __future__ import annotations

import argparse
import collections
import os
import re
import sys
import tempfile

os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="gearsim_asm_")

from _common import loadavg, save, setup_env  # noqa: E402

setup_env()

import numpy as np  # noqa: E402

from gearsim.cell import chains  # noqa: E402
from gearsim.cell.simulate import IntegrationSettings  # noqa: E402
from gearsim.dynamics.parameters import ModelParameters  # noqa: E402
from gearsim.numerics import kernel  # noqa: E402

ARITH = ("vfmadd", "vfmsub", "vfnmadd", "vfnmsub", "vmulpd", "vaddpd", "vsubpd", "vdivpd",
         "vmaxpd", "vminpd", "vsqrtpd")


def native_body(asm: str) -> list[str]:
    """Instruction lines of the native (non-wrapper) function of an ``inspect_asm`` text."""
    out, cur = [], None
    for line in asm.splitlines():
        m = re.match(r"^(\S+):$", line)
        if m and not m.group(1).startswith("."):
            cur = m.group(1)
            continue
        if cur and "cpython" not in cur and not cur.startswith("cfunc") and "NRT" not in cur:
            if "_block_step" in cur:
                out.append(line)
    return out


def loop_stats(lines: list[str]) -> list[dict]:
    """Counts in every loop (label ... backward jump) of a function body.

    The lane loop is straight-line code (one basic block) when it vectorised cleanly; a loop
    invariant (``bearings``) unswitched by LLVM gives one loop per case.
    """
    labels = {}
    ins = []
    for line in lines:
        m = re.match(r"^(\.LBB\w+):", line)
        if m:
            labels[m.group(1)] = len(ins)
        elif line.startswith("\t") and not line.strip().startswith("."):
            ins.append(line.strip())
    loops = []
    for i, s in enumerate(ins):
        m = re.match(r"j\w+\s+(\.LBB\w+)", s)
        if m and m.group(1) in labels and labels[m.group(1)] <= i:
            loops.append(ins[labels[m.group(1)] : i + 1])
    out = []
    for body in loops:
        ops = collections.Counter(s.split()[0] for s in body)
        fma = sum(n for o, n in ops.items() if o.startswith(("vfmadd", "vfmsub", "vfnm")))
        arith = sum(n for o, n in ops.items() if o.startswith(ARITH))
        mem = [s for s in body if "(" in s and s.split()[0].startswith("vmov")]
        width = 8 if any("zmm" in s for s in body) else 4 if any("ymm" in s for s in body) else 1
        out.append({
            "instructions": len(body), "function_instructions": len(ins),
            "branches_inside": sum(1 for s in body[:-1] if s.startswith("j")),
            "vector_width": width, "fma": fma, "arith": arith,
            "compares": sum(n for o, n in ops.items() if o.startswith("vcmp")),
            "vector_loads_stores": len(mem),
            "stack_spills_reloads": sum(1 for s in mem if "(%rsp)" in s),
            "masked_or_blend": sum(1 for s in body if "{%k" in s or "blend" in s),
            "calls": sum(1 for s in body if s.startswith("call")),
            # a vector instruction does its operation on every lane; an FMA is 2 flops
            "flops_per_cell_step": 2 * fma + (arith - fma),
            "instructions_per_cell_step": len(body) / width,
        })
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate", type=float, default=0.0,
                    help="measured vector-only cell-steps/s per core (for cycles, IPC)")
    ap.add_argument("--ghz", type=float, default=2.6, help="nominal clock (GHz)")
    args = ap.parse_args(argv)
    st = IntegrationSettings(method="rk4", transient=2, transient_continuation=1, chunk=4,
                             max_periods=8, n_max=2)
    chains.simulate_cells([ModelParameters(w=1.0), ModelParameters(w=1.3, b=0.2)], settings=st)
    out = {}
    fns = [f for f in ("_block_step", "_block_step_state") if hasattr(kernel, f)]
    for name in fns:
        fn = getattr(kernel, name)
        for sig, asm in fn.inspect_asm().items():
            key = f"{name}{tuple(str(t) for t in sig[-2:])}"
            loops = loop_stats(native_body(asm))
            for s in loops:
                if args.rate:
                    cyc = args.ghz * 1e9 / args.rate
                    s["cycles_per_cell_step"] = round(cyc, 1)
                    s["ipc"] = round(s["instructions_per_cell_step"] / cyc, 2)
                print(key, s)
            out[key] = loops
    path = save("kernel_asm", {"functions": out, "load": loadavg(), "numpy": np.__version__})
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
