"""The study's report: what a reader wants first, then the evidence.

Inputs (pipeline outputs): ``results/sweeps/<sweep>.parquet`` of the configured sweeps (orbit
diagrams), the cells of the configured planes (``results/catalogue.sqlite``, or
``results/<plane>/cells.parquet``), the planes' numerical audits ``results/<plane>/audit.parquet``,
the figure point sets ``results/points/<set>.parquet`` and optionally the calibration record
``docs/calibration.json``; the rule ``report`` declares each of them. Output: Markdown
(``results/report.md``).

A study that holds any of the paper's material (the standard sweep, a (w, b) or (w, xi) plane, the
paper's sequence sweeps) gets the reproduction report: a one-screen **scorecard** first (each
landmark, threshold, sequence, the DC/Kmax reading at the jump and the multistability summary:
paper, ours, the located bifurcation beside the grid reading, difference, within tolerance or
not), then what does not match and why, then the study's own planes, sweeps and points, then the
details, the numerical audit and, as an appendix, the model-form search of the calibration.
Any other study (``study:`` of one's own) gets a report about itself: its planes (pattern areas,
where each pattern ends along each axis), its sweeps (the pattern sequence, the transitions in
the sweep's own units, the bifurcation diagram), its points.

Paper numbers appear only in the "paper" columns; a quantity we did not compute is reported as
"not computed", never filled with the paper's value.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from gearsim.analysis.landmarks import (
    find_landmarks,
    is_subsequence,
    match_paper,
    pattern_sequence,
)
from gearsim.analysis.paper import (
    JUMP_DC_TOL,
    LANDMARK_TOL,
    PAPER_B_THRESHOLD,
    PAPER_JUMP_DC,
    PAPER_JUMP_KMAX,
    PAPER_PLANES,
    PAPER_SEQUENCE_TEXT,
    PAPER_SEQUENCES,
    PAPER_SWEEPS,
    PAPER_XI_THRESHOLD,
    THRESHOLD_TOL,
    listed_patterns,
    within,
)
from gearsim.cell.classify import KMAX_READINGS
from gearsim.cell.motion import double_sided, face_impact, no_impact
from gearsim.presentation.scorecard import scorecard_lines
from gearsim.presentation.study_summary import (
    axis_column,
    multistable_summary,
    plane_lines,
    plane_summary,
    point_lines,
    point_summary,
    sweep_lines,
    sweep_spec_of,
    sweep_summary,
)

NOT_APPLICABLE = "not applicable"


# ----------------------------------------------------------------------------- loading
def load_sweeps(directory: str | Path, names: Sequence[str] | None = None
                ) -> dict[str, pd.DataFrame]:
    """The orbit diagrams ``<name>.parquet`` in ``directory`` of the sweeps ``names`` (default:
    every one there), keyed by name; a missing file is left out."""
    d = Path(directory)
    if not d.is_dir():
        return {}
    paths = (sorted(d.glob("*.parquet")) if names is None else
             [d / f"{n}.parquet" for n in names if (d / f"{n}.parquet").is_file()])
    return {p.stem: pd.read_parquet(p) for p in paths}


def _cells_from_catalogue(path: Path, plane: str) -> pd.DataFrame | None:
    """Cells of ``plane`` from the pipeline's catalogue (``cells`` joined to ``planes`` by
    ``plane_id``; the impact state is stored as ``impact``, the axes as ``x`` / ``y``), opened
    through :func:`gearsim.results.catalogue.open_catalogue` (a file that is not a catalogue of our
    schema is an error). ``None`` when there is no catalogue or the plane is not in it."""
    if not path.is_file():
        return None
    from gearsim.results.catalogue import open_catalogue

    con = open_catalogue(path)
    try:
        df = pd.read_sql_query(
            "select c.* from cells c join planes p on c.plane_id = p.id where p.name = ?",
            con, params=(plane,))
    finally:
        con.close()
    if not len(df):
        return None
    if "I" not in df.columns and "impact" in df.columns:
        df = df.rename(columns={"impact": "I"})
    return df


def _fallback_notes(catalogue: str | Path | None, results: str | Path,
                    planes: Sequence[str]) -> list[str]:
    """A note for each plane whose cells came from its Parquet file although a catalogue was
    given (:func:`load_plane`): the report says where its numbers come from."""
    if catalogue is None or not planes:
        return []
    path = Path(catalogue)
    if not path.is_file():
        return [f"catalogue {path} not found: the cells of {', '.join(planes)} were read from "
                f"{Path(results)}/<plane>/cells.parquet"]
    from gearsim.results.catalogue import open_catalogue

    con = open_catalogue(path, check=False)  # checked when the cells were read
    try:
        have = {name for (name,) in con.execute("SELECT name FROM planes")}
    finally:
        con.close()
    return [f"plane {p} is not in the catalogue {path}: its cells were read from "
            f"{Path(results) / p / 'cells.parquet'}" for p in planes if p not in have]


def load_plane(plane: str, *, catalogue: str | Path | None = None,
               results: str | Path = "results") -> pd.DataFrame | None:
    """Cells of ``plane`` from the catalogue, else from ``results/<plane>/cells.parquet``."""
    if catalogue is not None:
        df = _cells_from_catalogue(Path(catalogue), plane)
        if df is not None:
            return df
    p = Path(results) / plane / "cells.parquet"
    if p.is_file():
        return pd.read_parquet(p)
    return None


# ----------------------------------------------------------------------------- verified motions
def verified_summary(plane: str, cells: pd.DataFrame | None) -> dict[str, Any] | None:
    """Per plane: cells refined by their Newton orbit, at a bifurcation (status), without a
    settled reading, with a Floquet margin, quasi-periodic, and multistable (from the cells'
    columns ``refined``, ``status``, ``mu_max``, ``motion``, ``n_attractors``)."""
    if cells is None or "status" not in cells.columns:
        return None
    status = cells["status"].astype(str)
    periodic = pd.to_numeric(cells.get("n"), errors="coerce").fillna(0) > 0
    mu = pd.to_numeric(cells.get("mu_max", pd.Series(np.nan, index=cells.index)),
                       errors="coerce")
    refined = cells.get("refined", pd.Series(False, index=cells.index)).fillna(False).astype(bool)
    out = {"plane": plane, "cells": len(cells), "periodic": int(periodic.sum()),
           "refined": int(refined.sum()), "bifurcation": int((status == "bifurcation").sum()),
           "not_converged": int((status == "not_converged").sum()),
           "with_margin": int((periodic & mu.notna()).sum()),
           "near_one": int((mu >= 0.99).sum()),
           "quasi_periodic": int((cells["motion"].astype(str) == "quasi-periodic").sum())}
    if "n_attractors" in cells.columns:
        n = pd.to_numeric(cells["n_attractors"], errors="coerce")
        out["searched"] = int(n.notna().sum())
        out["multistable"] = int((n > 1).sum())
    return out


def verified_lines(rows: list[dict[str, Any]], h: str = "##") -> list[str]:
    """The verified-motions table, per plane of this run."""
    if not rows:
        return []
    out = [f"{h} Verified motions", "",
           "Cells labelled by their Newton-refined orbit (`refined`), at a bifurcation "
           "(status `bifurcation`: within 1e-3 of |mu| = 1), without a settled reading "
           "(`not_converged`), with a Floquet margin `mu_max` (of the periodic cells), with "
           "`mu_max >= 0.99`, quasi-periodic, and multistable (two or more attractors, of the "
           "cells searched). docs/model.md, \"Settled motions, refined labels and statuses\".", "",
           "| plane | cells | refined | bifurcation | not converged | with margin (of periodic) "
           "| mu_max >= 0.99 | quasi-periodic | multistable (of searched) |",
           "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        multi = (f"{r['multistable']} (of {r['searched']})" if "multistable" in r
                 else "not searched")
        out.append(f"| {r['plane']} | {r['cells']} | {r['refined']} | {r['bifurcation']} | "
                   f"{r['not_converged']} | {r['with_margin']} (of {r['periodic']}) | "
                   f"{r['near_one']} | {r['quasi_periodic']} | {multi} |")
    out.append("")
    return out


# ----------------------------------------------------------------------------- thresholds
@dataclass
class Threshold:
    """A threshold read off a plane: the last row that still shows the property and the next."""

    name: str
    value: float  # midpoint between last_with and first_without
    last_with: float
    first_without: float
    rows: int
    paper: float
    note: str = ""

    @property
    def difference(self) -> float:
        return self.value - self.paper


def row_threshold(
    cells: pd.DataFrame, y: str, has_property: pd.Series, *, name: str, paper: float,
) -> Threshold | None:
    """Smallest y above which no row has the property (rows are plane rows of constant y)."""
    ys = np.sort(cells[y].unique())
    flag = has_property.groupby(cells[y]).any().reindex(ys).fillna(False).to_numpy()
    if not flag.any():
        return Threshold(name, float("nan"), float("nan"), float(ys[0]), len(ys), paper,
                         "no row has the property")
    last = int(np.nonzero(flag)[0].max())
    if last == len(ys) - 1:
        return Threshold(name, float("inf"), float(ys[-1]), float("nan"), len(ys), paper,
                         "the property persists to the top of the plane")
    holes = int((~flag[: last + 1]).sum())
    note = f"{holes} rows below it without the property" if holes else ""
    return Threshold(name, 0.5 * (ys[last] + ys[last + 1]), float(ys[last]),
                     float(ys[last + 1]), len(ys), paper, note)


def _listed(key: str) -> list[str] | None:
    """The patterns of the paper's sequence along sweep ``key``; None when it has none."""
    seq = PAPER_SEQUENCES.get(key)
    return None if seq is None else listed_patterns(seq)


