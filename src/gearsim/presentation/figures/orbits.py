"""Figures of the periodic-orbit analysis (docs/orbits.md), registered in the one figure table.

* Fig 21, 22: the two-parameter bifurcation curves (period doubling, fold, grazing; Newton-
  Floquet continuation) over the pattern maps of the (w, b) and (w, xi) planes (Figs 7b, 14b).
* Fig 23: the continuation of the standard set along w: every periodic branch, stable solid and
  unstable dashed, the located bifurcations and the largest Floquet multiplier.

Fig 4 (registry) reads the same standard continuation to mark the exact landmarks and draw the
unstable branches.
"""

from __future__ import annotations

import pandas as pd

from gearsim.presentation.figures.context import Built, Context, _need, _plane, axes_text


def _curve_notes(curves: pd.DataFrame, codim2: pd.DataFrame | None) -> list[str]:
    from gearsim.presentation.orbit_plots import curve_flank

    reasons = list(curves.attrs.get("reasons", []))
    out = []
    if len(curves):
        for _cid, c in curves.groupby("curve", sort=True):
            r = c.iloc[0]
            flank = curve_flank(r)
            bnd = f" {r['boundary']}" if r["boundary"] else ""
            ends = ""
            if "end_first" in c.columns:
                ends = f"; ends: {r['end_first']} / {c['end_last'].iloc[-1]}"
            out.append(f"{r['kind'].replace('_', ' ')}{bnd}{' (' + flank + ')' if flank else ''}"
                       f" of the {int(r['period'])}T orbit: {len(c)} points, "
                       f"{r['name2']} {c['value2'].min():.4g}-{c['value2'].max():.4g}{ends}")
    else:
        out.append("no bifurcation point located")
    if codim2 is not None and len(codim2):
        for r in codim2.itertuples(index=False):
            out.append(f"codimension-2 point {getattr(r, 'point', '')} "
                       f"({str(r.kind).replace('_', ' ')}, period {int(r.period)}) at "
                       f"{r.name} = {r.value:.6f}, {r.name2} = {r.value2:.6f}")
    if reasons:
        out.append("Where curves end: " + "; ".join(reasons))
    return out


#: what each kind of line in Figs 21 and 22 is (the caption)
CURVE_CAPTION = (
    "Solid: period doubling, where the orbit of period n loses stability through a multiplier "
    "-1 and the orbit of period 2n is born (the period of the map's label doubles across it). "
    "Dotted: grazing of the tooth face (x = +b), dashed: grazing of the tooth back (x = -b), "
    "where an orbit's turning point touches the boundary and an impact is born or lost (the "
    "impact state I, p or q changes across it). Dash-dot-dot: fold, where two orbits of one period "
    "meet and vanish; the chain jumps there, and between two folds both branches coexist (the "
    "hysteresis band). The colour is the orbit's period (black 1T, blue 2T, magenta 4T, purple 8T, "
    "brown 16T); white markers are the codimension-2 points where two curves meet or a curve "
    "ends inside the plane (kind in the legend).")


def fig_curves(number: int, plane: str):
    def build(ctx: Context) -> list[Built]:
        from gearsim.presentation.orbit_plots import figure_curves

        df = _plane(ctx, plane)
        curves = _need(ctx.orbits, f"{plane}_curves", "orbits")
        codim2 = ctx.orbits.get(f"{plane}_codim2")
        ax = axes_text(df)
        fig = figure_curves(curves, df, codim2=codim2,
                            title=f"{ax} plane: bifurcation curves by Newton-Floquet "
                            "continuation over the simulated pattern map")
        diffs = ["Not in the paper. Curves: each period doubling, fold and grazing located "
                 "between two cells of the map (or along the standard sweep) is followed "
                 "across the plane, each point located by its test function (docs/orbits.md); "
                 "the map is the simulated pattern of every cell (Fig "
                 + ("7" if plane == "wb" else "14") + "b).",
                 *_curve_notes(curves, codim2)]
        n2 = 0 if codim2 is None else len(codim2)
        return [Built(number, fig, f"Bifurcation curves and {n2} codimension-2 points over "
                      f"the pattern map of the {ax} plane. " + CURVE_CAPTION, diffs,
                      [f"{plane}/cells", f"orbits/{plane}_curves"])]
    return build


def fig23(ctx: Context) -> list[Built]:
    from gearsim.presentation.orbit_plots import figure_branches

    br = _need(ctx.orbits, "standard", "orbits")
    fig = figure_branches(br, title="Continuation of the standard set along ω: periodic "
                          "branches (stable solid, unstable dashed) and located bifurcations")
    ev = br[br["event"] != ""]
    diffs = ["Not in the paper. Pseudo-arclength continuation of the period-1 orbit from "
             f"ω = {br['value'].min():.3g} with branch switching at period doublings "
             "(docs/orbits.md); "
             f"{br['branch'].nunique()} branches, {len(ev)} located events."]
    diffs += [f"{r.event.replace('_', ' ')}{' ' + r.boundary if r.boundary else ''} of the "
              f"{int(r.period)}T orbit at ω = {r.value:.6f}" for r in ev.itertuples()]
    diffs += [str(r) for r in br.attrs.get("reasons", [])]
    return [Built(23, fig, "Periodic branches of the standard set versus ω: section displacement "
                  "x (stable solid, unstable dashed; colour by period) with folds, period "
                  "doublings and grazings marked; below, the largest Floquet multiplier modulus.",
                  diffs, ["orbits/standard"])]
