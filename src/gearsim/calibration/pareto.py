"""The trade-off between the lower landmarks and the upper cascade, from logged evaluations.

Every logged evaluation (``<log_dir>/<form>-<level>.<tag>.jsonl``, one JSON line per set: its
``measured`` record) gives two errors, each the RMS over its group of the landmark errors in
tolerances (capped at :data:`gearsim.calibration.targets.CAP`, a landmark not found counts the
cap, as in the objective):

* lower: first grazing, the jump, the first period doubling (:data:`LOWER`);
* upper: the inverse cascade and the return to period 1 (:data:`UPPER`).

:func:`pareto_points` reads them, :func:`front` keeps the sets no other set beats in both, and
:func:`pareto_figure` draws every form's evaluations and fronts (docs/calibration_pareto.png).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gearsim.calibration.search import logged_evaluations
from gearsim.calibration.targets import CAP, TARGETS, Measured, target_errors

LOWER = ("grazing_1", "jump", "pd_1_2")
UPPER = ("ipd_chaos_8", "ipd_8_4", "ipd_4_2", "period_one")
_TOL = {t.key: t.tol for t in TARGETS}


def group_error(errors: dict[str, float], keys: Sequence[str], cap: float = CAP) -> float:
    """RMS over ``keys`` of ``min(|e| / tol, cap)`` (NaN error: ``cap``)."""
    c = [cap if not np.isfinite(errors.get(k, math.nan)) else min(abs(errors[k]) / _TOL[k], cap)
         for k in keys]
    return math.sqrt(sum(v * v for v in c) / len(c))


def pareto_points(log_dir: str | Path) -> list[dict[str, Any]]:
    """One point per logged evaluation with a measurement: form, level, J, the two group
    errors and the set's signed landmark errors."""
    out: list[dict[str, Any]] = []
    for form, level, rec in logged_evaluations(log_dir):
        e = target_errors(Measured.from_dict(rec["measured"]))
        out.append({"form": form, "level": level, "J": float(rec["J"]), "x": rec["x"],
                    "lower": group_error(e, LOWER), "upper": group_error(e, UPPER),
                    "errors": {k: (None if not np.isfinite(e[k]) else float(e[k]))
                               for k in (*LOWER, *UPPER)}})
    return out


def front(points: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The points no other point beats in both errors (ties kept once), by lower error."""
    pts = sorted(points, key=lambda p: (p["lower"], p["upper"]))
    out: list[dict[str, Any]] = []
    best_up = math.inf
    for p in pts:
        if p["upper"] < best_up:
            out.append(p)
            best_up = p["upper"]
    return out


def pareto_record(log_dir: str | Path) -> dict[str, Any]:
    """Per form and for all forms together: the number of evaluations and the front
    (lower, upper, J, form, x)."""
    pts = pareto_points(log_dir)
    forms = sorted({p["form"] for p in pts})

    def slim(ps):
        return [{k: p[k] for k in ("form", "level", "lower", "upper", "J", "x", "errors")}
                for p in ps]

    return {"lower": list(LOWER), "upper": list(UPPER), "cap": CAP, "n": len(pts),
            "all": slim(front(pts)),
            "forms": {f: {"n": sum(p["form"] == f for p in pts),
                          "front": slim(front([p for p in pts if p["form"] == f]))}
                      for f in forms}}


def coexist_tally(log_dir: str | Path) -> dict[str, Any]:
    """The Figs 9-11 point (b = 0.15, w = 0.82) over every logged evaluation that ran its
    attractor search: how many sets, how many found each motion, how many found each pair and
    all three of the paper's, and the sets with the most of them."""
    from gearsim.analysis.paper import PAPER_COEXIST

    n = 0
    seen: dict[str, int] = {}
    best: list[dict[str, Any]] = []
    most = 0
    for form, _level, rec in logged_evaluations(log_dir):
        co = rec["measured"].get("coexist")
        if co is None:
            continue
        n += 1
        for lab in co:
            seen[lab] = seen.get(lab, 0) + 1
        hits = sum(1 for x in PAPER_COEXIST if x in co)
        if hits > most:
            most, best = hits, []
        if hits == most and len(best) < 5:
            best.append({"form": form, "x": rec["x"], "coexist": co, "J": rec["J"]})
    return {"paper": list(PAPER_COEXIST), "n_sets": n, "motions_found": seen,
            "most_of_the_paper_motions": most, "sets_with_most": best}


def pareto_figure(log_dir: str | Path, out: str | Path) -> Path:
    """Every logged evaluation of every form (lower vs upper group error, log axes) with each
    form's front and the within-tolerance corner (both <= 1)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pts = pareto_points(log_dir)
    fig, ax = plt.subplots(figsize=(7.0, 5.6), dpi=130)
    forms = sorted({p["form"] for p in pts})
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, f in enumerate(forms):
        ps = [p for p in pts if p["form"] == f]
        c = colours[i % len(colours)]
        ax.scatter([p["lower"] for p in ps], [p["upper"] for p in ps], s=10, alpha=0.45,
                   color=c, linewidths=0)
        fr = front(ps)
        ax.step([p["lower"] for p in fr], [p["upper"] for p in fr], where="post", color=c,
                lw=1.8, marker="o", ms=3, label=f"{f} ({len(ps)} evaluations)")
    ax.axvline(1.0, color="k", lw=0.8, ls="--")
    ax.axhline(1.0, color="k", lw=0.8, ls="--")
    ax.fill_between([0.01, 1.0], 0.01, 1.0, color="0.85", zorder=0)
    ax.text(0.05, 0.05, "both groups\nwithin tolerance", fontsize=8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(0.03, CAP * 1.1)
    ax.set_ylim(0.03, CAP * 1.1)
    ax.set_xlabel("lower landmarks: RMS error in tolerances (grazing, jump, first doubling)")
    ax.set_ylabel("upper cascade: RMS error in tolerances (3 inverse doublings, period 1)")
    ax.set_title("Calibration trade-off: every evaluated set, front per model form\n"
                 f"(a landmark not found counts {CAP:g} tolerances)", fontsize=10)
    # where it hides the fewest points (sets with landmarks not found sit at the cap, upper right)
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)
    return out