def double_sided_rows(cells: pd.DataFrame) -> pd.Series:
    """Cells with double-sided impact (:func:`gearsim.cell.motion.double_sided`)."""
    return double_sided(cells["I"], cells.get("q"))


def not_period_one(cells: pd.DataFrame) -> pd.Series:
    """Cells other than 0/1T and 1/1T (period n != 1, or not periodic)."""
    periodic = cells["motion"] == "periodic" if "motion" in cells.columns else cells["n"] > 0
    I = cells["I"]
    return ~(periodic & (cells["n"] == 1) & (no_impact(I) | face_impact(I)))


# ----------------------------------------------------------------------------- report
@dataclass
class Report:
    """Everything the report states, computed from the pipeline outputs."""

    landmarks: pd.DataFrame | None = None
    matched: pd.DataFrame | None = None
    jump: dict[str, Any] | None = None
    b_threshold: Threshold | None = None
    xi_threshold: Threshold | None = None
    sequences: dict[str, dict[str, Any]] = field(default_factory=dict)
    misses: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    calibration: dict[str, Any] | None = None
    audit: list[dict[str, Any]] = field(default_factory=list)
    compared: int = 0  # comparisons with the paper actually made
    thresholds_na: dict[str, str] = field(default_factory=dict)  # label -> why not applicable
    planes: list[dict[str, Any]] = field(default_factory=list)  # every plane of the study
    hysteresis: list[str] = field(default_factory=list)  # jump-up / jump-down of the fold
    hysteresis_band: tuple[float, float] | None = None
    exact: pd.DataFrame | None = None  # exact landmarks by continuation (docs/orbits.md)
    exact_form: dict | None = None  # provenance subtree of the standard sweep (its model form)
    study: str | None = None  # the config's ``study`` name (a study of one's own)
    sweep_summaries: list[dict[str, Any]] = field(default_factory=list)  # every sweep
    point_summaries: list[dict[str, Any]] = field(default_factory=list)  # every point set
    multistable: list[dict[str, Any]] = field(default_factory=list)  # per plane with attractors
    verified: list[dict[str, Any]] = field(default_factory=list)  # per plane: verified_summary
    curves: list[str] = field(default_factory=list)  # bifurcation curves skipped or cut short
    paper_material: bool = False  # the study configures a paper sweep or plane

    @property
    def paper_study(self) -> bool:
        """Whether any of the paper's material is in this study (then the scorecard leads)."""
        return self.paper_material or self.compared > 0 or self.matched is not None



