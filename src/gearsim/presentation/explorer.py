"""The explorer: one static HTML page (``results/explorer/index.html``) to browse a study.

For every plane of the study it draws the pattern, DC and Kmax maps (Plotly heatmaps); hovering
a cell shows its label, n-p-q, impact state, DC, Kmax, the largest Lyapunov exponent and, when
the catalogue has an ``attractors`` table, the coexisting attractors found there; clicking a
cell draws its Poincare points (x, x') in the side panel. Every sweep gets its bifurcation
diagram (Poincare x versus the swept parameter, coloured by impact state), zoomable.

The page needs no server and no network: Plotly.js is bundled inline and the data are embedded
as compact typed arrays (base64 of little-endian float32 / int16 / uint32; section points as
int16 over the plane's range), so a 400 x 400 plane costs about 36 bytes per cell plus about
5.3 bytes per Poincare point (at most :data:`MAX_POINTS` per cell, the last ``n`` only for a
periodic cell of period ``n``: they are its distinct points).

Every quantity is dimensionless as in the catalogue (docs/model.md): x = X_n / b_c,
x' = dx/dtau with tau = omega_n t; DC is a fraction of the mesh period; Kmax = F_n / F_m; the
Lyapunov exponent is per unit dimensionless time.
"""

from __future__ import annotations

import base64
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from gearsim.presentation.figures import style

#: Poincare points kept per cell (chaotic / unsettled cells); a periodic cell keeps its n points.
MAX_POINTS = 32
#: Poincare points kept per swept value in the bifurcation diagrams.
MAX_SWEEP_POINTS = 64

_SYMBOLS = {"w": "ω", "b": "b", "xi": "ξ", "eps": "ε", "Fm": "F_m", "Fe": "F_e"}


def _b64(a: np.ndarray, dtype: str) -> dict[str, str]:
    arr = np.ascontiguousarray(np.asarray(a).astype(dtype, copy=False))
    return {"dtype": np.dtype(dtype).name, "b64": base64.b64encode(arr.tobytes()).decode()}


def _f32(values) -> dict[str, str]:
    return _b64(np.asarray(values, dtype=float), "<f4")


def _quantised(v: np.ndarray) -> dict[str, Any]:
    """Section coordinates as int16 over the plane's range (resolution range / 65535, far below
    a marker's size): ``value = lo + (q + 32768) * step``."""
    v = np.asarray(v, dtype=float)
    lo = float(v.min()) if len(v) else 0.0
    hi = float(v.max()) if len(v) else 1.0
    step = (hi - lo) / 65535.0 if hi > lo else 1.0
    q = np.round((v - lo) / step) - 32768.0
    return {**_b64(np.clip(q, -32768, 32767), "<i2"), "lo": lo, "step": step}


def dequantise(enc: Mapping[str, Any]) -> np.ndarray:
    """The inverse of the page's int16 coding of section points (what the page draws)."""
    q = np.frombuffer(base64.b64decode(enc["b64"]), "<i2").astype(float)
    return enc["lo"] + (q + 32768.0) * enc["step"]


def _int_or(values: pd.Series, missing: int = -1) -> np.ndarray:
    return pd.to_numeric(values, errors="coerce").fillna(missing).to_numpy().astype(np.int64)


@dataclass
class PlaneData:
    """A plane's cells as the page needs them."""

    name: str
    xname: str
    yname: str
    cells: pd.DataFrame  # i, j, the axes, the CellResult columns, poincare_x / poincare_v
    attractors: dict[int, list[str]] | None = None  # cell index j * nx + i -> lines


def plane_from_cells(name: str, cells: pd.DataFrame, axes: tuple[str, str] | None = None
                     ) -> PlaneData:
    """A plane from its ``results/<plane>/cells.parquet`` table (axes from the config or from
    the varying columns)."""
    if axes is None:
        from gearsim.presentation.figures.data import plane_axes

        axes = plane_axes(cells)
    return PlaneData(name, axes[0], axes[1], cells)


