"""The report's plane atlas (``gearsim atlas``, docs/atlas.md): per plane, the boundary
length by mechanism, the share of the periodic boundaries a located curve or a fold band
explains, the link to the unexplained edges, and the chaotic band along its line. Text only:
the numbers are those of the atlas summaries."""

from __future__ import annotations

from typing import Any

from gearsim.analysis.boundaries import GROUPS, MECHANISMS

#: the periodic groups' target: the share of their edges a matching curve or a fold band
#: explains
TARGET = 0.99
_WORDS = {
    "grazing": "on a grazing curve",
    "period_doubling": "on a period-doubling curve",
    "fold": "on a fold curve (a jump)",
    "fold_band": "inside a fold's hysteresis band",
    "coexist": "both motions stable on both sides (Newton): a hysteresis band",
    "chaos_onset": "at the chaotic band's onset or exit (the cascade's last doubling)",
    "crisis": "chaotic band ends abruptly (a crisis, read from the grid)",
    "near_curve": "unsettled cell beside a located curve",
    "unexplained": "unexplained (a missed curve or a wrong label)",
}


def _pct(part: float, whole: float) -> str:
    return "—" if not whole else f"{100 * part / whole:.1f} %"


def _mechanism_table(a: dict[str, Any]) -> list[str]:
    cell: dict[tuple[str, str], int] = {(r["group"], r["mechanism"]): int(r["edges"])
                                        for r in a["by_mechanism"]}
    totals = {g: sum(v for (gg, _), v in cell.items() if gg == g) for g in GROUPS}
    out = ["| mechanism | " + " | ".join(f"{g} ({totals[g]})" for g in GROUPS) + " | all |",
           "|---|" + "---|" * (len(GROUPS) + 1)]
    for m in MECHANISMS:
        row = [cell.get((g, m), 0) for g in GROUPS]
        if not any(row):
            continue
        out.append(f"| {_WORDS[m]} | " + " | ".join(
            f"{v} ({_pct(v, totals[g])})" if v else "—" for v, g in zip(row, GROUPS,
                                                                         strict=True))
            + f" | {sum(row)} |")
    return out


def _cascade_lines(c: dict[str, Any], x: str) -> list[str]:
    y, g = c.get("value"), c.get("grid")
    if g is None:
        return [f"- Chaotic band: {c.get('note', 'not measured')}."]
    out = [f"- Chaotic band along {c['parameter']} = {y:.5g}: the grid's cascade "
           f"{' -> '.join(f'{p}T' for p in g['periods'])} from {x} = {g['start']:.4f}, the "
           f"first chaotic cell at {g['onset']:.4f}, the band's last at {g['end']:.4f}."]
    for side, what in (("onset", "onset"), ("exit", "exit (inverse cascade)")):
        s = c.get(side)
        if not s:
            continue
        if "error" in s:
            out.append(f"  - {what}: not located ({s['error']})")
            continue
        dd = s["doublings"]
        pts = ", ".join(f"{d['value']:.6f} ({d['period']}->{2 * d['period']})" for d in dd)
        rat = "; ".join(
            f"{d['ratio']:.3f} ({'smooth' if d['smooth'] else 'grazing between'})"
            for d in dd if d["ratio"] is not None) or "fewer than three doublings located"
        acc = s.get("accumulation")
        # the grid's interval the accumulation should fall in: the band's first chaotic cell
        # and the cell before it (onset), its last chaotic cell and the cell after (exit)
        lo, hi = ((g["onset_lo"], g["onset"]) if side == "onset"
                  else (g["end"], g["end"] + (g["onset"] - g["onset_lo"])))
        where = ("" if acc is None else
                 f", inside the grid's interval {lo:.4f}-{hi:.4f}" if lo <= acc <= hi else
                 f", **outside** the grid's interval {lo:.4f}-{hi:.4f}")
        out.append(f"  - {what}: doublings at {x} = {pts}; ratios of successive intervals "
                   f"{rat} (Feigenbaum {s['feigenbaum']:.3f}); accumulation "
                   + (f"{x} = {acc:.5f}{where}" if acc is not None else "not estimated"))
    if g.get("exit") == "crisis":
        out.append(f"  - the band ends by a crisis as the grid reads it: chaos -> "
                   f"{g['after_end']} after {x} = {g['end']:.4f} (not located)")
    return out


