"""Exact landmarks: each grid-read landmark of a sweep beside the continuation's located point.

A sweep's landmarks (:func:`gearsim.analysis.landmarks.find_landmarks`) sit between two grid
values; the
continuation of the same parameter set (:func:`gearsim.analysis.continuation.continue_orbit`)
locates
the bifurcation itself to 1e-8. Kinds pair as: ``grazing`` with ``grazing``; ``period_doubling``,
``inverse_period_doubling`` and ``period_one`` with ``period_doubling`` (an inverse doubling is
the same bifurcation passed the other way); ``jump`` with ``fold`` (a jump is the end of a
hysteresis branch). ``chaos_onset`` has no single exact point (the accumulation of the doubling
cascade) and stays empty.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from gearsim.analysis.landmarks import find_landmarks, match_paper
from gearsim.analysis.paper import PAPER_LANDMARKS

#: columns of the located bifurcation points of a continuation table
POINT_COLUMNS = (
    "point", "kind", "period", "boundary", "name", "value", "x", "v", "mu_max", "mu_re",
    "mu_im", "stable", "branch",
)


def bifurcation_points(branches: pd.DataFrame) -> pd.DataFrame:
    """The located events of a continuation table (one row each, in branch order)."""
    ev = branches[branches["event"] != ""].reset_index(drop=True)
    out = pd.DataFrame({
        "point": np.arange(len(ev)),
        "kind": ev["event"],
        "period": ev["period"],
        "boundary": ev["boundary"],
        "name": ev["name"],
        "value": ev["value"],
        "x": ev["x"],
        "v": ev["v"],
        "mu_max": ev["mu_max"],
        "mu_re": ev["mu_re"],
        "mu_im": ev["mu_im"],
        "stable": ev["stable"],
        "branch": ev["branch"],
    }, columns=list(POINT_COLUMNS))
    out.attrs.update(branches.attrs)
    return out


PAIRS = {
    "grazing": ("grazing",),
    "period_doubling": ("period_doubling",),
    "inverse_period_doubling": ("period_doubling",),
    "period_one": ("period_doubling",),
    "jump": ("fold",),
}

COLUMNS = (
    "key", "text", "kind", "paper", "grid", "grid_lo", "grid_hi", "exact", "exact_kind",
    "exact_period", "exact_stable", "inside", "exact_minus_paper",
)


def orbit_period(key: str) -> int:
    """Period of the orbit whose bifurcation a paper landmark is, from its key (0: any).

    ``pd_1_2`` and ``ipd_4_2``: the doubling of the smaller period's orbit; ``ipd_chaos_8``:
    of the 8T orbit; ``grazing_2``: of the 2T orbit; ``period_one`` and ``jump``: of the 1T
    orbit."""
    import re

    if key in ("period_one", "jump"):
        return 1
    nums = [int(v) for v in re.findall(r"\d+", key)]
    return min(nums) if nums else 0


def exact_landmarks(points: pd.DataFrame, sweep: pd.DataFrame | None = None,
                    grid: pd.DataFrame | None = None, *, slack: float | None = None
                    ) -> pd.DataFrame:
    """One row per paper landmark: the paper's value, the grid-read one, the exact one.

    Parameters
    ----------
    points
        Located continuation points (``kind``, ``value``, ``period``, ``stable``; the
        ``*_points.parquet`` of ``gearsim bifurcation-curves`` / ``gearsim continue``).
    sweep
        The sweep table (for :func:`gearsim.analysis.landmarks.find_landmarks`), or ``grid``
        directly.
    slack
        How far outside the grid interval ``[lo, hi]`` an exact point of the landmark's kind
        and orbit period (:func:`orbit_period`) may lie and still be paired (default: 3 grid
        spacings of the sweep, at least 0.05: on a coarse sweep a label next to a doubling can
        lag it by a cell or two, where the multiplier is within ~0.01 of -1; docs/orbits.md,
        "Simulated labels next to a period doubling").

    ``inside`` says whether the exact point lies in the grid interval where the labels change.
    """
    if grid is None:
        if sweep is None:
            raise ValueError("exact_landmarks needs the sweep or its landmarks")
        grid = find_landmarks(sweep)
    matched = match_paper(grid, PAPER_LANDMARKS)
    if slack is None:
        if sweep is not None and len(sweep) > 1:
            v = np.sort(sweep["value"].to_numpy())
            slack = max(3.0 * float(np.median(np.diff(v))), 0.05)
        else:
            slack = 0.05
    rows = []
    used: set[int] = set()
    for _, m in matched.iterrows():
        row = {"key": m["key"], "text": m["text"], "kind": m["kind"], "paper": m["paper"],
               "grid": m["ours"], "grid_lo": m["lo"], "grid_hi": m["hi"], "exact": math.nan,
               "exact_kind": "", "exact_period": 0, "exact_stable": False, "inside": False,
               "exact_minus_paper": math.nan}
        kinds = PAIRS.get(m["kind"], ())
        if m["found"] and kinds:
            cand = points[points["kind"].isin(kinds)]
            period = orbit_period(str(m["key"]))
            if period and "period" in cand.columns:
                cand = cand[cand["period"] == period]
            cand = cand[(cand["value"] >= m["lo"] - slack) & (cand["value"] <= m["hi"] + slack)]
            cand = cand[[i not in used for i in cand.index]]
            if len(cand):
                k = cand.index[int(np.argmin(np.abs(cand["value"].to_numpy() - m["ours"])))]
                c = points.loc[k]
                used.add(k)
                row.update(exact=float(c["value"]), exact_kind=c["kind"],
                           exact_period=int(c["period"]), exact_stable=bool(c["stable"]),
                           inside=bool(m["lo"] <= c["value"] <= m["hi"]),
                           exact_minus_paper=float(c["value"]) - float(m["paper"]))
        rows.append(row)
    return pd.DataFrame(rows, columns=list(COLUMNS))


FORM_KEYS = ("model", "te_damping", "mesh_damping_contact")


def model_form(subtree: dict | None) -> str:
    """One line naming the model form of a sweep from its provenance subtree (``parameters``,
    ``sweep``, ``integration``): the options of docs/model.md, "Model forms" (transmission-error
    path, mesh damping, friction arm, frequency scale, bearings) and the sweep method."""
    if not subtree or "parameters" not in subtree:
        return "model form unknown (the sweep table has no provenance)"
    from dataclasses import fields

    from gearsim.dynamics.parameters import ModelParameters

    p = {**subtree["parameters"], **((subtree.get("sweep") or {}).get("fixed") or {})}
    defaults = {f.name: f.default for f in fields(ModelParameters)}
    model = str(p.get("model", defaults["model"]))
    beta = float(p.get("te_damping", 1.0))
    delta = float(p.get("mesh_damping_contact", 0.0))
    parts = [f"{model.upper() if model[0].isdigit() else model}"]
    if model == "6dof":
        kap = "/".join(f"{float(p.get(k, defaults[k])):g}"
                       for k in ("kappa_py", "kappa_pz", "kappa_gy", "kappa_gz"))
        clear = [float(p.get(k, 0.0)) for k in ("b_py", "b_pz", "b_gy", "b_gz")]
        parts.append(f"bearings rho_p {float(p.get('rho_p', defaults['rho_p'])):g}, rho_g "
                     f"{float(p.get('rho_g', defaults['rho_g'])):g}, kappa {kap}, "
                     + ("no clearance" if not any(clear)
                        else "clearance " + "/".join(f"{c:g}" for c in clear)))
    else:
        parts.append("rigid bearings")
    parts.append("transmission error as the inertial load Fe w^2, damper on x' - e'"
                 if beta == 1.0 else
                 f"damper on x' - {beta:g} e' (te_damping {beta:g})")
    parts.append("mesh damping always" if delta == 0.0 else
                 f"mesh damping {delta:g} contact-only (mesh_damping_contact {delta:g})")
    arm = {k: v for k, v in p.items() if k.startswith("friction_arm")}
    parts.append("friction arm: its mean" if not any(float(v) for v in arm.values())
                 else "friction arm: " + ", ".join(f"{k} {float(v):g}" for k, v in arm.items()))
    parts.append("w over sqrt(Km / Me)")
    sw = subtree.get("sweep") or {}
    parts.append(f"sweep start: {sw.get('start', 'continuation')}")
    integ = subtree.get("integration") or {}
    if integ.get("method") == "rk4":
        parts.append(f"RK4, {integ.get('steps_per_period')} steps per period")
    elif integ.get("method"):
        parts.append(f"{integ['method']} rtol {integ.get('rtol')}")
    return "; ".join(parts)


def form_name(subtree: dict | None) -> str:
    """Short name of the model form (the names of docs/calibration.md's form table): ``single_dof``
    when every option is at its default, else the options that differ."""
    if not subtree or "parameters" not in subtree:
        return "?"
    p = {**subtree["parameters"], **((subtree.get("sweep") or {}).get("fixed") or {})}
    names = []
    if str(p.get("model", "6dof")) != "6dof":
        names.append(str(p["model"]))
    if float(p.get("te_damping", 1.0)) != 1.0:
        names.append(f"te_damping={float(p['te_damping']):g}")
    if float(p.get("mesh_damping_contact", 0.0)) != 0.0:
        names.append(f"contact_damping={float(p['mesh_damping_contact']):g}")
    if any(float(v) for k, v in p.items() if k.startswith("friction_arm")):
        names.append("friction_arm")
    if any(float(p.get(k, 0.0)) for k in ("b_py", "b_pz", "b_gy", "b_gz")):
        names.append("bearing_clearance")
    if (subtree.get("sweep") or {}).get("start", "continuation") != "continuation":
        names.append("fixed_start")
    return "+".join(names) or "single_dof"


def report_lines(table: pd.DataFrame, form: str | None = None) -> list[str]:
    """Markdown table lines for the reproduction report (``form``: the model form's short name,
    :func:`form_name`, one column)."""
    lines = [
        "| landmark | paper | grid (interval) | exact (continuation) | exact - grid "
        "| exact - paper | kind, period | in interval | model form |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for _, r in table.iterrows():
        grid = ("missing" if not np.isfinite(r["grid"])
                else f"{r['grid']:.3f} ({r['grid_lo']:.3f}-{r['grid_hi']:.3f})")
        ex = "-" if not np.isfinite(r["exact"]) else f"{r['exact']:.8f}"
        kp = f"{r['exact_kind']}, {r['exact_period']}T" if r["exact_kind"] else "-"
        inside = "-" if not r["exact_kind"] else ("yes" if r["inside"] else "no")
        d_grid = ("-" if not (np.isfinite(r["exact"]) and np.isfinite(r["grid"]))
                  else f"{r['exact'] - r['grid']:+.4f}")
        d_paper = "-" if not np.isfinite(r["exact"]) else f"{r['exact'] - r['paper']:+.4f}"
        lines.append(f"| {r['text']} | {r['paper']:.3f} | {grid} | {ex} | {d_grid} | {d_paper} "
                     f"| {kp} | {inside} | {form or '?'} |")
    return lines
