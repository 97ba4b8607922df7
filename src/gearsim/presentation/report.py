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
from collections.abc import Sequence
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
    PAPER_PLANES,
    PAPER_SEQUENCE_TEXT,
    PAPER_SEQUENCES,
    PAPER_SWEEPS,
    PAPER_XI_THRESHOLD,
    THRESHOLD_TOL,
    listed_patterns,
    within,
)
from gearsim.cell.motion import KMAX_READINGS, double_sided, face_impact, no_impact
from gearsim.presentation.report_inputs import (
    fallback_notes,
    load_atlas,
    load_audits,
    load_curve_status,
    load_plane,
    load_sweeps,
)
from gearsim.presentation.report_markdown import NOT_APPLICABLE, to_markdown
from gearsim.presentation.report_record import Report, Threshold
from gearsim.presentation.study_summary import (
    axis_column,
    multistable_summary,
    plane_summary,
    point_summary,
    sweep_spec_of,
    sweep_summary,
)


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


# ----------------------------------------------------------------------------- thresholds
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
    _landmarks(rep, sweeps.get("standard"), "standard" in configured)
    _hysteresis(rep, sweeps.get("hysteresis"))
    _thresholds(rep, planes, axes)
    for plane, ax in axes.items():
        rep.planes.append(plane_summary(plane, tuple(ax), planes.get(plane),
                                        paper=PAPER_PLANES.get(tuple(ax), NOT_APPLICABLE)))

    _sequences(rep, sweeps, configured)
    return rep


def _landmarks(rep: Report, std: pd.DataFrame | None, configured: bool) -> None:
    """The standard sweep's landmarks matched to the paper's, and the values at the jump."""
    if not configured:
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



def _hysteresis(rep: Report, hyst: pd.DataFrame | None) -> None:
    """The fold's jump up and jump down, from the forward and backward sweeps."""
    if hyst is not None and len(hyst) and {"forward", "backward"} <= set(hyst["direction"]):
        from gearsim.analysis.hysteresis import hysteresis

        h = hysteresis(hyst)
        rep.hysteresis = h.lines()
        rep.hysteresis_band = None if h.band is None else (float(h.band[0]), float(h.band[1]))


def _thresholds(rep: Report, planes: dict[str, pd.DataFrame | None],
                axes: dict[str, tuple[str, str]]) -> None:
    """The backlash and damping thresholds read off the (w, b) and (w, xi) planes."""
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


def _sequences(rep: Report, sweeps: dict[str, pd.DataFrame], configured: set[str]) -> None:
    """The pattern sequences along the sweeps of Figs 8 and 15 beside the paper's."""
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
    rep.notes += fallback_notes(catalogue, results, [p for p in names if cells[p] is not None])
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
    rep.atlas = load_atlas(results, names)
    # exact bifurcation points by continuation, when `gearsim continue` has run (docs/orbits.md)
    exact_points = Path(results) / "orbits" / "standard_points.parquet"
    if exact_points.is_file() and "standard" in loaded:
        from gearsim.analysis.exact_landmarks import exact_landmarks
        from gearsim.results.catalogue import read_metadata

        rep.exact = exact_landmarks(pd.read_parquet(exact_points), loaded["standard"])
        prov = read_metadata(Path(sweeps_dir) / "standard.parquet")
        rep.exact_form = (prov or {}).get("subtree")
    return rep, to_markdown(rep)