def atlas_lines(atlas: list[dict[str, Any]], h: str = "##") -> list[str]:
    """The atlas section: one block per plane."""
    if not atlas:
        return []
    out = [f"{h} The plane atlas: every boundary accounted for", "",
           "A boundary edge is a pair of adjacent cells (along either axis) with different "
           "labels, one cell side long. Each is explained by a located curve of the matching "
           "kind within 1.5 cells (grazing where the impact state changes, period doubling "
           "where the period doubles, fold at a jump), a fold's hysteresis band, motions "
           "that Newton finds stable on both sides of the edge (a hysteresis band whose fold "
           "lies farther away), or the chaotic band's onset or exit; the rest are "
           "unexplained and listed with their cells.", ""]
    for a in atlas:
        x = a["x"]
        out += [f"{h}# Plane {a['plane']}: boundary length by mechanism", "",
                f"{a['edges']} edges, {a['curves']} located curves.", ""]
        out += _mechanism_table(a) + [""]
        exp = a["explained"]
        parts = [f"{g}: {ok} of {n} ({_pct(ok, n)})" for g, (ok, n) in exp.items()]
        reach = all(n == 0 or ok / n >= TARGET for ok, n in exp.values())
        out.append(f"- Periodic edges explained (matching curve, fold band or coexisting "
                   f"motions): "
                   f"{'; '.join(parts)}; target {100 * TARGET:.0f} % each: "
                   f"{'met' if reach else '**not met**'}.")
        near = {r["group"]: r for r in a["near"]}
        out.append("- A located curve of any kind within 1.5 cells: " + "; ".join(
            f"{g} {_pct(near[g]['near'], near[g]['edges'])} of {near[g]['edges']}"
            for g in ("all", *GROUPS) if g in near) + ".")
        if a.get("unexplained_pairs"):
            link = a.get("unexplained_file")
            v = a.get("unexplained_verdicts") or {}
            out.append("- Unexplained edges" + (f" ([{link}]({link}), with their cells)"
                                                 if link else "")
                       + (f": {v.get('missed curve', 0)} on a boundary no located curve "
                          f"follows (a missed curve), {v.get('wrong label', 0)} beside a cell "
                          "whose label Newton refutes or no neighbour shares (a wrong label)"
                          if v else "")
                       + "; most frequent pairs: "
                       + "; ".join(f"{p['pair']} ({p['group']}, {p.get('verdict', '?')}) "
                                   f"{p['edges']}" for p in a["unexplained_pairs"]) + ".")
        nw = a.get("newton")
        if nw:
            out.append("- Newton on the cells of the edges no curve or band explains (periods "
                       f"up to {nw['max_period']}): " + "; ".join(
                           f"{g}: {nw[g]['read']} read, {nw[g]['coexist']} across two motions "
                           f"stable on both sides, {nw[g]['wrong_label']} beside a cell whose "
                           "state converges to an orbit of a smaller least period than its "
                           "label (a slowly decaying transient)"
                           for g in ("I changes", "I the same") if g in nw) + ".")
        if a.get("crises"):
            out.append("- The chaotic band ends abruptly (a crisis, read from the grid, not "
                       "located) between: " + "; ".join(
                           f"{c['pair']} ({c['edges']} edges, {x} {c['x_lo']:.3f}-"
                           f"{c['x_hi']:.3f}, {a['y']} {c['y_lo']:.4g}-{c['y_hi']:.4g})"
                           for c in a["crises"]) + ".")
        if a.get("cascade"):
            out += _cascade_lines(a["cascade"], x)
        out.append("")
    return out