def load_curve_status(results: str | Path, planes: Sequence[str]) -> list[str]:
    """A line for each plane whose bifurcation curves (``results/orbits/<plane>_curves.parquet``)
    were skipped or stopped at the job's budget, from the file's provenance."""
    from gearsim.results.catalogue import read_metadata

    out = []
    for plane in planes:
        f = Path(results) / "orbits" / f"{plane}_curves.parquet"
        if not f.is_file():
            continue
        meta = read_metadata(f) or {}
        status = meta.get("status", "ok")
        if status == "skipped":
            why = "; ".join(meta.get("reasons") or []) or "curves skipped"
            out.append(f"plane {plane}: {why}")
        elif status == "budget":
            out.append(f"plane {plane}: the bifurcation curves stopped at the job's budget "
                       f"({meta.get('budget_s', '?')} s); they are partial")
    return out


def load_audits(results: str | Path, planes: Sequence[str]) -> list[dict[str, Any]]:
    """The numerical audit of each plane (``results/<plane>/audit.parquet`` provenance)."""
    from gearsim.results.catalogue import read_metadata

    out = []
    for plane in planes:
        f = Path(results) / plane / "audit.parquet"
        if f.is_file():
            meta = read_metadata(f) or {}
            out.append({"plane": plane, "cells": meta.get("cells"),
                        "agreement": meta.get("agreement"), "threshold": meta.get("threshold")})
    return out