def read_attractors(catalogue: str | Path, plane: str, nx: int) -> dict[int, list[str]] | None:
    """Coexisting attractors of a plane's cells from the catalogue's ``attractors`` table, when
    it has one: ``{j * nx + i: [one line per attractor]}``.

    The table is matched to cells through ``cell_id`` (-> ``cells.id``), or ``plane`` /
    ``plane_id`` with ``i`` and ``j``; each attractor is shown as its remaining columns
    (``name=value``). ``None`` when the catalogue has no such table or no attractor of this
    plane (its ``multistability`` is off).
    """
    from gearsim.results.catalogue import open_catalogue

    path = Path(catalogue)
    if not path.is_file():
        return None
    con = open_catalogue(path)
    try:
        tables = {r[0] for r in con.execute("select name from sqlite_master where type='table'")}
        if "attractors" not in tables:
            return None
        cols = [r[1] for r in con.execute('pragma table_info("attractors")')]
        if "cell_id" in cols:
            df = pd.read_sql_query(
                "select a.*, c.i as _i, c.j as _j from attractors a join cells c on "
                "a.cell_id = c.id join planes p on c.plane_id = p.id where p.name = ?",
                con, params=(plane,))
        elif {"i", "j", "plane_id"} <= set(cols):
            df = pd.read_sql_query(
                "select a.*, a.i as _i, a.j as _j from attractors a join planes p on "
                "a.plane_id = p.id where p.name = ?", con, params=(plane,))
        elif {"i", "j", "plane"} <= set(cols):
            df = pd.read_sql_query("select a.*, a.i as _i, a.j as _j from attractors a "
                                   "where a.plane = ?", con, params=(plane,))
        else:
            return {}
    finally:
        con.close()
    if not len(df):
        return None  # multistability off for this plane
    if "attractor" in df.columns:
        df = df.sort_values(["_j", "_i", "attractor"])
    out: dict[int, list[str]] = {}
    for rec in df.to_dict("records"):
        out.setdefault(int(rec["_j"]) * nx + int(rec["_i"]), []).append(attractor_line(rec))
    return out


_HIDDEN = {"id", "cell_id", "plane_id", "plane", "i", "j", "_i", "_j", "run_id"}
_SHOWN = ("attractor", "label", "label_npq", "basin_fraction", "dc", "kmax", "lyapunov",
          "found_by")


def attractor_line(rec: Mapping[str, Any]) -> str:
    """One attractor of a cell in a line: ``#0 1/1T (1-1-0), basin 62.5 %, DC 0.1234, ...``
    (the ``attractors`` table of :mod:`gearsim.results.catalogue`; other columns as
    ``name=value``)."""
    parts = []
    if "attractor" in rec and not _blank(rec["attractor"]):
        parts.append(f"#{int(rec['attractor'])}")
    if "label" in rec:
        npq = rec.get("label_npq")
        parts.append(f"{rec['label']}" + (f" ({npq})" if npq else ""))
    if not _blank(rec.get("basin_fraction")):
        parts.append(f"basin {100 * float(rec['basin_fraction']):.1f} %")
    for key, name, digits in (("dc", "DC", 4), ("kmax", "Kmax", 4), ("lyapunov", "λ", 5)):
        if not _blank(rec.get(key)):
            parts.append(f"{name} {float(rec[key]):.{digits}f}")
    if rec.get("found_by"):
        parts.append(f"found by {rec['found_by']}")
    head = " ".join(parts[:2]) + (", " if len(parts) > 2 else "") + ", ".join(parts[2:])
    rest = [f"{k}={_fmt(v)}" for k, v in rec.items()
            if k not in _HIDDEN and k not in _SHOWN and k not in (
                "motion", "impact", "n", "p", "q", "n_starts", "n_early") and not _blank(v)]
    return head + ("; " + ", ".join(rest) if rest else "")


def _blank(v: Any) -> bool:
    return v is None or (isinstance(v, float) and not np.isfinite(v))


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, bytes | bytearray):
        return f"<{len(v)} bytes>"
    return str(v)


def _poincare(df: pd.DataFrame, order: np.ndarray, cap: int, periodic_n: np.ndarray | None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Offsets (uint32, len cells + 1) and the concatenated x, x' of the kept section points."""
    px_col, pv_col = df["poincare_x"].to_numpy(), df["poincare_v"].to_numpy()
    counts = np.zeros(len(order), dtype=np.int64)
    xs, vs = [], []
    for k, r in enumerate(order):
        px = np.asarray(px_col[r] if px_col[r] is not None else [], dtype=float)
        pv = np.asarray(pv_col[r] if pv_col[r] is not None else [], dtype=float)
        keep = cap
        if periodic_n is not None and periodic_n[r] > 0:
            keep = min(cap, int(periodic_n[r]))
        px, pv = px[-keep:], pv[-keep:]
        ok = np.isfinite(px) & np.isfinite(pv)
        xs.append(px[ok])
        vs.append(pv[ok])
        counts[k] = int(ok.sum())
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.uint32)
    cat = (np.concatenate(xs) if xs else np.zeros(0), np.concatenate(vs) if vs else np.zeros(0))
    return offsets, cat[0], cat[1]


