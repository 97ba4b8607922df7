"""The study's own material in a few numbers and lines, for any study: its planes (cells,
patterns, where each pattern lies), sweeps (pattern sequence and transitions in the sweep's own
units, its diagram), recorded points and coexisting attractors. Used by the report
(:mod:`gearsim.presentation.report`)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pandas as pd

from gearsim.analysis.landmarks import find_landmarks, pattern_sequence


def axis_column(df: pd.DataFrame, name: str, which: str) -> str:
    """Column holding the plane's ``which`` ('x' or 'y') axis named ``name``."""
    for c in (name, f"{which}_value", which, f"value_{which}"):
        if c in df.columns:
            return c
    raise KeyError(f"no column for the plane axis '{name}' ({which}); columns: {list(df.columns)}")


def value_text(x: Any, fmt: str, missing: str = "not computed") -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return missing
    return format(x, fmt)


def plane_summary(plane: str, axes: tuple[str, str], cells: pd.DataFrame | None, *,
                  paper: str = "not applicable") -> dict[str, Any]:
    """A plane of the study in a few numbers: cells, grid, the most frequent patterns and
    where each lies; ``paper``: what the paper has to compare with it."""
    out: dict[str, Any] = {"plane": plane, "axes": axes, "paper": paper}
    if cells is None or not len(cells):
        out["cells"] = None
        return out
    out["cells"] = len(cells)
    if {"i", "j"} <= set(cells.columns):
        out["grid"] = (int(cells["i"].max()) + 1, int(cells["j"].max()) + 1)
    if "label" in cells.columns:
        labels = cells["label"].fillna("?")
        counts = labels.value_counts()
        out["patterns"] = [(str(k), int(v)) for k, v in counts.head(6).items()]
        out["n_patterns"] = int(len(counts))
        try:
            xc, yc = axis_column(cells, axes[0], "x"), axis_column(cells, axes[1], "y")
        except KeyError:
            return out
        x, y = cells[xc].astype(float), cells[yc].astype(float)
        out["extents"] = [
            {"label": str(k), "cells": int(v), "share": v / len(cells),
             "x": (float(x[labels == k].min()), float(x[labels == k].max())),
             "y": (float(y[labels == k].min()), float(y[labels == k].max()))}
            for k, v in counts.head(8).items()]
        out["range"] = ((float(x.min()), float(x.max())), (float(y.min()), float(y.max())))
    return out


def plane_lines(planes: list[dict[str, Any]], h: str = "##") -> list[str]:
    if not planes:
        return []
    out = [f"{h} Planes", "",
           "| plane | axes (x, y) | cells (grid) | patterns (most frequent, cells) | "
           "the paper has |", "|---|---|---|---|---|"]
    for p in planes:
        ax = f"({p['axes'][0]}, {p['axes'][1]})"
        if p["cells"] is None:
            out.append(f"| {p['plane']} | {ax} | not computed | | {p['paper']} |")
            continue
        grid = f" ({p['grid'][0]} x {p['grid'][1]})" if p.get("grid") else ""
        pats = ", ".join(f"{k} {v}" for k, v in p.get("patterns", []))
        more = p.get("n_patterns", 0) - len(p.get("patterns", []))
        pats += f", {more} more" if more > 0 else ""
        out.append(f"| {p['plane']} | {ax} | {p['cells']}{grid} | {pats} | {p['paper']} |")
    out.append("")
    for p in planes:
        if not p.get("extents"):
            continue
        (x0, x1), (y0, y1) = p["range"]
        xn, yn = p["axes"]
        out += [f"Plane {p['plane']}: where each pattern lies (cell centres; the plane spans "
                f"{xn} {x0:.4g}-{x1:.4g}, {yn} {y0:.4g}-{y1:.4g}). A pattern that ends inside "
                "the plane ends at the edge of its range.", "",
                f"| pattern | area | {xn} from | {xn} to | {yn} from | {yn} to |",
                "|---|---|---|---|---|---|"]
        for e in p["extents"]:
            n = f"{e['cells']} cell" + ("s" if e["cells"] != 1 else "")
            out.append(f"| {e['label']} | {100 * e['share']:.1f} % ({n}) | "
                       f"{e['x'][0]:.4g} | {e['x'][1]:.4g} | {e['y'][0]:.4g} | "
                       f"{e['y'][1]:.4g} |")
        out.append("")
    return out


