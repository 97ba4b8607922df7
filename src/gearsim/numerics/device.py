"""Where the lanes run: the CPU (the SIMD kernel) or a CUDA GPU (the CUDA lane kernel).

``execution.device`` in the configuration (``--device`` on the commands that simulate) is
``cpu`` (the default), ``cuda`` or ``auto``. :func:`select` resolves it once per process and
every :class:`gearsim.numerics.batch.Lanes` made afterwards runs there. ``cuda`` on a machine
without numba-cuda (``pip install -e .[gpu]``) or without a GPU is one line naming the setting
(:class:`DeviceError`, exit 2); ``auto`` falls back to the CPU and says so (the log, and the
``device`` record of every result's provenance). This module loads ``numba.cuda`` only when a
GPU is asked for: a CPU run never imports it.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import logging
from dataclasses import asdict, dataclass

from gearsim.errors import UsageError

DEVICES = ("cpu", "cuda", "auto")
log = logging.getLogger(__name__)


class DeviceError(UsageError):
    """The device asked for cannot run the lanes (one line naming the device and the setting)."""


@dataclass(frozen=True)
class Device:
    """The device the lanes run on, and how it was chosen."""

    kind: str = "cpu"  # where lanes run: "cpu" or "cuda"
    asked: str = "cpu"  # the setting's value: cpu, cuda or auto
    name: str = ""  # the GPU's name ("" on the CPU)
    numba_cuda: str = ""  # numba-cuda's version where it is installed
    simulated: bool = False  # Numba's CUDA simulator (NUMBA_ENABLE_CUDASIM=1)
    multiprocessors: int = 0  # the GPU's streaming multiprocessors (0 on the CPU)
    note: str = ""  # why ``auto`` stayed on the CPU

    def record(self) -> dict | None:
        """The provenance record: None for the default CPU run (its files stay as they were)."""
        if self.asked == "cpu":
            return None
        return asdict(self)


_current = [Device()]


def current() -> Device:
    """The device chosen by the last :func:`select` (the CPU before any)."""
    return _current[0]


def _probe() -> tuple[str, str, bool, str]:
    """``(name, numba-cuda version, simulated, why not)`` of the first GPU; ``why not`` is
    empty when a GPU (or the simulator) can run the lanes."""
    return _probe_all()[:4]


def _probe_all() -> tuple[str, str, bool, str, int]:
    """:func:`_probe` and the GPU's multiprocessors (1 under the simulator)."""
    if importlib.util.find_spec("numba_cuda") is None:
        return "", "", False, "numba-cuda is not installed (pip install -e '.[gpu]')", 0
    version = importlib.metadata.version("numba-cuda")
    try:
        from numba import cuda

        simulated = bool(cuda.core.config.ENABLE_CUDASIM)
        if not cuda.is_available():
            return "", version, simulated, "no CUDA GPU or driver found", 0
        gpu = cuda.get_current_device()
        name = getattr(gpu, "name", "Numba CUDA simulator")
        sms = int(getattr(gpu, "MULTIPROCESSOR_COUNT", 1))
    except Exception as exc:  # a driver or bindings fault: the GPU cannot be used
        return "", version, False, f"CUDA unavailable ({str(exc).splitlines()[0][:120]})", 0
    name = name.decode() if isinstance(name, bytes) else str(name)
    return name, version, simulated, "", sms


def select(asked: str, setting: str = "execution.device") -> Device:
    """Resolve ``asked`` (cpu, cuda or auto), make it the process's device and return it."""
    if asked not in DEVICES:
        raise DeviceError(f"{setting}: '{asked}' is not one of {', '.join(DEVICES)}")
    dev = Device()
    if asked != "cpu":
        name, version, simulated, why, sms = _probe_all()
        if why and asked == "cuda":
            raise DeviceError(f"{setting}: cuda: {why}; use cpu or auto")
        if why:
            dev = Device(asked="auto", numba_cuda=version, note=f"on the CPU: {why}")
            log.warning("%s: auto: %s", setting, dev.note)
        else:
            dev = Device(kind="cuda", asked=asked, name=name, numba_cuda=version,
                         simulated=simulated, multiprocessors=sms)
            log.info("%s: %s on %s (numba-cuda %s)", setting, asked, name, version)
    _current[0] = dev
    return dev


#: lanes of the finder's probing pool per multiprocessor of a GPU: 8 blocks of 128 threads, half
#: of the 2 048 threads a multiprocessor of compute capability 9.0 keeps resident (the lane
#: kernel's registers and ~1 kB of local memory per thread leave no more; docs/decisions.md)
POOL_LANES_PER_SM = 1024


def pool_lanes(cpu_lanes: int) -> int:
    """The width of the finder's probing pool on the process's device: ``cpu_lanes`` (the
    finder's ``lanes`` option) on the CPU; on a GPU at least its multiprocessors x
    :data:`POOL_LANES_PER_SM` (an H200's 132: 135 168 lanes), so that a launch fills it."""
    dev = current()
    if dev.kind != "cuda":
        return cpu_lanes
    return max(cpu_lanes, dev.multiprocessors * POOL_LANES_PER_SM)
