"""The bifurcation diagram of any sweep: Poincare section points, DC and Kmax against the swept
value, in the sweep's own units (e.g. torque in N m when the sweep was given as ``torque_Nm``
with a gear file). Drawn by the pipeline for every sweep of every study
(``results/figures/sweeps/<sweep>.png``); the paper's orbit-diagram figures stay in the registry.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from gearsim.cell.motion import DEFAULT_KMAX
from gearsim.presentation.figures import style

#: section points drawn per swept value (the last ones: a periodic motion repeats them)
MAX_POINTS = 64


def sweep_axis_label(df: pd.DataFrame, spec: Mapping[str, Any] | None
                     ) -> tuple[str, float, str]:
    """``(axis label, factor, parameter)``: the swept value times ``factor`` is in the sweep's
    own unit (1 for a dimensionless sweep)."""
    from gearsim.physical.units import axis_label_values

    param = (str(df["parameter"].iloc[0]) if "parameter" in df.columns and len(df)
             else str((spec or {}).get("name", "value")))
    if spec and isinstance(spec.get("physical"), Mapping):
        label, factor = axis_label_values({**spec, "name": param}, 1.0)
        return label, float(factor), param
    return style.param_label(param), 1.0, param


def figure_sweep_diagram(df: pd.DataFrame, *, name: str,
                         spec: Mapping[str, Any] | None = None,
                         physical: Mapping[str, Any] | None = None) -> tuple[Any, str]:
    """Three stacked panels sharing the swept axis: section points x (coloured by impact
    state), DC, Kmax; a ``direction: both`` sweep draws the backward pass as open markers.
    ``physical``: ``{name, unit, k}`` of a dimensionless swept parameter on the study's gear
    (:func:`gearsim.physical.units.physical_factors`), drawn as a second axis on top.
    Returns ``(figure, caption)``."""
    import matplotlib.pyplot as plt

    label, factor, param = sweep_axis_label(df, spec)
    fig, axes = plt.subplots(3, 1, figsize=(7.0, 7.2), sharex=True,
                             gridspec_kw={"height_ratios": [2.2, 1, 1]})
    ax_x, ax_dc, ax_k = axes
    kcol = "kmax" if "kmax" in df.columns else DEFAULT_KMAX
    dirs = list(dict.fromkeys(df["direction"])) if "direction" in df.columns else ["forward"]
    seen: set[int] = set()
    for d in dirs:
        sub = df[df["direction"] == d] if "direction" in df.columns else df
        back = d == "backward"
        vals = sub["value"].to_numpy(dtype=float) * factor
        groups: dict[int, tuple[list, list]] = {}  # impact state -> (values, points)
        for v, px, imp in zip(vals, sub["poincare_x"], sub["I"], strict=True):
            pts = np.asarray(px if px is not None else [], dtype=float)[-MAX_POINTS:]
            pts = pts[np.isfinite(pts)]
            if not len(pts):
                continue
            i = int(imp) if pd.notna(imp) else -9
            xs, ys = groups.setdefault(i, ([], []))
            xs.append(np.full(len(pts), v))
            ys.append(pts)
        # one collection per impact state (one per sweep value cost ~5 s of drawing a sweep)
        for i, (xs, ys) in groups.items():
            colour = style.impact_colour(i)
            first = i not in seen and not back
            seen.add(i)
            ax_x.scatter(np.concatenate(xs), np.concatenate(ys), s=3 if not back else 9,
                         facecolors="none" if back else colour, edgecolors=colour,
                         linewidths=0.6, label=style.IMPACT_NAMES.get(i, f"I = {i}")
                         if first else None, rasterized=len(df) > 400)
        style_kw = {"ls": "--" if back else "-", "lw": 1.0, "marker": "o" if len(vals) < 60
                    else None, "ms": 2.5, "mfc": "none" if back else None}
        ax_dc.plot(vals, sub["dc"].to_numpy(dtype=float), color="#1f4e79", **style_kw,
                   label=d if len(dirs) > 1 else None)
        ax_k.plot(vals, sub[kcol].to_numpy(dtype=float), color="#8b1a1a", **style_kw,
                  label=d if len(dirs) > 1 else None)
    ax_x.set_ylabel(style.X_LABEL + "\nat the Poincare section")
    ax_x.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7.5, frameon=False,
                markerscale=2.5, title="impact state", title_fontsize=8)
    ax_dc.set_ylabel("DC")
    ax_dc.set_ylim(-0.03, 1.03)
    ax_k.set_ylabel(style.kmax_label(kcol if kcol != "kmax" else None), fontsize=8)
    ax_k.set_xlabel(label)
    if len(dirs) > 1:
        ax_dc.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7.5, frameon=False)
    for ax in axes:
        ax.grid(alpha=0.25, lw=0.5)
    fixed = ", ".join(f"{k} = {v:g}" for k, v in ((spec or {}).get("fixed") or {}).items()
                      if isinstance(v, int | float))
    title = f"Sweep {name}: {label}" + (f" ({fixed})" if fixed else "")
    top = None
    if physical and factor == 1.0:
        k = float(physical["k"])
        top = f"{physical['name']} [{physical['unit']}]"
        sec = ax_x.secondary_xaxis("top", functions=(lambda v: v * k, lambda v: v / k))
        sec.set_xlabel(top, fontsize=8)
        sec.tick_params(labelsize=7)
    ax_x.set_title(title, fontsize=10, pad=28 if top else 6)
    fig.tight_layout()
    n = len(df)
    caption = (f"Bifurcation diagram of the sweep '{name}' ({n} points, {label}"
               + (f", {fixed}" if fixed else "") + "): Poincare section points of the mesh "
               "displacement (the last up to 64 per value, coloured by impact state), the "
               "disengagement duty cycle DC and the dynamic load coefficient Kmax."
               + (" Open markers and dashed lines: the backward pass." if len(dirs) > 1
                  else "")
               + (f" Top axis: {top} (the gear file)." if top else ""))
    return fig, caption


def sweep_spec_of(path, config: Mapping[str, Any] | None, name: str) -> dict[str, Any] | None:
    """A sweep's config entry: from the configuration, else from its table's provenance."""
    spec = ((config or {}).get("sweeps") or {}).get(name)
    if spec:
        return dict(spec)
    from gearsim.presentation.study_summary import sweep_spec_of as from_table

    return from_table(path)
