"""The numerical settings of a cell simulation (:class:`IntegrationSettings`) and their bounds.

The bound tables are the configuration's too: the schema of the ``integration:`` section is
:meth:`IntegrationSettings.json_schema`, checked against workflow/schemas/config.schema.yaml.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from enum import StrEnum
from typing import Any

from gearsim.dynamics.parameters import ParameterError

# The integration methods' codes, as the kernels read them (gearsim.numerics.steps). Defined
# here, without Numba, so that reading a configuration does not load the compiler.
METHOD_DP5 = 0
METHOD_RK4 = 1
METHODS = {"dp5": METHOD_DP5, "rk4": METHOD_RK4}


class Method(StrEnum):
    """An integration method (the configuration's ``integration.method``): DP5, adaptive, one
    cell at a time; or fixed-step RK4, which runs the batched kernel's lanes. A ``str``: it is
    written and hashed as its name, so a settings record reads as before."""

    DP5 = "dp5"
    RK4 = "rk4"

    @property
    def code(self) -> int:
        """The kernels' code of the method (:data:`METHOD_DP5`, :data:`METHOD_RK4`)."""
        return METHODS[self.value]

    @property
    def lanes(self) -> bool:
        """Whether the method runs in the batched kernel's lanes (fixed-step RK4)."""
        return self is Method.RK4

# DP5 with the tangent vector in the error norm (kernel code only, not a settings method:
# run_periods(..., tangent=True, tangent_error=True), the shooting path of gearsim.analysis.orbits)
METHOD_DP5_TANGENT = 2

#: Fixed seed of a cell's initial tangent vector (gearsim.cell.simulate; recorded in provenance).
TANGENT_SEED = 20251022

#: Shortest useful ``transient_recurrence``: the period test confirms over at least 16 points
#: (``estimate_period``'s ``min_confirm``), so period 1 needs 17 recorded periods.
RECURRENCE_MIN = 17

#: Open intervals of the real settings of :class:`IntegrationSettings`.
REAL_BOUNDS: dict[str, tuple[float, float]] = {
    "rtol": (0, 1),
    "atol": (0, 1),
    "hmax": (0, 100),
    "period_rtol": (0, 1),
    "lyap_threshold": (0, 10),
    "divergence_bound": (0, 1e300),
}
#: Closed intervals of the integer settings: the upper bounds keep a cell's work bounded.
INTEGER_BOUNDS: dict[str, tuple[int, int]] = {
    "steps_per_period": (4, 65_536),
    "transient": (0, 100_000),
    "transient_continuation": (0, 100_000),
    "chunk": (4, 10_000),
    "max_periods": (8, 100_000),
    "n_max": (1, 4096),
    "tangent_lead": (0, 10_000),
    "max_steps": (1000, 1_000_000_000),
    "transient_recurrence": (0, 100_000),
    "settle_check": (0, 10_000),
}


#: ``IntegrationSettings.floquet``, weakest first (docs/model.md, "Settled motions")
FLOQUET_MODES = ("slow", "margin", "all")


@dataclass(frozen=True)
class IntegrationSettings:
    """Numerical settings of a cell simulation (all times in mesh periods unless stated).

    method
        ``"dp5"`` adaptive Dormand-Prince 5(4) or ``"rk4"`` fixed step.
    rtol, atol
        DP5 tolerances (RMS norm over the physical states).
    hmax
        Absolute step cap in dimensionless time (stiff bearing modes at low ``w``).
    steps_per_period
        RK4 steps per mesh period (raised to ``ceil(T / hmax)`` when needed).
    transient
        Periods integrated before measuring, starting from the static state / ``u0``.
    transient_continuation
        Periods of transient when a continuation start ``u0`` is given.
    chunk
        Periods per measuring chunk; the period is tested after each chunk.
    max_periods
        Budget of measured periods.
    n_max, period_rtol
        Largest period looked for, relative tolerance of the period test.
    lyap_threshold
        Lyapunov exponents above it (per unit tau) mean chaos, within +/- it quasi-periodic.
    divergence_bound
        A state component beyond it (or NaN) ends the cell with status ``diverged``.
    max_steps
        Budget of integrator steps per cell: a cell that needs more (e.g. ``w -> 0``, where the
        step cap ``hmax`` makes a period cost ``T / hmax`` steps) ends with status ``budget``
        and the run goes on.
    tangent_lead
        Periods at the end of the transient during which the tangent vector already runs, so
        that it is aligned with the most unstable direction when measuring starts (a fresh
        random vector overestimates the largest exponent by ~log(transient growth) / window).
    transient_recurrence
        0 (off, the default): every transient runs to its end. ``k > 0``: a continued cell
        (start ``u0`` given) first runs a probe of ``k`` periods with the tangent vector on and
        its section points recorded; if they recur (the period test,
        :func:`gearsim.cell.classify.estimate_period`) the start was already on the attractor and
        measuring starts at once, else the cell restarts from ``u0`` without the probe (its
        numbers are then those of the option off, to the bit; the probe's steps are counted).
        ``k`` must be at least ``tangent_lead`` (the tangent vector's alignment) and 17 (the
        period test's shortest window: 16 confirming points); ``k >= transient_continuation``
        means no probe.
    settle_check
        0 (off, the default): every transient runs to its end. ``s > 0``: the transient adapts
        to the measured contraction (:mod:`gearsim.cell.simulate`): the tangent lead is
        recorded and checked every ``s`` periods; the cell ends as soon as the last window has
        a period, is settled (settle distance at most
        :data:`gearsim.cell.verify.REFINE_RTOL`) and repeats throughout. A cell that does not
        settle so runs the whole transient and then measures as with the option off. Not
        together with ``transient_recurrence``.
    floquet
        Which periodic cells get their Floquet margin ``mu_max``
        (:mod:`gearsim.cell.verify`): ``"slow"`` only the cells Newton-refined because they
        settle slowly; ``"margin"`` (the default) also every other periodic cell, from the
        monodromy of its settled orbit; ``"all"`` refines every periodic cell by Newton.
    """

    method: Method = Method.RK4  # given as its name, "dp5" or "rk4"
    rtol: float = 1e-9
    atol: float = 1e-12
    hmax: float = 0.2
    steps_per_period: int = 192
    transient: int = 150
    transient_continuation: int = 40
    chunk: int = 24
    max_periods: int = 256
    n_max: int = 64
    period_rtol: float = 1e-5
    lyap_threshold: float = 0.005
    divergence_bound: float = 1.0e6
    tangent_lead: int = 24
    max_steps: int = 5_000_000
    transient_recurrence: int = 0
    settle_check: int = 0
    floquet: str = "margin"

    def __post_init__(self) -> None:
        if not isinstance(self.method, str) or self.method not in METHODS:
            raise ParameterError(
                f"setting 'method' = {self.method!r}; allowed: {', '.join(METHODS)}"
            )
        object.__setattr__(self, "method", Method(self.method))
        if self.floquet not in FLOQUET_MODES:
            raise ParameterError(
                f"setting 'floquet' = {self.floquet!r}; allowed: {', '.join(FLOQUET_MODES)}"
            )
        for name, (lo, hi) in REAL_BOUNDS.items():
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and lo < v < hi):
                raise ParameterError(f"setting '{name}' = {v!r} must be in ({lo}, {hi})")
        for name, (lo, hi) in INTEGER_BOUNDS.items():
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                raise ParameterError(f"setting '{name}' = {v!r} must be an integer in [{lo}, {hi}]")
        k = self.transient_recurrence
        lo = max(RECURRENCE_MIN, self.tangent_lead)
        if isinstance(k, bool) or not isinstance(k, int) or (k != 0 and not lo <= k <= 100_000):
            raise ParameterError(
                f"setting 'transient_recurrence' = {k!r} must be 0 (off) or an integer in "
                f"[{lo}, 100000] (at least tangent_lead and {RECURRENCE_MIN})"
            )
        if k and self.settle_check:
            raise ParameterError(
                f"settings 'transient_recurrence' = {k} and 'settle_check' = "
                f"{self.settle_check}: at most one of them may be nonzero"
            )

    def with_(self, **changes: Any) -> IntegrationSettings:
        return replace(self, **changes)

    def tightened(self, factor: float = 100.0) -> IntegrationSettings:
        """Settings for convergence checks: ``factor`` times tighter DP5 tolerance, half the RK4
        step and half the step cap (the audit's reference uses ``audit.tighten`` as factor)."""
        return replace(
            self,
            rtol=self.rtol / factor,
            atol=self.atol / factor,
            steps_per_period=self.steps_per_period * 2,
            hmax=self.hmax / 2,
        )

    @classmethod
    def json_schema(cls) -> dict[str, Any]:
        """The JSON-Schema properties of the configuration's ``integration:`` section: types,
        bounds and defaults of these fields (workflow/schemas/config.schema.yaml holds exactly
        this; a test checks it)."""
        out: dict[str, Any] = {}
        defaults = cls()
        for f in fields(cls):
            d = getattr(defaults, f.name)
            if f.name == "method":
                out[f.name] = {"type": "string", "enum": list(METHODS), "default": str(d)}
            elif f.name == "floquet":
                out[f.name] = {"type": "string", "enum": list(FLOQUET_MODES), "default": d}
            elif f.name in INTEGER_BOUNDS:
                lo, hi = INTEGER_BOUNDS[f.name]
                out[f.name] = {"type": "integer", "minimum": lo, "maximum": hi, "default": d}
            else:
                lo, hi = REAL_BOUNDS[f.name]
                s = {"type": "number", "exclusiveMinimum": lo}
                if f.name != "divergence_bound":
                    s["exclusiveMaximum"] = hi
                out[f.name] = {**s, "default": d}
        return out

    def to_dict(self) -> dict[str, Any]:
        """The settings as plain data (the method as its name)."""
        return {**asdict(self), "method": str(self.method)}
