"""What the reproduction report states: the :class:`Report` record and its thresholds.

:mod:`gearsim.presentation.report` fills it from the pipeline outputs;
:mod:`gearsim.presentation.report_markdown` writes it as Markdown.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import pandas as pd


@dataclass
class Threshold:
    """A threshold read off a plane: the last row that still shows the property and the next."""

    name: str
    value: float  # midpoint between last_with and first_without
    last_with: float
    first_without: float
    rows: int
    paper: float
    note: str = ""

    @property
    def difference(self) -> float:
        return self.value - self.paper


@dataclass
class Report:
    """Everything the report states, computed from the pipeline outputs."""

    landmarks: pd.DataFrame | None = None
    matched: pd.DataFrame | None = None
    jump: dict[str, Any] | None = None
    b_threshold: Threshold | None = None
    xi_threshold: Threshold | None = None
    sequences: dict[str, dict[str, Any]] = field(default_factory=dict)
    misses: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    calibration: dict[str, Any] | None = None
    audit: list[dict[str, Any]] = field(default_factory=list)
    compared: int = 0  # comparisons with the paper actually made
    thresholds_na: dict[str, str] = field(default_factory=dict)  # label -> why not applicable
    planes: list[dict[str, Any]] = field(default_factory=list)  # every plane of the study
    hysteresis: list[str] = field(default_factory=list)  # jump-up / jump-down of the fold
    hysteresis_band: tuple[float, float] | None = None
    exact: pd.DataFrame | None = None  # exact landmarks by continuation (docs/orbits.md)
    exact_form: dict | None = None  # provenance subtree of the standard sweep (its model form)
    study: str | None = None  # the config's ``study`` name (a study of one's own)
    sweep_summaries: list[dict[str, Any]] = field(default_factory=list)  # every sweep
    point_summaries: list[dict[str, Any]] = field(default_factory=list)  # every point set
    multistable: list[dict[str, Any]] = field(default_factory=list)  # per plane with attractors
    verified: list[dict[str, Any]] = field(default_factory=list)  # per plane: verified_summary
    curves: list[str] = field(default_factory=list)  # bifurcation curves skipped or cut short
    atlas: list[dict[str, Any]] = field(default_factory=list)  # per plane: gearsim atlas
    paper_material: bool = False  # the study configures a paper sweep or plane

    @property
    def paper_study(self) -> bool:
        """Whether any of the paper's material is in this study (then the scorecard leads)."""
        return self.paper_material or self.compared > 0 or self.matched is not None
