"""What the figures draw that is simulated: the steady motions of Fig 2, the attractor search
of Figs 9-11 and the basins of Figs 19 and 20, each computed by one job (``gearsim
figure-data``) into a table that the figure job reads (presentation never simulates).

A table holds one row per motion in the point sets' format
(:func:`gearsim.study.sweeps.motion_row`: classification, section points, a recorded
trajectory) with the motion's ``key``, ``role``, ``hits``, ``seed`` (how it was reached) and
``samples_per_period``, or for a basin picture one row per start; what the figure states
beside them (the backlash of Fig 2, the initial conditions tried, the basin point and its
attractors) is the table's ``FIGURE_DATA_KEY`` metadata. Every motion is settled with
``point_settings`` (a longer transient than the plane cells). Those light names, and which
tables there are and what each reads, are in :mod:`gearsim.study.figure_tables`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from gearsim.analysis.attractors import FinderOptions, find_attractors, start_box
from gearsim.analysis.basins import basin_grid
from gearsim.analysis.hysteresis import hysteresis
from gearsim.analysis.paper import COEXIST_POINT, PAPER_COEXIST
from gearsim.cell.simulate import (
    CellResult,
    IntegrationSettings,
    Trajectory,
    simulate_cell,
    trajectory,
)
from gearsim.cell.sweep import continuation_chain
from gearsim.dynamics.model import static_state
from gearsim.dynamics.parameters import ModelParameters
from gearsim.errors import UsageError
from gearsim.study.config import Study
from gearsim.study.figure_tables import FIGURE_DATA, basin_n, point_settings
from gearsim.study.sweeps import motion_row


@dataclass
class Motion:
    """One simulated steady motion with a recorded trajectory on it."""

    params: ModelParameters
    result: CellResult
    traj: Trajectory
    samples_per_period: int
    seed: str = "static state"  # how the motion was reached

    @property
    def npq(self) -> str:
        c = self.result.classification
        return c.label_npq or c.label


@dataclass
class Search:
    """Steady motions reached from several initial conditions at one parameter point."""

    params: ModelParameters
    tried: int
    found: dict[str, tuple[Motion, int]]  # npq (or motion name) -> (motion, starts reaching it)
    elsewhere: dict[str, Motion] = field(default_factory=dict)  # npq -> other-w motion
    # targets the sweep lists at other w that did not persist when re-simulated there
    unconfirmed: dict[str, list[str]] = field(default_factory=dict)


def seed_state(params: ModelParameters, x: float, v: float) -> np.ndarray:
    """A section state with mesh coordinates ``(x, v)`` and the bearings at their static state."""
    y = static_state(params.to_array())
    y[0], y[1] = float(x), float(v)
    return y


def seed_from_sweep(sweep: pd.DataFrame | None, params: ModelParameters,
                    name: str = "w") -> tuple[np.ndarray | None, str]:
    """Initial state from the swept row nearest to ``params.<name>`` (continuation seed).

    Uses the row's full ``final_state`` when the table has it (``gearsim sweep`` writes it);
    otherwise only ``(x, x')`` of its last section point are known and the bearing coordinates
    start from the static state.
    """
    if sweep is None or len(sweep) == 0:
        return None, "static state"
    target = getattr(params, name)
    k = int(np.argmin(np.abs(sweep["value"].to_numpy(dtype=float) - target)))
    row = sweep.iloc[k]
    if "final_state" in sweep.columns and row["final_state"] is not None:
        fs = np.asarray(row["final_state"], dtype=float)
        if fs.shape == (len(static_state(params.to_array())),) and np.all(np.isfinite(fs)):
            return fs.copy(), f"sweep state at {name} = {row['value']:.4g}"
    px, pv = np.asarray(row["poincare_x"]), np.asarray(row["poincare_v"])
    if len(px) == 0:
        return None, "static state"
    return seed_state(params, px[-1], pv[-1]), f"sweep section point {name} = {row['value']:.4g}"


def reach(params: ModelParameters, targets: Sequence[float], *, sweep: pd.DataFrame | None,
          settings: IntegrationSettings | None = None) -> tuple[dict[float, CellResult], str]:
    """Steady motions at ``targets`` (values of ``w``) on the branch the forward sweep followed.

    With the sweep's full final states: one continuation step from the nearest swept value at
    or below each target. Otherwise a forward continuation chain (:func:`continuation_to`).
    """
    if sweep is not None and len(sweep) and "final_state" in sweep.columns:
        out = {}
        vals = sweep["value"].to_numpy(dtype=float)
        for t in targets:
            below = np.where(vals <= float(t) + 1e-12)[0]
            k = int(below[np.argmax(vals[below])]) if len(below) else int(np.argmin(vals))
            fs = np.asarray(sweep["final_state"].iloc[k], dtype=float)
            out[float(t)] = simulate_cell(params.with_(w=float(t)), fs, settings=settings)
        return out, "continuation from the sweep state"
    values = sweep["value"].to_numpy(dtype=float) if sweep is not None and len(sweep) else None
    return (continuation_to(params, targets, settings=settings, values=values),
            "forward continuation in w")


def continuation_to(
    params: ModelParameters,
    targets: Sequence[float],
    *,
    name: str = "w",
    settings: IntegrationSettings | None = None,
    values: Sequence[float] | np.ndarray | None = None,
    start: float | None = None,
    step: float = 0.01,
    min_step: float = 0.005,
) -> dict[float, CellResult]:
    """Steady motions at ``targets`` reached by forward continuation in ``name``.

    The chain runs over ``values`` (e.g. the swept values of the matching sweep, so the figure
    follows the branch of the bifurcation diagram) or a uniform grid of spacing ``step`` from
    ``start`` (default 0.1 for ``w``), up to the largest target, with the targets inserted;
    ``values`` closer than ``min_step`` are thinned out (cost).
    Seeding a single point from a stored section state is not enough: the sweep tables keep only
    ``(x, x')``, and with the bearings reset the motion can land on a coexisting attractor.
    """
    tg = sorted(float(t) for t in targets)
    if not tg:
        return {}
    if values is None:
        lo = (0.1 if name == "w" else tg[0]) if start is None else start
        values = np.arange(lo, tg[-1], step) if tg[-1] > lo else np.zeros(0)
    vals = np.sort(np.asarray(values, dtype=float))
    vals = vals[vals < tg[-1]]
    if min_step > 0 and len(vals) > 1:  # thin a fine sweep grid (cost), keep its first value
        keep = [0]
        for k in range(1, len(vals)):
            if vals[k] - vals[keep[-1]] >= min_step:
                keep.append(k)
        vals = vals[keep]
    chain = np.unique(np.concatenate([vals, tg]))
    res = continuation_chain([params.with_(**{name: float(v)}) for v in chain],
                             settings=settings)
    by_value = dict(zip(chain.tolist(), res, strict=True))
    return {t: by_value[t] for t in tg}


def simulate_point(
    params: ModelParameters,
    *,
    settings: IntegrationSettings | None = None,
    u0: np.ndarray | None = None,
    seed: str = "static state",
    periods: int | None = None,
    samples_per_period: int = 128,
    min_periods: int = 32,
    result: CellResult | None = None,
) -> Motion:
    """Settle the motion at ``params`` (from ``u0``) and record a trajectory on it.

    ``periods`` defaults to a whole number of motion periods, at least ``min_periods``
    (chaotic motion: ``4 * min_periods``).
    """
    st = settings or IntegrationSettings()
    res = result if result is not None else simulate_cell(params, u0, settings=st)
    n = res.classification.n
    if periods is None:
        periods = max(min_periods, n * int(np.ceil(min_periods / n))) if n > 0 else 4 * min_periods
    tr = trajectory(params, res.final_state, periods=periods,
                    samples_per_period=samples_per_period, settings=st,
                    start_period=res.final_period)
    return Motion(params, res, tr, samples_per_period, seed)


def _middle_of_longest_run(sweep: pd.DataFrame, I: int, n: int) -> float:
    """Value in the middle of the longest run of consecutive swept cells that are periodic with
    impact state ``I`` and period ``n`` (far from the run's bifurcations)."""
    d = sweep.sort_values("value").reset_index(drop=True)
    ok = ((d["I"] == I) & (d["motion"] == "periodic") & (d["n"] == n)).to_numpy()
    best, start = (0, 0), None
    for k, flag in enumerate(list(ok) + [False]):
        if flag and start is None:
            start = k
        elif not flag and start is not None:
            if k - start > best[1] - best[0]:
                best = (start, k)
            start = None
    return float(d["value"].iloc[(best[0] + best[1] - 1) // 2])


def compute_fig2(params: ModelParameters, *, settings: IntegrationSettings | None = None,
                 sweep: pd.DataFrame | None = None, b: float = 0.15,
                 candidates: Sequence[float] | None = None
                 ) -> tuple[dict[int, Motion], list[str]]:
    """One real trajectory each of I = 0, 1 and 2 at the same backlash ``b``.

    The mesh frequency of each is taken from ``sweep`` (a sweep at this ``b``: the periodic
    cell of that impact state with the smallest period, middle of its run), or else from a
    forward continuation over ``candidates``; the motion is then reached on the sweep's branch
    (:func:`reach`). Returns the motions by impact state and the notes on what was not found.
    """
    base = params.with_(b=b)
    chosen: dict[int, float] = {}
    if sweep is not None and len(sweep):
        for I in (0, 1, 2):
            sub = sweep[(sweep["I"] == I) & (sweep["motion"] == "periodic")]
            if len(sub):
                chosen[I] = _middle_of_longest_run(sweep, I, int(sub["n"].min()))
    notes = []
    missing = [I for I in (0, 1, 2) if I not in chosen]
    if missing:
        cand = list(candidates) if candidates is not None else list(np.linspace(0.2, 2.4, 23))
        for w, r in continuation_to(base, cand, settings=settings, values=cand).items():
            I = r.classification.I
            if I in missing and r.classification.motion == "periodic":
                chosen[I] = float(w)
                missing.remove(I)
    reached, how = reach(base, list(chosen.values()), sweep=sweep, settings=settings)
    motions = {}
    for I, w in sorted(chosen.items()):
        pm = simulate_point(base.with_(w=w), settings=settings, result=reached[w], seed=how)
        motions[I] = pm
        if pm.result.classification.I != I:
            notes.append(f"I = {I} expected at w = {w:.3f}, got {pm.result.classification.I}")
    for I in missing:
        notes.append(f"no I = {I} motion found at b = {b:g}")
    return motions, notes


def compute_points(params: ModelParameters, ws: Sequence[float], *,
                   settings: IntegrationSettings | None = None,
                   sweep: pd.DataFrame | None = None, min_periods: int = 32,
                   samples_per_period: int = 128) -> list[Motion]:
    """Motions at each ``w`` reached by forward continuation (over the sweep's values if given,
    so the panels follow the branch of the bifurcation diagram)."""
    reached, how = reach(params, ws, sweep=sweep, settings=settings)
    return [simulate_point(params.with_(w=float(w)), settings=settings, result=reached[float(w)],
                           seed=how, min_periods=min_periods,
                           samples_per_period=samples_per_period) for w in ws]


def initial_conditions(params: ModelParameters, scale: tuple[float, float, float, float],
                       nx: int = 6, nv: int = 5) -> list[np.ndarray]:
    """A grid of section states ``(x, x')`` over ``[xlo, xhi] x [vlo, vhi]``; bearings static."""
    xlo, xhi, vlo, vhi = scale
    return [seed_state(params, x, v) for x in np.linspace(xlo, xhi, nx)
            for v in np.linspace(vlo, vhi, nv)]


def search_attractors(params: ModelParameters, *, settings: IntegrationSettings | None = None,
                      sweep: pd.DataFrame | None = None, grid: tuple[int, int] = (6, 5),
                      targets: Sequence[str] = PAPER_COEXIST,
                      min_periods: int = 16, backward_from: float = 0.5,
                      backward_step: float = 0.01, max_retries: int = 4) -> Search:
    """Steady motions reached from several initial conditions at one parameter point.

    Initial conditions: the static state, the state reached by forward continuation in ``w``
    (over the sweep's values when given), the state reached by backward continuation from
    ``w + backward_from``, the nearest stored point of ``sweep`` and a ``grid``
    of ``(x, x')`` over twice the range of the first motion found. Targets not reached here are
    looked for along ``sweep`` (same fixed parameters, other ``w``) and, when present there,
    reached by continuation at the nearest such ``w`` so the figure can show them (clearly
    labelled with that ``w``).
    """
    st = settings or IntegrationSettings()
    cont = reach(params, [params.w], sweep=sweep, settings=st)[0][params.w]
    seeds: list[tuple[np.ndarray | None, str]] = [(None, "static state"),
                                                  (cont.final_state, "forward continuation")]
    u, how = seed_from_sweep(sweep, params)
    if u is not None:
        seeds.append((u, how))
    # backward continuation from above (coexisting branches often show up only that way)
    back = [params.with_(w=float(w)) for w in np.arange(params.w + backward_from, params.w,
                                                         -backward_step)]
    if back:
        res = continuation_chain(back, settings=st)
        seeds.append((res[-1].final_state, "backward continuation"))
    first = simulate_cell(params, settings=st)
    c = first.classification
    amp = max(c.x_max - c.x_min, 2 * params.b, 1e-3) if np.isfinite(c.x_max) else 1.0
    mid = 0.5 * (c.x_max + c.x_min) if np.isfinite(c.x_max) else params.b
    vamp = amp * params.w
    scale = (mid - amp, mid + amp, -vamp, vamp)
    seeds += [(s, "grid") for s in initial_conditions(params, scale, *grid)]
    found: dict[str, tuple[Motion, int]] = {}
    for k, (u0, how) in enumerate(seeds):
        r = first if k == 0 else simulate_cell(params, u0, settings=st)
        cl = r.classification
        if cl.status == "diverged":
            continue
        key = cl.label_npq or cl.motion
        if key in found:
            found[key] = (found[key][0], found[key][1] + 1)
            continue
        pm = simulate_point(params, settings=st, result=r, seed=how, min_periods=min_periods)
        found[key] = (pm, 1)
    search = Search(params, len(seeds), found)
    if sweep is not None and len(sweep):
        for t in targets:
            if t in found:
                continue
            rows = sweep[sweep["label_npq"] == t]
            if not len(rows):
                continue
            # nearest swept values first; the sweep's label must persist when re-simulated
            order = np.argsort(np.abs(rows["value"].to_numpy(dtype=float) - params.w))
            tried = []
            for k in order[:max_retries]:
                w = float(rows["value"].iloc[int(k)])
                r, how = reach(params, [w], sweep=sweep, settings=st)
                pm = simulate_point(params.with_(w=w), settings=st, result=r[w], seed=how,
                                    min_periods=min_periods)
                tried.append(f"{w:.4g} -> {pm.npq}")
                if pm.npq == t:
                    search.elsewhere[t] = pm
                    break
            else:
                search.unconfirmed[t] = tried
    return search


def basin_box(params, settings, starts: int = 32) -> tuple[float, float, float, float]:
    """The finder's start box, widened (15 % margin) to hold the section points of the
    attractors that ``starts`` seeded starts reach (so every attractor is inside the picture)."""
    x0, hx, v0, hv = start_box(params)
    lo = np.array([x0 - hx, v0 - hv])
    hi = np.array([x0 + hx, v0 + hv])
    ca = find_attractors(params, FinderOptions(starts=starts), settings=settings)
    for a in ca.attractors:
        p = a.points[:, :2]
        lo, hi = np.minimum(lo, p.min(axis=0)), np.maximum(hi, p.max(axis=0))
    pad = 0.15 * (hi - lo)
    return (float(lo[0] - pad[0]), float(hi[0] + pad[0]), float(lo[1] - pad[1]),
            float(hi[1] + pad[1]))  # fmt: skip


# ------------------------------------------------------------------------------ the tables
def _motion_rows(motions: Sequence[tuple[str, str, int, Motion]]) -> pd.DataFrame:
    """One row per ``(key, role, hits, motion)``: the point sets' row of the motion
    (:func:`~gearsim.study.sweeps.motion_row`), its parameters, how it was reached and its
    samples per period."""
    rows = []
    for key, role, hits, m in motions:
        row = {"key": key, "role": role, "hits": int(hits), "seed": m.seed,
               "samples_per_period": int(m.samples_per_period), **m.params.to_dict()}
        row.update(motion_row(m.result, m.traj))
        rows.append(row)
    return pd.DataFrame.from_records(rows)


def _fig9_11_point(study: Study) -> ModelParameters:
    """The parameters of Figs 9-11's point (config ``points.fig9_11``, the paper's by default)."""
    spec = (study.config.get("points") or {}).get("fig9_11", COEXIST_POINT)
    fixed = {k: float(v[0] if isinstance(v, list) else v) for k, v in spec.items()}
    return study.parameters().model.with_(**fixed)


def _fig2(study: Study, sweeps: Mapping[str, pd.DataFrame]) -> tuple[pd.DataFrame, dict]:
    fixed = ((study.config.get("sweeps") or {}).get("b015") or {}).get("fixed") or {}
    b = fixed.get("b", 0.15)
    motions, notes = compute_fig2(study.parameters().model,
                                  settings=point_settings(study.settings),
                                  sweep=sweeps["b015"], b=b)  # fmt: skip
    df = _motion_rows([(str(I), "motion", 1, m) for I, m in motions.items()])
    return df, {"b": b, "notes": notes}


def _fig9_11(study: Study, sweeps: Mapping[str, pd.DataFrame]) -> tuple[pd.DataFrame, dict]:
    p = _fig9_11_point(study)
    search = search_attractors(p, settings=point_settings(study.settings), sweep=sweeps["b015"])
    rows = [(k, "found", hits, m) for k, (m, hits) in search.found.items()]
    rows += [(k, "elsewhere", 0, m) for k, m in search.elsewhere.items()]
    return _motion_rows(rows), {"params": p.to_dict(), "tried": search.tried,
                                "unconfirmed": search.unconfirmed}


def _basins(study: Study, p: ModelParameters, extra: dict) -> tuple[pd.DataFrame, dict]:
    st = study.settings.with_(method="rk4")
    n = basin_n(study.settings)
    g = basin_grid(p, n=n, settings=st, box=basin_box(p, st))
    att = g.attractor_table()
    return g.frame(), {"params": p.to_dict(), "n": n,
                       "attractors": att.to_dict(orient="records"), **extra}


def _fig19(study: Study, sweeps: Mapping[str, pd.DataFrame]) -> tuple[pd.DataFrame, dict]:
    return _basins(study, _fig9_11_point(study), {})


def _fig20(study: Study, sweeps: Mapping[str, pd.DataFrame]) -> tuple[pd.DataFrame, dict]:
    h = hysteresis(sweeps["hysteresis"])
    if h.band is None:
        w = 0.62
        note = "no hysteresis band found in the sweep; drawn at w = 0.62"
    else:
        w = round(0.5 * (h.band[0] + h.band[1]), 4)
        note = f"hysteresis band {h.band[0]:.4f} <= w <= {h.band[1]:.4f}; drawn at its middle"
    return _basins(study, study.parameters().model.with_(w=w), {"w": w, "note": note})


_JOBS = {"fig2": _fig2, "fig9_11": _fig9_11, "fig19": _fig19, "fig20": _fig20}


def figure_table(name: str, study: Study, sweeps: Mapping[str, pd.DataFrame]
                 ) -> tuple[pd.DataFrame, dict[str, Any]]:
    """The figure-data table ``name`` (:data:`~gearsim.study.figure_tables.FIGURE_DATA`) and
    what it states beside its rows, from the study and the sweep tables it reads."""
    if name not in FIGURE_DATA:
        raise UsageError(f"unknown figure-data table '{name}'; allowed: "
                         f"{', '.join(FIGURE_DATA)}")
    missing = [s for s in FIGURE_DATA[name].sweeps if s not in sweeps]
    if missing:
        raise UsageError(f"figure-data table '{name}' reads the sweep(s) {', '.join(missing)}: "
                         "give each as --sweep NAME=PATH")
    return _JOBS[name](study, sweeps)
