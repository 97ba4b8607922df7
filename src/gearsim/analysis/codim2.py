"""Codimension-2 points of a plane's bifurcation curves: where a curve ends inside the plane
(docs/orbits.md, "Codimension-2 points").

A codimension-2 point satisfies two defining conditions at once, each the zero of a test
function of one orbit: ``mu + 1`` (period doubling), ``mu - 1`` (fold), the signed distance of
a turning point to a contact boundary (grazing of ``x = +b`` or ``x = -b``). Kinds:
``pd_grazing``, ``fold_grazing``, ``double_grazing`` (both flanks), ``grazing_grazing``,
``pd_fold``, ``pd_pd``, ``cusp``.

At a curve end lost inside the plane, the test functions of the last point's orbit name the
second condition (one near its zero). Period doublings and grazings: Newton on the two test
functions of the orbit at ``(w, y)`` (:func:`newton2`, a grazing approached from its smooth
side). A fold: nested, the fold curve re-located at each value of the coordinate it was
stepped in and the second test function's zero along it found by the secant method
(:func:`locate_on_curve`). Each point is checked (:func:`check_point`): both test functions
recomputed with the full (state + tangent) error control (``residual_1``, ``residual_2``,
converged below 1e-8) and a Newton step of the two conditions in both parameters from there
(finite-difference Jacobian; ``step`` below 1e-6).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from gearsim.analysis.atlas_seeds import distance_to_polyline
from gearsim.analysis.continuation_options import Continuation
from gearsim.analysis.orbits import OrbitError, grazing_margin, section_map
from gearsim.analysis.relocation import (
    fold_test,
    pd_test,
    relocate_fold,
    relocate_secant,
    test_value,
)
from gearsim.dynamics.parameters import ModelParameters, ParameterError

CODIM2_COLUMNS = (
    "point", "plane", "kind", "conditions", "period", "boundary", "name", "value", "name2",
    "value2", "curves", "curve_kinds", "residual_1", "residual_2", "residual", "step",
    "iterations", "converged", "gap_cells", "x", "v", "mu_max", "mu_re", "mu_im",
)
#: both conditions met to this (test-function units) ...
RESIDUAL = 1e-8
#: ... and a Newton step of the two conditions below this in both parameters: converged
STEP = 1e-6
BOUNDARIES = ("x=+b", "x=-b")
#: a second condition is tried at a lost end only when its test function is this near zero
NEAR = 0.01


def _kind(a: tuple[str, str], b: tuple[str, str]) -> str:
    ka, kb = sorted((a[0], b[0]))
    if ka == kb == "grazing":
        return "double_grazing" if a[1] != b[1] else "grazing_grazing"
    return {("grazing", "period_doubling"): "pd_grazing", ("fold", "grazing"): "fold_grazing",
            ("fold", "period_doubling"): "pd_fold", ("fold", "fold"): "cusp",
            ("period_doubling", "period_doubling"): "pd_pd"}[(ka, kb)]


def _cond(c: tuple[str, str]) -> str:
    return f"{c[0]} {c[1]}".strip()


class _Curve:
    """The first condition: re-locates a point of curve ``(kind, boundary, n)`` at a value of
    the stepped coordinate; its points ``(w, y, state, row)``."""

    def __init__(self, base: ModelParameters, grid, kind: str, boundary: str, n: int,
                 cfg: Continuation):
        self.base, self.grid, self.kind, self.boundary, self.n = base, grid, kind, boundary, n
        self.cfg = cfg

    def point(self, fix_x: bool, c: float, along_guess: float, state: np.ndarray):
        g = self.grid
        if fix_x:
            p, along, win = self.base.with_(**{g.x_name: c}), g.y_name, g.dy
        else:
            p, along, win = self.base.with_(**{g.y_name: c}), g.x_name, g.dx
        p = p.with_(**{along: along_guess})
        try:
            if self.kind == "fold":
                r = relocate_fold(p, self.n, along, along_guess, state, win, self.cfg)
            else:
                r = relocate_secant(p, self.kind, self.boundary, self.n, along, along_guess,
                                    state, win, self.cfg, wtol=1e-11, max_eval=30,
                                    tangent_error=None)
        except (OrbitError, ParameterError, np.linalg.LinAlgError):
            return None
        if r is None:
            return None
        row, y = r
        v = float(row["value"])
        w, yv = (c, v) if fix_x else (v, c)
        return w, yv, y, row


def _second_value(base, grid, second: tuple[str, str], n: int, w: float, yv: float,
                  state: np.ndarray, cfg: Continuation) -> float | None:
    """The second test function at the curve point ``(w, yv)`` (orbit through ``state``)."""
    p = base.with_(**{grid.x_name: w, grid.y_name: yv})
    try:
        r = test_value(p, second[0], second[1], n, state, cfg)
    except (OrbitError, ParameterError, np.linalg.LinAlgError):
        return None
    return None if r is None else r[2]


def locate_on_curve(base: ModelParameters, grid, first: tuple[str, str], second: tuple[str, str],
                    n: int, start: dict[str, Any], tangent: np.ndarray, cfg: Continuation,
                    max_iter: int = 24) -> dict[str, Any] | None:
    """The point of curve ``first`` where the test function ``second`` vanishes, searched
    from the curve point ``start`` (``w``, ``y``, ``state``) along the curve's ``tangent``
    (cell units, pointing where the zero is expected). Returns the located point or None."""
    curve = _Curve(base, grid, first[0], first[1], n, cfg)
    fix_x = abs(tangent[0]) > abs(tangent[1])
    cell = grid.dx if fix_x else grid.dy
    sgn = 1.0 if (tangent[0] if fix_x else tangent[1]) >= 0 else -1.0
    c0 = start["w"] if fix_x else start["y"]

    def at(s: float, guess):
        a_guess = guess[1] if fix_x else guess[0]
        pt = curve.point(fix_x, c0 + sgn * s * cell, a_guess, guess[2])
        if pt is None:
            return None
        f = _second_value(base, grid, second, n, pt[0], pt[1], pt[2], cfg)
        return None if f is None or not math.isfinite(f) else (f, pt)

    first_pt = at(0.0, (start["w"], start["y"], np.asarray(start["state"], dtype=float)))
    if first_pt is None:
        return None
    behind = at(-0.3, first_pt[1])
    if behind is None:
        return None
    hist = [(-0.3, *behind), (0.0, *first_pt)]  # (s, f, point), last two secant points
    lo = hi = None  # bracket (s, f, pt) with opposite signs
    iters = 0
    while iters < max_iter:
        iters += 1
        if cfg.out_of_budget():
            return None
        (sa, fa, _pa), (sb, fb, _pb) = hist[-2], hist[-1]
        s_new = sb - fb * (sb - sa) / (fb - fa) if fb != fa else sb + 0.5
        if lo is not None and not (min(lo[0], hi[0]) < s_new < max(lo[0], hi[0])):
            s_new = 0.5 * (lo[0] + hi[0])
        s_new = min(max(s_new, sb - 3.0), sb + 3.0)
        good = hist[-1] if lo is None else (lo if abs(lo[0] - s_new) < abs(hi[0] - s_new)
                                            else hi)
        r = None
        for _ in range(8):  # beyond the point the curve may not exist: back off
            r = at(s_new, good[2])
            if r is not None:
                break
            s_new = 0.5 * (s_new + good[0])
        if r is None:
            return None
        f_new, p_new = r
        new = (s_new, f_new, p_new)
        if lo is None and f_new * fb <= 0:
            lo, hi = hist[-1], new
        elif lo is not None:
            lo, hi = (new, hi) if (f_new < 0) == (lo[1] < 0) else (lo, new)
        hist.append(new)
        if abs(f_new) < 1e-11 or abs(s_new - sb) * cell < 1e-13:
            break
    s, f, (w, yv, state, row) = hist[-1]
    if abs(f) > 1e-6:
        return None
    return {"w": w, "y": yv, "state": state, "row": row, "iterations": iters,
            "second_value": f}


def _both(base, grid, conds, n, w, yv, state, cfg):
    """``(f, y, M)``: both test functions of the period-``n`` orbit at ``(w, yv)`` (Newton from
    ``state``, full error control), the orbit's section state and monodromy; None without the
    orbit."""
    p = base.with_(**{grid.x_name: w, grid.y_name: yv})
    try:
        r = test_value(p, conds[0][0], conds[0][1], n, state, cfg)
        if r is None:
            return None
        y, M, f1 = r
        gm = grazing_margin(p, y, n, cfg.settings, substeps=cfg.substeps)
        c = conds[1]
        if c[0] == "grazing":
            f2 = gm.signed.get(c[1])
        else:
            if M is None:
                _, M = section_map(p, y, n, cfg.settings)
            f2 = pd_test(M) if c[0] == "period_doubling" else fold_test(M)
        if M is None:
            _, M = section_map(p, y, n, cfg.settings)
    except (OrbitError, ParameterError, np.linalg.LinAlgError):
        return None
    if f2 is None or not (math.isfinite(f1) and math.isfinite(f2)):
        return None
    return np.array([f1, f2]), y, M, gm.switches


def newton2(base, grid, conds, n, start: dict[str, Any], cfg: Continuation,
            max_iter: int = 20) -> dict[str, Any] | None:
    """Newton on the two test functions of one orbit in ``(w, y)`` (cell units), from the
    curve end ``start`` (period doublings and grazings: each test function is one of the
    orbit at fixed parameters).

    A grazing is approached from its smooth side: across it a turning point makes a small
    excursion through the boundary (two more contact switches) and the multipliers gain a
    square-root term (``c sqrt(-g)``, with ``c`` ~ 20 here), so a Newton step that lands
    there is halved, and the grazing distance is driven to zero by tenths (its target a
    tenth of its value) while the other condition is solved in full. The Jacobian is a fresh
    finite difference every step, its probes on the smooth side."""
    u = grid.index([start["w"]], [start["y"]])[0]
    graz = [k for k in range(2) if conds[k][0] == "grazing"]

    def ev(uu, st):
        w, yv = grid.x_of(uu[0]), grid.y_of(uu[1])
        return _both(base, grid, conds, n, w, yv, st, cfg)

    r0 = ev(u, np.asarray(start["state"], dtype=float))
    if r0 is None:
        return None
    f, y, M, sw = r0
    h = 1e-3
    probes = [(u + d, ev(u + d, y)) for d in (np.array([h, 0.0]), np.array([-h, 0.0]),
                                              np.array([0.0, h]), np.array([0.0, -h]))]
    probes = [(uu, r) for uu, r in probes if r is not None]
    smooth = min([sw] + [r[3] for _u, r in probes])
    sign = {}
    for k in graz:  # the smooth side's sign of each grazing distance
        vals = [r[0][k] for _u, r in probes + [(u, r0)] if r[3] == smooth]
        sign[k] = float(np.sign(np.mean(vals))) if vals else 1.0

    def ok(r) -> bool:
        return r is not None and r[3] == smooth and all(r[0][k] * sign[k] >= 0 for k in graz)

    if not ok(r0):
        good = [(uu, r) for uu, r in probes if ok(r)]
        if not good:
            return None
        u, (f, y, M, sw) = min(good, key=lambda t: float(np.max(np.abs(t[1][0]))))
    it = 0
    best = [float(np.max(np.abs(f)))]
    while it < max_iter:
        it += 1
        if cfg.out_of_budget():
            return None
        # the residual has not halved in four steps: at its noise floor (accepted below
        # 1e-7), or no point near
        if len(best) > 4 and best[-1] > 0.5 * best[-5]:
            break
        step = min(h, max(1e-7, 0.1 * float(np.max(np.abs(f)))))
        J = np.zeros((2, 2))
        for k in range(2):
            cols = []
            for sgn in (1.0, -1.0):
                d = np.zeros(2)
                d[k] = sgn * step
                r = ev(u + d, y)
                if ok(r):
                    cols.append((r[0] - f) / (sgn * step))
            if not cols:
                return None
            J[:, k] = np.mean(cols, axis=0)
        target = np.zeros(2)
        for k in graz:
            target[k] = 0.1 * f[k]
        try:
            du = np.linalg.solve(J, target - f)
        except np.linalg.LinAlgError:
            return None
        du *= min(1.0, 3.0 / max(float(np.max(np.abs(du))), 1e-300))  # at most 3 cells
        for _ in range(30):
            r = ev(u + du, y)
            if ok(r):
                break
            du *= 0.5
        else:
            return None
        u = u + du
        f, y, M, _sw = r
        best.append(min(best[-1], float(np.max(np.abs(f)))))
        if float(np.max(np.abs(f))) < 1e-11:
            break
    if float(np.max(np.abs(f))) > 1e-7:
        return None
    w, yv = grid.x_of(u[0]), grid.y_of(u[1])
    return {"w": w, "y": yv, "state": y, "row": _orbit_row(M, y), "iterations": it,
            "second_value": float(f[1])}


def _orbit_row(M: np.ndarray, y: np.ndarray) -> dict[str, Any]:
    mu = np.linalg.eigvals(M).astype(complex)
    mu = mu[np.argsort(-np.abs(mu), kind="stable")]
    return {"x": float(y[0]), "v": float(y[1]), "mu_max": float(abs(mu[0])),
            "mu_re": [float(m.real) for m in mu], "mu_im": [float(m.imag) for m in mu],
            "stable": bool(abs(mu[0]) < 1.0)}


def check_point(base, grid, conds, n, pt: dict, cfg: Continuation) -> dict[str, Any]:
    """Residuals of both conditions at the located point and the size of one Newton step of
    the two conditions in ``(w, y)`` (finite-difference Jacobian, one-sided steps of 1e-4
    cells towards the point's own side)."""
    w, yv, state = pt["w"], pt["y"], pt["state"]
    r0 = _both(base, grid, conds, n, w, yv, state, cfg)
    if r0 is None:
        return {"residual_1": math.nan, "residual_2": math.nan, "step": math.nan}
    f0 = r0[0]
    J = np.zeros((2, 2))
    ok = True
    for k, (dw, dy) in enumerate(((1e-4 * grid.dx, 0.0), (0.0, 1e-4 * grid.dy))):
        for sgn in (-1.0, 1.0):
            r = _both(base, grid, conds, n, w + sgn * dw, yv + sgn * dy, state, cfg)
            if r is not None:
                J[:, k] = sgn * (r[0] - f0) / (dw + dy)
                break
        else:
            ok = False
    step = math.nan
    if ok:
        try:
            d = np.linalg.solve(J, -f0)
            step = float(max(abs(d[0]), abs(d[1])))
        except np.linalg.LinAlgError:
            pass
    return {"residual_1": float(abs(f0[0])), "residual_2": float(abs(f0[1])), "step": step}


def _candidates(base, grid, first: tuple[str, str], n: int, end: dict, cfg) -> list:
    """Second conditions for a lost curve end, nearest its zero first."""
    p = base.with_(**{grid.x_name: end["w"], grid.y_name: end["y"]})
    out = []
    try:
        r = test_value(p, "period_doubling", "", n, np.asarray(end["state"], dtype=float), cfg)
        if r is None:
            return out
        gm = grazing_margin(p, r[0], n, cfg.settings, substeps=cfg.substeps).signed
    except (OrbitError, ParameterError, np.linalg.LinAlgError):
        return out
    for bnd in BOUNDARIES:
        if bnd in gm and (first[0] != "grazing" or first[1] != bnd):
            out.append((abs(gm[bnd]), ("grazing", bnd)))
    if r is not None and r[1] is not None:
        for kind, f in (("period_doubling", pd_test(r[1])), ("fold", fold_test(r[1]))):
            if f is not None and kind != first[0]:
                out.append((abs(f), (kind, "")))
    # only a test function already near its zero: a lost end far from every other
    # condition is not a codimension-2 point (a curve lost for another reason)
    return [c for v, c in sorted(out, key=lambda t: t[0]) if v < NEAR]


def codim2_points(base: ModelParameters, curves: pd.DataFrame, grid, opts: Any,
                  ends: list[dict] | None = None) -> pd.DataFrame:
    """The codimension-2 points of ``curves`` (columns :data:`CODIM2_COLUMNS`): at every
    lost end in ``ends`` (``curve``, ``side``, ``w``, ``y``, ``state``, ``tangent``, ``kind``,
    ``boundary``, ``period``), and where two curves of one period cross. Sets the curves'
    ``end_*`` to ``codim2`` and ``codim2_*`` to the point where a lost end converged to it."""
    cfg = Continuation(**{**opts.config.__dict__, "progress": None})
    log = opts.config.progress or (lambda _s: None)
    rows: list[dict[str, Any]] = []
    polys = {int(c): grid.index(g["value"].to_numpy(), g["value2"].to_numpy())
             for c, g in curves.groupby("curve")} if len(curves) else {}
    meta = {int(c): (str(g["kind"].iloc[0]), str(g["boundary"].iloc[0] or ""),
                     int(g["period"].iloc[0])) for c, g in curves.groupby("curve")} \
        if len(curves) else {}
    todo = [e for e in ends or [] if e.get("end") == "lost"]
    log(f"{len(todo)} curve ends lost inside the plane: locating their codimension-2 points")
    workers = max(1, int(getattr(opts, "workers", 1)))
    pool = None
    if workers > 1 and len(todo) > 1:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        pool = ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("fork"))
    k = 0
    try:
        # rounds of ``workers`` ends taken in order: an end that runs into a point already
        # located is not solved again, and the table does not depend on which process
        # finishes first
        while k < len(todo):
            batch = []
            while k < len(todo) and len(batch) < workers:
                end = todo[k]
                k += 1
                hit = _located_at(grid, end, rows)
                if hit is not None:
                    row, pt = hit
                    end["codim2"], end["codim2_point"] = row["point"], pt
                    log(f"curve {end['curve']} {end['side']} end: runs into codimension-2 "
                        f"point {row['point']} ({row['kind']}), "
                        f"{_gap(grid, end, row):.2f} cells from its last point")
                    continue
                batch.append(end)
            args = [(base, grid, e, cfg) for e in batch]
            solved = (list(pool.map(_solve_end, args)) if pool is not None and len(args) > 1
                      else [_solve_end(a) for a in args])
            for end, res in zip(batch, solved, strict=True):
                if res is None:
                    log(f"curve {end['curve']} {end['side']} end at {grid.x_name} = "
                        f"{end['w']:.8f}, {grid.y_name} = {end['y']:.8f}: no codimension-2 "
                        "point located")
                    continue
                second, pt, chk = res
                first = (end["kind"], end["boundary"])
                row = _row(grid, first, second, int(end["period"]), pt, chk, polys, meta, rows)
                row.setdefault("_point", pt)
                log(f"codimension-2 point {row['kind']} ({row['conditions']}) at "
                    f"{grid.x_name} = {row['value']:.8f}, {grid.y_name} = "
                    f"{row['value2']:.8f}: residual {row['residual']:.1e}, Newton step "
                    f"{row['step']:.1e}, curves {row['curves']} (curve {end['curve']} "
                    f"{end['side']} end)")
                end["codim2"] = row["point"]
                end["codim2_point"] = pt
    finally:
        if pool is not None:
            pool.shutdown()
    by_id = {r["point"]: r for r in rows}
    for end in todo:  # a point re-solved to convergence later is where its ends end
        if "codim2" in end:
            end["codim2_point"] = by_id[end["codim2"]]["_point"]
    rows = [{c: r.get(c) for c in CODIM2_COLUMNS} for r in rows]
    df = pd.DataFrame(rows, columns=list(CODIM2_COLUMNS))
    return df


