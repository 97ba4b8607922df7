"""The plane atlas: bifurcation curves seeded from every boundary of a plane's pattern map.

Each boundary edge between two periodic cells (:mod:`gearsim.analysis.atlas_seeds`) says which
bifurcation to look for. A seed is located between the two cells from the simulated section
state of one of them: a period doubling or grazing by the secant on its test function along the
edge's parameter (:func:`gearsim.analysis.relocation.relocate_secant`, warm-started from the
cell's state), anything else (a jump, or a secant that fails) by a short continuation across
the edge whose located events become the seeds. The seed is then followed both ways across the
whole plane (:func:`gearsim.analysis.bifcurves.follow_curve`, steps adapted to the curvature,
one cell the unit).

Cost stays bounded by the seeds' order and deduplication: most edges of a boundary lie on one
curve, so the edges of the largest boundaries seed first, every followed curve marks the edges
within ``radius`` cells of it that it explains (same kind, period and grazing boundary) and a
marked edge seeds nothing; a seed that fails marks its neighbours as tried; a seed that lands on
a curve already followed is not followed again. ``workers`` seeds run at once (processes), two
in flight never within ``defer`` cells of each other for the same kind.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from gearsim.analysis.atlas_seeds import (
    Grid,
    Hint,
    boundary_edges,
    covered,
    distance_to_polyline,
    edge_hints,
    matches,
)
from gearsim.analysis.bifcurves import CURVE_COLUMNS, follow_curve
from gearsim.analysis.boundaries import is_jump
from gearsim.analysis.continuation import COLUMNS as BRANCH_COLUMNS
from gearsim.analysis.continuation import continue_orbit
from gearsim.analysis.continuation_options import BUDGET, Continuation
from gearsim.analysis.orbits import OrbitError, find_periodic_orbit
from gearsim.analysis.relocation import relocate_secant
from gearsim.dynamics.parameters import ModelParameters, ParameterError

#: the columns a curve table adds to :data:`CURVE_COLUMNS` (docs/orbits.md, "The plane atlas")
ATLAS_COLUMNS = (
    "flank", "seq", "source", "seed_i", "seed_j", "seed_i2", "seed_j2", "label_a", "label_b",
    "end_first", "end_last", "end_first_detail", "end_last_detail", "codim2_first",
    "codim2_last",
)
SEED_COLUMNS = (
    "point", "kind", "period", "boundary", "name", "value", "x", "v", "mu_max", "mu_re",
    "mu_im", "stable", "branch", "name2", "value2", "curve", "source", "seed_i", "seed_j",
    "seed_i2", "seed_j2", "label_a", "label_b",
)


def flank(boundary: str) -> str:
    """``face``, ``back``, ``bearing`` or ``""`` for a grazing boundary name."""
    if not boundary:
        return ""
    if boundary.startswith("x="):
        return "face" if "+" in boundary else "back"
    return "bearing"


@dataclass
class AtlasOptions:
    """Settings of :func:`plane_atlas` (distances in cells of the map)."""

    kinds: tuple[str, ...] = ("fold", "period_doubling", "grazing")
    max_period: int = 16
    max_period_jump: int = 4  # a jump's continuation only from orbits of at most this period
    workers: int = 1
    radius: float = 1.5  # an edge this close to a curve that explains it seeds nothing
    tried: float = 4.0  # a failed seed marks the edges of its kind this close as tried
    defer: float = 12.0  # two seeds of one kind in flight are at least this far apart
    #: a located seed this close to a curve of its kind already followed is on that curve
    #: (its polygon lies within ~``deviation`` of the curve, a refused step's chord within a
    #: cell): it is not followed again
    landed: float = 1.0
    max_failures: int = 60  # failed seeds of one kind, period and boundary before it stops
    max_fold_failures: int = 12  # the same for folds (each a continuation from both cells)
    step_cells: float = 40.0  # the longest curve step
    deviation: float = 0.3  # the curve polygon's distance from the curve (step control)
    max_points: int = 300  # points of a curve half
    method: str = "secant"
    fallback: int = 1  # secant failures of a curve half retried by a windowed continuation
    #: DP5 tolerance of the orbits that track a curve between its seed and its ends (the
    #: seeds and the codimension-2 points at the shooting's 1e-12): 2.5x fewer steps, the
    #: points within ~1e-8 of the 1e-12 ones (docs/decisions.md, "The plane atlas's cost")
    tracking_rtol: float | None = 1e-9
    config: Continuation = field(default_factory=Continuation)


@dataclass
class _Task:
    key: int  # index into the candidate table
    edge: dict[str, Any]
    hint: Hint
    curves: list[np.ndarray]  # the same kind's polylines when it was sent (cell units)


def _cell_params(base: ModelParameters, grid: Grid, i: int, j: int) -> ModelParameters:
    return base.with_(**{grid.x_name: grid.x_of(i), grid.y_name: grid.y_of(j)})


def _locate_seeds(base, grid, task: _Task, states, opts: AtlasOptions,
                  branches: list[pd.DataFrame]) -> list[dict]:
    """The located points of a task's edge (rows with ``name``, ``value`` = the x value and
    ``value2`` = the y value); the short continuations it ran are appended to ``branches``."""
    e, h = task.edge, task.hint
    axis = e["axis"]
    along = grid.x_name if axis == "x" else grid.y_name
    cell = grid.dx if axis == "x" else grid.dy
    cfg = Continuation(**{**opts.config.__dict__, "progress": None, "switch_depth": 0})
    order = (("a", "b") if h.start == "a" else ("b", "a"))
    found: list[dict] = []
    far: list[dict] = []  # located by the secant, but away from the edge

    def near_edge(row: dict) -> bool:
        u = grid.index([row["value"]], [row["value2"]])[0]
        return math.dist(u, (e["ci"], e["cj"])) <= opts.radius

    if h.kind in ("period_doubling", "grazing"):
        for s in order:
            i, j = (e["i"], e["j"]) if s == "a" else (e["i2"], e["j2"])
            p = _cell_params(base, grid, i, j)
            y = states.get((i, j))
            if y is None:
                continue
            try:
                r = relocate_secant(p, h.kind, h.boundary, h.period, along,
                                    float(getattr(p, along)), y, cell, cfg, wtol=1e-10,
                                    max_eval=20)
            except (OrbitError, ParameterError, np.linalg.LinAlgError):
                r = None
            if r is not None:
                row = _seed_row(r[0], h.kind, h.period, h.boundary, grid, axis, p)
                if near_edge(row):
                    return [row]
                # away from the edge: the cell's orbit may lie on another branch (beyond a
                # fold) than the one whose bifurcation the edge is; the other cell's state,
                # then a continuation along the chain's branch, may find the edge's own
                far.append(row)
    # a jump (or a secant that failed or landed away): a short continuation across the edge
    # from each cell in turn; every event it locates near the edge seeds
    for s in (order if (h.kind == "fold" or far) else order[:1]):
        i, j = (e["i"], e["j"]) if s == "a" else (e["i2"], e["j2"])
        i2, j2 = (e["i2"], e["j2"]) if s == "a" else (e["i"], e["j"])
        p = _cell_params(base, grid, i, j)
        y = states.get((i, j))
        if y is None:
            continue
        v0 = float(getattr(p, along))
        v1 = float(getattr(_cell_params(base, grid, i2, j2), along))
        stop = v0 + 2.5 * (v1 - v0)
        n = h.period if h.kind != "fold" else int(e[f"n_{s}"])
        if n > opts.max_period_jump:  # a continuation of a long orbit costs n times more
            continue
        try:
            orbit = find_periodic_orbit(p, n, y, cfg.settings, max_iter=20, grazing=False)
            c = Continuation(**{**cfg.__dict__, "ds": 0.2 * cell, "ds_max": 0.5 * cell,
                                "ds_min": 1e-4 * cell, "max_points": 40, "grazing": True,
                                "parameter_steps": True})
            br = continue_orbit(p, along, v0, stop, orbit, config=c)
        except (OrbitError, ParameterError, np.linalg.LinAlgError):
            continue
        branches.append(br.assign(name2=grid.y_name if axis == "x" else grid.x_name,
                                  value2=float(getattr(p, grid.y_name if axis == "x"
                                                       else grid.x_name))))
        ev = br[(br["event"] != "") & (br["branch"] == 0)]
        for _, r in ev.iterrows():
            # a jump seeds every kind it finds near the edge; a doubling or grazing the
            # secant did not find (or found away from the edge) its own kind, or the fold
            # the chain jumped at (a label change at a jump reads like a grazing or a
            # doubling)
            if r["event"] not in opts.kinds or r["event"] not in (h.kind, "fold"):
                continue
            row = _seed_row(r, r["event"], int(r["period"]), str(r["boundary"] or ""),
                            grid, axis, p)
            if r["event"] == h.kind and (r["event"] != "grazing" or
                                         row["boundary"] == h.boundary) and far \
                    and not near_edge(row):
                continue  # the far point again
            found.append(row)
        if found:
            return found
    return far


def _seed_row(r, kind: str, period: int, boundary: str, grid: Grid, axis: str,
              p: ModelParameters) -> dict[str, Any]:
    """A located seed as a point row in the plane (``value`` x, ``value2`` y)."""
    v = float(r["value"])
    x, y = (v, float(getattr(p, grid.y_name))) if axis == "x" else (
        float(getattr(p, grid.x_name)), v)
    return {"kind": kind, "period": int(period), "boundary": boundary, "name": grid.x_name,
            "value": x, "name2": grid.y_name, "value2": y, "x": float(r["x"]),
            "v": float(r["v"]), "mu_max": float(r["mu_max"]), "mu_re": list(r["mu_re"]),
            "mu_im": list(r["mu_im"]), "stable": bool(r["stable"]), "axis": axis}


def _run_task(args) -> dict[str, Any]:
    """Locate a task's seed and follow it both ways (one process)."""
    base, grid, task, states, opts = args
    t0 = time.process_time()
    out: dict[str, Any] = {"key": task.key, "seeds": [], "curves": [], "why": "",
                           "branches": []}
    try:
        seeds = _locate_seeds(base, grid, task, states, opts, out["branches"])
    except Exception as exc:  # a seed that cannot be located is a failed seed, never a crash
        seeds = []
        out["why"] = f"{type(exc).__name__}: {exc}"
    for s in seeds:
        u = grid.index([s["value"]], [s["value2"]])
        same = [c for k, c in task.curves if k == (s["kind"], s["period"], s["boundary"])]
        if any(float(distance_to_polyline(u, c)[0]) < opts.landed for c in same):
            s["curve"] = -2  # landed on a curve already followed: not followed again
            out["seeds"].append(s)
            continue
        halves = _follow_both(base, grid, s, opts, [c for k, c in task.curves
                                                    if k == (s["kind"], s["period"],
                                                             s["boundary"])])
        s["curve"] = len(out["curves"])
        out["seeds"].append(s)
        out["curves"].append(halves)
        task.curves.append(((s["kind"], s["period"], s["boundary"]),
                            grid.index(*_xy(halves))))
    out["cpu_s"] = time.process_time() - t0
    return out