def plane_payload(plane: PlaneData) -> dict[str, Any]:
    """Everything the page shows of one plane, as typed arrays in row-major (j, i) order."""
    df = plane.cells.reset_index(drop=True)
    nx, ny = int(df["i"].max()) + 1, int(df["j"].max()) + 1
    xs = df.groupby("i")[plane.xname].first().reindex(range(nx)).to_numpy(dtype=float)
    ys = df.groupby("j")[plane.yname].first().reindex(range(ny)).to_numpy(dtype=float)
    # row of each grid cell (-1 where the table has no cell)
    where = np.full(nx * ny, -1, dtype=np.int64)
    where[df["j"].to_numpy(dtype=int) * nx + df["i"].to_numpy(dtype=int)] = np.arange(len(df))
    present = where >= 0
    rows = np.where(present, where, 0)

    def grid(col: str, dtype=float) -> np.ndarray:
        v = pd.to_numeric(df[col], errors="coerce").to_numpy(dtype=float)[rows]
        return np.where(present, v, np.nan)

    cats = style.pattern_categories(df)
    keys = [k for k in style.PATTERN_KEYS if k in set(cats)]
    kidx = {k: n for n, k in enumerate(keys)}
    cat = np.array([kidx[c] for c in cats], dtype=np.int64)[rows]
    labels = sorted(set(df["label"].fillna("").astype(str)) | set(
        df["label_npq"].fillna("").astype(str)))
    lidx = {s: n for n, s in enumerate(labels)}
    label = np.array([lidx[s] for s in df["label"].fillna("").astype(str)])[rows]
    npq = np.array([lidx[s] for s in df["label_npq"].fillna("").astype(str)])[rows]
    motion = df["motion"].fillna("").astype(str)
    n = _int_or(df["n"])
    periodic = np.where(motion.to_numpy() == "periodic", n, 0)
    order = np.where(present, where, -1)
    order = order[order >= 0]
    offsets_c, px, pv = _poincare(df, order, MAX_POINTS, periodic)
    # offsets per grid cell (a missing cell has none)
    counts = np.zeros(nx * ny, dtype=np.int64)
    counts[present] = np.diff(offsets_c.astype(np.int64))
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.uint32)
    kmax_col = "kmax" if "kmax" in df.columns else "kmax_peak_mean"
    kmax = grid(kmax_col)
    finite = kmax[np.isfinite(kmax)]
    from gearsim.presentation.figures.planes import robust_max

    payload: dict[str, Any] = {
        "name": plane.name, "nx": nx, "ny": ny,
        "xname": plane.xname, "yname": plane.yname,
        "xsym": _SYMBOLS.get(plane.xname, plane.xname),
        "ysym": _SYMBOLS.get(plane.yname, plane.yname),
        "xs": xs.tolist(), "ys": ys.tolist(),
        "present": _b64(present, "u1"),
        "cat": _b64(np.where(present, cat, -1), "<i2"),
        "cat_keys": keys,
        "cat_labels": [style.PATTERN_LABELS[k] for k in keys],
        "cat_colours": [style.PATTERN_COLOURS[k] for k in keys],
        "labels": labels,
        "label": _b64(np.where(present, label, -1), "<i2"),
        "npq": _b64(np.where(present, npq, -1), "<i2"),
        "I": _b64(np.where(present, _int_or(df["I"], -9)[rows], -9), "<i2"),
        "n": _b64(np.where(present, n[rows], -1), "<i2"),
        "dc": _f32(grid("dc")),
        "kmax": _f32(kmax),
        "kmax_cap": float(robust_max(kmax)) if len(finite) else 1.0,
        "kmax_reading": kmax_col,
        "lyapunov": _f32(grid("lyapunov") if "lyapunov" in df.columns
                         else np.full(nx * ny, np.nan)),
        "offsets": _b64(offsets, "<u4"),
        "px": _quantised(px), "pv": _quantised(pv),
        "attractors": None,
    }
    if plane.attractors is not None:
        payload["attractors"] = {str(k): v for k, v in plane.attractors.items()}
    return payload


