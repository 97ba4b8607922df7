"""Provenance: canonical JSON, configuration hashes, the code version, package versions.

Every tile, sweep and point set records :func:`provenance` (Parquet key-value metadata, then the
catalogue's ``runs`` table); the Snakemake rules take :func:`plane_subtree` /
:func:`sweep_subtree` and :func:`code_version` as params, so a change to either re-runs exactly
the jobs it affects.
"""

from __future__ import annotations

import copy
import hashlib
import json
import platform
from collections.abc import Mapping
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path
from typing import Any

from gearsim.numerics.settings import TANGENT_SEED
from gearsim.study.config import Study

#: Packages whose versions go into the provenance.
PACKAGES = ("gearsim", "numpy", "numba", "scipy", "pandas", "pyarrow", "dask", "distributed")


def now_iso() -> str:
    """Now, UTC, to the second (ISO 8601): the time stamps of every record."""
    return datetime.now(UTC).isoformat(timespec="seconds")


def canonical_json(obj: Any) -> str:
    """JSON with sorted keys and no spaces (the text that is hashed and given to Snakemake)."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=_plain)


def _plain(obj: Any) -> Any:
    """A read-only mapping (a study's configuration) as a dict, anything else as a float."""
    return dict(obj) if isinstance(obj, Mapping) else float(obj)


def config_hash(obj: Any) -> str:
    """sha256 (16 hex digits) of the canonical JSON of ``obj``."""
    return hashlib.sha256(canonical_json(obj).encode()).hexdigest()[:16]


#: What each kind of job's results depend on: the sources that go into its
#: :func:`code_version`. An entry is a layer (a subpackage of ``src/gearsim``) or a module or
#: package inside one (``analysis/attractors``: ``analysis/attractors.py`` or the package, with
#: the layer's ``__init__.py``); the package root's modules (``errors.py``, ``__init__.py``)
#: count for every scope. Editing a source re-runs exactly the jobs whose scope names it: a
#: presentation or calibration edit re-runs no tile, an orbit-module edit no attractor tile.
SIMULATION = ("dynamics", "physical", "numerics", "cell", "study")
CODE_SCOPES: dict[str, tuple[str, ...]] = {
    "tiles": SIMULATION,
    # the attractor tiles run the finder (its modules and the simulation layers below them)
    "attractors": SIMULATION + ("analysis/attractors",),
    "analysis": SIMULATION + ("analysis",),
    "calibration": SIMULATION + ("analysis", "calibration"),
    "catalogue": SIMULATION + ("analysis", "results"),
    "presentation": SIMULATION + ("analysis", "results", "calibration", "presentation"),
}


def _package_dir() -> Path:
    return Path(__file__).resolve().parents[1]


def git_commit(root: str | Path | None = None, short: bool = False
               ) -> tuple[str | None, bool | None]:
    """``(commit, dirty)`` of the source checkout (``dirty``: uncommitted changes to tracked
    files under ``src``; ``short``: git's abbreviated hash), ``(None, None)`` outside a git
    checkout."""
    import subprocess

    root = Path(root) if root is not None else _package_dir().parents[1]
    if not (root / ".git").exists():
        return None, None
    try:
        head = subprocess.run(
            ["git", "-C", str(root), "rev-parse", *(["--short"] if short else []), "HEAD"],
            capture_output=True,
            text=True,
            timeout=10,
        )
        if head.returncode != 0:
            return None, None
        st = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no", "--", "src"],
            capture_output=True,
            text=True,
            timeout=10,
        )
    except (OSError, subprocess.SubprocessError):
        return None, None
    return head.stdout.strip(), bool(st.stdout.strip()) if st.returncode == 0 else None


def code_files(scope: str = "tiles", package: str | Path | None = None) -> list[Path]:
    """The source files that decide the results of a ``scope`` of :data:`CODE_SCOPES`: every
    ``*.py`` of its layers and of the package root, sorted by relative path."""
    if scope not in CODE_SCOPES:
        raise ValueError(f"code scope {scope!r}: one of {', '.join(CODE_SCOPES)}")
    pkg = Path(package) if package is not None else _package_dir()
    files = list(pkg.glob("*.py"))
    missing = []
    for entry in CODE_SCOPES[scope]:
        if "/" in entry:
            files += [pkg / entry.split("/")[0] / "__init__.py"]
        part = [pkg / f"{entry}.py"] if (pkg / f"{entry}.py").is_file() else []
        if (pkg / entry).is_dir():
            part += (pkg / entry).rglob("*.py")
        files += part
        missing += [] if part else [entry]
    inner = [e for e in CODE_SCOPES[scope] if "/" in e]
    if any("/" not in e for e in missing) or (inner and set(inner) <= set(missing)):
        # a renamed layer, module or package must not drop out of the jobs' code versions
        # (one of a scope's modules may go when another takes over its code)
        raise ValueError(f"code scope {scope!r}: {', '.join(missing)} not in {pkg}")
    rel = lambda f: f.relative_to(pkg).as_posix()  # noqa: E731
    return sorted(set(f for f in files if "__pycache__" not in rel(f)), key=rel)


