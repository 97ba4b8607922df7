"""Reading the standard-parameter file (the reconstructed Table 1).

Format of ``config/standard_parameters.yaml``::

    dimensionless:
      Fm: {value: 0.1, provenance: calibrated, note: "..."}
      ...
    dimensional:
      module_mm: {value: 4.0, provenance: paper}
      ...

Each entry carries its provenance: ``paper``, ``ISO formula``, ``calibrated`` or ``assumed``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from .parameters import ModelParameters, ParameterError

PROVENANCES = ("paper", "ISO formula", "calibrated", "assumed", "derived")


def load_yaml(path: str | Path) -> Any:
    path = Path(path)
    if not path.is_file():
        raise ParameterError(f"file not found: {path}")
    try:
        return yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        first = str(exc).splitlines()[0] if str(exc) else "syntax error"
        raise ParameterError(f"{path}: not valid YAML ({first})") from None


def load_standard_parameters(path: str | Path) -> dict[str, Any]:
    """Dimensionless parameter values from a standard-parameter file, validated by name."""
    doc = load_yaml(path)
    if not isinstance(doc, dict) or not isinstance(doc.get("dimensionless"), dict):
        raise ParameterError(f"{path}: expected a mapping with key 'dimensionless'")
    values: dict[str, Any] = {}
    for name, entry in doc["dimensionless"].items():
        value = entry.get("value") if isinstance(entry, dict) else entry
        values[name] = value
    ModelParameters.from_mapping(values)  # validates names and ranges
    return values