def _audit_lines(audits: list[dict[str, Any]]) -> list[str]:
    if not audits:
        return []
    out = ["## Numerical audit", "",
           "A seeded sample of every plane re-simulated with the adaptive DP5 integrator at "
           "tightened tolerance (the configuration's DP5 tolerances divided by `audit.tighten`) "
           "from the same start states; agreement = same label and n-p-q.", "",
           "| plane | audited cells | agreement | threshold |", "|---|---|---|---|"]
    low = []
    for a in audits:
        out.append(f"| {a['plane']} | {a['cells']} | {_f(a['agreement'], '.3f')} | "
                   f"{_f(a['threshold'], '.2f')} |")
        if a["agreement"] is not None and a["threshold"] is not None and (
            a["agreement"] < a["threshold"]
        ):
            low.append(a["plane"])
    out.append("")
    if low:
        out = [f"> **WARNING: the numerical audit is below its threshold on {', '.join(low)}: "
               "the plane's classification depends on the integration settings. Tighten "
               "`integration` before trusting these maps.**", ""] + out
    return out


def _table_axes(plane: str, df: pd.DataFrame | None) -> tuple[str, str]:
    """(x, y) parameter names of a cells table (names of varying parameter columns)."""
    known = {"wb": ("w", "b"), "wxi": ("w", "xi")}
    if df is not None and len(df) and {"i", "j"} <= set(df.columns):
        from gearsim.dynamics.parameters import ModelParameters

        names = [c for c in df.columns if c in ModelParameters.names()]
        x = [c for c in names if df.groupby("j")[c].nunique().max() > 1]
        y = [c for c in names if df.groupby("i")[c].nunique().max() > 1]
        if len(x) == 1 and len(y) == 1:
            return x[0], y[0]
    return known.get(plane, ("x", "y"))