def _xy(halves: list[pd.DataFrame]) -> tuple[np.ndarray, np.ndarray]:
    c = _join(halves)
    return c["value"].to_numpy(), c["value2"].to_numpy()


def _follow_both(base: ModelParameters, grid: Grid, s: dict, opts: AtlasOptions,
                 avoid: list[np.ndarray]):
    """Both halves of the curve through seed ``s`` (the second one empty when the first
    closed)."""
    p = base.with_(**{grid.y_name: s["value2"], grid.x_name: s["value"]})
    t0 = (0.0, 1.0) if s["axis"] == "x" else (1.0, 0.0)
    point = {k: s[k] for k in ("kind", "period", "boundary", "name", "value", "x", "v",
                               "mu_max", "mu_re", "mu_im", "stable")}
    halves = []
    for sign in (-1.0, 1.0):
        c = follow_curve(p, point, grid.y_name, grid.y_max if sign > 0 else grid.y_min,
                         step2=opts.step_cells * grid.dy, config=opts.config,
                         max_points=opts.max_points, method=opts.method,
                         range2=(grid.y_min, grid.y_max), range1=(grid.x_min, grid.x_max),
                         cell=(grid.dx, grid.dy), deviation=opts.deviation,
                         tangent=(sign * t0[0], sign * t0[1]), avoid=avoid,
                         fallback=opts.fallback, rtol=opts.tracking_rtol)
        halves.append(c)
        if c.attrs.get("end") == "closed":
            break
    return halves


