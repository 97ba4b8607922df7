"""Boundary edges across which both cells' motions coexist (Newton-backed).

A plane row is a forward continuation chain: where two attractors coexist, the label a cell
gets is the branch the chain followed, and inside such a hysteresis band the chain can hop
between the branches without any bifurcation in the cell gap (a period-``2n`` orbit born in a
fold beside a subcritical doubling of the period-``n`` orbit: the small basin of one branch
loses the chain at a one-cell step). No located curve explains those edges; what does is the
claim that both motions exist on both sides of the edge.

:func:`coexisting_edges` checks that claim for each given edge: each cell's orbit is solved by
Newton at its own parameters from its simulated section state
(:func:`gearsim.analysis.orbits.find_periodic_orbit`), then continued to the other cell's
parameters (Newton from its state; the cells are one grid step apart). The edge's two motions
coexist when all four orbits converge, each is stable (every Floquet multiplier inside the
unit circle), each has its cell's least period and, at each cell, the two orbits are distinct
(different least periods, or section states more than :data:`DISTINCT` apart).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd

from gearsim.analysis.orbits import OrbitError, PeriodicOrbit, find_periodic_orbit
from gearsim.dynamics.parameters import ModelParameters, ParameterError
from gearsim.numerics.settings import IntegrationSettings

#: two section states closer than this (max-norm, dimensionless) are one orbit
DISTINCT = 1e-6
#: an orbit of period n repeats after a proper divisor d of n when its section points d
#: apart agree to this (max-norm): its least period is then below n
REPEAT = 1e-7
#: edges whose larger period exceeds this are not tested (a Newton solve costs n periods;
#: the atlas's curves reach period 16 too)
MAX_PERIOD = 16
#: the shooting's DP5 tolerance for these solves (the atlas's curve tracking tolerance)
NEWTON_RTOL = 1e-9


def least_period(orbit: PeriodicOrbit, tol: float = REPEAT) -> int:
    """The smallest divisor ``d`` of ``orbit.n`` after which its section points repeat."""
    sec = np.asarray(orbit.section, dtype=float)
    n = int(orbit.n)
    for d in range(1, n):
        if n % d == 0 and float(np.max(np.abs(sec[d:] - sec[:-d]))) <= tol:
            return d
    return n


def _distinct(a: PeriodicOrbit, b: PeriodicOrbit) -> bool:
    """Whether two orbits at one parameter point are different motions."""
    if least_period(a) != least_period(b):
        return True
    sb = np.asarray(b.section, dtype=float)
    return float(np.min(np.max(np.abs(sb - np.asarray(a.state)[None, :]), axis=1))) > DISTINCT


def newton_edges(base: ModelParameters, cells: pd.DataFrame, edges: pd.DataFrame, *,
                 x_name: str, y_name: str, settings: IntegrationSettings,
                 progress: Callable[[str], Any] | None = None) -> pd.DataFrame:
    """Per edge (columns ``i0, j0, i1, j1, n0, n1``): ``newton_n0`` and ``newton_n1``, the
    least period of the stable orbit Newton finds from each cell's simulated state with its
    label's period (0: no stable orbit converged; a least period below the label's says the
    cell's reading was a slowly decaying transient, a wrong label), and ``coexist``, whether
    both cells' motions exist and are stable at both cells (module docstring). Cells need
    ``i, j``, the plane's two parameters and ``final_state``; edges whose larger period
    exceeds :data:`MAX_PERIOD` are not tested (0, 0, False)."""
    by = {(int(i), int(j)): k for k, (i, j) in enumerate(zip(cells["i"], cells["j"],
                                                            strict=True))}
    xs, ys = cells[x_name].to_numpy(float), cells[y_name].to_numpy(float)
    states = cells["final_state"].to_numpy()
    own: dict[tuple[int, int], PeriodicOrbit | None] = {}
    moved: dict[tuple[tuple[int, int], tuple[int, int]], PeriodicOrbit | None] = {}

    def params(c: tuple[int, int]) -> ModelParameters:
        k = by[c]
        return base.with_(**{x_name: float(xs[k]), y_name: float(ys[k])})

    def solve(p: ModelParameters, n: int, y) -> PeriodicOrbit | None:
        try:
            o = find_periodic_orbit(p, n, np.asarray(y, dtype=float), settings, max_iter=15,
                                    grazing=False)
        except (OrbitError, ParameterError, np.linalg.LinAlgError, FloatingPointError):
            return None
        return o if (o.stable and math.isfinite(o.residual)) else None

    def own_orbit(c: tuple[int, int], n: int) -> PeriodicOrbit | None:
        if c not in own:
            s = states[by[c]]
            own[c] = None if s is None or not len(s) else solve(params(c), n, s)
        return own[c]

    def moved_orbit(c: tuple[int, int], to: tuple[int, int], n: int) -> PeriodicOrbit | None:
        if (c, to) not in moved:
            o = own_orbit(c, n)
            moved[(c, to)] = None if o is None else solve(params(to), n, o.state)
        return moved[(c, to)]

    co = np.zeros(len(edges), dtype=bool)
    nn = np.zeros((len(edges), 2), dtype=np.int64)
    rows = list(edges[["i0", "j0", "i1", "j1", "n0", "n1"]].itertuples(index=False))
    for k, (i0, j0, i1, j1, n0, n1) in enumerate(rows):
        a, b, na, nb = (int(i0), int(j0)), (int(i1), int(j1)), int(n0), int(n1)
        if min(na, nb) < 1 or max(na, nb) > MAX_PERIOD or a not in by or b not in by:
            continue
        oa, ob = own_orbit(a, na), own_orbit(b, nb)
        nn[k] = [0 if oa is None else least_period(oa), 0 if ob is None else least_period(ob)]
        if nn[k, 0] == na and nn[k, 1] == nb:
            ab, ba = moved_orbit(a, b, na), moved_orbit(b, a, nb)
            co[k] = (ab is not None and ba is not None and least_period(ab) == na
                     and least_period(ba) == nb and _distinct(ab, ob) and _distinct(ba, oa))
        if progress and ((k + 1) % 50 == 0 or k + 1 == len(rows)):
            progress(f"Newton on the unexplained edges' cells: {k + 1} of {len(rows)} edges, "
                     f"{int(co[:k + 1].sum())} with both motions on both sides")
    return pd.DataFrame({"newton_n0": nn[:, 0], "newton_n1": nn[:, 1], "coexist": co},
                        index=edges.index)