def analyse(
    sweeps: dict[str, pd.DataFrame],
    planes: dict[str, pd.DataFrame | None],
    *,
    calibration: dict[str, Any] | None = None,
    plane_axes: dict[str, tuple[str, str]] | None = None,
    configured_sweeps: Sequence[str] | None = None,
) -> Report:
    """Compute the report's content (no formatting).

    ``plane_axes``: the (x, y) parameter names of every plane of the study (the config's
    ``planes``; default: read off the tables, ``wb`` = (w, b) and ``wxi`` = (w, xi) when
    they cannot be). ``configured_sweeps``: the study's sweeps (default: the paper's and those
    given); a paper sweep outside it is "not applicable" rather than "not computed".
    """
    rep = Report(calibration=calibration)
    axes = dict(plane_axes) if plane_axes is not None else {
        p: _table_axes(p, df) for p, df in planes.items()}
    configured = ({"standard", *PAPER_SWEEPS, *sweeps} if configured_sweeps is None
                  else set(configured_sweeps))
    rep.paper_material = bool(({"standard", *PAPER_SWEEPS} & configured) or any(
        tuple(ax) in PAPER_PLANES for ax in axes.values()))
    std = sweeps.get("standard")
    if "standard" not in configured:
        rep.notes.append("this study has no sweep 'standard': the paper's landmarks are "
                         f"{NOT_APPLICABLE}")
    elif std is not None and len(std):
        lms = find_landmarks(std)
        rep.landmarks = lms
        rep.matched = match_paper(lms)
        rep.compared += len(rep.matched)
        for r in rep.matched.itertuples():
            if not r.found:
                rep.misses.append(f"landmark '{r.text}' (paper w = {r.paper:g}) not found in "
                                  "the standard sweep")
            elif not within(r.error, LANDMARK_TOL):
                rep.misses.append(f"landmark '{r.text}': ours w = {r.ours:.4f} (between "
                                  f"{r.lo:.4f} and {r.hi:.4f}), paper {r.paper:g}, difference "
                                  f"{r.error:+.4f} > {LANDMARK_TOL}")
            elif not r.exact_pattern:
                rep.misses.append(f"landmark '{r.text}': found at w = {r.ours:.4f} but as "
                                  f"{r.ours_from} -> {r.ours_to}")
        jumps = lms[(lms["kind"] == "jump") & (lms["direction"] > 0)]
        if len(jumps):
            j = jumps.iloc[0]
            after = std.reset_index(drop=True).loc[int(j["i_hi"])]
            before = std.reset_index(drop=True).loc[int(j["i_lo"])]
            rep.jump = {
                "w_lo": float(j["lo"]), "w_hi": float(j["hi"]),
                "dc_before": float(before["dc"]), "dc_after": float(after["dc"]),
                "kmax_before": {k: float(before[k]) for k in KMAX_READINGS if k in before},
                "kmax_after": {k: float(after[k]) for k in KMAX_READINGS if k in after},
            }
            if not within(rep.jump["dc_after"] - PAPER_JUMP_DC, JUMP_DC_TOL):
                rep.misses.append(f"DC after the jump {rep.jump['dc_after']:.3f}, paper "
                                  f"{PAPER_JUMP_DC}")
        else:
            rep.misses.append("no upward DC jump in the standard sweep")
    else:
        rep.notes.append("results/sweeps/standard.parquet missing: landmarks not computed")

    hyst = sweeps.get("hysteresis")
    if hyst is not None and len(hyst) and {"forward", "backward"} <= set(hyst["direction"]):
        from gearsim.analysis.attractors import hysteresis

        h = hysteresis(hyst)
        rep.hysteresis = h.lines()
        rep.hysteresis_band = None if h.band is None else (float(h.band[0]), float(h.band[1]))

    for paper_axes, fn, name, paper in (
        (("w", "b"), double_sided_rows, "b above which no double-sided impact occurs",
         PAPER_B_THRESHOLD),
        (("w", "xi"), not_period_one, "xi above which only 0/1T and 1/1T remain",
         PAPER_XI_THRESHOLD),
    ):
        standard = "w" + paper_axes[1]
        names = sorted((p for p, ax in axes.items() if tuple(ax) == paper_axes),
                       key=lambda p: p != standard)
        if not names:
            rep.thresholds_na[paper_axes[1]] = (f"this study has no ({paper_axes[0]}, "
                                               f"{paper_axes[1]}) plane")
            continue
        plane = names[0]
        cells = planes.get(plane)
        if cells is None or len(cells) == 0:
            rep.notes.append(f"plane {plane} not available: threshold not computed")
            continue
        try:
            y = axis_column(cells, paper_axes[1], "y")
        except KeyError as exc:
            rep.notes.append(f"plane {plane}: {exc}")
            continue
        th = row_threshold(cells, y, fn(cells), name=name, paper=paper)
        th.note = (f"plane {plane}; " + th.note) if th.note else f"plane {plane}"
        rep.compared += 1
        if paper_axes[1] == "b":
            rep.b_threshold = th
        else:
            rep.xi_threshold = th
        if th is not None and not within(th.difference, THRESHOLD_TOL):
            rep.misses.append(f"{name}: ours {th.value:.4f} (rows {th.last_with:.4f} / "
                              f"{th.first_without:.4f}, plane {plane}), paper {paper}")

    for plane, ax in axes.items():
        rep.planes.append(plane_summary(plane, tuple(ax), planes.get(plane),
                                        paper=PAPER_PLANES.get(tuple(ax), NOT_APPLICABLE)))

    for key, (pname, pval) in PAPER_SWEEPS.items():
        df = sweeps.get(key)
        entry: dict[str, Any] = {"parameter": pname, "value": pval,
                                 "paper_text": PAPER_SEQUENCE_TEXT[key],
                                 "paper": _listed(key)}
        if key not in configured:
            entry.update(ours=None, in_order=None, exact=None, applicable=False)
        elif df is None or len(df) == 0:
            entry.update(ours=None, in_order=None, exact=None)
            rep.notes.append(f"sweep {key} missing: sequence not computed")
        else:
            seq = pattern_sequence(df)
            entry["ours"] = seq
            entry["ours_npq"] = pattern_sequence(df, use_npq=True)
            expected = _listed(key)
            if expected is not None:
                rep.compared += 1
                entry["in_order"] = is_subsequence(expected, seq)
                entry["exact"] = list(seq) == list(expected)
                if not entry["exact"]:
                    extra = [x for x in dict.fromkeys(seq) if x not in expected]
                    what = ("paper's patterns not in its order" if not entry["in_order"]
                            else "paper's patterns in order, with extra patterns "
                            + ", ".join(extra) if extra else "paper's patterns in order, "
                            "repeated")
                    rep.misses.append(f"sequence {key} ({pname} = {pval}): {what}; ours "
                                      f"{' -> '.join(seq)}; paper {' -> '.join(expected)}")
            else:
                entry.update(in_order=None, exact=None)
        rep.sequences[key] = entry
    return rep


def _f(x: Any, fmt: str = ".4f") -> str:
    if x is None:
        return "not computed"
    if isinstance(x, float) and math.isnan(x):
        return "—"
    return format(x, fmt)