def code_version(scope: str = "tiles", package: str | Path | None = None) -> str:
    """sha256 (16 hex digits) over the relative path and bytes of every :func:`code_files` file
    of ``scope``.

    ``package`` is the ``gearsim`` package directory (default: this installation); editing,
    adding, removing or renaming a module of one of the scope's layers changes the hash.
    """
    pkg = Path(package) if package is not None else _package_dir()
    h = hashlib.sha256()
    for f in code_files(scope, pkg):
        rel = f.relative_to(pkg).as_posix().encode()
        data = f.read_bytes()
        h.update(len(rel).to_bytes(8, "little") + rel)
        h.update(len(data).to_bytes(8, "little") + data)
    return h.hexdigest()[:16]


def package_versions() -> dict[str, str]:
    """Versions of Python and of :data:`PACKAGES` (``absent`` when not installed)."""
    out = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:  # pragma: no cover
            out[name] = "absent"
    return out


def plane_subtree(study: Study, plane: str) -> dict[str, Any]:
    """What a plane's tiles depend on (the Snakemake params and the hashed provenance)."""
    return {
        "plane": copy.deepcopy(dict(study.config["planes"][plane])),
        "parameters": study.parameters().model.to_dict(),
        "integration": study.settings.to_dict(),
        "tile_rows": int(study.config["tile_rows"]),
    }


def sweep_subtree(study: Study, sweep: str) -> dict[str, Any]:
    """What a sweep depends on (its Snakemake params and hashed provenance)."""
    return {
        "sweep": copy.deepcopy(dict(study.config["sweeps"][sweep])),
        "parameters": study.parameters().model.to_dict(),
        "integration": study.settings.to_dict(),
    }


def point_subtree(study: Study, points: str) -> dict[str, Any]:
    """What a point set depends on (its Snakemake params and hashed provenance)."""
    return {
        "points": copy.deepcopy(study.config["points"][points]),
        "parameters": study.parameters().model.to_dict(),
        "integration": study.settings.to_dict(),
    }


def provenance(
    subtree: Mapping,
    *,
    kind: str,
    name: str,
    study: Study | None = None,
    scope: str = "tiles",
    device: Mapping[str, Any] | None = None,
    **extra: Any,
) -> dict[str, Any]:
    """Provenance record (goes into Parquet key-value metadata and the catalogue's runs).
    ``device``: where the lanes ran (the lanes backend's record; None, the default CPU run,
    adds nothing, so its files are unchanged)."""
    source = study.parameters().source if study is not None else "unknown"
    rec = {
        "kind": kind,
        "name": name,
        "config_hash": config_hash(subtree),
        "code_version": code_version(scope),
        "package_versions": package_versions(),
        "tangent_seed": TANGENT_SEED,
        "parameters_source": source,
        "subtree": subtree,
        "host": platform.node(),
    }
    if device is not None:
        rec["device"] = dict(device)  # where the lanes ran: outside the configuration hash
    rec.update(extra)
    return rec


def plane_record(study: Study, plane: str) -> dict:
    """What a plane's cells.parquet records about the plane: axes, fixed values, parameters,
    configuration hash, code version and integration settings."""
    pl = study.config["planes"][plane]
    return {
        "name": plane,
        "x": dict(pl["x"]),
        "y": dict(pl["y"]),
        "fixed": dict(pl.get("fixed", {})),
        "parameters": study.parameters(plane=plane).model.to_dict(),
        "config_hash": config_hash(plane_subtree(study, plane)),
        "code_version": code_version(),
        "integration": study.settings.to_dict(),
        # the axes in physical units when the study has a gear file (the catalogue's views)
        "physical": _physical_axes(study, (pl["x"]["name"], pl["y"]["name"])),
    }


def _physical_axes(study: Study, names) -> dict[str, dict[str, Any]]:
    from gearsim.physical.units import config_gear, physical_factors

    return physical_factors(config_gear(study.config, study.root), names)
