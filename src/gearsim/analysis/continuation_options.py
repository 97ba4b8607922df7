"""The settings of a one-parameter continuation
(:func:`gearsim.analysis.continuation.continue_orbit`) and of the curves that reuse it
(:mod:`gearsim.analysis.bifcurves`), and the stop reason of a job whose budget is spent."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

from gearsim.analysis.orbits import SHOOTING, SUBSTEPS
from gearsim.numerics.settings import IntegrationSettings


@dataclass
class Continuation:
    """Settings of :func:`~gearsim.analysis.continuation.continue_orbit` (``ds`` in the Euclidean
    norm of ``(y, lam)``)."""

    ds: float = 0.01
    ds_min: float = 1e-5
    ds_max: float = 0.05
    max_points: int = 400
    corrector_tol: float = 1e-10
    corrector_iter: int = 8
    switch_depth: int = 2
    locate_xtol: float = 1e-12
    grazing: bool = True
    #: ``ds``, ``ds_min`` and ``ds_max`` are steps of the parameter at the start: each is
    #: divided by the start tangent's parameter component (so a branch whose state moves
    #: fast with the parameter still crosses a given parameter span in a few points; near a
    #: fold the parameter steps then shrink as the branch turns)
    parameter_steps: bool = False
    substeps: int = SUBSTEPS
    settings: IntegrationSettings = field(default_factory=lambda: SHOOTING)
    progress: Any = None  # optional callable(str): a line every 10 branch points
    #: ``time.monotonic()`` value at which the job's wall-clock budget ends (None: no budget;
    #: a system-wide clock, so worker processes share it). Checked between points: the
    #: computation stops with status ``budget``, keeping what it has.
    deadline: float | None = None

    def out_of_budget(self) -> bool:
        """The job's wall-clock budget is spent."""
        return self.deadline is not None and time.monotonic() >= self.deadline


#: Stop reasons of a continuation or a curve that ran out of its budget start with this.
BUDGET = "budget"