#: a lost end whose last point is this close (cells) to a point already located (converged, or
#: solved once more), one of whose conditions is its own, runs into it: it is not solved again
REUSE = 1.5


def _conditions_of(row: dict[str, Any]) -> list[tuple[str, str, int]]:
    """The curves a located point ends: each condition with the periods it holds for (a
    grazing at a period doubling of period n is a grazing of the doubled orbit too)."""
    out = []
    for c in str(row["conditions"]).split("; "):
        kind, _, bnd = c.partition(" ")
        out.append((kind, bnd, int(row["period"])))
        if kind == "grazing":
            out.append((kind, bnd, 2 * int(row["period"])))
    return out


def _gap(grid, end: dict, row: dict[str, Any]) -> float:
    a = grid.index([end["w"]], [end["y"]])[0]
    b = grid.index([row["value"]], [row["value2"]])[0]
    return float(np.hypot(*(a - b)))


def _located_at(grid, end: dict, rows: list[dict]) -> tuple[dict, dict] | None:
    """The point already in ``rows`` that the lost ``end`` runs into, if any: a converged
    one, or one that did not converge and was solved again from one more end already."""
    key = (end["kind"], end["boundary"] or "", int(end["period"]))
    for r in rows:
        if key in _conditions_of(r) and _gap(grid, end, r) <= REUSE:
            if r["converged"] or r.get("_retried"):
                return r, r["_point"]
            r["_retried"] = True  # one more end solves a point that did not converge
    return None


