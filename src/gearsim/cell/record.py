"""What a cell's result records: the classification of its steady motion
(:class:`Classification`, made by :mod:`gearsim.cell.classify`) and the columns of its table row
(:func:`result_columns`). Light: the tables' schema (catalogue, export) reads it without loading
the integrators."""

from __future__ import annotations

import typing
from dataclasses import dataclass, fields

from gearsim.cell.motion import DEFAULT_KMAX


@dataclass
class Classification:
    """The steady motion of one cell."""

    motion: str  # one of MOTIONS
    status: str  # ok | bifurcation | not_converged | diverged | budget
    I: int
    n: int  # 0 when no period <= n_max
    p: int | None
    q: int | None
    label: str  # I/nT, or 'chaos' / 'quasi-periodic' / 'unsettled' / 'diverged'
    label_npq: str  # n-p-q or ''
    dc: float
    kmax_peak_mean: float
    kmax_peak_static: float
    kmax_section_mean: float
    kmax_section_static: float
    kmin_peak_mean: float
    lyapunov: float
    x_min: float
    x_max: float
    converged: bool
    window_periods: int
    # Floquet margin: largest multiplier modulus of the Newton-refined orbit (per motion
    # period), NaN where no orbit was refined
    mu_max: float = float("nan")
    critical: str = ""  # kind of that multiplier: fold | period_doubling | neimark_sacker
    refined: bool = False  # the label is that of the Newton-refined orbit
    settle: float = float("nan")  # settle distance of the window (relative to the x range)
    # motions without a period (chaos, quasi-periodic): the linear limit's largest multiplier
    # (gearsim.cell.growth) and, where it exceeds 1, the periods of the long run that showed the
    # motion bounded (or, status diverged, growing); NaN where neither was needed
    mu_lin: float = float("nan")
    long_run: float = float("nan")

    @property
    def kmax(self) -> float:
        return getattr(self, DEFAULT_KMAX)


#: the fields of :class:`Classification`, in order (the first columns of a cell's row)
CLASSIFICATION_FIELDS = tuple(f.name for f in fields(Classification))

#: Motions that reached no steady state: a ``diverged`` motion left every bound (or its long run
#: grew), an ``unsettled`` one was still changing at the end of its window (status
#: ``not_converged``) or of the step budget (status ``budget``). What the window read of them is
#: a transient's, not a property of the cell: their rows hold no :data:`STEADY_READINGS`.
UNSTEADY_MOTIONS = ("diverged", "unsettled")
#: The readings of a steady motion, NULL (NaN) in the row of an :data:`UNSTEADY_MOTIONS` motion:
#: the Kmax readings, the smallest force, the fraction of time in the backlash and the Lyapunov
#: exponent. ``x_min`` / ``x_max`` stay: how far the motion went is what shows it diverging.
STEADY_READINGS = ("dc", "kmax_peak_mean", "kmax_peak_static", "kmax_section_mean",
                   "kmax_section_static", "kmin_peak_mean", "lyapunov", "kmax")
#: Where the dictionary says when a steady reading is NULL (one wording, every table).
UNSTEADY_NULL = ("NULL when the motion is diverged or unsettled (status diverged, not_converged "
                 "or budget: no steady motion to read)")


def row_values(cls: Classification) -> dict:
    """The classification's columns of a table row (:func:`result_columns`, but ``periods`` and
    ``steps``): every field plus ``kmax``, the :data:`STEADY_READINGS` NaN for an
    :data:`UNSTEADY_MOTIONS` motion."""
    row = {name: getattr(cls, name) for name in CLASSIFICATION_FIELDS}  # flat: no deepcopy
    row["kmax"] = cls.kmax
    if cls.motion in UNSTEADY_MOTIONS:
        row.update(dict.fromkeys(STEADY_READINGS, float("nan")))
    return row


def result_columns() -> dict[str, tuple[type, bool]]:
    """Name -> (Python type, optional) of every column of a cell's row
    (:meth:`gearsim.cell.simulate.CellResult.row`), in order.

    Derived from the fields of :class:`Classification` (a new field there is a new column in
    the tiles and the catalogue), plus ``kmax``, ``periods``, ``steps``. Floats are
    optional (NaN is stored as NULL), as are the fields typed ``X | None`` (``p``, ``q``).
    """
    hints = typing.get_type_hints(Classification)
    cols: dict[str, tuple[type, bool]] = {}
    for f in fields(Classification):
        t = hints[f.name]
        args = [a for a in typing.get_args(t) if a is not type(None)]
        base = args[0] if args else t
        cols[f.name] = (base, bool(args) or base is float)
    cols.update(kmax=(float, True), periods=(int, False), steps=(int, False))
    return cols
