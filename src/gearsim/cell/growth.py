"""Growing motions: the linear limit of the mesh and the long run that tells a bounded motion
without a period from one that grows without bound.

For ``|x| >> b`` the dead zone is the identity shifted by a constant, ``f(x, b) = x - b sign(x)``
(likewise every bearing clearance): a motion large enough obeys the model at ``b = 0`` (no
clearance anywhere, docs/model.md: the teeth never separate), a linear, parametrically excited
(Mathieu-type) system ``y' = A(tau) y + g(tau)``. Its homogeneous part decides whether such a
motion grows: the monodromy of one mesh period of the variational equations at ``b = 0`` (the one
field's Jacobian, the same along every trajectory there) has the largest multiplier modulus
``mu_lin`` (:func:`linear_multipliers`; it does not depend on ``b``, ``Fm``, ``Fe``, ``phi_e``
nor the variable-ratio forcing, which are all in ``g``). ``mu_lin > 1`` (the principal
parametric resonance of the mesh stiffness near ``w = 2``): every motion that becomes nearly
linear grows like ``mu_lin^k``.

At such a point a motion without a period (chaos, quasi-periodic, unsettled: the classifier
reads a window whose amplitude grows throughout as unsettled) may be a growing motion: it keeps
its label only after a :data:`LONG_RUN`-period run from the end of its window stays within the
divergence bound and does not grow
(:func:`grows`); else it is ``diverged`` (:func:`check_growth`, the last step of the batched and
the scalar driver: :func:`gearsim.cell.chains.simulate_rows`,
:func:`gearsim.cell.simulate.simulate_cell`).
Periodic motions are not checked: a periodic orbit is bounded by construction.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gearsim.cell.classify import amplitude_grows
from gearsim.dynamics.parameters import ModelParameters
from gearsim.numerics.settings import Method

#: mesh periods of the long run from the end of the window (docs/decisions.md, "Growing
#: motions"): a nearly linear motion grows over one quarter of it (1 000 periods) by mu_lin^1000,
#: enough for both parts of amplitude_grows wherever mu_lin > 1 + 3.2e-5
LONG_RUN = 4000

#: motions that the long run checks (``unsettled``: among them the windows whose amplitude grew)
CHECKED = ("chaos", "quasi-periodic", "unsettled")
#: long runs per batched kernel call
CALL_LANES = 256

_MU_LIN: dict[tuple, float] = {}


def linear_limit(params: ModelParameters) -> ModelParameters:
    """The parameters of the linear limit: no backlash and no bearing clearance (the dead zones
    linear), and the forcing that does not enter the homogeneous part at its neutral values (one
    cached multiplier per column of a plane)."""
    return params.with_(b=0.0, b_py=0.0, b_pz=0.0, b_gy=0.0, b_gz=0.0, Fm=0.0, Fe=0.0,
                        phi_e=0.0, var_ratio=0.0)  # fmt: skip


def _key(lin: ModelParameters, st) -> tuple:
    return (lin, st.method, st.steps_per_period, st.hmax, st.rtol, st.atol)


def linear_multipliers(params_list: Sequence[ModelParameters], st) -> np.ndarray:
    """``mu_lin`` of every cell: the largest multiplier modulus of the linear limit's monodromy
    over one mesh period (:func:`gearsim.numerics.variational.monodromies` at
    :func:`linear_limit`, the cell's own integrator: its RK4 map, or DP5), cached per
    linear limit (a plane column shares one)."""
    from gearsim.dynamics.model import static_state
    from gearsim.numerics.shooting import sorted_eigs
    from gearsim.numerics.variational import monodromies

    lins = [linear_limit(p) for p in params_list]
    todo = list({_key(q, st): q for q in lins if _key(q, st) not in _MU_LIN}.values())
    if todo:
        got = monodromies(todo, [static_state(q.to_array()) for q in todo], 1, st)
        for q, (_y, M, status) in zip(todo, got, strict=True):
            ok = status == 0 and np.all(np.isfinite(M))
            _MU_LIN[_key(q, st)] = float(abs(sorted_eigs(M)[0])) if ok else float("inf")
    return np.array([_MU_LIN[_key(q, st)] for q in lins])


def grows(xmax: np.ndarray, xmin: np.ndarray) -> bool:
    """Whether the per-period amplitudes of a long run grow: :func:`amplitude_grows` over the
    whole run, its last half or its last quarter (a motion that lingers near the unstable
    forced response before its growth dominates rises only late in the run)."""
    m = len(xmax)
    return any(amplitude_grows(xmax[m - k :], xmin[m - k :]) for k in (m, m // 2, m // 4)
               if k >= 4)  # fmt: skip


def _long_runs(cells: Sequence, st, periods: int, backend=None) -> list[tuple[bool, int, int]]:
    """``(bounded, periods run, steps)`` of a :data:`LONG_RUN` from each result's final state:
    RK4 cells of one step grid in one batched kernel call, others one by one."""
    from gearsim.numerics.batch import run_periods_batched, steps_per_period
    from gearsim.numerics.integrate import run_periods

    out: list[tuple[bool, int, int] | None] = [None] * len(cells)
    groups: dict[tuple, list[int]] = {}
    for i, r in enumerate(cells):
        p = r.params
        if st.method is Method.RK4:
            key = (steps_per_period(p, st), p.var_ratio_order if p.var_ratio != 0.0 else None)
            groups.setdefault(key, []).append(i)
            continue
        run = run_periods(p, r.final_state, periods, st, start_period=int(r.final_period))
        s = run.summaries
        out[i] = (run.status == 0 and len(s) == periods and not grows(s.xmax, s.xmin),
                  run.periods_done, run.n_steps)  # fmt: skip
    # at most CALL_LANES per kernel call: each lane records its periods (~0.3 MB per lane)
    calls = [g[k : k + CALL_LANES] for g in groups.values() for k in range(0, len(g), CALL_LANES)]
    for idx in calls:
        y = np.zeros((len(idx), 20))
        y[:, :10] = [cells[i].final_state[:10] for i in idx]
        summ, _fin, status, steps = run_periods_batched(
            [cells[i].params for i in idx], y, periods, st,
            start_periods=[int(cells[i].final_period) for i in idx], tangent=False,
            backend=backend)
        for q, i in enumerate(idx):
            s = summ[q]
            out[i] = (int(status[q]) == 0 and len(s) == periods and not grows(s.xmax, s.xmin),
                      len(s), int(steps[q]))  # fmt: skip
    return out  # type: ignore[return-value]


def check_growth(results: Sequence, st, periods: int = LONG_RUN, backend=None) -> None:
    """The rule for motions without a period, in place on
    :class:`~gearsim.cell.simulate.CellResult` s: each chaotic, quasi-periodic or unsettled
    result gets its
    ``mu_lin``; where ``mu_lin > 1`` a ``periods``-period run from its final state decides
    (``long_run`` = its periods): bounded, the label stands; diverged or growing, the result
    becomes ``diverged`` (its window's readings kept in the classification; its table row
    holds none, :func:`gearsim.cell.record.row_values`). The run's periods and steps are the
    cell's. Its final state stays the window's (the state a continuation chain went on from).
    ``backend``: where the long runs' lanes run (default the CPU)."""
    todo = [r for r in results if r.classification.motion in CHECKED]
    if not todo:
        return
    mus = linear_multipliers([r.params for r in todo], st)
    for r, mu in zip(todo, mus, strict=True):
        r.classification.mu_lin = float(mu)
    check = [r for r, mu in zip(todo, mus, strict=True) if mu > 1.0]
    if not check:
        return
    runs = _long_runs(check, st, periods, backend)
    for r, (bounded, done, steps) in zip(check, runs, strict=True):
        c = r.classification
        c.long_run = float(done)
        r.periods += done
        r.steps += steps
        if not bounded:
            c.motion = c.status = c.label = "diverged"
            c.label_npq = ""
            c.converged = False
