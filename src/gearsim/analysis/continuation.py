"""Pseudo-arclength continuation of periodic orbits in one parameter, with located bifurcations.

Unknowns ``u = (y, lam)``: the section state over the model's free states and the parameter
``lam`` (any :class:`~gearsim.dynamics.parameters.ModelParameters` name). The branch is the
solution curve
of ``G(y, lam) = P^n(y; lam) - y = 0`` (:mod:`gearsim.analysis.orbits`); ``dG/dy = M - I`` comes
from the
variational equations, ``dG/dlam`` from a forward difference of the map (step ``1e-7 (1 +
|lam|)``; its error only slows the corrector, never moves the solution).

The predictor-corrector, the test functions and the location of events between two points are
:mod:`gearsim.analysis.corrector`; the settings
:class:`gearsim.analysis.continuation_options.Continuation`.

Branch switching at a period doubling: the period-``2n`` branch leaves the located point along
the critical eigenvector ``v`` (multiplier -1) with ``lam`` fixed to first order, so its first
point solves ``P^{2n}(y) = y`` on the hyperplane ``v . (y - y*) = ds`` (the pitchfork of the
doubled map); it is then continued like any branch.
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any

import numpy as np
import pandas as pd

from gearsim.analysis.continuation_options import BUDGET, Continuation
from gearsim.analysis.corrector import BranchPoint, BranchProblem, branch_events, critical_kind
from gearsim.analysis.orbits import (
    KIND_PD,
    OrbitError,
    PeriodicOrbit,
    find_periodic_orbit,
    section_map,
)
from gearsim.dynamics.parameters import ModelParameters, ParameterError

COLUMNS = (
    "branch", "period", "name", "value", "x", "v", "norm", "amplitude", "mu_max", "mu_re",
    "mu_im", "stable", "critical_kind", "event", "grazing_margin", "boundary",
)


def _row(prob: BranchProblem, branch: int, n: int, pt: BranchPoint, event: str = "",
         boundary: str = "") -> dict[str, Any]:
    mu = pt.mu
    return {
        "branch": branch,
        "period": n,
        "name": prob.name,
        "value": pt.lam,
        "x": float(pt.y[0]),
        "v": float(pt.y[1]),
        "norm": float(np.linalg.norm(pt.y[prob.dims])),
        "amplitude": pt.amplitude,
        "mu_max": float(abs(mu[0])),
        "mu_re": [float(m.real) for m in mu],
        "mu_im": [float(m.imag) for m in mu],
        "stable": bool(abs(mu[0]) < 1.0),
        "critical_kind": critical_kind(mu[0]),
        "event": event,
        "grazing_margin": pt.margin,
        "boundary": boundary,
    }


def continue_orbit(
    params: ModelParameters,
    name: str,
    start: float,
    stop: float,
    orbit: PeriodicOrbit | None = None,
    *,
    n: int | None = None,
    config: Continuation | None = None,
) -> pd.DataFrame:
    """Continue a periodic orbit in parameter ``name`` from ``start`` towards ``stop``.

    Parameters
    ----------
    params
        Model parameters; ``name`` is set to ``start`` (or taken from ``orbit``).
    orbit
        Starting orbit at ``name = start`` (:func:`gearsim.analysis.orbits.find_periodic_orbit`);
        default: simulated from rest at ``start`` and refined for period ``n``.
    n
        Period of the branch (default: ``orbit.n``).

    Returns
    -------
    DataFrame, one row per branch point (columns :data:`COLUMNS`): ``branch`` (0 the start
    branch; period-doubled branches get new numbers), ``period``, parameter ``value``, section
    ``x``, ``v``, ``norm`` (Euclidean norm of the section state over the free states),
    ``mu_max``, the multipliers (``mu_re``, ``mu_im``, decreasing modulus), ``stable``,
    ``critical_kind``, ``event`` (``""`` on regular points; ``fold``, ``period_doubling``,
    ``neimark_sacker``, ``grazing`` on located points, inserted in branch order),
    ``grazing_margin`` and the ``boundary`` that grazes. ``df.attrs`` holds the parameters,
    the stop reasons and the wall time.
    """
    cfg = config or Continuation()
    t0 = time.perf_counter()
    p0, orbit = _start_orbit(params, name, start, stop, orbit, n, cfg)
    n = orbit.n
    rows: list[dict[str, Any]] = []
    prob = BranchProblem(p0, name, n, cfg)
    G, M, dGdl = prob.evaluate(orbit.state, start)
    direction = 1.0 if stop > start else -1.0
    first = prob.point(orbit.state, start, M, dGdl, None)
    if first.tangent[-1] * direction < 0:
        first.tangent = -first.tangent
    if cfg.parameter_steps:
        f = 1.0 / max(abs(float(first.tangent[-1])), 1e-2)
        cfg = dataclasses.replace(cfg, ds=cfg.ds * f, ds_min=cfg.ds_min * f,
                                  ds_max=cfg.ds_max * f, parameter_steps=False)
    reasons = _run_jobs(p0, name, n, first, min(start, stop), max(start, stop), rows, cfg)
    df = pd.DataFrame(rows, columns=list(COLUMNS))
    df.attrs.update(
        params=p0.to_dict(), name=name, start=start, stop=stop, reasons=reasons,
        wall_s=time.perf_counter() - t0,
        status=BUDGET if any(f"{BUDGET}: " in r for r in reasons) else "ok",
    )
    return df


def _start_orbit(params: ModelParameters, name: str, start: float, stop: float,
                 orbit: PeriodicOrbit | None, n: int | None,
                 cfg: Continuation) -> tuple[ModelParameters, PeriodicOrbit]:
    """The parameters and the orbit a continuation starts from (``name`` set to ``start``)."""
    if name not in ModelParameters.names():
        raise ParameterError(
            f"continuation parameter 'name' = {name!r}; allowed: "
            f"{', '.join(ModelParameters.names())}"
        )
    if orbit is None:
        if n is None:
            raise ParameterError("continue_orbit needs 'orbit' or the period 'n'")
        orbit = find_periodic_orbit(params.with_(**{name: start}), n, None, cfg.settings,
                                    grazing=False)
    n = orbit.n
    p0 = orbit.params
    lam0 = float(getattr(p0, name))
    if not math.isclose(lam0, start, rel_tol=0, abs_tol=1e-12):
        p0 = p0.with_(**{name: start})
        orbit = find_periodic_orbit(p0, n, orbit.state, cfg.settings, grazing=False)
    if start == stop:
        raise ParameterError(f"continuation range of '{name}' is empty: from = to = {start}")
    return p0, orbit


def _run_jobs(p0: ModelParameters, name: str, n: int, first: BranchPoint, lo: float, hi: float,
              rows: list[dict[str, Any]], cfg: Continuation) -> list[str]:
    """Continue the start branch and the branches switched onto at its period doublings (to
    ``cfg.switch_depth``); append their rows; return the stop reasons."""
    reasons: list[str] = []
    # jobs: continue a branch ("run"), or switch onto the doubled branch at a period doubling
    # ("switch"). The doublings of one branch form a group; a doubled branch that ends at
    # another doubling of its group (a period-2n bubble joining two doublings) makes the switch
    # there redundant.
    jobs: list[dict[str, Any]] = [dict(kind="run", branch=0, n=n, pt=first, origins=[],
                                       own=-1, group=None, depth=0)]
    reached: dict[int, set[int]] = {}
    next_branch = 1
    while jobs:
        if cfg.out_of_budget():
            reasons.append(f"{BUDGET}: wall-clock budget spent, {len(jobs)} branch job(s) "
                           "not run")
            break
        job = jobs.pop(0)
        nb = job["n"]
        if job["kind"] == "switch":
            pd_pt = job["pt"]
            if job["own"] in reached[job["group"]]:
                reasons.append(f"no switch at {name} = {pd_pt.lam:.8f}: the doubled branch of "
                               "another doubling ends there")
                continue
            sw = _switch(BranchProblem(p0, name, nb // 2, cfg), pd_pt, cfg)
            if sw is None:
                reasons.append(f"branch switch at {name} = {pd_pt.lam:.8f} failed")
                continue
            jobs.insert(0, dict(job, kind="run", branch=next_branch, pt=sw))
            next_branch += 1
            continue
        branch, depth = job["branch"], job["depth"]
        bprob = BranchProblem(p0, name, nb, cfg)
        reason, new, hit = _run_branch(bprob, branch, job["pt"], lo, hi, rows, cfg,
                                       origins=job["origins"], own=job["own"])
        reasons.append(f"branch {branch} (period {nb}): {reason}")
        if hit is not None and job["group"] is not None:
            reached[job["group"]].add(hit)
        if depth < cfg.switch_depth and new:
            gid = len(reached)
            reached[gid] = set()
            origins = [_orbit_points(bprob, q) for q in new]
            for k, pd_pt in enumerate(new):
                jobs.append(dict(kind="switch", n=2 * nb, pt=pd_pt, origins=origins, own=k,
                                 group=gid, depth=depth + 1))
    return reasons


def _switch(prob: BranchProblem, pd_pt: BranchPoint, cfg: Continuation) -> BranchPoint | None:
    """First point of the period-doubled branch at a located period doubling."""
    mu, vecs = np.linalg.eig(pd_pt.M)
    k = int(np.argmin(np.abs(mu + 1.0)))
    v = np.real(vecs[:, k])
    v /= np.linalg.norm(v)
    n2 = 2 * prob.n
    dprob = BranchProblem(prob.base, prob.name, n2, cfg)
    d = prob.d
    for ds in (1e-3, 3e-3, 1e-2, 3e-4):
        for sgn in (1.0, -1.0):
            normal = np.concatenate([sgn * v, [0.0]])
            anchor = np.concatenate([pd_pt.y[prob.dims] + sgn * ds * v, [pd_pt.lam]])
            y0 = dprob.full(anchor[:d], pd_pt.y)
            try:
                yy, lam, M, dGdl = dprob.correct(y0, pd_pt.lam, normal, anchor)
            except (OrbitError, np.linalg.LinAlgError):
                continue
            # reject the period-n orbit itself
            yn, _ = section_map(prob.params(lam), yy, prob.n, cfg.settings, jacobian=False)
            if float(np.max(np.abs(yn[prob.dims] - yy[prob.dims]))) < 1e-3 * ds:
                continue
            pt = dprob.point(yy, lam, M, dGdl, normal)
            return pt
    return None


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Euclidean distance of point ``p`` to the segment ``[a, b]``."""
    ab = b - a
    L2 = float(ab @ ab)
    s = 0.0 if L2 == 0.0 else min(max(float((p - a) @ ab) / L2, 0.0), 1.0)
    return float(np.linalg.norm(p - (a + s * ab)))