def _misses_lines(rep: Report) -> list[str]:
    out = ["## What does not match, and why", ""]
    if rep.misses:
        out += [f"- {m}" for m in rep.misses]
        out += ["", "Why: the paper's equations and Table 1 are reconstructed (docs/model.md); "
                "the standard parameters are a fit to the paper's landmarks "
                "(docs/calibration.md); grid readings carry half a grid spacing of error."]
    elif rep.compared:
        out += [f"- nothing beyond the tolerances ({LANDMARK_TOL} in w, {THRESHOLD_TOL} "
                f"thresholds) in {rep.compared} comparisons with the paper"]
    else:
        out += [f"- {NOT_APPLICABLE}: nothing of this study was compared with the paper (it "
                "has none of the paper's sweeps or planes, or they were not computed)"]
    if rep.notes:
        out += ["", "Notes:", ""] + [f"- {n}" for n in rep.notes]
    out.append("")
    return out


def _detail_lines(rep: Report) -> list[str]:
    """The paper comparison in full (landmarks, DC/Kmax, thresholds, sequences)."""
    out: list[str] = []
    out += ["### Landmarks of the standard sweep", ""]
    if any("no sweep 'standard'" in n for n in rep.notes):
        out += ["Not applicable: this study has no sweep 'standard'.", ""]
    elif rep.matched is not None:
        out += ["| landmark | paper w | ours w | grid interval | difference | pattern (ours) |",
                "|---|---|---|---|---|---|"]
        errs = []
        for r in rep.matched.itertuples():
            paper = (f"{r.paper_lo:g}-{r.paper_hi:g}" if r.paper_lo != r.paper_hi
                     else f"{r.paper:g}")
            if r.found:
                errs.append(r.error)
                out.append(f"| {r.text} | {paper} | {r.ours:.4f} | [{r.lo:.4f}, {r.hi:.4f}] | "
                           f"{r.error:+.4f} | {r.ours_from} -> {r.ours_to} |")
            else:
                out.append(f"| {r.text} | {paper} | not found | | | |")
        if errs:
            e = np.asarray(errs)
            out += ["", f"Found {len(e)} of {len(rep.matched)}; RMS difference "
                    f"{np.sqrt(np.mean(e**2)):.4f}, worst {np.max(np.abs(e)):.4f}; within "
                    f"{LANDMARK_TOL}: {sum(within(x, LANDMARK_TOL) for x in e)}."]
        out.append("")
        if rep.landmarks is not None and len(rep.landmarks):
            out += ["All landmarks found (sweep order):", "",
                    "| kind | w | from | to | DC before / after |", "|---|---|---|---|---|"]
            for r in rep.landmarks.itertuples():
                out.append(f"| {r.kind} | {r.value:.4f} | {r.from_npq} | {r.to_npq} | "
                           f"{r.dc_lo:.3f} / {r.dc_hi:.3f} |")
            out.append("")
    else:
        out += ["Not computed (standard sweep missing).", ""]
    if rep.exact is not None:
        from gearsim.analysis.exact_landmarks import form_name, model_form, report_lines

        out += ["Exact bifurcation points (Newton-Floquet continuation of the standard set, "
                "located to 1e-8; docs/orbits.md). Each landmark is paired with the located "
                "bifurcation of its kind and orbit period nearest the grid reading; \"in "
                "interval\" says whether it lies between the two swept values where the "
                "simulated labels change.", "",
                f"Model form ({form_name(rep.exact_form)}): {model_form(rep.exact_form)}.", "",
                *report_lines(rep.exact, form_name(rep.exact_form)), ""]
    out += ["### DC and Kmax at the jump", ""]
    if any("no sweep 'standard'" in n for n in rep.notes):
        out += ["Not applicable: this study has no sweep 'standard'.", ""]
    elif rep.jump:
        j = rep.jump
        out += [f"Jump between w = {j['w_lo']:.4f} and {j['w_hi']:.4f}. DC {j['dc_before']:.3f}"
                f" -> {j['dc_after']:.3f} (paper: DC -> {PAPER_JUMP_DC}).", "",
                "| Kmax reading | before | after | paper |", "|---|---|---|---|"]
        for k, text in KMAX_READINGS.items():
            if k in j["kmax_after"]:
                out.append(f"| {k}: {text} | {j['kmax_before'][k]:.3f} | "
                           f"{j['kmax_after'][k]:.3f} | {PAPER_JUMP_KMAX} |")
        best = min(j["kmax_after"].items(), key=lambda kv: abs(kv[1] - PAPER_JUMP_KMAX),
                   default=None)
        if best:
            out += ["", f"Closest reading to the paper's {PAPER_JUMP_KMAX}: {best[0]} = "
                    f"{best[1]:.3f}. (Paper Fig 17: Kmax 1.8-2.1 at the jump for small xi.)"]
        out.append("")
    else:
        out += ["Not computed (no jump found or standard sweep missing).", ""]
    if rep.hysteresis:
        out += ["Hysteresis of the fold (sweep 'hysteresis', both directions; Fig 18):", "",
                *rep.hysteresis, ""]
    out += ["### Thresholds", "", "| threshold | paper | ours | rows (last with / first "
            "without) | difference |", "|---|---|---|---|---|"]
    for th, paper, label, key in ((rep.b_threshold, PAPER_B_THRESHOLD, "b: no double-sided "
                                   "impact above", "b"),
                                  (rep.xi_threshold, PAPER_XI_THRESHOLD,
                                   "xi: only 0/1T, 1/1T above", "xi")):
        if key in rep.thresholds_na:
            out.append(f"| {label} | {paper} | {NOT_APPLICABLE} ({rep.thresholds_na[key]}) "
                       "| | |")
        elif th is None:
            out.append(f"| {label} | {paper} | not computed | | |")
        else:
            note = f"; {th.note}" if th.note else ""
            out.append(f"| {label} | {paper} | {_f(th.value)} | {_f(th.last_with)} / "
                       f"{_f(th.first_without)} ({th.rows} rows{note}) | "
                       f"{_f(th.difference, '+.4f')} |")
    out.append("")
    out += ["### Pattern sequences (Fig 8, Fig 15)", ""]
    for key, e in rep.sequences.items():
        out.append(f"**{e['parameter']} = {e['value']}** (sweep `{key}`)")
        out.append("")
        out.append(f"- paper: {e['paper_text']}")
        if e.get("applicable") is False:
            out.append(f"- ours: {NOT_APPLICABLE} (this study has no sweep `{key}`)")
        elif e.get("ours") is None:
            out.append("- ours: not computed")
        else:
            out.append(f"- ours: {' -> '.join(e['ours'])}")
            out.append(f"- ours (n-p-q): {' -> '.join(e['ours_npq'])}")
            if e.get("in_order") is not None:
                out.append(f"- paper's patterns in order: {'yes' if e['in_order'] else 'no'}; "
                           f"identical sequence: {'yes' if e['exact'] else 'no'}")
        out.append("")
    return out


