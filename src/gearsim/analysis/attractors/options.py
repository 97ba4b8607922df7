"""The finder's one set of options (every mapper of the package reads it)."""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

from gearsim.dynamics.parameters import ParameterError

#: the recurrence's own period test: a start's last points repeat after n periods within
#: 1e-4 of the orbit's range (the classifier's test is 1e-5; docs/decisions.md)
RECUR_PERIOD_RTOL = 1e-4

#: lanes of the probing pool (a kernel call of 8 periods over 256 lanes is ~10 ms: the Python
#: bookkeeping per chunk stays a small share; docs/decisions.md)
POOL_LANES = 256

_POSITIVE_INTS = ("starts", "chunk", "confirm", "confirm_cloud", "rescout", "grid", "lanes",
                  "certify_tries")


@dataclass(frozen=True)
class FinderOptions:
    """How the attractors of a cell are found (docs/multistability.md).

    ``starts`` seeded Sobol starts per cell (``seed``); ``early``: label a start early by
    recurrence onto a known attractor (False: every start its full-length run). Recurrence:
    every ``chunk`` periods a start's last ``max(2 n, confirm)`` points follow a period-``n``
    attractor's in phase order within ``recur_rtol`` of its range and repeat after ``n``
    periods within ``recur_period_rtol``; ``early_clouds`` also labels onto chaotic and
    quasi-periodic clouds (the last ``confirm_cloud`` points in the cloud's ``grid``
    occupancy). Merging: periodic points within ``merge_rtol`` of the range, clouds sharing
    ``cloud_overlap`` of their occupancy; a period-n and a period-2n motion within
    ``doubling_rtol`` sit at a doubling (no early label onto either). ``period_rtol``: the
    classifier's period test (None: the integration settings'). Scheduling: a start goes on
    alone past ``rescout`` probed periods without a label (its cell's *runner*); ``scouts``
    starts per cell run full first (the recurrence mapper); ``lanes`` of the probing pool.
    ``certified``: label a probing start onto a periodic attractor once one of its section
    points is inside the orbit's certified ellipsoid and the point one orbit period later is
    inside and closer (:mod:`gearsim.analysis.attractors.certify`: the Lyapunov norm of the
    orbit's monodromy; radii from ``certify_radius`` of the range down by factors of 3,
    ``certify_tries`` of them); recurrence stays for the rest. ``newton_seeds``: the cell's
    forward-continuation motion (``forward_results``) is a recurrence target from the first
    chunk when it is a stable orbit Newton-converged in this cell at its least period
    (:func:`gearsim.analysis.attractors.gear.newton_verified`); otherwise it becomes one only
    when a start's full-length run reaches it. ``neighbour_seeds``: a cell's known attractors
    also come from its neighbouring cells (``neighbours`` of the call): their periodic motions
    of another label, continued by Newton into this cell
    (:func:`gearsim.analysis.attractors.certify.continue_orbits`) and run there for their
    classification, are recurrence targets (and certified) once that run confirms them.
    """

    starts: int = 16
    seed: int = 0
    early: bool = True
    chunk: int = 8
    confirm: int = 8
    confirm_cloud: int = 32
    recur_rtol: float = 1e-3
    recur_period_rtol: float = RECUR_PERIOD_RTOL
    merge_rtol: float = 1e-3
    grid: int = 32
    cloud_overlap: float = 0.5
    doubling_rtol: float = 0.05
    early_clouds: bool = False
    period_rtol: float | None = None
    scouts: int = 1
    rescout: int = 24
    lanes: int = POOL_LANES
    certified: bool = True
    certify_radius: float = 0.3
    certify_tries: int = 5
    newton_seeds: bool = True
    neighbour_seeds: bool = True

    def __post_init__(self):
        for name in _POSITIVE_INTS + ("scouts",):
            v = getattr(self, name)
            low = 0 if name == "scouts" else 1
            if isinstance(v, bool) or not isinstance(v, int) or v < low:
                raise ParameterError(f"setting '{name}' = {v!r} must be an integer >= {low}")
        for name in ("recur_rtol", "recur_period_rtol", "merge_rtol", "doubling_rtol",
                     "cloud_overlap", "period_rtol", "certify_radius"):  # fmt: skip
            v = getattr(self, name)
            if v is None and name == "period_rtol":
                continue
            if isinstance(v, bool) or not isinstance(v, int | float) or not 0.0 < v <= 1.0:
                raise ParameterError(f"setting '{name}' = {v!r} must be a number in (0, 1]")

    @classmethod
    def from_mapping(cls, m) -> FinderOptions:
        """Options from a mapping of their names (unknown names refused, one line)."""
        allowed = {f.name for f in fields(cls)}
        bad = set(m) - allowed
        if bad:
            raise ParameterError(f"unknown finder option(s) {sorted(bad)}; allowed: "
                                 f"{', '.join(sorted(allowed))}")  # fmt: skip
        return cls(**dict(m))

    def with_(self, **changes) -> FinderOptions:
        return replace(self, **changes)

    def resolved(self, period_rtol: float) -> FinderOptions:
        """These options with the classifier's period test filled in where it is None."""
        return self if self.period_rtol is not None else replace(self, period_rtol=period_rtol)
