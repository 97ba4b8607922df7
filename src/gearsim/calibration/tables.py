"""Markdown of the calibration: the side-by-side form table, the per-form summary, the Kmax
readings and the per-target evidence (pure functions of the records; the report's model-form
section is :func:`form_report_lines`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from gearsim.analysis.paper import (
    PAPER_COEXIST,
    PAPER_JUMP_KMAX,
    PAPER_KMAX_FIG17,
    PAPER_LANDMARKS,
    PAPER_SEQUENCES,
)
from gearsim.calibration.targets import (
    TARGET_KEYS,
    TARGETS,
    sequence_distance,
)

#: what each Kmax reading of :func:`gearsim.calibration.fidelity.kmax_readings` is
KMAX_READINGS_TEXT = {
    "peak_mesh_over_Fm": "peak mesh force F over the mean load Fm",
    "peak_mesh_over_Fm_Few2": "peak F over Fm + Fe w^2 (mean load + inertial error load)",
    "peak_mesh_over_Fm_Fe": "peak F over Fm + Fe (mean load + stiffness-path error load Km Em)",
    "mean_period_peak_over_Fm": "mean of the per-period peaks of F over Fm",
    "mean_period_peak_over_Fm_Few2": "mean of the per-period peaks of F over Fm + Fe w^2",
    "peak_elastic_over_Fm": "peak elastic mesh force (1 + eps cos) f(x) over Fm (no damper)",
    "peak_pair_over_Fm": "peak tooth-pair load k_s f(x) over its static value (deflection "
                         "ratio: a pair's load follows the deflection, not the mesh stiffness)",
    "peak_pair_over_Fm_Few2": "peak deflection f(x) over (Fm + Fe w^2)",
    "peak_over_rms": "peak F over the RMS of F",
    "section_mesh_over_Fm": "largest once-per-period (Poincare section) value of F over Fm",
}



#: short column heads of the targets
SHORT_HEAD = {
    "grazing_1": "G 1-0-0>1-1-0", "jump": "jump", "pd_1_2": "PD 1>2", "grazing_2": "G 2-2-0>2-1-0",
    "pd_2_4": "PD 2>4", "grazing_4": "G 4-2-0>4-3-0", "pd_4_8": "PD >8-6-0",
    "chaos_onset": "chaos", "ipd_chaos_8": "chaos>8", "ipd_8_4": "8>4", "ipd_4_2": "4>2",
    "period_one": "2>1", "b_threshold": "b*", "xi_threshold": "xi*", "dc_jump": "DC jump",
    "gap": "gap", "seq_b015": "seq b0.15", "seq_xi005": "seq xi0.05", "seq_xi009": "seq xi0.09",
    "seq_xi015": "seq xi0.15", "coexist": "Figs 9-11",
}


def target_values(m: Mapping[str, Any]) -> dict[str, str]:
    """Formatted value of every target from a :meth:`Measured.to_dict` record."""
    out: dict[str, str] = {}
    for pl in PAPER_LANDMARKS:
        v = m["landmarks"].get(pl.key)
        src = m.get("landmark_source", {}).get(pl.key, "grid")
        out[pl.key] = "miss" if v is None else f"{v:.4f}" + ("" if src == "exact" else "g")
    fmt = {"b_threshold": ".4f", "xi_threshold": ".4f", "dc_jump": ".3f", "gap": ".4f"}
    for k, f in fmt.items():
        v = m.get(k)
        out[k] = "-" if v is None or not np.isfinite(v) else format(v, f)
    for k, paper in PAPER_SEQUENCES.items():
        ours = m.get("sequences", {}).get(k)
        out[f"seq_{k}"] = "-" if ours is None else f"d={sequence_distance(paper, ours)}"
    co = m.get("coexist")
    out["coexist"] = "-" if co is None else ("/".join(co) if co else "none")
    return out


def form_table_lines(forms: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """Markdown: one row per model form (every target's value, the cost J), the paper on top.

    ``forms``: ``{name: record}`` with ``J``, ``measured`` (:meth:`Measured.to_dict`), ``text``.
    Landmark values are exact (continuation) unless marked ``g`` (grid read); sequences show
    the distance to the paper's sequence (0 = same); Figs 9-11 the motions found there.
    """
    keys = list(TARGET_KEYS)
    head = "| form | J | " + " | ".join(SHORT_HEAD[k] for k in keys) + " |"
    sep = "|---" * (len(keys) + 2) + "|"
    paper = {t.key: (f"{t.paper:g}" if isinstance(t.paper, float) else "d=0") for t in TARGETS}
    paper["pd_4_8"] = "1.37-1.384"
    paper["coexist"] = "/".join(PAPER_COEXIST)
    lines = [head, sep, "| paper | 0 | " + " | ".join(paper[k] for k in keys) + " |"]
    for name, rec in forms.items():
        m = rec.get("measured")
        if not m:
            lines.append(f"| {name} | {rec.get('skipped', 'failed')} |" + " |" * len(keys))
            continue
        v = target_values(m)
        label = name if rec.get("searched", True) else (
            f"{name} (not searched: at {rec.get('best_point', 'start')})")
        if rec.get("unfinished"):
            label = f"{name} (unfinished: best logged {rec['unfinished'].get('level')})"
        lines.append(f"| {label} | {rec['J']:.3f} | " + " | ".join(v[k] for k in keys) + " |")
    return lines


def landmarks_within(m: Mapping[str, Any] | None, tol: float = 0.02) -> int:
    """Number of the 12 landmarks of a :meth:`Measured.to_dict` record within ``tol`` in w."""
    if not m:
        return 0
    n = 0
    for pl in PAPER_LANDMARKS:
        v = m["landmarks"].get(pl.key)
        if v is not None and np.isfinite(v) and abs(pl.error(float(v))) <= tol:
            n += 1
    return n


def landmark_rms(m: Mapping[str, Any] | None) -> float:
    """RMS of the found landmarks' errors in w (NaN if none)."""
    if not m:
        return math.nan
    e = [pl.error(float(m["landmarks"][pl.key])) for pl in PAPER_LANDMARKS
         if m["landmarks"].get(pl.key) is not None]
    return math.sqrt(sum(x * x for x in e) / len(e)) if e else math.nan


def _evals(rec: Mapping[str, Any]) -> str:
    b = rec.get("budget") or {}
    if rec.get("unfinished"):
        u = rec["unfinished"]
        return f"{u.get('n_coarse', 0)} + {u.get('n_exact', 0)} (unfinished)"
    if "nfev_coarse" in b:
        return f"{b['nfev_coarse']} + {b['nfev_exact']}"
    if rec.get("searched") is False:
        return "not searched"
    return "-"


def _code(rec: Mapping[str, Any]) -> str:
    """Git commit of the fit's process (its ``run`` record) and the results-deciding code hash
    (:func:`gearsim.study.provenance.code_version`) it recorded."""
    git = (rec.get("run") or {}).get("code")
    cv = rec.get("code_version")
    if git and cv:
        return f"{git} ({cv[:8]})"
    return git or cv or "-"


def form_summary_lines(forms: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """Markdown: one row per form with its cost and budget: J, landmarks within 0.02, landmark
    RMS, xi*, b* (the scale Fm that makes it the paper's threshold, from b* at the search
    scale), evaluations (coarse + exact), wall time, load average at its start, code version."""
    lines = ["| form | J | landmarks within 0.02 | landmark RMS | xi* | b* (Fm derived; b* at "
             "Fm 0.1) | evaluations (coarse + exact) | wall s | load at start | code |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for name, rec in forms.items():
        m = rec.get("measured")
        if not m:
            lines.append(f"| {name} | {rec.get('skipped', 'failed')} | | | | | {_evals(rec)} | "
                         "| | |")
            continue
        run = rec.get("run") or {}
        wall = run.get("wall_s", rec.get("wall_s"))
        xi = m.get("xi_threshold")
        xi_s = "-" if xi is None or not np.isfinite(xi) else f"{xi:.4f}"
        bt = m.get("b_threshold")
        b_s = "-" if bt is None or not np.isfinite(bt) else (
            f"{bt:.4f} (Fm {m['Fm_derived']:.4f}; {m['b_star_raw']:.4f})")
        label = name + (" (unfinished: best logged evaluation)" if rec.get("unfinished") else "")
        lines.append(
            f"| {label} | {rec['J']:.3f} | {landmarks_within(m)} of 12 | "
            f"{landmark_rms(m):.4f} | {xi_s} | {b_s} | {_evals(rec)} | "
            f"{'-' if wall is None else format(wall, '.0f')} | {run.get('load', '-')} | "
            f"{_code(rec)} |")
    return lines


def kmax_lines(kmax: Mapping[str, Any]) -> list[str]:
    """Markdown: every Kmax reading before and after the jump against the paper's values."""
    if not kmax or "hi" not in kmax:
        return ["Kmax readings: not computed (no jump found)."]
    lo, hi = kmax["lo"], kmax["hi"]
    lines = [f"Kmax readings at the jump (w = {lo['w']:.3f} -> {hi['w']:.3f}, DC {lo['dc']:.3f} "
             f"-> {hi['dc']:.3f}); paper: {PAPER_JUMP_KMAX} at the jump (Sect 3.1), "
             f"{PAPER_KMAX_FIG17[0]}-{PAPER_KMAX_FIG17[1]} in Fig 17 at the jump for small xi.",
             "", f"| reading | before | after | after - {PAPER_JUMP_KMAX} | in "
             f"{PAPER_KMAX_FIG17[0]}-{PAPER_KMAX_FIG17[1]} |",
             "|---|---|---|---|---|"]
    for k, text in KMAX_READINGS_TEXT.items():
        if k not in hi:
            continue
        a = hi[k]
        inside = "yes" if PAPER_KMAX_FIG17[0] <= a <= PAPER_KMAX_FIG17[1] else "no"
        lines.append(f"| {text} | {lo[k]:.3f} | {a:.3f} | {a - PAPER_JUMP_KMAX:+.3f} | {inside} |")
    return lines


def form_report_lines(forms: Mapping[str, Any]) -> list[str]:
    """The report's model-form section from docs/calibration.json's ``forms`` entry."""
    recs = forms.get("records", {})
    if not recs:
        return []
    out = ["## Model forms: one objective, the same search for every form", "",
           "J = RMS error in tolerances over 21 targets (landmarks 0.02 in w, b* and xi* 0.01, "
           "DC 0.03, gap 0.02, one pattern per sequence, one motion at Figs 9-11; capped at 10). "
           "Landmark values are exact (continuation) unless marked g (grid read). "
           "Details: docs/calibration.md, docs/calibration.json (`forms`).", "",
           *form_table_lines(recs), "", *form_summary_lines(recs), ""]
    starts = {n: {"J": r["start"]["J"], "measured": r["start"]["measured"]}
              for n, r in recs.items() if (r.get("start") or {}).get("measured")}
    if starts:
        out += ["Each searched form's start (the standard shape, measured as that form the same "
                "way):", "", *form_table_lines(starts), "", *form_summary_lines(starts), ""]
    budget = {n: r.get("budget") for n, r in recs.items() if r.get("budget")}
    if budget:
        b0 = next(iter(budget.values()))
        seeds = {r.get("seed") for r in recs.values() if "seed" in r}
        out += [f"Search per form: differential evolution, population {b0['population']}, "
                f"{b0['generations']} generations, seed {', '.join(str(s) for s in seeds)}; "
                f"refinement: best {b0['refine_top']} re-measured exact, Nelder-Mead "
                f"{b0['refine_fev']} exact evaluations.", ""]
    if forms.get("adopted"):
        out += [f"Adopted: **{forms['adopted']}**. {forms.get('decision', '')}", ""]
    k = forms.get("kmax_form")
    km = forms.get("kmax") or recs.get(k, {}).get("measured", {}).get("kmax")
    if k and km:
        kl = kmax_lines(km)
        at = km.get("at", "its best set")
        out += [f"Form {k}, {at} (jump resolved on a 0.002 grid): " + kl[0], "", *kl[2:], ""]
        if km.get("best"):
            kb = kmax_lines(km["best"])
            out += [f"Form {k}, its best set (jump resolved on a 0.002 grid): " + kb[0], "",
                    *kb[2:], ""]
    if forms.get("evidence_lines"):
        out += ["Closest error any logged evaluation of any form reached per target "
                "(`gearsim.calibration.evidence.best_per_target`):", "", *forms["evidence_lines"],
                ""]
    return out


def evidence_lines(best: dict[str, dict[str, Any]]) -> list[str]:
    """Markdown: per target the closest any evaluation came, and what that evaluation's J was
    (a target met only by sets with a large J is a trade-off, not a fit)."""
    lines = ["| target | tol | closest error any evaluation reached | form | level | J of that "
             "evaluation | evaluations measuring it | within tol | lowest J within tol "
             "(form, level): landmarks then missing 0.02 |",
             "|---|---|---|---|---|---|---|---|---|"]
    for t in TARGETS:
        b = best.get(t.key)
        if not b or "error" not in b:
            lines.append(f"| {SHORT_HEAD[t.key]} | {t.tol:g} | never measured | | | | 0 | 0 | |")
            continue
        hit = ""
        if b.get("n_hit"):
            miss = b.get("hit_misses") or {}
            ms = ", ".join(f"{SHORT_HEAD[k]} {'miss' if v is None else format(v, '+.3f')}"
                           for k, v in miss.items()) or "none"
            hit = f"{b['hit_J']:.2f} ({b['hit_form']}, {b['hit_level']}): {ms}"
        lines.append(f"| {SHORT_HEAD[t.key]} | {t.tol:g} | {b['error']:+.4g} | {b['form']} | "
                     f"{b['level']} | {b['J']:.2f} | {b['n']} | {b.get('n_hit', 0)} | {hit} |")
    return lines


def fit_report_lines(fit: Mapping[str, Any]) -> list[str]:
    """Markdown: the lane fits (per form evaluations, seeds, each seed's best J and why it
    stopped, the spread, CPU), the Pareto fronts' ends per form, the Figs 9-11 tally and the
    per-target evidence of the lane evaluations."""
    lines = ["## CMA-ES fits in lanes (docs/calibration.md Sect 8)", "",
             "| form | evaluations | seeds | best J per seed (lanes) | stopped by | spread | "
             "CPU s | wall s |", "|---|---|---|---|---|---|---|---|"]
    for name, f in fit.get("forms", {}).items():
        seeds = f["seeds"].values()
        lines.append(
            f"| {name} | {f['evaluations']} | {f['n_seeds']} | "
            f"{', '.join(format(s['J_lanes'], '.3f') for s in seeds)} | "
            f"{', '.join(s['stopped_by'] for s in seeds)} | {f['spread']:.1%} | "
            f"{f['cpu_s']:.0f} | {f['wall_s']:.0f} |")
    par = fit.get("pareto") or {}
    if par.get("forms"):
        lines += ["", "Trade-off (RMS error in tolerances; lower: grazing, jump, first doubling; "
                  "upper: the inverse cascade and period 1), the front's ends per form "
                  "(figure: docs/calibration_pareto.png):", "",
                  "| form | evaluations | front points | best lower (its upper) | "
                  "best upper (its lower) |", "|---|---|---|---|---|"]
        for name, f in par["forms"].items():
            fr = f["front"]
            if not fr:
                continue
            lo, up = fr[0], fr[-1]
            lines.append(f"| {name} | {f['n']} | {len(fr)} | {lo['lower']:.2f} "
                         f"({lo['upper']:.2f}) | {up['upper']:.2f} ({up['lower']:.2f}) |")
    co = fit.get("coexist") or {}
    if co:
        found = ", ".join(f"{k} {v}" for k, v in sorted(co["motions_found"].items())) or "none"
        lines += ["", f"Figs 9-11 (b = 0.15, w = 0.82, {co['n_sets']} evaluated sets past the "
                  f"gate): motions found (sets) {found}; at most "
                  f"{co['most_of_the_paper_motions']} of the paper's "
                  f"{' / '.join(co['paper'])} in one set."]
    if fit.get("evidence"):
        lines += ["", *evidence_lines(fit["evidence"])]
    return lines
