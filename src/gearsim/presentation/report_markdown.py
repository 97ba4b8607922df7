"""The report as Markdown: the scorecard first (when the study holds the paper's material), the
misses, the details of every comparison, the study's own planes, sweeps and points, the audits
and the verified motions. Text only: the numbers are those of
:class:`gearsim.presentation.report_record.Report`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from gearsim.analysis.paper import (
    LANDMARK_TOL,
    PAPER_B_THRESHOLD,
    PAPER_JUMP_DC,
    PAPER_JUMP_KMAX,
    PAPER_KMAX_FIG17,
    PAPER_XI_THRESHOLD,
    THRESHOLD_TOL,
    within,
)
from gearsim.cell.motion import DEFAULT_KMAX, KMAX_READINGS
from gearsim.presentation.report_atlas import atlas_lines
from gearsim.presentation.report_record import Report
from gearsim.presentation.scorecard import scorecard_lines
from gearsim.presentation.study_summary import plane_lines, point_lines, sweep_lines

NOT_APPLICABLE = "not applicable"


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
    return [*_landmark_lines(rep), *_jump_lines(rep), *_threshold_lines(rep),
            *_sequence_lines(rep)]


def _landmark_lines(rep: Report) -> list[str]:
    """The standard sweep's landmarks against the paper's, and the exact points."""
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
    return out


def _jump_lines(rep: Report) -> list[str]:
    """DC and Kmax at the jump, and the fold's hysteresis."""
    out: list[str] = []
    out += ["### DC and Kmax at the jump", ""]
    if any("no sweep 'standard'" in n for n in rep.notes):
        out += ["Not applicable: this study has no sweep 'standard'.", ""]
    elif rep.jump:
        j = rep.jump
        out += [f"Jump between w = {j['w_lo']:.4f} and {j['w_hi']:.4f}. DC {j['dc_before']:.3f}"
                f" -> {j['dc_after']:.3f} (paper: DC -> {PAPER_JUMP_DC}).", "",
                "| reading | before | after | paper's Kmax |", "|---|---|---|---|"]
        for k, text in KMAX_READINGS.items():
            if k in j["kmax_after"]:
                name = f"**Kmax** ({k})" if k == DEFAULT_KMAX else f"{k} (not Kmax)"
                out.append(f"| {name}: {text} | {j['kmax_before'][k]:.3f} | "
                           f"{j['kmax_after'][k]:.3f} | {PAPER_JUMP_KMAX} |")
        best = min(j["kmax_after"].items(), key=lambda kv: abs(kv[1] - PAPER_JUMP_KMAX),
                   default=None)
        if best:
            out += ["", f"Closest reading to the paper's {PAPER_JUMP_KMAX}: {best[0]} = "
                    f"{best[1]:.3f}. (Paper Fig 17: Kmax "
                    f"{PAPER_KMAX_FIG17[0]}-{PAPER_KMAX_FIG17[1]} at the jump for small xi.)"]
        out.append("")
    else:
        out += ["Not computed (no jump found or standard sweep missing).", ""]
    if rep.hysteresis:
        out += ["Hysteresis of the fold (sweep 'hysteresis', both directions; Fig 18):", "",
                *rep.hysteresis, ""]
    return out


def _threshold_lines(rep: Report) -> list[str]:
    """The b and xi thresholds against the paper's."""
    out: list[str] = []
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
    return out


def _sequence_lines(rep: Report) -> list[str]:
    """The pattern sequences of Figs 8 and 15 against the paper's."""
    out: list[str] = []
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
    out += atlas_lines(rep.atlas)
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
