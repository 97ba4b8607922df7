"""The standard-parameter file (the reconstructed Table 1).

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

from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.safe_yaml import load_yaml

PROVENANCES = ("paper", "ISO formula", "calibrated", "assumed", "derived")


def load_standard_parameters(path: str | Path) -> dict[str, Any]:
    """Dimensionless parameter values from a standard-parameter file, validated by name."""
    doc = load_yaml(path)
    if not isinstance(doc, dict) or not isinstance(doc.get("dimensionless"), dict):
        raise ParameterError(f"{path}: expected a mapping with key 'dimensionless'")
    values: dict[str, Any] = {}
    for name, entry in doc["dimensionless"].items():
        value = entry.get("value") if isinstance(entry, dict) else entry
        values[name] = value
    try:
        ModelParameters.from_mapping(values)  # validates names and ranges
    except ParameterError as exc:
        raise ParameterError(f"{path}: {exc}") from None  # which file holds the bad value
    return values