def sweep_payload(name: str, df: pd.DataFrame, fixed: Mapping[str, float] | None = None
                  ) -> dict[str, Any]:
    """A sweep's bifurcation diagram: every kept Poincare x against the swept value."""
    param = str(df["parameter"].iloc[0]) if "parameter" in df.columns and len(df) else "w"
    vals, xs, Is, ks = [], [], [], []
    for k, (v, px, I) in enumerate(zip(df["value"], df["poincare_x"], df["I"], strict=True)):
        px = np.asarray(px if px is not None else [], dtype=float)[-MAX_SWEEP_POINTS:]
        px = px[np.isfinite(px)]
        vals.append(np.full(len(px), float(v)))
        xs.append(px)
        Is.append(np.full(len(px), int(I) if pd.notna(I) else -9))
        ks.append(np.full(len(px), k))

    def cat(a, d):
        return np.concatenate(a) if a else np.zeros(0, dtype=d)

    impacts = sorted({int(i) for i in df["I"].dropna()})
    return {
        "name": name, "parameter": param, "psym": _SYMBOLS.get(param, param),
        "fixed": dict(fixed or {}),
        "value": _f32(cat(vals, float)), "x": _f32(cat(xs, float)),
        "I": _b64(cat(Is, int), "<i2"), "k": _b64(cat(ks, int), "<u4"),
        "labels": [f"{lab} ({npq})" if npq else str(lab) for lab, npq in
                   zip(df["label"].fillna(""), df["label_npq"].fillna(""), strict=True)],
        "values": df["value"].astype(float).tolist(),
        "impacts": impacts,
        "impact_colours": {str(i): style.impact_colour(i) for i in impacts},
        "impact_names": {str(i): style.IMPACT_NAMES.get(i, f"I = {i}") for i in impacts},
    }


def _colorscale(name: str, n: int = 16) -> list[list[Any]]:
    """A matplotlib colour map as a Plotly colour scale (the maps look like the figures')."""
    from matplotlib import colormaps
    from matplotlib.colors import to_hex

    cmap = colormaps[name]
    return [[k / (n - 1), to_hex(cmap(k / (n - 1)))] for k in range(n)]


def plotly_js() -> str:
    """The Plotly.js bundle shipped with the plotly package (inlined: no network)."""
    from plotly.offline import get_plotlyjs

    return get_plotlyjs()


_TEMPLATE = Path(__file__).with_name("explorer_page.html")


def render(planes: Sequence[PlaneData], sweeps: Mapping[str, pd.DataFrame], *,
           sweep_fixed: Mapping[str, Mapping[str, float]] | None = None,
           title: str = "gearsim explorer", provenance: Mapping[str, Any] | None = None
           ) -> str:
    """The page (one HTML string)."""
    data = {
        "title": title,
        "planes": [plane_payload(p) for p in planes],
        "sweeps": [sweep_payload(n, df, (sweep_fixed or {}).get(n)) for n, df in sweeps.items()],
        "provenance": dict(provenance or {}),
        "max_points": MAX_POINTS,
        "turbo": _colorscale("turbo"),
    }
    blob = json.dumps(data, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")
    page = _TEMPLATE.read_text()
    return (page.replace("%%TITLE%%", _html_escape(title))
            .replace("%%PLOTLYJS%%", plotly_js().replace("</script", "<\\/script"))
            .replace("%%DATA%%", blob))


def _html_escape(s: str) -> str:
    return s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def write_explorer(out: str | Path, *, planes: Mapping[str, tuple[str, str]] | Sequence[str],
                   sweeps: Sequence[str], results: str | Path = "results",
                   catalogue: str | Path | None = None,
                   sweep_fixed: Mapping[str, Mapping[str, float]] | None = None,
                   provenance: Mapping[str, Any] | None = None) -> Path:
    """Read the study's tables (``results/<plane>/cells.parquet``,
    ``results/sweeps/<sweep>.parquet``, the catalogue's ``attractors`` when present) and write
    the page to ``out`` (atomically)."""
    results = Path(results)
    axes = dict(planes) if isinstance(planes, Mapping) else {p: None for p in planes}
    loaded = []
    for name, ax in axes.items():
        cells = pd.read_parquet(results / name / "cells.parquet")
        p = plane_from_cells(name, cells, tuple(ax) if ax else None)
        if catalogue is not None:
            p.attractors = read_attractors(catalogue, name, int(cells["i"].max()) + 1)
        loaded.append(p)
    tables = {s: pd.read_parquet(results / "sweeps" / f"{s}.parquet") for s in sweeps}
    html = render(loaded, tables, sweep_fixed=sweep_fixed, provenance=provenance)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(html, encoding="utf-8")
    tmp.replace(out)
    return out
