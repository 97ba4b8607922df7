"""The scorecard: the paper's results beside ours, one row each, on the first screen of the
report and at the head of the explorer (docs/figures.md, "The report")."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from gearsim.analysis.paper import (
    JUMP_DC_TOL,
    LANDMARK_TOL,
    PAPER_B_THRESHOLD,
    PAPER_JUMP_DC,
    PAPER_JUMP_KMAX,
    PAPER_LANDMARKS,
    PAPER_XI_THRESHOLD,
    THRESHOLD_TOL,
    within,
)
from gearsim.cell.motion import DEFAULT_KMAX, KMAX_DEFINITION
from gearsim.presentation.study_summary import value_text


@dataclass
class ScoreRow:
    """One line of the scorecard: a paper result beside ours."""

    item: str
    paper: str
    ours: str
    located: str = "—"  # the located bifurcation (continuation), where there is one
    difference: str = "—"
    ok: bool | None = None  # within tolerance; None: no tolerance applies
    tolerance: str = "—"

    @property
    def verdict(self) -> str:
        return {True: "yes", False: "**no**", None: "—"}[self.ok]


def scorecard(rep: Any) -> list[ScoreRow]:
    """The paper's results beside ours, one row each, from a
    :class:`gearsim.presentation.report.Report`."""
    rows: list[ScoreRow] = []
    exact = {}
    if rep.exact is not None and len(rep.exact):
        exact = {r["key"]: r for _, r in rep.exact.iterrows()}
    if rep.matched is None and rep.paper_material and not any(
            "no sweep 'standard'" in n for n in rep.notes):
        rows.append(ScoreRow(f"w of the {len(PAPER_LANDMARKS)} landmarks of the standard sweep",
                             "Sect 3.1", "not computed"))
    if rep.matched is not None:
        for r in rep.matched.itertuples():
            paper = (f"{r.paper_lo:g}-{r.paper_hi:g}" if r.paper_lo != r.paper_hi
                     else f"{r.paper:g}")
            ex = exact.get(r.key)
            located = ("—" if ex is None or not math.isfinite(ex["exact"])
                       else f"{ex['exact']:.4f}")
            if r.found:
                ok = within(r.error, LANDMARK_TOL)
                rows.append(ScoreRow(f"w: {r.text}", paper,
                                     f"{r.ours:.4f} [{r.lo:.3f}, {r.hi:.3f}]", located,
                                     f"{r.error:+.4f}", ok, f"{LANDMARK_TOL} in w"))
            else:
                rows.append(ScoreRow(f"w: {r.text}", paper, "not found", located, "—", False,
                                     f"{LANDMARK_TOL} in w"))
    if rep.jump:
        j = rep.jump
        rows.append(ScoreRow("DC after the jump", f"{PAPER_JUMP_DC}", f"{j['dc_after']:.3f}",
                             difference=f"{j['dc_after'] - PAPER_JUMP_DC:+.3f}",
                             ok=within(j["dc_after"] - PAPER_JUMP_DC, JUMP_DC_TOL),
                             tolerance=f"{JUMP_DC_TOL}"))
        kmax = j["kmax_after"].get(DEFAULT_KMAX)
        if kmax is not None:  # Kmax itself, never the closest of the other readings
            rows.append(ScoreRow(f"Kmax after the jump ({KMAX_DEFINITION})",
                                 f"{PAPER_JUMP_KMAX}", f"{kmax:.3f}",
                                 difference=f"{kmax - PAPER_JUMP_KMAX:+.3f}",
                                 tolerance="none (the paper's Kmax is not defined exactly)"))
    for th, label, key, paper in (
            (rep.b_threshold, "b above which no double-sided impact occurs", "b",
             PAPER_B_THRESHOLD),
            (rep.xi_threshold, "xi above which only 0/1T and 1/1T remain", "xi",
             PAPER_XI_THRESHOLD)):
        if th is None:
            if key not in rep.thresholds_na:
                rows.append(ScoreRow(label, f"{paper}", "not computed"))
            continue
        ok = within(th.difference, THRESHOLD_TOL)
        if math.isinf(th.value):
            ours = f"above the plane (still at {th.last_with:.4g})"
        elif math.isnan(th.value):
            ours = "no row has the property"
        else:
            ours = f"{th.value:.4f} [{th.last_with:.3f}, {th.first_without:.3f}]"
        rows.append(ScoreRow(label, f"{th.paper}", ours,
            difference=value_text(th.difference, "+.4f", "—"), ok=ok,
            tolerance=f"{THRESHOLD_TOL}"))
    for key, e in rep.sequences.items():
        if e.get("paper") is None or e.get("applicable") is False:
            continue
        if e.get("ours") is None:
            rows.append(ScoreRow(f"sequence {e['parameter']} = {e['value']} ({key})",
                                 " -> ".join(e["paper"]), "not computed", ok=None))
            continue
        extra = [x for x in dict.fromkeys(e["ours"]) if x not in e["paper"]]
        ours = ("identical" if e["exact"] else "paper's patterns in order" if e["in_order"]
                else "not in the paper's order")
        if extra and not e["exact"]:
            ours += "; extra " + ", ".join(extra)
        rows.append(ScoreRow(f"sequence {e['parameter']} = {e['value']} ({key})",
                             " -> ".join(e["paper"]), ours, ok=bool(e["exact"]),
                             tolerance="same sequence"))
    if rep.hysteresis_band is not None:
        lo, hi = rep.hysteresis_band
        rows.append(ScoreRow("hysteresis of the fold (Fig 18)", "jump up and down differ",
                             f"band {lo:.4f} <= w <= {hi:.4f}", ok=hi > lo,
                             tolerance="a band exists"))
    rows += _atlas_rows(getattr(rep, "atlas", []) or [])
    for m in rep.multistable:
        rows.append(ScoreRow(f"coexisting attractors, plane {m['plane']}",
                             "coexistence near the fold",
                             f"{m['multi']} of {m['searched']} searched cells"))
    return rows


def _share_text(counts: dict[str, int], main: str, also: str) -> tuple[str, float | None]:
    n = counts.get("edges", 0)
    if not n:
        return "no such boundary", None
    x = counts.get(main, 0) / n
    return (f"{100 * x:.1f} % of {n} edges on {main.replace('_', '-')} curves "
            f"({100 * counts.get(also, 0) / n:.1f} % on {also} curves)"), x


#: an area "shrinks" when the highest quarter of xi has at most this share of the lowest's
SHRINK = 0.9


def _atlas_rows(atlas: list[dict[str, Any]]) -> list[ScoreRow]:
    """The paper's mechanisms measured on the whole of each plane (``gearsim atlas``)."""
    rows = []
    for a in atlas:
        m, p = a.get("mechanisms") or {}, a["plane"]
        if "grazing" in m:
            text, _ = _share_text(m["grazing"], "grazing", "fold")
            rows.append(ScoreRow(f"non-impact <-> impact boundaries by grazing, plane {p}",
                                 "grazing bifurcation", text))
        if "doubling" in m:
            text, _ = _share_text(m["doubling"], "period_doubling", "grazing")
            rows.append(ScoreRow(f"adjacent impact motions by period doubling, plane {p}",
                                 "period doubling", text))
        bi = a.get("b_independence")
        if bi:
            rows.append(ScoreRow(
                f"patterns independent of b above b = {bi['above']:g}, plane {p}",
                "independent of b",
                f"largest |dw/db| of any curve above it {bi['max_slope']:.3g}"
                + (f" ({bi['curve']})" if bi.get("curve") else "")
                + f"; {bi['edges_along_y_periodic']} edges between periodic cells along b "
                f"above it ({bi['edges_along_y']} in all)"))
        dm = a.get("damping")
        if dm:
            b0, b1 = dm["bands"][0], dm["bands"][-1]
            # shrinks: falls by a tenth or more from the lowest quarter of xi to the highest
            shrink = all(b1[k] <= SHRINK * b0[k] and b0[k] > 0 for k in ("impact", "chaos"))
            rows.append(ScoreRow(
                f"more damping shrinks the impact and chaotic regions, plane {p}",
                "both shrink as xi grows",
                f"impact {100 * b0['impact']:.1f} % -> {100 * b1['impact']:.1f} %, chaotic "
                f"{100 * b0['chaos']:.2f} % -> {100 * b1['chaos']:.2f} % of the cells from "
                f"xi {b0['lo']:.3g}-{b0['hi']:.3g} to {b1['lo']:.3g}-{b1['hi']:.3g}; rank "
                f"correlation with xi {_rho(dm['rho_impact'])} / {_rho(dm['rho_chaos'])}",
                ok=shrink, tolerance=f"each area at most {SHRINK:g} x from the lowest to the "
                "highest quarter of xi"))
    return rows


def _rho(v: float | None) -> str:
    return "—" if v is None else f"{v:+.2f}"


def scorecard_lines(rep: Any) -> list[str]:
    rows = scorecard(rep)
    if not rows:
        return []
    judged = [r for r in rows if r.ok is not None]
    out = ["## Scorecard", "",
           f"{sum(r.ok for r in judged)} of {len(judged)} results within tolerance. Grid "
           "readings are the midpoint of the two swept values where the labels change "
           "[interval]; \"located\" is the bifurcation found by continuation.", "",
           "| result | paper | ours (grid) | located | difference | within |",
           "|---|---|---|---|---|---|"]
    out += [f"| {r.item} | {r.paper} | {r.ours} | {r.located} | {r.difference} | {r.verdict} |"
            for r in rows]
    out.append("")
    return out