def _join(halves: list[pd.DataFrame]) -> pd.DataFrame:
    """One curve from its halves: the first reversed, then the second without the seed."""
    parts = [halves[0].iloc[::-1]] + [h.iloc[1:] for h in halves[1:]]
    return pd.concat(parts, ignore_index=True)


def _jumps(edges: pd.DataFrame) -> np.ndarray:
    """Per edge, whether it is a jump (the accounting's test, docs/atlas.md)."""
    if not len(edges) or "dc_a" not in edges:
        return np.zeros(len(edges), dtype=bool)
    return np.array([is_jump(a, b, xa1 - xa0, xb1 - xb0) for a, b, xa0, xa1, xb0, xb1 in zip(
        edges["dc_a"], edges["dc_b"], edges["x_min_a"], edges["x_max_a"], edges["x_min_b"],
        edges["x_max_b"], strict=True)], dtype=bool)


def _candidates(edges: pd.DataFrame, opts: AtlasOptions) -> pd.DataFrame:
    """One row per (edge, hint) to try, the largest boundaries' densest edges first.

    An edge of one period whose readings jump (:func:`gearsim.analysis.boundaries.is_jump`:
    a grazing or a doubling changes the motion continuously) is tried as a fold first, and
    those folds before everything else: one fold curve explains a whole jump line, which its
    labels (the contacts change) would otherwise seed as grazings that land elsewhere."""
    rows = []
    jump = _jumps(edges)
    for k, e in enumerate(edges.to_dict("records")):
        hints = edge_hints(e)
        first = jump[k] and int(e["n_a"]) == int(e["n_b"]) and hints[0].kind != "fold"
        if first:
            hints = [Hint("fold", int(e["n_a"]), "", hints[0].start), *hints]
        for h in hints:
            # the cascade to max_period: a doubling of period n makes 2n
            top = h.period * (2 if h.kind == "period_doubling" else 1)
            if h.kind in opts.kinds and top <= opts.max_period:
                rows.append({"edge": k, "hint": h, "key": h.key, "ci": e["ci"], "cj": e["cj"],
                             "jump": bool(jump[k]), "prio": int(not (first and h.kind == "fold"))})
    cand = pd.DataFrame(rows, columns=["edge", "hint", "key", "ci", "cj", "jump", "prio"])
    if not len(cand):
        return cand
    from scipy.spatial import cKDTree

    size = cand.groupby("key")["edge"].transform("size")
    dens = np.zeros(len(cand))
    for _key, idx in cand.groupby("key").groups.items():
        pts = cand.loc[idx, ["ci", "cj"]].to_numpy()
        dens[np.asarray([cand.index.get_loc(i) for i in idx])] = [
            len(v) for v in cKDTree(pts).query_ball_point(pts, 3.0)]
    cand = cand.assign(size=size.to_numpy(), dens=dens)
    return cand.sort_values(["prio", "size", "dens", "ci", "cj"],
                            ascending=[True, False, False, True, True],
                            kind="stable").reset_index(drop=True)


