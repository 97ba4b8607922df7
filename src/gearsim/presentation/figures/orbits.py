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


def _curve_notes(curves: pd.DataFrame) -> list[str]:
    reasons = list(curves.attrs.get("reasons", []))
    out = []
    if len(curves):
        for _cid, c in curves.groupby("curve", sort=True):
            r = c.iloc[0]
            bnd = f" {r['boundary']}" if r["boundary"] else ""
            out.append(f"{r['kind'].replace('_', ' ')}{bnd}"
                       f" of the {int(r['period'])}T orbit: {len(c)} points, "
                       f"{r['name2']} {c['value2'].min():.4g}-{c['value2'].max():.4g}")
    else:
        out.append("no bifurcation point located along the seeding continuation")
    if reasons:
        out.append("Where curves end: " + "; ".join(reasons))
    return out


def fig_curves(number: int, plane: str):
    def build(ctx: Context) -> list[Built]:
        from gearsim.presentation.orbit_plots import figure_curves

        df = _plane(ctx, plane)
        curves = _need(ctx.orbits, f"{plane}_curves", "orbits")
        ax = axes_text(df)
        fig = figure_curves(curves, df, title=f"{ax} plane: bifurcation curves by Newton-Floquet "
                            "continuation over the simulated pattern map")
        diffs = ["Not in the paper. Curves: each period doubling, fold and grazing located "
                 "along ω at the standard set is re-located (to 1e-8 in ω) at successive values "
                 "of the plane's second parameter (docs/orbits.md); the map is the simulated "
                 "pattern of every cell (Fig " + ("7" if plane == "wb" else "14") + "b).",
                 *_curve_notes(curves)]
        return [Built(number, fig, f"Bifurcation curves (period doubling solid red, fold "
                      f"dash-dot green, grazing dotted orange; nT the orbit's period) over the "
                      f"pattern map of the {ax} plane.", diffs,
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