def _orbit_points(prob: BranchProblem, pt: BranchPoint) -> np.ndarray:
    """The ``n`` section points of the orbit at ``pt`` as ``(y_free, lam)`` rows."""
    from gearsim.cell.simulate import run_periods

    r = run_periods(prob.params(pt.lam), pt.y, prob.n, prob.cfg.settings)
    sec = np.asarray(r.summaries.section, dtype=float)[:, : len(pt.y)]
    return np.column_stack([sec[:, prob.dims], np.full(len(sec), pt.lam)])


def _run_branch(prob: BranchProblem, branch: int, first: BranchPoint, lo: float, hi: float,
                rows: list[dict[str, Any]], cfg: Continuation,
                origins: list[np.ndarray] | None = None,
                own: int = -1) -> tuple[str, list[BranchPoint], int | None]:
    """Continue one branch; append rows; return (stop reason, located period doublings, index
    of the origin it ended at).

    A closed branch ends where it returns through a doubling point of its parent (``origins``:
    per doubling, the parent orbit's section points as ``(y, lam)`` rows; ``own`` the one it
    was switched at) or through its own first point: a doubled branch joining two doublings
    (a bubble), or coming back through its own doubling (it then continues as the same orbit
    shifted by ``n/2`` periods), and an isola would otherwise be traced round and round until
    ``max_points``.
    """
    n = prob.n
    d = prob.d
    pt = first
    origins = list(origins or [])
    targets = [(k, o) for k, pts in enumerate(origins) for o in np.atleast_2d(pts)]
    if own < 0:
        targets.append((-1, np.concatenate([first.y[prob.dims], [first.lam]])))
    home = [o for k, o in targets if k == own or k < 0]  # where the branch starts
    far = 0.0
    rows.append(_row(prob, branch, n, pt))
    ds = cfg.ds
    pds: list[BranchPoint] = []
    for step in range(cfg.max_points):
        if cfg.out_of_budget():
            return (f"{BUDGET}: wall-clock budget spent at {prob.name} = {pt.lam:.8g}", pds,
                    None)
        u = np.concatenate([pt.y[prob.dims], [pt.lam]])
        while True:
            upred = u + ds * pt.tangent
            y0 = prob.full(upred[:d], pt.y)
            try:
                yy, lam, M, dGdl = prob.correct(y0, float(upred[d]), pt.tangent, upred,
                                                max_step=max(0.5 * ds, 1e-4))
                ok = True
            except (OrbitError, np.linalg.LinAlgError):
                ok = False
            if ok:
                break
            if cfg.out_of_budget():
                return (f"{BUDGET}: wall-clock budget spent at {prob.name} = {pt.lam:.8g}",
                        pds, None)
            ds *= 0.5
            if ds < cfg.ds_min:
                return (f"step size below {cfg.ds_min} at {prob.name} = {pt.lam:.8g}", pds,
                        None)
        new = prob.point(yy, lam, M, dGdl, pt.tangent)
        # closed branch: it passes through a doubling point (a pitchfork of P^n, where the
        # fold test changes sign without a fold); the interval is not tested, the point not kept
        u_new = np.concatenate([new.y[prob.dims], [new.lam]])
        seg = float(np.linalg.norm(u_new - u))
        for k, o in targets:
            if k == own or k < 0:  # its own start: only after it has gone away
                if far <= 4.0 * max(seg, cfg.ds):
                    continue
            if _segment_distance(o, u, u_new) < 0.1 * seg:
                what = "its start" if k < 0 else ("its own doubling" if k == own else
                                                  "another doubling of its parent")
                return (f"closed: returned through {what} at {prob.name} = {new.lam:.8g}",
                        pds, (k if k >= 0 else None))
        if home:
            far = max(far, min(float(np.linalg.norm(u_new - o)) for o in home))
        # the first interval of a switched branch starts on a branch point: skip its tests
        events = [] if (step == 0 and branch > 0) else branch_events(prob, pt, new, n)
        for ev_pt, kind, bnd in sorted(events, key=lambda e: abs(e[0].lam - pt.lam)):
            rows.append(_row(prob, branch, n, ev_pt, kind, bnd))
            if kind == KIND_PD:
                pds.append(ev_pt)
        rows.append(_row(prob, branch, n, new))
        if cfg.progress is not None and step % 10 == 9:
            cfg.progress(f"branch {branch} (period {n}): {step + 1} points, {prob.name} = "
                         f"{new.lam:.6f}, |mu|max = {abs(new.mu[0]):.4f}")
        # merged back into a shorter period (a doubled branch ending at its inverse doubling)
        if n > 1 and branch > 0:
            half = n // 2
            yn, _ = section_map(prob.params(new.lam), new.y, half, cfg.settings, jacobian=False)
            if float(np.max(np.abs(yn[prob.dims] - new.y[prob.dims]))) < 1e-7:
                # turned onto its parent at a doubling: which one (the nearest)
                near = [(float(np.linalg.norm(u_new - o)), k) for k, o in targets if k >= 0]
                hit = min(near)[1] if near and min(near)[0] < 4.0 * cfg.ds_max else None
                return (f"merged into period {half} at {prob.name} = {new.lam:.8g}", pds,
                        hit)
        pt = new
        if not (lo - 1e-12 <= pt.lam <= hi + 1e-12):
            return f"left [{lo}, {hi}] at {prob.name} = {pt.lam:.8g}", pds, None
        ds = min(cfg.ds_max, ds * 1.3)
    return f"{cfg.max_points} points", pds, None


def write_branches(df: pd.DataFrame, path) -> None:
    """Write a branch table as Parquet (``df.attrs`` as JSON schema metadata)."""
    import json
    import os
    from pathlib import Path

    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    table = pa.Table.from_pandas(df, preserve_index=False)
    meta = {b"gearsim.analysis.continuation": json.dumps(df.attrs, default=float).encode()}
    table = table.replace_schema_metadata({**(table.schema.metadata or {}), **meta})
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        pq.write_table(table, tmp)
        tmp.replace(path)
    finally:  # a full disk or a kill leaves the previous file and no temporary one
        if tmp.exists():
            tmp.unlink()
