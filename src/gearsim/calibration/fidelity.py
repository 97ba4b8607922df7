"""The measurement of a model form: every target of :mod:`gearsim.calibration.targets` for one
parameter set.

Every model form (an option of the one vector field, :mod:`gearsim.dynamics.model`, or of the
sweep method) is measured by :func:`measure`, scored by :func:`gearsim.calibration.targets.score`
and fitted by :mod:`gearsim.calibration.form_search` and :mod:`gearsim.calibration.lane_fit`;
docs/calibration.md compares the forms.

How each target is measured: the landmarks are read off the standard sweep
(:func:`gearsim.analysis.landmarks.find_landmarks`, matched to the paper in sweep order); the
backlash threshold sets the scale ``Fm``: ``b*`` is read off the standard sweep
(:func:`gearsim.calibration.sweeps.backlash_from_sweep`, exact for a forward sweep without back
contact) or given by a bisection of whole sweeps, and ``Fm`` follows; the damping threshold by
bisection between the sequence sweeps' bracket; the coexisting motions of Figs 9-11 by
:func:`gearsim.analysis.attractors.find_attractors`.

Measurement levels (:class:`FidelitySettings`): the search reads landmarks off a coarse sweep
(``exact=False``) and skips the expensive targets of a candidate whose landmark part is already
hopeless (``gate``; the skipped targets then count ``cap``, an upper bound, so a gated candidate
never looks better than it is). The reported values locate each bifurcation landmark by
continuation (:func:`locate_exact`: period doubling, fold at the jump, grazing = contact gap
zero, to ~1e-8 in w), never by grid reading; the chaos onset (an accumulation point) stays a
grid value and is marked so.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from gearsim.analysis.landmarks import find_landmarks, match_paper, pattern_sequence
from gearsim.analysis.paper import COEXIST_POINT, PAPER_B_THRESHOLD, SEQUENCE_SWEEPS
from gearsim.calibration.sweeps import (
    SweepSettings,
    backlash_from_sweep,
    has_subharmonics,
    w_sweeps,
)
from gearsim.calibration.tables import form_report_lines  # noqa: F401  (the report's import)
from gearsim.calibration.targets import Measured, landmark_part
from gearsim.dynamics.model import dead_zone_series, elastic_mesh_force, pack_parameters
from gearsim.dynamics.parameters import ModelParameters


@dataclass(frozen=True)
class FidelitySettings(SweepSettings):
    """Grids and integration of one measurement (recorded with every result); the w grid and
    the integration are :class:`gearsim.calibration.sweeps.SweepSettings`."""

    seq_dw: float = 0.02
    xi_bisect: int = 3  # bisection steps of the xi threshold after the 0.09 / 0.15 bracket
    attractor_starts: int = 16
    gate: float = 4.0  # landmark RMS in tolerances above which the other targets are not run
    exact: bool = False  # locate bifurcation landmarks by continuation


# ---------------------------------------------------------------------------- exact landmarks
#: landmark key -> how its exact point is located: (side the orbit starts on, event kind)
_EXACT_RULE = {
    "grazing": ("lo", "grazing"),
    "jump": ("lo", "fold"),
    "period_doubling": ("lo", "period_doubling"),
    "inverse_period_doubling": ("hi", "period_doubling"),
    "period_one": ("hi", "period_doubling"),
}


def _npq_n(npq: Any) -> int | None:
    if not isinstance(npq, str) or not npq or not npq[0].isdigit():
        return None
    try:
        return int(npq.split("-")[0])
    except ValueError:
        return None


def locate_exact(params: ModelParameters, df: pd.DataFrame, row: Mapping[str, Any], *,
                 pad: float = 0.02, max_points: int = 120, w_factor: float = 1.0
                 ) -> tuple[float, str]:
    """Continuation-located point of one grid landmark (``row`` of :func:`find_landmarks`).

    The orbit of the flanking cell (``lo`` for grazing, jump and period doubling, ``hi`` for an
    inverse doubling / the return to period 1) is refined by Newton from the sweep's final state
    and continued across the interval (plus ``pad``); the event of the landmark's kind nearest
    the grid value is returned with ``"exact"``. Falls back to ``(grid value, "grid")`` when the
    kind has no exact point (chaos onset) or continuation fails.
    """
    from gearsim.analysis.continuation import continue_orbit
    from gearsim.analysis.continuation_options import Continuation
    from gearsim.analysis.orbits import find_periodic_orbit

    kind = row["kind"]
    rule = _EXACT_RULE.get(kind)
    grid_value = float(row["value"])
    if rule is None:
        return grid_value, "grid"
    side, event = rule
    idx = int(row["i_lo"] if side == "lo" else row["i_hi"])
    n = _npq_n(row["from_npq"] if side == "lo" else row["to_npq"])
    if n is None:
        n_col = row["n_from"] if side == "lo" else row["n_to"]
        n = int(n_col) if n_col and np.isfinite(n_col) and n_col > 0 else None
    if n is None or n > 16:
        return grid_value, "grid"
    start = float(df["value"].iloc[idx]) * w_factor
    stop = (float(row["hi"]) + pad if side == "lo" else float(row["lo"]) - pad) * w_factor
    cfg = Continuation(ds=0.004, ds_max=0.01, switch_depth=0, max_points=max_points)
    try:
        p0 = params.with_(w=start)
        orb = find_periodic_orbit(p0, n, np.asarray(df["final_state"].iloc[idx]), cfg.settings,
                                  grazing=False)
        br = continue_orbit(params, "w", start, stop, orb, config=cfg)
    except Exception:  # noqa: BLE001 - a failed location falls back to the grid, recorded
        return grid_value, "grid"
    ev = br[br["event"] == event]
    lo, hi = min(start, stop), max(start, stop)
    ev = ev[(ev["value"] >= lo) & (ev["value"] <= hi)]
    if not len(ev):
        return grid_value, "grid"
    vals = ev["value"].to_numpy() / w_factor
    k = int(np.argmin(np.abs(vals - grid_value)))
    return float(vals[k]), "exact"


# ---------------------------------------------------------------------------- the measurement
def measure(params: ModelParameters, st: FidelitySettings = FidelitySettings(), *,
            continuation: bool = True, b_star: float | None = None, w_factor: float = 1.0,
            log: Callable[[str], None] | None = None) -> Measured:
    """Measure every target for ``params`` (any model form: the form is in ``params``; the
    sweep method is ``continuation``). ``params`` are at the search scale: ``b = st.b0`` above
    the backlash threshold (checked: a sweep with back contact gets no derived scale).

    ``b_star``: the backlash threshold at this scale from a bisection of whole sweeps
    (:func:`gearsim.calibration.sweeps.backlash_threshold`), used for the scale instead of the
    standard sweep's reading (:func:`gearsim.calibration.sweeps.backlash_from_sweep`, a lower
    bound: it sees only the branch the sweep follows, not a double-sided attractor that a
    transient can reach). :func:`measure_many` for one parameter set."""
    m = measure_many([params], st, continuation=continuation, b_stars=[b_star],
                     w_factors=[w_factor])[0]
    if log:
        log(f"measured in {m.seconds:.1f} s")
    return m


def measure_many(params_list: Sequence[ModelParameters], st: FidelitySettings = FidelitySettings(),
                 *, continuation: bool = True, b_stars: Sequence[float | None] | None = None,
                 w_factors: Sequence[float] | None = None) -> list[Measured]:
    """:func:`measure` for many parameter sets (e.g. a search population), stage by stage: the
    standard sweeps of all sets, then (sets past the gate) their sequence sweeps, the xi
    bisection (one sweep per set and step) and the Figs 9-11 attractor search. With
    ``st.lanes`` each stage's sweeps are the chains of one batched-kernel call
    (:func:`gearsim.calibration.sweeps.w_sweeps`, the study's RK4 settings); otherwise each
    sweep is a scalar DP5 chain. ``seconds`` of each result is the stages' wall time shared
    out over the sets measured in them."""
    n = len(params_list)
    ps = list(params_list)
    wfs = [1.0] * n if w_factors is None else [float(w) for w in w_factors]
    bss = [None] * n if b_stars is None else list(b_stars)
    integ = st.integration()
    ms = [Measured() for _ in range(n)]
    secs = [0.0] * n

    def sweeps(specs: list[tuple[int, ModelParameters, np.ndarray]]) -> list[pd.DataFrame]:
        t0 = time.perf_counter()
        out = w_sweeps([(q, g, wfs[k]) for k, q, g in specs], integ, continuation=continuation)
        dt = (time.perf_counter() - t0) / max(len(specs), 1)
        for k, _q, _g in specs:
            secs[k] += dt
        return out

    dfs = sweeps([(k, ps[k], st.grid()) for k in range(n)])
    scales = [math.nan] * n
    t0 = time.perf_counter()
    for k in range(n):
        scales[k] = _from_standard(ms[k], ps[k], dfs[k], st, bss[k], wfs[k])
    for k in range(n):
        secs[k] += (time.perf_counter() - t0) / max(n, 1)
    live = [k for k in range(n) if not ms[k].gated]
    # sequences (the b sweep needs the scale)
    seq_grid = st.grid(st.seq_dw)
    xi_grid = st.grid(st.xi_dw, st.xi_w_min)
    specs, keys = [], []
    for k in live:
        for key, (name, val) in SEQUENCE_SWEEPS.items():
            if name == "b":
                if not np.isfinite(scales[k]):
                    continue
                q = ps[k].with_(b=val / scales[k])
            else:
                q = ps[k].with_(xi=val)
            specs.append((k, q, seq_grid))
            keys.append((k, key, name, val))
    sub: dict[int, dict[float, bool]] = {k: {} for k in live}
    for (k, key, name, val), d in zip(keys, sweeps(specs), strict=True):
        ms[k].sequences[key] = pattern_sequence(d)
        if name == "xi":
            sub[k][val] = has_subharmonics(d[d["value"] >= st.xi_w_min])
    # xi threshold: bracket from the sequence sweeps, then bisection on a coarse grid
    br: dict[int, list[float]] = {}
    top = []
    for k in live:
        s = sub[k]
        if s.get(0.09, True) and not s.get(0.15, True):
            br[k] = [0.09, 0.15]
        elif s.get(0.15, False):
            br[k] = [0.15, 0.3]
            top.append(k)
    if top:
        for k, d in zip(top, sweeps([(k, ps[k].with_(xi=0.3), xi_grid) for k in top]),
                        strict=True):
            if has_subharmonics(d):
                del br[k]
                ms[k].notes.append("subharmonics at xi = 0.3: threshold above the bracket")
    for _ in range(st.xi_bisect):  # bisect_bool's steps, all sets at once
        todo = sorted(br)
        mids = [0.5 * (br[k][0] + br[k][1]) for k in todo]
        got = sweeps([(k, ps[k].with_(xi=x), xi_grid) for k, x in zip(todo, mids, strict=True)])
        for k, x, d in zip(todo, mids, got, strict=True):
            br[k][0 if has_subharmonics(d) else 1] = x
    for k, (lo, hi) in br.items():
        ms[k].xi_threshold = 0.5 * (lo + hi)
    # Figs 9-11: coexisting attractors at b = 0.15, w = 0.82
    cx = [k for k in live if np.isfinite(scales[k])]
    if cx:
        from gearsim.analysis.attractors import FinderOptions, find_attractors

        t0 = time.perf_counter()
        qs = [ps[k].with_(b=COEXIST_POINT["b"] / scales[k], w=COEXIST_POINT["w"] * wfs[k])
              for k in cx]
        cas = find_attractors(qs, FinderOptions(starts=st.attractor_starts))
        for k, ca in zip(cx, cas, strict=True):
            ms[k].coexist = sorted({str(a.steady.info.get("label_npq") or a.label)
                                    for a in ca.attractors if a.steady.status != "unsettled"})
            secs[k] += (time.perf_counter() - t0) / len(cx)
    for k in range(n):
        ms[k].seconds = secs[k]
    return ms


def _from_standard(m: Measured, p: ModelParameters, df: pd.DataFrame, st: FidelitySettings,
                   b_star: float | None, wf: float) -> float:
    """The standard sweep's targets into ``m`` (landmarks, exact with ``st.exact``; Kmax at
    the jump, DC after it, gap, the scale, the gate); returns the scale (paper-scale lengths
    over search-scale ones, NaN if not derived)."""
    lms = find_landmarks(df)
    matched = match_paper(lms)
    for r in matched.itertuples():
        if not r.found:
            m.landmarks[r.key] = None
            continue
        m.landmarks[r.key] = float(r.ours)
        m.landmark_source[r.key] = "grid"
    if st.exact:
        by_value = {round(float(v), 9): i for i, v in enumerate(lms["value"])}
        for r in matched.itertuples():
            if not r.found:
                continue
            i = by_value.get(round(float(r.ours), 9))
            if i is None:
                continue
            v, src = locate_exact(p, df, lms.iloc[i].to_dict(), w_factor=wf)
            m.landmarks[r.key] = v
            m.landmark_source[r.key] = src
        try:
            m.kmax = kmax_at_jump(p, df, st)
        except Exception as exc:  # noqa: BLE001 - recorded, not fatal
            m.notes.append(f"Kmax readings failed: {exc!r}")
    # DC after the jump, gap
    jump = lms[lms["kind"] == "jump"]
    if len(jump):
        m.dc_jump = float(jump.iloc[0]["dc_hi"])
    g1, jv = m.landmarks.get("grazing_1"), m.landmarks.get("jump")
    if g1 is not None and jv is not None:
        m.gap = float(jv - g1)
    # scale: backlash threshold
    b_star = backlash_from_sweep(df, st.b0) if b_star is None else float(b_star)
    m.b_star_raw = b_star
    if np.isfinite(b_star) and b_star > 0:
        m.Fm_derived = p.Fm * PAPER_B_THRESHOLD / b_star
        m.b_threshold = PAPER_B_THRESHOLD  # by construction: Fm derived from it
        scale = PAPER_B_THRESHOLD / b_star
    else:
        m.notes.append("back contact in the standard sweep at b0: scale not derived")
        scale = math.nan
    m.gated = landmark_part(m) > st.gate
    return scale


# ============================================================================ Kmax readings
def kmax_readings(params: ModelParameters, u0: np.ndarray | None, *, periods: int = 32,
                  samples: int = 512, transient: int = 64, settings=None) -> dict[str, float]:
    """Every candidate Kmax reading of the steady motion at ``params`` (started from ``u0``).

    The mesh force ``F`` is the trajectory's (:func:`gearsim.cell.simulate.trajectory`), the elastic
    part and the deflection ``f(x)`` are read from the recorded states; ``samples`` points per
    mesh period (the peak of a smooth 1T motion is resolved to ~(pi/samples)^2 / 2 ~ 2e-5).
    """
    from gearsim.cell.simulate import trajectory

    tr = trajectory(params, u0, periods=periods, samples_per_period=samples,
                    transient=transient, settings=settings)
    x = tr.state[:, 0]
    f = dead_zone_series(x, params.b)
    elastic = elastic_mesh_force(pack_parameters(params), np.cos(params.w * tr.tau), x)
    F = np.asarray(tr.mesh_force)
    Fm, few2, fe = params.Fm, params.Fe * params.w**2, params.Fe
    per = F[:-1].reshape(periods, samples)
    peaks = per.max(axis=1)
    sec = F[::samples]
    return {
        "peak_mesh_over_Fm": float(F.max() / Fm),
        "peak_mesh_over_Fm_Few2": float(F.max() / (Fm + few2)),
        "peak_mesh_over_Fm_Fe": float(F.max() / (Fm + fe)),
        "mean_period_peak_over_Fm": float(peaks.mean() / Fm),
        "mean_period_peak_over_Fm_Few2": float(peaks.mean() / (Fm + few2)),
        "peak_elastic_over_Fm": float(elastic.max() / Fm),
        "peak_pair_over_Fm": float(f.max() / Fm),
        "peak_pair_over_Fm_Few2": float(f.max() / (Fm + few2)),
        "peak_over_rms": float(F.max() / math.sqrt(float(np.mean(F**2)))),
        "section_mesh_over_Fm": float(sec.max() / Fm),
        "dc_sampled": float(np.mean(f[:-1] == 0.0)),
    }


def kmax_at_jump(params: ModelParameters, df: pd.DataFrame, st: FidelitySettings
                 ) -> dict[str, Any]:
    """Kmax readings on both sides of the first jump of a sweep (``df`` from
    :func:`gearsim.calibration.sweeps.w_sweep`)."""
    lms = find_landmarks(df)
    jump = lms[lms["kind"] == "jump"]
    if not len(jump):
        return {}
    j = jump.iloc[0]
    out: dict[str, Any] = {}
    for side in ("lo", "hi"):
        i = int(j[f"i_{side}"])
        w = float(df["w_sim"].iloc[i])
        r = kmax_readings(params.with_(w=w), np.asarray(df["final_state"].iloc[i]),
                          settings=st.integration())
        out[side] = {"w": w, "dc": float(df["dc"].iloc[i]), **r}
    return out




def coexist_scan(params_list: Sequence[ModelParameters], w_values: Sequence[float],
                 b_values: Sequence[float], st: FidelitySettings,
                 *, starts: int = 64, continuation: bool = True,
                 w_factors: Sequence[float] | None = None) -> list[dict[str, Any]]:
    """The Figs 9-11 search around the paper's point: for every set (its scale from its
    standard sweep, :func:`measure_many` stopped at the gate) and every paper-scale ``(w, b)``,
    the motions the attractor search (``starts`` seeded starts) finds, all cells of all sets
    in one :func:`gearsim.analysis.attractors.find_attractors`. One row per set and
    point: ``set``, ``w``, ``b``, ``motions`` (least-period n-p-q labels of settled
    attractors), ``scale``."""
    from dataclasses import replace

    from gearsim.analysis.attractors import FinderOptions, find_attractors

    wfs = [1.0] * len(params_list) if w_factors is None else list(w_factors)
    ms = measure_many(params_list, replace(st, gate=-1.0), continuation=continuation,
                      w_factors=wfs)
    cells, rows = [], []
    for k, (p, m) in enumerate(zip(params_list, ms, strict=True)):
        if not (np.isfinite(m.b_star_raw) and m.b_star_raw > 0):
            rows.append({"set": k, "scale": math.nan, "motions": None})
            continue
        scale = PAPER_B_THRESHOLD / m.b_star_raw
        for w in w_values:
            for b in b_values:
                cells.append(p.with_(b=float(b) / scale, w=float(w) * wfs[k]))
                rows.append({"set": k, "w": float(w), "b": float(b), "scale": scale})
    todo = [r for r in rows if "w" in r]
    cas = find_attractors(cells, FinderOptions(starts=starts)) if cells else []
    for r, ca in zip(todo, cas, strict=True):
        r["motions"] = sorted({str(a.steady.info.get("label_npq") or a.label)
                               for a in ca.attractors if a.steady.status != "unsettled"})
    return rows