def _appendix_lines(rep: Report) -> list[str]:
    """The calibration search and its model-form tables: evidence behind the standard set."""
    out: list[str] = []
    if rep.calibration:
        s = rep.calibration.get("search", {})
        if s:
            best = ", ".join(f"{k} = {v:.4g}" for k, v in s.get("best", {}).items())
            out += ["### Calibration", "",
                    f"Differential evolution (seed {s.get('seed')}, {s.get('nfev')} evaluations,"
                    f" objective J = {s.get('J', float('nan')):.4f}): {best}. Details: "
                    "docs/calibration.md.", ""]
    if rep.calibration and rep.calibration.get("forms"):
        from gearsim.calibration.tables import form_report_lines

        out += [_demote(line) for line in form_report_lines(rep.calibration["forms"])]
    if rep.calibration and rep.calibration.get("fit"):
        from gearsim.calibration.tables import fit_report_lines

        out += ["", *(_demote(line) for line in fit_report_lines(rep.calibration["fit"]))]
    return (["## Appendix: calibration and model forms", ""] + out) if out else []


def _demote(line: str) -> str:
    """A heading of an embedded section one level down (it sits inside the appendix)."""
    return "#" + line if line.startswith("#") else line


def to_markdown(rep: Report) -> str:
    """Format the report: the scorecard first for a study with the paper's material, else a
    report about the study itself."""
    audit = _audit_lines(rep.audit)
    warning = [line for line in audit[:2] if line.startswith("> **WARNING")]
    audit = audit[len(warning) + (1 if warning else 0):] if warning else audit
    if rep.paper_study:
        out = ["# Reproduction report", "",
               "Paper: Liu et al., PLOS ONE 2025 (doi 10.1371/journal.pone.0335920). Every "
               "'ours' value is computed from this run's outputs.", ""]
        out += [*warning, ""] if warning else []
        out += scorecard_lines(rep)
        out += _misses_lines(rep)
        out += _study_lines(rep, heading="## This study")
        out += ["## Details of the paper comparison", ""]
        out += _detail_lines(rep)
        out += audit
        out += _appendix_lines(rep)
    else:
        name = rep.study or "this study"
        out = [f"# Study report: {name}", "",
               "What this study computed: its planes, sweeps and points. None of the paper's "
               "sweeps or planes is part of it, so nothing is compared with the paper.", ""]
        out += [*warning, ""] if warning else []
        out += _study_lines(rep, heading=None)
        out += audit
    if rep.curves:
        out += ["## Bifurcation curves not followed in full", "",
                *[f"- {line}" for line in rep.curves], ""]
    return "\n".join(out).rstrip() + "\n"


