"""The paper's three motion classes, one predicate each, from a cell's impact state ``I`` and
back-impact count ``q`` (:mod:`gearsim.cell.classify`: ``I`` = 0 no disengagement, 1 face impacts
only, -1 back impacts only, 2 both, -2 never in contact).

* **double-sided impact**: the tooth back is hit (``I`` = 2 or -1, or ``q > 0``). Back impacts
  without face impacts (``I = -1``) count here: the backlash threshold is where back contact
  stops, whatever the face side does.
* **face impact** (single-sided): face impacts only (``I = 1``).
* **no impact**: the teeth stay in mesh (``I = 0``).

A motion never in contact (``I = -2``) is in none of the three. Each predicate takes scalars,
numpy arrays or pandas Series (then it returns a Series on the same index); a missing ``q`` (NaN,
e.g. a chaotic cell) counts as no back impact.
"""

from __future__ import annotations

from typing import Any

#: The four Kmax readings of a cell (:mod:`gearsim.cell.classify`), each under its own name.
#: Here, beside the motion classes, so that readers of tables need not load the integrators.
KMAX_READINGS = {
    "kmax_peak_mean": "max over the steady motion of F / Fm",
    "kmax_peak_static": "max over the steady motion of F / (Fm + Fe w^2)",
    "kmax_section_mean": "max over the Poincare samples of F / Fm",
    "kmax_section_static": "max over the Poincare samples of F / (Fm + Fe w^2)",
}
#: Kmax, the paper's maximum dynamic load coefficient, is this reading (the one docs/model.md
#: reconstructs): the catalogue's ``kmax`` and what ``gearsim point``, the maps, the explorer and
#: the scorecard show as Kmax. The other readings keep their own names, never "Kmax".
DEFAULT_KMAX = "kmax_peak_static"
#: What Kmax is, in the words printed beside it.
KMAX_DEFINITION = KMAX_READINGS[DEFAULT_KMAX]

#: The motion labels a classification takes.
MOTIONS = ("periodic", "quasi-periodic", "chaos", "unsettled", "diverged")


def double_sided(I: Any, q: Any = None) -> Any:
    """Whether the tooth back is hit: ``I`` in {2, -1}, or ``q > 0`` when ``q`` is given."""
    out = (I == 2) | (I == -1)
    if q is None:
        return out
    return out | ((q.fillna(0) if hasattr(q, "fillna") else q) > 0)


def face_impact(I: Any) -> Any:
    """Whether the motion impacts on the tooth face only (``I = 1``)."""
    return I == 1


def no_impact(I: Any) -> Any:
    """Whether the teeth stay in mesh throughout (``I = 0``)."""
    return I == 0