def sweep_summary(name: str, df: pd.DataFrame, spec: dict[str, Any] | None = None,
                  figure: str | None = None) -> dict[str, Any]:
    """A sweep in a few lines: its parameter (in the sweep's own units when it was given in
    physical ones), range, pattern sequence and transitions (grid intervals), per direction."""
    from gearsim.physical.units import axis_label_values

    spec = dict(spec or {})
    param = (str(df["parameter"].iloc[0]) if "parameter" in df.columns and len(df)
             else str(spec.get("name", "value")))
    spec.setdefault("name", param)
    label, factor = axis_label_values(spec, 1.0) if spec.get("physical") else (param, 1.0)
    out: dict[str, Any] = {"name": name, "parameter": param, "label": label, "factor": factor,
                           "points": len(df), "figure": figure, "directions": []}
    if not len(df):
        return out
    dirs = (list(dict.fromkeys(df["direction"])) if "direction" in df.columns
            else ["forward"])
    for d in dirs:
        sub = df[df["direction"] == d] if "direction" in df.columns else df
        lms = find_landmarks(sub.reset_index(drop=True))
        v = sub["value"].astype(float) * factor
        out["directions"].append({
            "direction": d, "min": float(v.min()), "max": float(v.max()), "n": len(sub),
            "sequence": pattern_sequence(sub),
            "transitions": [{"kind": r.kind, "lo": r.lo * factor, "hi": r.hi * factor,
                             "from": r.from_label, "to": r.to_label} for r in lms.itertuples()],
        })
    return out


def sweep_lines(sweeps: list[dict[str, Any]], h: str = "##") -> list[str]:
    if not sweeps:
        return []
    out = [f"{h} Sweeps", ""]
    for s in sweeps:
        out += [f"**{s['name']}**: {s['label']}, {s['points']} points.", ""]
        if s.get("figure"):
            out += [f"![bifurcation diagram of sweep {s['name']}]({s['figure']})", ""]
        for d in s["directions"]:
            head = f"- {d['direction']}: " if len(s["directions"]) > 1 else "- "
            out.append(f"{head}{s['label']} {d['min']:.5g} to {d['max']:.5g}: "
                       + " -> ".join(d["sequence"]))
            for t in d["transitions"]:
                out.append(f"  - {t['kind'].replace('_', ' ')} between {t['lo']:.5g} and "
                           f"{t['hi']:.5g}: {t['from']} -> {t['to']}")
        out.append("")
    return out


def point_summary(name: str, df: pd.DataFrame) -> dict[str, Any]:
    """A recorded point set: each point's parameters, start and pattern."""
    from gearsim.dynamics.parameters import ModelParameters

    params = [c for c in df.columns if c in ModelParameters.names()
              and df[c].nunique(dropna=True) > 1] or (["w"] if "w" in df.columns else [])
    rows = []
    for r in df.to_dict("records"):
        rows.append({"point": ", ".join(f"{k} = {float(r[k]):.4g}" for k in params),
                     "start": r.get("start", ""), "label": r.get("label", ""),
                     "npq": r.get("label_npq", "") or "", "dc": r.get("dc"),
                     "kmax": r.get("kmax")})
    return {"name": name, "rows": rows}


def point_lines(points: list[dict[str, Any]], h: str = "##") -> list[str]:
    if not points:
        return []
    out = [f"{h} Points", "", "| set | point | start | pattern | DC | Kmax |",
           "|---|---|---|---|---|---|"]
    for s in points:
        for r in s["rows"]:
            pat = f"{r['label']} ({r['npq']})" if r["npq"] else str(r["label"])
            out.append(f"| {s['name']} | {r['point']} | {r['start']} | {pat} | "
                       f"{value_text(r['dc'], '.3f', '—')} | {value_text(r['kmax'], '.3f', '—')} |")
    out.append("")
    return out


def multistable_summary(plane: str, cells: pd.DataFrame | None) -> dict[str, Any] | None:
    """Cells searched for coexisting attractors and those with more than one."""
    if cells is None or "n_attractors" not in cells.columns:
        return None
    n = pd.to_numeric(cells["n_attractors"], errors="coerce")
    if not n.notna().any():
        return None
    return {"plane": plane, "searched": int(n.notna().sum()), "multi": int((n > 1).sum())}


def sweep_spec_of(path: str | Path) -> dict[str, Any] | None:
    """A sweep's config entry from its table's provenance (``subtree.sweep``)."""
    path = Path(path)
    if not path.is_file():
        return None
    from gearsim.results.catalogue import read_metadata

    sub = (read_metadata(path) or {}).get("subtree") or {}
    spec = sub.get("sweep") if isinstance(sub, dict) else None
    return dict(spec) if isinstance(spec, dict) else None
