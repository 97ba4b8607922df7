"""Keep Numba's on-disk cache consistent with the one source of the numerics.

Numba checks only the source file of a cached function: ``kernel.advance`` inlines the field of
``model.py``, the steps of ``steps.py`` and the event layer of ``events.py``, so after an edit of
one of those files its cached machine code would still hold the old equations. Before any kernel
is compiled or loaded, the cache entries of this package are dropped whenever the hash of the
numerics modules differs from the one stamped in the cache directory.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

#: Subpackages (relative to ``src/gearsim``) whose compiled code is inlined into kernels of other
#: modules: the equations and the numerics. Every ``.py`` file below them is hashed.
NUMERICS = ("dynamics", "numerics", "cell")


def cache_directory(package_dir: Path) -> Path:
    """Where Numba caches this package's kernels (its ``_UserProvidedCacheLocator`` rule)."""
    root = os.environ.get("NUMBA_CACHE_DIR", "")
    if not root:
        return package_dir / "__pycache__"
    digest = hashlib.sha1(str(package_dir).encode()).hexdigest()
    return Path(root) / f"{package_dir.name}_{digest}"


def invalidate_stale_cache() -> None:
    """Drop this package's cached kernels when the numerics sources changed since they were made."""
    package = Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for sub in NUMERICS:
        for f in sorted((package / sub).rglob("*.py")):
            h.update(f.relative_to(package).as_posix().encode())
            h.update(f.read_bytes())
    stamp_value = h.hexdigest()[:20]
    for sub in NUMERICS:
        _refresh(cache_directory(package / sub), stamp_value)


def _refresh(cache: Path, stamp_value: str) -> None:
    """Drop the cached kernels in ``cache`` unless its stamp is ``stamp_value``; stamp it."""
    stamp = cache / "gearsim-numerics.stamp"
    try:
        if stamp.read_text() == stamp_value:
            return
    except OSError:
        pass
    try:
        for f in list(cache.glob("*.nbi")) + list(cache.glob("*.nbc")):
            f.unlink(missing_ok=True)
        cache.mkdir(parents=True, exist_ok=True)
        tmp = stamp.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(stamp_value)
        os.replace(tmp, stamp)
    except OSError:
        pass  # a read-only cache: Numba then compiles in memory


def host_features() -> str:
    """This host's LLVM CPU features (the string ``NUMBA_CPU_FEATURES`` takes)."""
    from llvmlite import binding as ll

    return ll.get_host_cpu_features().flatten()


def avx2_features() -> str:
    """This host's LLVM CPU features with every AVX-512 feature off: ``NUMBA_CPU_FEATURES`` for
    building the AVX2 code of an AVX2-only CPU on an AVX-512 machine.

    ``NUMBA_CPU_NAME`` alone does not change the instruction set: Numba's JIT takes the host's
    features unless ``NUMBA_CPU_FEATURES`` is set (``NUMBA_CPU_NAME=znver3`` on a Zen 4 still
    emits zmm code)."""
    feats = host_features().split(",")
    return ",".join("-" + f[1:] if f[1:].startswith("avx512") else f for f in feats if f)