def _study_lines(rep: Report, heading: str | None) -> list[str]:
    out: list[str] = [heading, ""] if heading else []
    out += plane_lines(rep.planes, "###" if heading else "##")
    out += verified_lines(rep.verified, "###" if heading else "##")
    out += sweep_lines(rep.sweep_summaries, "###" if heading else "##")
    out += point_lines(rep.point_summaries, "###" if heading else "##")
    return out


def build_report(
    *,
    sweeps_dir: str | Path = "results/sweeps",
    catalogue: str | Path | None = "results/catalogue.sqlite",
    results: str | Path = "results",
    calibration: str | Path | None = "docs/calibration.json",
    planes: Sequence[str] | dict[str, tuple[str, str]] = ("wb", "wxi"),
    sweeps: Sequence[str] | None = None,
    study: str | None = None,
    sweep_specs: dict[str, dict[str, Any]] | None = None,
    point_sets: Sequence[str] | None = None,
) -> tuple[Report, str]:
    """Load the pipeline outputs, analyse and format. Returns (report, markdown).

    ``planes``: the study's planes, by name, or ``{name: (x, y)}`` with their axes (the
    config's ``planes``, :func:`study_from_config`); ``sweeps``: the study's sweeps (default:
    every table in ``sweeps_dir``); ``study``: the config's study name; ``sweep_specs``: the
    sweeps' config entries (their units; default: read from each table's provenance);
    ``point_sets``: the recorded point sets under ``results/points``."""
    loaded = load_sweeps(sweeps_dir, sweeps)
    names = list(planes)
    cells = {p: load_plane(p, catalogue=catalogue, results=results) for p in names}
    cal = None
    if calibration is not None and Path(calibration).is_file():
        cal = json.loads(Path(calibration).read_text())
    axes = ({p: tuple(v) for p, v in planes.items()} if isinstance(planes, dict) else None)
    rep = analyse(loaded, cells, calibration=cal, plane_axes=axes,
                  configured_sweeps=sweeps)
    rep.audit = load_audits(results, names)
    rep.notes += _fallback_notes(catalogue, results, [p for p in names if cells[p] is not None])
    rep.study = study
    for name, df in loaded.items():
        png = Path(results) / "figures" / "sweeps" / f"{name}.png"
        spec = ((sweep_specs or {}).get(name)
                or sweep_spec_of(Path(sweeps_dir) / f"{name}.parquet"))
        rep.sweep_summaries.append(sweep_summary(
            name, df, spec, f"figures/sweeps/{name}.png" if png.is_file() else None))
    for name in point_sets or ():
        f = Path(results) / "points" / f"{name}.parquet"
        if f.is_file():
            rep.point_summaries.append(point_summary(name, pd.read_parquet(f)))
    rep.multistable = [m for m in (multistable_summary(p, cells.get(p)) for p in names) if m]
    rep.verified = [v for v in (verified_summary(p, cells.get(p)) for p in names) if v]
    rep.curves = load_curve_status(results, names)
    # exact bifurcation points by continuation, when `gearsim continue` has run (docs/orbits.md)
    exact_points = Path(results) / "orbits" / "standard_points.parquet"
    if exact_points.is_file() and "standard" in loaded:
        from gearsim.analysis.exact_landmarks import exact_landmarks
        from gearsim.results.catalogue import read_metadata

        rep.exact = exact_landmarks(pd.read_parquet(exact_points), loaded["standard"])
        prov = read_metadata(Path(sweeps_dir) / "standard.parquet")
        rep.exact_form = (prov or {}).get("subtree")
    return rep, to_markdown(rep)


def study_from_config(config: dict[str, Any]) -> tuple[dict[str, tuple[str, str]], list[str]]:
    """The planes ``{name: (x, y)}`` and sweep names of a pipeline config."""
    planes = {name: (str(spec["x"]["name"]), str(spec["y"]["name"]))
              for name, spec in (config.get("planes") or {}).items()}
    return planes, list(config.get("sweeps") or {})
