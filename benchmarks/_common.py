"""Shared helpers of the benchmarks: machine description, timing with load, JSON results."""

from __future__ import annotations

import json
import os
import platform
import statistics
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def setup_env() -> None:
    root = Path(__file__).resolve().parents[1]
    os.environ.setdefault("NUMBA_CACHE_DIR", str(root / ".numba_cache"))
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")


def loadavg() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def machine() -> dict:
    info = {"python": platform.python_version(), "platform": platform.platform()}
    try:
        lscpu = subprocess.run(["lscpu"], capture_output=True, text=True, check=True).stdout
        for line in lscpu.splitlines():
            k, _, v = line.partition(":")
            if k.strip() in (
                "Model name",
                "CPU(s)",
                "Thread(s) per core",
                "L2 cache",
                "L3 cache",
                "Hypervisor vendor",
            ):
                info[k.strip()] = v.strip()
        flags = next((ln for ln in lscpu.splitlines() if ln.startswith("Flags")), "")
        info["avx2"] = " avx2 " in flags + " "
        info["avx512f"] = " avx512f " in flags + " "
    except (OSError, subprocess.CalledProcessError):
        pass
    try:
        mem = Path("/proc/meminfo").read_text().split("\n")[0]
        info["memory"] = mem.split(":")[1].strip()
    except OSError:
        pass
    import numba
    import numpy

    info["numba"] = numba.__version__
    info["numpy"] = numpy.__version__
    info["llvm_cpu"] = os.environ.get("NUMBA_CPU_NAME", "host")
    return info


def measure(fn: Callable[[], object], repeats: int = 5) -> dict:
    """Run ``fn`` ``repeats`` times: median and min of CPU time and wall time, load before/after."""
    cpu, wall = [], []
    load0 = loadavg()
    for _ in range(repeats):
        c0, w0 = time.process_time(), time.perf_counter()
        fn()
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - w0)
    return {
        "cpu_median_s": statistics.median(cpu),
        "cpu_min_s": min(cpu),
        "wall_median_s": statistics.median(wall),
        "wall_min_s": min(wall),
        "repeats": repeats,
        "load_before": load0,
        "load_after": loadavg(),
    }


def save(name: str, payload: dict) -> Path:
    RESULTS.mkdir(parents=True, exist_ok=True)
    payload = {
        "benchmark": name,
        "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "machine": machine(),
        **payload,
    }
    path = RESULTS / f"{name}.json"
    path.write_text(json.dumps(payload, indent=1, default=float) + "\n")
    return path


def run_json_worker(worker: str, args: list, env: dict) -> dict:
    """Run ``python -c worker args...`` in ``env``; its last printed line is a JSON record."""
    import sys

    res = subprocess.run([sys.executable, "-c", worker, *map(str, args)], env=env, check=True,
                         capture_output=True, text=True)
    return json.loads(res.stdout.strip().splitlines()[-1])