def plane_atlas(base: ModelParameters, cells: pd.DataFrame, grid: Grid,
                opts: AtlasOptions | None = None) -> dict[str, Any]:
    """The curves of a plane seeded from its map's boundaries.

    Returns ``{"curves", "seeds", "edges", "reasons", "stats", "branches"}``: the curve table
    (columns
    :data:`CURVE_COLUMNS` + :data:`ATLAS_COLUMNS`, the codimension-2 columns -1 here), the
    located seeds (:data:`SEED_COLUMNS`), the boundary edges with the curve that explains
    each (``curve``, -1 none), the curves' stop reasons, counts, and the short continuations
    that located the seeds at jumps.
    """
    opts = opts or AtlasOptions()
    log = opts.config.progress or (lambda _s: None)
    t0 = time.perf_counter()
    edges = boundary_edges(cells)
    cand = _candidates(edges, opts)
    states = {(int(i), int(j)): np.asarray(s, dtype=float) for i, j, s in
              zip(cells["i"], cells["j"], cells["final_state"], strict=True)
              if s is not None and len(s)}
    pts = cand[["ci", "cj"]].to_numpy() if len(cand) else np.zeros((0, 2))
    jumps = cand["jump"].to_numpy(dtype=bool) if len(cand) else np.zeros(0, dtype=bool)
    # the two cells' periods of each candidate's edge (a fold marks the jumps of its period)
    periods = (edges[["n_a", "n_b"]].to_numpy()[cand["edge"].to_numpy(dtype=np.int64)]
               if len(cand) else np.zeros((0, 2), dtype=np.int64))
    status = np.zeros(len(cand), dtype=np.int64)  # 0 pending, 1 covered, 2 tried, 3 sent
    curves: list[tuple[tuple, np.ndarray, list[pd.DataFrame], dict]] = []
    seeds: list[dict] = []
    branches: list[pd.DataFrame] = []
    failures: dict[tuple, int] = {}
    reasons: list[str] = []
    log(f"{len(edges)} boundary edges between periodic cells, {len(cand)} seeds to try "
        f"({cand['key'].nunique() if len(cand) else 0} kinds of boundary)")

    def mark(key, poly):
        same = np.array([matches(k, key) for k in cand["key"]], dtype=bool)
        if key[0] == "fold":  # a fold explains a jump of its period, whatever the labels say
            same |= jumps & (periods == key[1]).any(axis=1)
        todo = same & (status != 1)
        if todo.any():
            idx = np.nonzero(todo)[0]
            hit = covered(pts[idx], [poly], opts.radius)
            status[idx[hit]] = 1

    def next_task(inflight: list[_Task]) -> _Task | None:
        for k in np.nonzero(status == 0)[0]:
            key = cand.at[k, "key"]
            cap = opts.max_fold_failures if key[0] == "fold" else opts.max_failures
            if failures.get(key, 0) >= cap:
                status[k] = 2
                continue
            if any(t.hint.key == key and math.dist(pts[k], pts[t.key]) < opts.defer
                   for t in inflight):
                continue
            status[k] = 3
            e = edges.iloc[int(cand.at[k, "edge"])].to_dict()
            return _Task(int(k), e, cand.at[k, "hint"],
                         [(c[0], c[1]) for c in curves if matches(key, c[0])])
        return None

    def done(task: _Task, res: dict) -> None:
        k = task.key
        e = task.edge
        status[k] = 2
        got = list(res["seeds"])
        branches.extend(res["branches"])
        new = 0
        for s in got:
            s.update(source="map", seed_i=int(e["i"]), seed_j=int(e["j"]),
                     seed_i2=int(e["i2"]), seed_j2=int(e["j2"]), label_a=e["label_a"],
                     label_b=e["label_b"])
            if s["curve"] >= 0:
                halves = res["curves"][s["curve"]]
                key = (s["kind"], s["period"], s["boundary"])
                poly = grid.index(*_xy(halves))
                dup = [c for c in curves if c[0] == key and
                       float(np.max(distance_to_polyline(poly, c[1]))) < 1.0]
                if dup:
                    s["curve"] = -2
                else:
                    s["curve"] = len(curves)
                    curves.append((key, poly, halves, dict(s)))
                    mark(key, poly)
                    new += 1
                    for hv, side in zip(halves, ("first", "last"), strict=False):
                        reasons.append(f"curve {s['curve']} ({s['kind']} {s['boundary']} "
                                       f"period {s['period']}) {side} end: "
                                       f"{hv.attrs.get('reason', '')}, {len(hv)} points")
            seeds.append(s)
        if not new:  # nothing new here: its neighbours of the same kind are not tried again
            key = task.hint.key
            if not got:
                failures[key] = failures.get(key, 0) + 1
            same = np.array([matches(kk, key) for kk in cand["key"]], dtype=bool)
            near = same & (status == 0) & (np.hypot(*(pts - pts[k]).T) <= opts.tried)
            status[near] = 2
        left = int((status == 0).sum())
        log(f"seed {e['label_a']} | {e['label_b']} at cells ({e['i']}, {e['j']})-"
            f"({e['i2']}, {e['j2']}), {task.hint.kind} {task.hint.boundary} period "
            f"{task.hint.period}: {len(got)} located, {new} new curve(s) "
            f"({res.get('cpu_s', 0):.1f} CPU-s){' ' + res['why'] if res['why'] else ''}; "
            f"{len(curves)} curves, {left} seeds pending")

    _drive(base, grid, states, opts, next_task, done)
    cur = _curve_table(curves, grid)
    ends = [_end_of(cid, side, hv, grid, c[3])
            for cid, c in enumerate(curves)
            for side, hv in zip(("first", "last"), (c[2][0], c[2][-1]), strict=True)]
    edges = edges.assign(curve=_explaining_curve(edges, curves, opts))
    wall = time.perf_counter() - t0
    stats = {"edges": len(edges), "candidates": len(cand), "seeds": len(seeds),
             "curves": len(curves), "tried": int((status == 2).sum()),
             "covered": int((status == 1).sum()), "wall_s": wall,
             "budget": bool(opts.config.out_of_budget())}
    seed_df = pd.DataFrame([{**{c: s.get(c) for c in SEED_COLUMNS}, "point": k, "branch": 0}
                            for k, s in enumerate(seeds)], columns=list(SEED_COLUMNS))
    br = (pd.concat(branches, ignore_index=True) if branches
          else pd.DataFrame(columns=[*BRANCH_COLUMNS, "name2", "value2"]))
    return {"curves": cur, "seeds": seed_df, "edges": edges, "reasons": reasons,
            "stats": stats, "branches": br, "ends": ends}