def _solve_end(args) -> tuple | None:
    """The codimension-2 point at a lost curve end: ``(second condition, point, check)``."""
    base, grid, end, cfg = args
    if cfg.out_of_budget():
        return None
    first = (end["kind"], end["boundary"])
    n = int(end["period"])
    for second in _candidates(base, grid, first, n, end, cfg)[:1]:
        if "fold" in (first[0], second[0]):
            pt = locate_on_curve(base, grid, first, second, n, end,
                                 np.asarray(end["tangent"], dtype=float), cfg)
        else:
            pt = newton2(base, grid, (first, second), n, end, cfg)
        if pt is not None:
            return second, pt, check_point(base, grid, (first, second), n, pt, cfg)
    return None


def _row(grid, first, second, n, pt, chk, polys, meta, rows) -> dict[str, Any]:
    """The table row of a located point (a point already in ``rows`` within 0.05 cells with
    the same conditions is reused)."""
    u = grid.index([pt["w"]], [pt["y"]])
    kind = _kind(first, second)
    res = max(chk["residual_1"], chk["residual_2"])
    converged = bool(res < RESIDUAL and chk["step"] < STEP)
    same = None
    for r in rows:
        if r["kind"] == kind and float(np.hypot(*(grid.index([r["value"]], [r["value2"]])
                                                  - u)[0])) < 0.05:
            same = r
            break
    if same is not None and (same["converged"] or not converged):
        return same
    # a new point, or a converged solve of one located before without converging (it
    # replaces that one under its id)
    joined = [c for c, poly in polys.items()
              if meta[c][2] in (n, 2 * n) and float(distance_to_polyline(u, poly)[0]) < 1.0]
    gaps = [float(distance_to_polyline(u, polys[c])[0]) for c in joined]
    r = pt["row"]
    same_id = same["point"] if same is not None else len(rows)
    row = {"point": len(rows), "kind": kind, "conditions": f"{_cond(first)}; {_cond(second)}",
           "period": n, "boundary": next((c[1] for c in (first, second) if c[0] == "grazing"),
                                         ""),
           "name": grid.x_name, "value": pt["w"], "name2": grid.y_name, "value2": pt["y"],
           "curves": joined, "curve_kinds": [meta[c][0] for c in joined], **chk,
           "residual": res, "iterations": pt["iterations"],
           "converged": converged,
           "gap_cells": max(gaps) if gaps else math.nan, "x": float(r["x"]), "v": float(r["v"]),
           "mu_max": float(r["mu_max"]), "mu_re": list(r["mu_re"]), "mu_im": list(r["mu_im"])}
    if same is not None:
        same.clear()
        same.update({**row, "point": same_id})
        return same
    rows.append(row)
    return row
