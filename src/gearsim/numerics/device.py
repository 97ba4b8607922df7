"""Where the lanes run: the CPU (the SIMD kernel) or a CUDA GPU (the CUDA lane kernel).

``execution.device`` in the configuration (:class:`Execution`, the study's execution settings;
``--device`` on the commands that simulate) is ``cpu`` (the default), ``cuda`` or ``auto``.
:func:`resolve` reads it into a :class:`Device`, and :func:`gearsim.numerics.backend.select`
returns the lanes backend that runs there; the caller hands the backend on to whatever makes
lanes. There is no process-wide choice. ``cuda`` on a machine without numba-cuda (``pip install
-e .[gpu]``) or without a GPU is one line naming the setting (:class:`DeviceError`, exit 2);
``auto`` falls back to the CPU and says so (the log, and the ``device`` record of the provenance
of the results it made). This module loads ``numba.cuda`` only when a GPU is asked for: a CPU run
never imports it.
"""

from __future__ import annotations

import functools
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


@dataclass(frozen=True)
class Execution:
    """Where a study's simulating jobs run (the configuration's ``execution`` section): outside
    every settings hash, so a CPU run's files do not change."""

    device: str = "cpu"  # cpu, cuda or auto

    @property
    def uses_gpu(self) -> bool:
        """Whether the simulating jobs hold a GPU (the workflow's ``gpu`` resource)."""
        return self.device != "cpu"


def _probe() -> tuple[str, str, bool, str]:
    """``(name, numba-cuda version, simulated, why not)`` of the first GPU; ``why not`` is
    empty when a GPU (or the simulator) can run the lanes."""
    return _probe_all()[:4]


@functools.cache
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


def resolve(asked: str, setting: str = "execution.device") -> Device:
    """The device of ``asked`` (cpu, cuda or auto; ``setting`` names where it was set in the
    one line of a device that cannot run)."""
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
    return dev