def _end_of(cid: int, side: str, half: pd.DataFrame, grid: Grid, s: dict) -> dict[str, Any]:
    """A curve end: its last point, orbit state and direction, the kind and why it ended."""
    last = half.iloc[-1]
    return {"curve": cid, "side": side, "w": float(last["value"]),
            "y": float(last["value2"]), "state": half.attrs.get("last_state"),
            "tangent": half.attrs.get("last_tangent"), "end": half.attrs.get("end", ""),
            "kind": s["kind"], "boundary": s["boundary"], "period": s["period"]}


def apply_codim2(curves: pd.DataFrame, ends: list[dict], grid: Grid) -> pd.DataFrame:
    """The curve table with each end that converged to a codimension-2 point ending there:
    ``end_*`` ``codim2``, ``codim2_*`` its id, and the curve point located at it (the
    first condition's point where the second vanishes) added as the curve's end point."""
    out = []
    for cid, c in curves.groupby("curve", sort=True):
        c = c.sort_values("seq")
        for e in ends:
            if e["curve"] != cid or "codim2" not in e:
                continue
            pt = e["codim2_point"]
            r = pt["row"]
            add = {**c.iloc[0 if e["side"] == "first" else -1].to_dict(),
                   "value": pt["w"], "value2": pt["y"], "x": float(r["x"]),
                   "v": float(r["v"]), "mu_max": float(r["mu_max"]),
                   "mu_re": list(r["mu_re"]), "mu_im": list(r["mu_im"]),
                   "stable": bool(r["stable"])}
            side = e["side"]
            add[f"end_{side}"] = "codim2"
            c = c.assign(**{f"end_{side}": "codim2", f"codim2_{side}": int(e["codim2"]),
                            f"end_{side}_detail": f"{c[f'end_{side}_detail'].iloc[0]}; "
                            f"ends at codimension-2 point {e['codim2']}"})
            add = {**add, f"codim2_{side}": int(e["codim2"]),
                   f"end_{side}_detail": c[f"end_{side}_detail"].iloc[0]}
            row = pd.DataFrame([add], columns=c.columns)
            c = pd.concat([row, c] if side == "first" else [c, row], ignore_index=True)
        out.append(c.assign(seq=np.arange(len(c))))
    if not out:
        return curves
    return pd.concat(out, ignore_index=True)[list(curves.columns)]


