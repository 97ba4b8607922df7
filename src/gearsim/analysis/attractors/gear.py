"""The gear model as the finder's system: start box, seeded starts, cells on the batched kernel,
the steady motion of a cell result."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from gearsim.analysis.attractors.results import CellAttractors, Steady
from gearsim.dynamics.parameters import ModelParameters, ParameterError


def start_box(params: ModelParameters) -> tuple[float, float, float, float]:
    """Centre and half-widths ``(x0, hx, v0, hv)`` of the start box in ``(x, x')``.

    Around the static state ``x0 = b + Fm`` (displacements in units of the nominal length
    ``b_c``): ``hx = b + 2 (Fm + Fe w^2)`` (the backlash plus twice the static excitation
    amplitude, forces in units of ``Km b_c``), velocities ``x' = dx/dtau`` in ``+/- w hx``
    (``tau = w_n t``).
    """
    x0 = params.b + params.Fm
    hx = params.b + 2.0 * (params.Fm + params.Fe * params.w**2)
    return x0, hx, 0.0, params.w * hx


def sobol_unit(k: int, seed: int) -> np.ndarray:
    """``k`` scrambled Sobol points of the unit square (seeded; any ``k``, balance warning off)."""
    from scipy.stats import qmc

    if isinstance(k, bool) or not isinstance(k, int) or k < 1:
        raise ParameterError(f"setting 'starts' = {k!r} must be an integer >= 1")
    eng = qmc.Sobol(d=2, scramble=True, seed=int(seed))
    m = max(0, math.ceil(math.log2(k)))
    return eng.random_base2(m)[:k]


class GearCells:
    """The gear model as a :class:`System`: one cell per :class:`ModelParameters`.

    Runs through the batched RK4 kernel (:func:`gearsim.numerics.batch.run_periods_batched` to
    advance,
    :func:`gearsim.cell.chains.simulate_cells` for full-length runs, i.e.
    :mod:`gearsim.cell.classify`).
    Section states have 10 components ``(x, x', u_py, u_py', ...)``; ``transient`` is
    ``settings.transient`` (a start far from the motion is a start "from rest"),
    ``transient_continuation`` the settings' one for continuation states.
    """

    def __init__(self, params_list: Sequence[ModelParameters], settings=None, backend=None):
        from gearsim.cell.simulate import IntegrationSettings

        self.params = list(params_list)
        self.backend = backend  # where the lanes run (gearsim.numerics.backend; None: the CPU)
        st = settings or IntegrationSettings(method="rk4")
        self.settings = st.with_(method="rk4")
        self.transient = int(self.settings.transient)
        self.transient_continuation = int(self.settings.transient_continuation)
        from gearsim.cell.verify import OrbitCache

        self.orbits = OrbitCache()  # the starts of a cell share their refined orbits

    def start_states(self, cell: int, unit: np.ndarray) -> np.ndarray:
        from gearsim.dynamics.model import static_state

        p = self.params[cell]
        x0, hx, v0, hv = start_box(p)
        base = static_state(p.to_array())
        y = np.repeat(base[None, :], len(unit), axis=0)
        y[:, 0] = x0 + (2.0 * unit[:, 0] - 1.0) * hx
        y[:, 1] = v0 + (2.0 * unit[:, 1] - 1.0) * hv
        return y

    def advance(self, cells, states, n_periods, start_periods):
        from gearsim.cell.simulate import initial_tangent
        from gearsim.dynamics.model import N_STATE
        from gearsim.numerics.batch import run_periods_batched, steps_per_period

        k = len(cells)
        secs = np.full((k, n_periods, N_STATE), np.nan)
        finals = np.array(states, dtype=float)[:, :N_STATE].copy()
        div = np.zeros(k, dtype=bool)
        groups: dict[tuple, list[int]] = {}
        for r, c in enumerate(cells):
            p = self.params[c]
            key = (steps_per_period(p, self.settings), p.model,
                   p.var_ratio_order if p.var_ratio != 0.0 else None)  # fmt: skip
            groups.setdefault(key, []).append(r)
        for (_, model, _), rows in groups.items():
            plist = [self.params[cells[r]] for r in rows]
            t0 = initial_tangent(plist[0])  # on the states this group's model evolves
            if model != "6dof":
                for r, p in zip(rows, plist, strict=True):
                    self._advance_scalar(r, p, states, n_periods, start_periods, secs, finals,
                                         div)  # fmt: skip
                continue
            y = np.hstack([np.asarray(states, dtype=float)[rows, :N_STATE],
                           np.repeat(t0[None, :], len(rows), axis=0)])  # fmt: skip
            # probing needs the section points only (the tangent is restarted by every
            # full-length run): no tangent vector (same states, bit for bit)
            summ, fin, status, _ = run_periods_batched(
                plist, y, n_periods, self.settings, start_periods=[int(start_periods[r])
                                                                   for r in rows],
                tangent=False, backend=self.backend,
            )  # fmt: skip
            for q, r in enumerate(rows):
                s = summ[q].section
                secs[r, : len(s)] = s
                finals[r] = fin[q, :N_STATE]
                div[r] = status[q] != 0 or len(s) < n_periods
        return secs, finals, div

    def _advance_scalar(self, r, p, states, n, start_periods, secs, finals, div) -> None:
        from gearsim.cell.simulate import run_periods

        run = run_periods(p, np.asarray(states[r], dtype=float)[:10], n, self.settings,
                          start_period=int(start_periods[r]))  # fmt: skip
        s = run.summaries.section
        secs[r, : len(s)] = s
        finals[r] = run.state[:10]
        div[r] = run.status != 0 or len(s) < n

    def steady(self, cells, states, transient, start_periods):
        from gearsim.cell.chains import simulate_cells

        st = self.settings.with_(transient_continuation=int(transient))
        plist = [self.params[c] for c in cells]
        res = simulate_cells(plist, settings=st, u0=[np.asarray(s, dtype=float)[:10]
                                                     for s in states],
                             start_periods=[int(k) for k in start_periods],
                             orbits=self.orbits, backend=self.backend)  # fmt: skip
        return [gear_steady(r) for r in res]

    def fill_margins(self, found: Sequence[CellAttractors]) -> None:
        """Every periodic attractor its Floquet margin where its run did not give one (in
        place; ``found[c]`` belongs to cell ``c``): the margin of a plane cell's motion
        (:func:`gearsim.cell.verify.orbit_margins`, the cells' attractors in shared kernel
        calls; only with ``floquet`` ``"margin"``)."""
        fill_orbit_margins([(p, a.steady) for p, ca in zip(self.params, found, strict=True)
                            for a in ca.attractors], self.settings, self.backend)


def gear_steady(res) -> Steady:
    """:class:`Steady` of a :class:`gearsim.cell.simulate.CellResult`."""
    c = res.classification
    w = res.params.w
    info = res.row()
    info.pop("n", None)
    info.pop("label", None)
    scale = float(c.x_max - c.x_min) if math.isfinite(c.x_max - c.x_min) else 0.0
    return Steady(
        status="diverged" if c.status == "diverged" else (
            "unsettled" if c.motion == "unsettled" else "ok"
        ),
        period=int(c.n),
        points=np.asarray(res.poincare, dtype=float),
        scale_x=scale,
        scale_v=scale * w,
        label=c.label,
        info=info,
        final_state=np.asarray(res.final_state, dtype=float),
    )


def fill_orbit_margins(pairs: Sequence[tuple[ModelParameters, Steady | None]], st,
                       backend=None) -> None:
    """Each settled periodic motion of ``pairs`` (its cell's parameters, the motion) that lacks
    a Floquet margin gets one, in place (``info["mu_max"]``, ``info["critical"]``), all in
    shared kernel calls on ``backend`` (:func:`gearsim.cell.verify.orbit_margins`); only with
    ``floquet`` ``"margin"``."""
    from gearsim.cell.verify import orbit_margins, wants_margin

    if st.floquet != "margin":
        return
    todo = []
    for p, s in pairs:
        if s is None or s.status != "ok" or s.final_state is None:
            continue
        i = s.info or {}
        if wants_margin(s.period, i.get("status", "ok"), bool(i.get("refined")),
                        i.get("mu_max"), p.var_ratio):  # fmt: skip
            todo.append((p, s))
    got = orbit_margins([p for p, _ in todo], [s.period for _, s in todo],
                        [s.final_state for _, s in todo], st, backend=backend)  # fmt: skip
    for (_, s), m in zip(todo, got, strict=True):
        if m is not None:
            s.info["mu_max"], s.info["critical"] = m


#: a forward motion is a Newton-converged orbit of its cell when ``max |P^n(y) - y|`` is below
#: this at its section state ``y``, or at ``y`` plus one Newton step of at most
#: :data:`NEWTON_STEP_RTOL` of the motion's range (so its window's points are the orbit's)
NEWTON_TOL = 1e-9
NEWTON_STEP_RTOL = 1e-5
#: Newton iterations of :func:`newton_orbits` with ``solve`` (a settled reading is close)
SOLVE_ITER = 8
#: ... and its section points have no shorter period: two phases ``m`` apart (``m`` a proper
#: divisor of ``n``) closer than this fraction of the range everywhere make it a reading of a
#: period-``m`` orbit (Newton on ``P^n`` also converges to the fixed points of ``P^m``)
LEAST_PERIOD_RTOL = 1e-4


def _shorter_period(s: Steady) -> bool:
    n = s.period
    pts = np.asarray(s.points, dtype=float)[-n:, :2]
    return shorter_period(pts, np.array([max(s.scale_x, 1e-9), max(s.scale_v, 1e-9)]))


def shorter_period(pts: np.ndarray, sc: np.ndarray) -> bool:
    """Whether ``n`` section points ``pts`` ``(n, 2)`` (scales ``sc`` of ``x`` and ``x'``) repeat
    after a proper divisor ``m`` of ``n`` within :data:`LEAST_PERIOD_RTOL`: a period-``m``
    orbit read ``n`` times."""
    n = len(pts)
    for m in range(1, n):
        if n % m == 0 and np.all(np.abs(pts - np.roll(pts, -m, axis=0)) / sc
                                 <= LEAST_PERIOD_RTOL):  # fmt: skip
            return True
    return False


def newton_orbits(pairs: Sequence[tuple[ModelParameters, Steady | None]], st,
                  solve: bool = False) -> list[tuple[np.ndarray, np.ndarray] | None]:
    """Per ``(cell parameters, motion)``: ``(y, M)``, the section state of the motion's orbit
    Newton-converged in *that* cell (:data:`NEWTON_TOL`, at most one Newton step of
    :data:`NEWTON_STEP_RTOL` from its section state) and the monodromy of its ``n`` periods
    there, where the motion's points have no shorter period (:data:`LEAST_PERIOD_RTOL`) and
    ``|mu|max < 1``; else None. The orbits of one period share kernel calls
    (:func:`gearsim.numerics.variational.monodromies`, the cell's own RK4 map). ``solve``:
    where one small step does not converge, the one orbit solver
    (:func:`gearsim.analysis.orbits.newton_orbit`, :data:`SOLVE_ITER` iterations, the cell's
    own settings) from the motion's state; the caller then checks that the orbit found is the
    motion's (its points, its least period)."""
    from gearsim.dynamics.model import N_STATE
    from gearsim.numerics.integrate import STATUS_OK
    from gearsim.numerics.shooting import newton_step, sorted_eigs
    from gearsim.numerics.variational import monodromies

    out: list[tuple[np.ndarray, np.ndarray] | None] = [None] * len(pairs)
    by_n: dict[int, list[int]] = {}
    for i, (p, s) in enumerate(pairs):
        if (s is not None and s.status == "ok" and s.period > 0 and s.final_state is not None
                and (s.info or {}).get("status", "ok") == "ok" and p.var_ratio == 0.0
                and not _shorter_period(s)):  # fmt: skip
            by_n.setdefault(s.period, []).append(i)
    for n, group in by_n.items():
        ys = [np.asarray(pairs[i][1].final_state, dtype=float)[:N_STATE].copy() for i in group]
        for step in (0, 1):
            if not group:
                break
            maps = monodromies([pairs[i][0] for i in group], ys, n, st)
            again, y_again = [], []
            for i, y, (yn, M, status) in zip(group, ys, maps, strict=True):
                if status != STATUS_OK or not np.all(np.isfinite(M)):
                    continue
                d = len(M)
                G = yn[:d] - y[:d]
                if float(np.max(np.abs(G))) < NEWTON_TOL:
                    if abs(sorted_eigs(M)[0]) < 1.0:
                        out[i] = (y, M)
                elif step == 0:
                    s = pairs[i][1]
                    dy = newton_step(M, G)
                    sc = np.where(np.arange(d) % 2 == 0, max(s.scale_x, 1e-9),
                                  max(s.scale_v, 1e-9))  # fmt: skip
                    if float(np.max(np.abs(dy) / sc)) <= NEWTON_STEP_RTOL:
                        y1 = y.copy()
                        y1[:d] += dy
                        again.append(i)
                        y_again.append(y1)
            group, ys = again, y_again
    if solve:
        from gearsim.analysis.orbits import OrbitError, newton_orbit

        for n, group in by_n.items():
            for i in group:
                if out[i] is not None:
                    continue
                p, s = pairs[i]
                try:
                    y, _yn, M, r, _ = newton_orbit(p, n, s.final_state, st, tol=NEWTON_TOL,
                                                   max_iter=SOLVE_ITER)  # fmt: skip
                except OrbitError:
                    continue
                if r < NEWTON_TOL and abs(sorted_eigs(M)[0]) < 1.0:
                    out[i] = (y, M)
    return out


def newton_verified(pairs: Sequence[tuple[ModelParameters, Steady | None]], st) -> list[bool]:
    """Per ``(cell parameters, motion)``: whether the motion is a stable periodic orbit of *that*
    cell, Newton-converged there at its least period (:func:`newton_orbits`)."""
    return [o is not None for o in newton_orbits(pairs, st)]


def bounded_clouds(params_list, found: list[CellAttractors], st, backend=None
                   ) -> list[CellAttractors]:
    """A chaotic, quasi-periodic or unsettled motion of a cell where the mesh's linear limit is
    unstable (``mu_lin > 1``: the parametric instability of the nearly linear mesh near w = 2;
    motions that grow after their window look like clouds in it, and one growing inside its
    window reads unsettled) is checked by the rule of
    :func:`gearsim.cell.growth.check_growth`: the full-length run of the first of its starts,
    then a long run from its end (:data:`gearsim.cell.growth.LONG_RUN` periods); where that
    diverges or grows, the attractor is no attractor and its starts count as diverged (the
    periods are the start's too). A cloud whose own run was checked already is not run again.
    The last step of every gear mapper, after :func:`least_periods`."""
    from gearsim.analysis.attractors.matching import drop
    from gearsim.cell.chains import simulate_cells
    from gearsim.cell.growth import CHECKED, linear_multipliers

    todo = []  # (cell, attractor index, start)
    for c, ca in enumerate(found):
        for a in ca.attractors:
            s = a.steady
            if (s.period <= 0 and a.label in CHECKED and a.n_starts > 0
                    and not math.isfinite((s.info or {}).get("long_run", math.nan))):
                i = int(np.nonzero(ca.start_labels == a.index)[0][0])
                todo.append((c, a.index, i))
    mus = linear_multipliers([params_list[c] for c, _, _ in todo], st)
    todo = [t for t, mu in zip(todo, mus, strict=True) if mu > 1.0]
    if not todo:
        return found
    res = simulate_cells([params_list[c] for c, _, _ in todo],
                         settings=st.with_(transient_continuation=st.transient),
                         u0=[np.asarray(found[c].starts[i], dtype=float)[:10]
                             for c, _, i in todo], backend=backend)  # fmt: skip
    gone: dict[int, set[int]] = {}
    for (c, a, i), r in zip(todo, res, strict=True):
        found[c].start_periods_run[i] += int(r.periods)  # the long run is the start's too
        if gear_steady(r).status == "diverged":
            gone.setdefault(c, set()).add(a)
        else:  # bounded: the attractor records its check
            info = next(x for x in found[c].attractors if x.index == a).steady.info
            info["mu_lin"], info["long_run"] = r.classification.mu_lin, r.classification.long_run
    return [drop(ca, gone.get(c, set())) for c, ca in enumerate(found)]


def plain_value(v):
    """A table value as plain data: lists for arrays, None for missing (pandas' NA), Python
    scalars for NumPy ones."""
    if isinstance(v, np.ndarray):
        return v.tolist()
    if v is None:
        return None
    import pandas as pd

    if v is pd.NA:
        return None
    return v.item() if isinstance(v, np.generic) else v


def steady_from_row(row: Mapping[str, Any], w: float) -> Steady | None:
    """The :class:`~gearsim.analysis.attractors.Steady` of a plane tile's cell row (its
    classification, Poincare points and final state; ``w`` the cell's frequency ratio), None
    without them."""
    from gearsim.cell.record import result_columns

    if row.get("poincare_x") is None or row.get("n") is None:
        return None
    info = {k: plain_value(row.get(k)) for k in result_columns() if k in row}
    n = int(info.pop("n"))
    label = str(info.pop("label"))
    scale = float(info["x_max"]) - float(info["x_min"])
    scale = scale if math.isfinite(scale) else 0.0
    status, motion = info.get("status"), info.get("motion")
    return Steady(
        status="diverged" if status == "diverged" else (
            "unsettled" if motion == "unsettled" else "ok"),
        period=n,
        points=np.column_stack([np.asarray(row["poincare_x"], dtype=float),
                                np.asarray(row["poincare_v"], dtype=float)]),
        scale_x=scale,
        scale_v=scale * float(w),
        label=label,
        info=info,
        final_state=None if row.get("final_state") is None
        else np.asarray(row["final_state"], dtype=float),
    )  # fmt: skip