def _drive(base, grid, states, opts: AtlasOptions, next_task, done) -> None:
    """Run tasks until none is left or the budget is spent, in rounds of ``workers`` tasks
    (processes) whose results are taken in the order they were sent: the atlas does not
    depend on which process finishes first."""
    pool = None
    if opts.workers > 1:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        pool = ProcessPoolExecutor(max_workers=opts.workers, mp_context=mp.get_context("fork"))
    try:
        while not opts.config.out_of_budget():
            batch: list[_Task] = []
            while len(batch) < opts.workers:
                t = next_task(batch)
                if t is None:
                    break
                batch.append(t)
            if not batch:
                return
            args = [(base, grid, t, _states_near(states, t), opts) for t in batch]
            results = (list(pool.map(_run_task, args)) if pool is not None and len(batch) > 1
                       else [_run_task(a) for a in args])
            for t, res in zip(batch, results, strict=True):
                done(t, res)
    finally:
        if pool is not None:
            pool.shutdown()


def _states_near(states: dict, t: _Task) -> dict:
    e = t.edge
    return {k: states[k] for k in ((e["i"], e["j"]), (e["i2"], e["j2"])) if k in states}


def _curve_table(curves, grid: Grid) -> pd.DataFrame:
    """The curve table: each curve's points in order along it, the atlas columns filled."""
    out = []
    for cid, (_key, _poly, halves, s) in enumerate(curves):
        c = _join(halves)
        first, last = halves[0].attrs, (halves[1].attrs if len(halves) > 1 else halves[0].attrs)
        c.insert(0, "curve", cid)
        c = c.assign(flank=flank(s["boundary"]), seq=np.arange(len(c)), source="map",
                     seed_i=s["seed_i"], seed_j=s["seed_j"], seed_i2=s["seed_i2"],
                     seed_j2=s["seed_j2"], label_a=s["label_a"], label_b=s["label_b"],
                     end_first=first.get("end", ""), end_last=last.get("end", ""),
                     end_first_detail=first.get("reason", ""),
                     end_last_detail=last.get("reason", ""), codim2_first=-1, codim2_last=-1)
        c.attrs = {}
        out.append(c)
    cols = list(CURVE_COLUMNS) + list(ATLAS_COLUMNS)
    if not out:
        return pd.DataFrame(columns=cols)
    return pd.concat(out, ignore_index=True)[cols]


def _explaining_curve(edges: pd.DataFrame, curves, opts: AtlasOptions) -> np.ndarray:
    """Per edge, the nearest curve within ``radius`` whose kind its labels point to (-1)."""
    best = np.full(len(edges), -1, dtype=np.int64)
    dist = np.full(len(edges), np.inf)
    pts = edges[["ci", "cj"]].to_numpy()
    keys = [[h.key for h in edge_hints(e)] for e in edges.to_dict("records")]
    for cid, (key, poly, _h, _s) in enumerate(curves):
        ok = np.array([any(matches(k, key) for k in ks) for ks in keys], dtype=bool)
        if not ok.any():
            continue
        idx = np.nonzero(ok)[0]
        d = distance_to_polyline(pts[idx], poly)
        better = (d <= opts.radius) & (d < dist[idx])
        best[idx[better]] = cid
        dist[idx[better]] = d[better]
    return best


__all__ = ["ATLAS_COLUMNS", "SEED_COLUMNS", "AtlasOptions", "BUDGET", "flank", "plane_atlas"]
