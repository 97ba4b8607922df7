"""The explorer: one static HTML page (``results/explorer/index.html``) to browse a study.

The page opens with the report's scorecard (the paper's results beside ours) when the study holds
the paper's material. Every plane is a map drawn on a canvas from per-cell arrays, with its
layers: pattern, DC, Kmax, the largest Lyapunov exponent, attractors per cell (when the plane was
searched for coexisting attractors), the Floquet margin max|mu| (when the cells carry it) and the
bifurcation curves on top (when the catalogue holds them); the legend sits beside the map.
Hovering a cell shows its label, n-p-q, impact state, DC, Kmax, Lyapunov exponent; clicking it
draws its Poincare points, lists its coexisting attractors with their basin fractions and draws
the diagram of the nearest sweep through it. Every sweep has its bifurcation diagram. Axes are
in physical units (rpm, N m, um) when the study has a gear file.

The page needs no server and no network, and loads in about a second: no plotting library, and
the data are one gzip-compressed binary block (base64) of typed arrays that the browser inflates
with its own ``DecompressionStream``. Per cell: pattern, label and n-p-q indices, impact state,
period (one or two bytes each); the value layers (:data:`VALUE_LAYERS`: DC, Kmax, Lyapunov
exponent, Floquet margin) as the catalogue's values rounded to the digits the page shows
(integers, stored as differences of neighbours in four byte planes; a value too large for 32
bits travels as JSON beside them), so that the readout shows each cell's catalogue value to its
last digit whatever the other cells hold; the number of section points; the section points
themselves as 16-bit steps over the plane's range (resolution range / 65534), at most
:data:`MAX_POINTS` per cell (the last ``n`` only for a periodic cell of period ``n``: they are
its distinct points; fewer per chaotic cell when a page would hold more than
:data:`POINTS_BUDGET` bytes of them); the coexisting attractors of each searched cell
(one line each) as JSON text inside the same block.

A value layer is drawn over a range (:class:`ValueLayer`): DC over [0, 1], Kmax from its
smallest value to the static maps' cap (:func:`gearsim.presentation.figures.planes.robust_max`),
the others over their values. A cell outside the drawn range is drawn at the end colour and
marked so in its readout and, with the count of such cells, in the legend; a cell without a
value (a motion that never settled has no Kmax, DC or Lyapunov exponent) says why. A new layer
is one :class:`ValueLayer` in :data:`VALUE_LAYERS` (the page builds its button, colours, legend
and readout line from it).

Every quantity is dimensionless as in the catalogue (docs/model.md): x = X_n / b_c,
x' = dx/dtau with tau = omega_n t; DC is a fraction of the mesh period; Kmax is the catalogue's
``kmax`` (:data:`gearsim.cell.motion.KMAX_DEFINITION`, named on the page); the Lyapunov exponent
is per unit dimensionless time.
"""

from __future__ import annotations

import base64
import gzip
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from gearsim.cell.motion import DEFAULT_KMAX, KMAX_DEFINITION
from gearsim.presentation.figures import style
from gearsim.presentation.orbit_plots import CURVE_STYLE

#: Poincare points kept per cell (chaotic / unsettled cells); a periodic cell keeps its n points.
MAX_POINTS = 16
#: At most this many bytes of section points on a page (4 per point): on planes with many
#: chaotic cells the cap per cell drops (to no fewer than :data:`MIN_POINTS`), so that the page
#: of the default run stays under 5 MB whatever its share of chaos (benchmarks/README.md, (m)).
POINTS_BUDGET = 2_000_000
MIN_POINTS = 2
#: Poincare points kept per swept value in the bifurcation diagrams.
MAX_SWEEP_POINTS = 64
#: columns that hold a cell's Floquet margin max|mu| (the first present is shown)
FLOQUET_COLUMNS = ("floquet_margin", "mu_max", "max_abs_mu")
#: 16-bit code of a missing value in a quantised array
MISSING = 65535
#: code of a missing value in a layer of shown digits (:meth:`Block.digits`)
NO_VALUE = -(2**31)
#: code of a value too large for 32 bits at its digits (the value travels in the layer's JSON)
BIG_VALUE = 2**31 - 1


@dataclass(frozen=True)
class ValueLayer:
    """A per-cell number drawn as a colour map: its page key and button, the table columns it
    reads (the first present), the legend's title (``{reading}``: the Kmax definition,
    ``{column}``: the column read), the decimals the readout shows (the values travel as these
    digits), the colour map and the drawn range (``unit``: [0, 1]; ``capped``: smallest value to
    :func:`~gearsim.presentation.figures.planes.robust_max`, as the static maps; ``full``: the
    values' range; ``margin``: log10 of 1 - value over [-4, 0], black at status bifurcation)."""

    key: str
    button: str
    columns: tuple[str, ...]
    title: str
    readout: str
    digits: int
    cmap: str = "turbo"
    scale: str = "full"
    optional: bool = False  # a layer only where the cells carry a column


VALUE_LAYERS = (
    ValueLayer("dc", "DC", ("dc",), "DC (fraction of the mesh period)", "DC", 4, scale="unit"),
    ValueLayer("kmax", "Kmax", ("kmax", DEFAULT_KMAX), "Kmax ({reading})", "Kmax", 4,
               scale="capped"),
    ValueLayer("lyapunov", "λ", ("lyapunov",), "largest Lyapunov exponent (1/τ)", "λ", 5,
               cmap="magma"),
    ValueLayer("floquet", "Floquet margin 1 − max|μ|", FLOQUET_COLUMNS,
               "log10 of the Floquet margin 1 − max|μ| ({column}); black: status bifurcation",
               "max|μ|", 5, scale="margin", optional=True),
)

_SYMBOLS = {"w": "ω", "b": "b", "xi": "ξ", "eps": "ε", "Fm": "F_m", "Fe": "F_e"}


# ----------------------------------------------------------------------------- binary block
class Block:
    """Typed arrays packed into one buffer (8-byte aligned), described by ``{name: [dtype,
    offset, length]}`` for the page."""

    def __init__(self) -> None:
        self.parts: list[bytes] = []
        self.size = 0

    def add(self, a: np.ndarray, dtype: str) -> list[Any]:
        arr = np.ascontiguousarray(np.asarray(a).astype(dtype, copy=False))
        raw = arr.tobytes()
        offset = self.size
        pad = (-len(raw)) % 8
        self.parts.append(raw + b"\0" * pad)
        self.size += len(raw) + pad
        return [np.dtype(dtype).name, offset, int(arr.size)]

    def quantised(self, v: np.ndarray, lo: float | None = None, hi: float | None = None
                  ) -> dict[str, Any]:
        """Values as uint16 steps over ``[lo, hi]`` (default: their finite range); NaN ->
        :data:`MISSING`. ``value = lo + q * step``."""
        v = np.asarray(v, dtype=float)
        finite = v[np.isfinite(v)]
        lo = float(finite.min()) if lo is None and len(finite) else (lo or 0.0)
        hi = float(finite.max()) if hi is None and len(finite) else (hi if hi is not None
                                                                       else 1.0)
        step = (hi - lo) / (MISSING - 1) if hi > lo else 1.0
        q = np.where(np.isfinite(v), np.clip(np.round((v - lo) / step), 0, MISSING - 1),
                     MISSING).astype(np.uint16)
        # neighbours differ little: store the differences (mod 2^16), high bytes then low
        # bytes, which gzip packs far better than the values themselves
        d = np.diff(q, prepend=np.uint16(0)).astype(np.uint16)
        planes = np.concatenate([(d >> 8).astype(np.uint8), (d & 0xFF).astype(np.uint8)])
        return {"array": self.add(planes, "u1"), "n": int(q.size), "coding": "delta16",
                "lo": lo, "step": step}

    def digits(self, v: np.ndarray, digits: int) -> dict[str, Any]:
        """Values as the integers of their ``digits``-decimal rounding (``value = q / 10**digits``
        exactly as Python's ``f"{v:.{digits}f}"`` prints it); NaN -> :data:`NO_VALUE`, a value
        beyond 32 bits -> :data:`BIG_VALUE` with ``{cell: value}`` in ``big``. Stored as
        differences of neighbours (mod 2^32) in four byte planes, high bytes first."""
        q, big = shown_digits(v, digits)
        d = np.diff(q.astype(np.uint32), prepend=np.uint32(0)).astype(np.uint32)
        planes = np.concatenate([((d >> s) & 0xFF).astype(np.uint8) for s in (24, 16, 8, 0)])
        return {"array": self.add(planes, "u1"), "n": int(q.size), "coding": "delta32",
                "digits": int(digits), "big": big}

    def add_json(self, obj: Any) -> dict[str, Any]:
        """``obj`` as UTF-8 JSON text in the buffer (``{"json": [dtype, offset, length]}``):
        text of many similar lines, which gzip packs to a small fraction of its size."""
        raw = np.frombuffer(json.dumps(_json_safe(obj), ensure_ascii=False,
                                       separators=(",", ":")).encode(), dtype=np.uint8)
        return {"json": self.add(raw, "u1")}

    def encoded(self) -> str:
        """gzip + base64 of the whole buffer."""
        return base64.b64encode(gzip.compress(b"".join(self.parts), compresslevel=9,
                                              mtime=0)).decode()


def json_of(buffer: bytes, enc: Mapping[str, Any]) -> Any:
    """The object of a :meth:`Block.add_json` entry in a decoded buffer."""
    return json.loads(array_of(buffer, enc["json"]).tobytes().decode())


def quantised_of(buffer: bytes, enc: Mapping[str, Any]) -> np.ndarray:
    """The 16-bit steps of a :meth:`Block.quantised` array in a decoded buffer."""
    planes = array_of(buffer, enc["array"])
    n = enc["n"]
    d = (planes[:n].astype(np.uint16) << 8) | planes[n:2 * n].astype(np.uint16)
    return np.cumsum(d, dtype=np.uint16)


def dequantise(q: np.ndarray, lo: float, step: float) -> np.ndarray:
    """The values of 16-bit steps (what the page shows)."""
    q = np.asarray(q)
    return np.where(q == MISSING, np.nan, lo + q.astype(float) * step)


def values_of(buffer: bytes, enc: Mapping[str, Any]) -> np.ndarray:
    """A :meth:`Block.quantised` array back as values (NaN where missing)."""
    return dequantise(quantised_of(buffer, enc), enc["lo"], enc["step"])


def shown_digits(v: np.ndarray, digits: int) -> tuple[np.ndarray, dict[str, float]]:
    """``(q, big)``: the int32 ``q`` with ``q / 10**digits`` the value ``v`` rounded to
    ``digits`` decimals as ``f"{v:.{digits}f}"`` rounds it (correctly rounded, ties to even),
    :data:`NO_VALUE` where ``v`` is NaN, :data:`BIG_VALUE` where ``q`` would not fit 32 bits
    (those values in ``big``, by cell index)."""
    from decimal import ROUND_HALF_EVEN, Decimal

    v = np.asarray(v, dtype=float)
    ok = np.isfinite(v)
    scaled = np.where(ok, v, 0.0) * 10.0**digits
    q = np.rint(scaled)
    # near a tie the product's rounding error may decide: those few by exact decimal rounding
    frac = np.abs(scaled - np.floor(scaled) - 0.5)
    unit = Decimal(1).scaleb(-digits)
    for k in np.flatnonzero(ok & (frac < 1e-6 * np.maximum(1.0, np.abs(scaled)))):
        q[k] = float(Decimal(float(v[k])).quantize(unit, ROUND_HALF_EVEN).scaleb(digits))
    big_cells = ok & (np.abs(q) >= BIG_VALUE)
    out = np.where(ok, np.where(big_cells, BIG_VALUE, q), NO_VALUE).astype(np.int64)
    return out.astype(np.int32), {str(int(k)): float(v[k]) for k in np.flatnonzero(big_cells)}


def digits_of(buffer: bytes, enc: Mapping[str, Any]) -> np.ndarray:
    """A :meth:`Block.digits` array back as values (NaN where missing; the big values exact)."""
    planes = array_of(buffer, enc["array"]).astype(np.uint32)
    n = enc["n"]
    d = (planes[:n] << 24) | (planes[n:2 * n] << 16) | (planes[2 * n:3 * n] << 8) | planes[3 * n:]
    q = np.cumsum(d, dtype=np.uint32).astype(np.int32).astype(np.int64)
    out = np.where(q == NO_VALUE, np.nan, q / 10.0**enc["digits"])
    for k, value in enc["big"].items():
        out[int(k)] = value
    return out


def decode_block(encoded: str) -> bytes:
    """The raw buffer of :meth:`Block.encoded` (for tests and benchmarks)."""
    return gzip.decompress(base64.b64decode(encoded))


def array_of(buffer: bytes, desc: Sequence[Any]) -> np.ndarray:
    """One array of a decoded buffer from its ``[dtype, offset, length]``."""
    dtype, offset, n = desc
    return np.frombuffer(buffer, dtype=np.dtype(dtype).newbyteorder("<"), count=n,
                         offset=offset)


def _int_or(values: pd.Series, missing: int = -1) -> np.ndarray:
    return pd.to_numeric(values, errors="coerce").fillna(missing).to_numpy().astype(np.int64)


# ----------------------------------------------------------------------------- planes
@dataclass
class PlaneData:
    """A plane's cells as the page needs them."""

    name: str
    xname: str
    yname: str
    cells: pd.DataFrame  # i, j, the axes, the CellResult columns, poincare_x / poincare_v
    attractors: dict[int, list[str]] | None = None  # cell index j * nx + i -> lines
    n_attractors: dict[int, int] | None = None  # cell index -> attractors found
    curves: list[dict[str, Any]] = field(default_factory=list)  # bifurcation curves
    codim2: list[dict[str, Any]] = field(default_factory=list)  # codimension-2 points
    physical: dict[str, dict[str, Any]] = field(default_factory=dict)  # axis -> name/unit/k


def plane_from_cells(name: str, cells: pd.DataFrame, axes: tuple[str, str] | None = None
                     ) -> PlaneData:
    """A plane from its ``results/<plane>/cells.parquet`` table (axes from the config or from
    the varying columns)."""
    if axes is None:
        from gearsim.presentation.figures.data import plane_axes

        axes = plane_axes(cells)
    return PlaneData(name, axes[0], axes[1], cells)


def read_attractors(catalogue: str | Path, plane: str, nx: int
                    ) -> tuple[dict[int, list[str]] | None, dict[int, int] | None]:
    """Coexisting attractors of a plane's cells from the catalogue: ``({j * nx + i: [one line
    per attractor]}, {j * nx + i: attractors found})``; ``(None, None)`` when the catalogue has
    none for this plane (its ``multistability`` is off)."""
    from gearsim.results.catalogue import open_catalogue

    path = Path(catalogue)
    if not path.is_file():
        return None, None
    con = open_catalogue(path)
    try:
        tables = {r[0] for r in con.execute("select name from sqlite_master where type='table'")}
        counts = None
        cols = [r[1] for r in con.execute('pragma table_info("cells")')]
        if "n_attractors" in cols:
            n = pd.read_sql_query(
                "select c.i, c.j, c.n_attractors from cells c join planes p on "
                "c.plane_id = p.id where p.name = ? and c.n_attractors is not null",
                con, params=(plane,))
            counts = {int(r.j) * nx + int(r.i): int(r.n_attractors) for r in n.itertuples()}
        if "attractors" not in tables:
            return None, counts or None
        df = pd.read_sql_query(
            "select a.*, c.i as _i, c.j as _j from attractors a join cells c on "
            "a.cell_id = c.id join planes p on c.plane_id = p.id where p.name = ?",
            con, params=(plane,))
    finally:
        con.close()
    if not len(df):
        return None, counts or None
    if "attractor" in df.columns:
        df = df.sort_values(["_j", "_i", "attractor"])
    out: dict[int, list[str]] = {}
    for rec in df.to_dict("records"):
        out.setdefault(int(rec["_j"]) * nx + int(rec["_i"]), []).append(attractor_line(rec))
    if not counts:
        counts = {k: len(v) for k, v in out.items()}
    return out, counts


def _columns(con, table: str) -> set[str]:
    return {r[1] for r in con.execute(f'PRAGMA table_info("{table}")')}


def read_curves(catalogue: str | Path, plane: str) -> list[dict[str, Any]]:
    """The plane's two-parameter bifurcation curves from the catalogue (``bifurcation_curves``):
    one polyline per curve, ``{kind, period, flank, x, y}`` in the plane's axes, with the look
    of Figs 21 and 22 (:func:`gearsim.presentation.orbit_plots.curve_look`: ``colour`` by
    period, ``dash`` by kind and flank, the legend's ``text``)."""
    from gearsim.presentation.orbit_plots import curve_look
    from gearsim.results.catalogue import open_catalogue

    path = Path(catalogue)
    if not path.is_file():
        return []
    con = open_catalogue(path)
    try:
        tables = {r[0] for r in con.execute("select name from sqlite_master where type='table'")}
        if "bifurcation_curves" not in tables:
            return []
        extra = [c for c in ("boundary", "flank") if c in _columns(con, "bifurcation_curves")]
        df = pd.read_sql_query("select curve, kind, period, name, value, name2, value2"
                               + "".join(f", {c}" for c in extra) + " from "
                               "bifurcation_curves where plane = ? order by curve, id", con,
                               params=(plane,))
    finally:
        con.close()
    out = []
    for (curve, kind, period), g in df.groupby(["curve", "kind", "period"], sort=False):
        look = curve_look(g.iloc[0].to_dict())
        out.append({"curve": int(curve), "kind": str(kind), "period": int(period),
                    "xname": str(g["name"].iloc[0]), "yname": str(g["name2"].iloc[0]),
                    "x": g["value"].astype(float).round(6).tolist(),
                    "y": g["value2"].astype(float).round(6).tolist(), **look})
    return out


def read_codim2(catalogue: str | Path, plane: str) -> list[dict[str, Any]]:
    """The plane's codimension-2 points from the catalogue (``codim2_points``): ``{kind,
    marker, text, xname, yname, x, y, period, converged}`` (the markers of Figs 21 and 22)."""
    from gearsim.presentation.orbit_plots import CODIM2_MARKERS
    from gearsim.results.catalogue import open_catalogue

    path = Path(catalogue)
    if not path.is_file():
        return []
    con = open_catalogue(path)
    try:
        tables = {r[0] for r in con.execute("select name from sqlite_master where type='table'")}
        if "codim2_points" not in tables:
            return []
        df = pd.read_sql_query("select kind, period, name, value, name2, value2, converged, "
                               "conditions from codim2_points where plane = ? order by point",
                               con, params=(plane,))
    finally:
        con.close()
    out = []
    for r in df.itertuples(index=False):
        marker, text = CODIM2_MARKERS.get(str(r.kind), ("o", str(r.kind)))
        out.append({"kind": str(r.kind), "marker": marker, "text": text,
                    "conditions": str(r.conditions), "period": int(r.period),
                    "xname": str(r.name), "yname": str(r.name2), "x": round(float(r.value), 6),
                    "y": round(float(r.value2), 6), "converged": bool(r.converged)})
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


def _poincare(df: pd.DataFrame, rows: np.ndarray, present: np.ndarray, cap: int,
              periodic_n: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points per grid cell (uint8) and the concatenated x, x' of the kept section points, in
    grid order."""
    px_col, pv_col = df["poincare_x"].to_numpy(), df["poincare_v"].to_numpy()
    counts = np.zeros(len(rows), dtype=np.int64)
    xs, vs = [], []
    for k, r in enumerate(rows):
        if not present[k]:
            continue
        px = np.asarray(px_col[r] if px_col[r] is not None else [], dtype=float)
        pv = np.asarray(pv_col[r] if pv_col[r] is not None else [], dtype=float)
        keep = min(cap, int(periodic_n[r])) if periodic_n[r] > 0 else cap
        px, pv = px[-keep:], pv[-keep:]
        ok = np.isfinite(px) & np.isfinite(pv)
        xs.append(px[ok])
        vs.append(pv[ok])
        counts[k] = int(ok.sum())
    cat = (np.concatenate(xs) if xs else np.zeros(0), np.concatenate(vs) if vs else np.zeros(0))
    return counts, cat[0], cat[1]


def _indexed(values: pd.Series) -> tuple[list[str], np.ndarray]:
    names = sorted(set(values))
    idx = {s: n for n, s in enumerate(names)}
    return names, np.array([idx[s] for s in values], dtype=np.int64)


def points_cap(planes: Sequence[PlaneData]) -> int:
    """Section points kept per non-periodic cell on a page of these planes: :data:`MAX_POINTS`,
    fewer when the planes' non-periodic cells would exceed :data:`POINTS_BUDGET`."""
    free = sum(int((p.cells["motion"].fillna("") != "periodic").sum()) for p in planes)
    periodic = sum(int(np.minimum(_int_or(p.cells.loc[p.cells["motion"] == "periodic", "n"],
                                          0), MAX_POINTS).sum()) for p in planes)
    room = POINTS_BUDGET / 4 - periodic
    if free == 0 or room >= free * MAX_POINTS:
        return MAX_POINTS
    return int(max(MIN_POINTS, min(MAX_POINTS, room // free)))


def plane_payload(plane: PlaneData, block: Block, cap: int = MAX_POINTS) -> dict[str, Any]:
    """Everything the page shows of one plane: metadata, and typed arrays in row-major (j, i)
    order added to ``block``."""
    df = plane.cells.reset_index(drop=True)
    nx, ny = int(df["i"].max()) + 1, int(df["j"].max()) + 1
    xs = df.groupby("i")[plane.xname].first().reindex(range(nx)).to_numpy(dtype=float)
    ys = df.groupby("j")[plane.yname].first().reindex(range(ny)).to_numpy(dtype=float)
    where = np.full(nx * ny, -1, dtype=np.int64)
    where[df["j"].to_numpy(dtype=int) * nx + df["i"].to_numpy(dtype=int)] = np.arange(len(df))
    present = where >= 0
    rows = np.where(present, where, 0)

    def grid(col: str) -> np.ndarray:
        v = pd.to_numeric(df[col], errors="coerce").to_numpy(dtype=float)[rows]
        return np.where(present, v, np.nan)

    cats = style.pattern_categories(df)
    keys = [k for k in style.PATTERN_KEYS if k in set(cats)]
    kidx = {k: n for n, k in enumerate(keys)}
    cat = np.array([kidx[c] for c in cats], dtype=np.int64)[rows]
    labels, label = _indexed(df["label"].fillna("").astype(str))
    npqs, npq = _indexed(df["label_npq"].fillna("").astype(str))
    n = _int_or(df["n"])
    periodic = np.where(df["motion"].fillna("").astype(str).to_numpy() == "periodic", n, 0)
    counts, px, pv = _poincare(df, rows, present, cap, periodic)
    small = "<u1" if max(len(labels), len(npqs)) < 255 else "<u2"
    layers: dict[str, Any] = {}
    for layer in VALUE_LAYERS:
        column = next((c for c in layer.columns if c in df.columns), None)
        if column is None and layer.optional:
            continue
        values = grid(column) if column is not None else np.full(nx * ny, np.nan)
        layers[layer.key] = layer_payload(layer, values, block, column)
    floquet = layers["floquet"]["column"] if "floquet" in layers else None
    # the verified-motion columns of the readout: status, critical multiplier, refined
    verified: dict[str, Any] = {}
    for col in ("status", "critical"):
        if col in df.columns:
            names, idx = _indexed(df[col].fillna("").astype(str))
            verified[col] = {"names": names,
                             "index": block.add(np.where(present, idx[rows], 255), "u1")}
    if "refined" in df.columns:
        ref = df["refined"].fillna(False).astype(bool).to_numpy()[rows]
        verified["refined"] = block.add(np.where(present, ref, 0), "u1")
    payload: dict[str, Any] = {
        "name": plane.name, "nx": nx, "ny": ny,
        "xname": plane.xname, "yname": plane.yname,
        "xsym": _SYMBOLS.get(plane.xname, plane.xname),
        "ysym": _SYMBOLS.get(plane.yname, plane.yname),
        "xs": block.add(xs, "<f8"), "ys": block.add(ys, "<f8"),
        "present": block.add(present, "u1"),
        "cat": block.add(np.where(present, cat, 255), "u1"),
        "cat_keys": keys,
        "cat_labels": [style.PATTERN_LABELS[k] for k in keys],
        "cat_colours": [style.PATTERN_COLOURS[k] for k in keys],
        "labels": labels, "npqs": npqs,
        "label": block.add(label[rows], small), "npq": block.add(npq[rows], small),
        "I": block.add(np.where(present, _int_or(df["I"], -9)[rows], -9), "<i1"),
        "n": block.add(np.where(present, n[rows], -1), "<i2"),
        "layers": layers,
        "floquet_column": floquet,
        "verified": verified,
        "counts": block.add(np.clip(counts, 0, 255), "u1"),
        "px": block.quantised(px), "pv": block.quantised(pv),
        "attractors": None, "n_attractors": None,
        "curves": plane.curves,
        "codim2": plane.codim2,
        "physical": plane.physical,
    }
    if plane.attractors is not None:  # one line per attractor of each searched cell
        payload["attractors"] = block.add_json({str(k): v for k, v in plane.attractors.items()})
    if plane.n_attractors:
        na = np.full(nx * ny, 255, dtype=np.int64)
        for k, v in plane.n_attractors.items():
            na[k] = min(int(v), 254)
        payload["n_attractors"] = block.add(na, "u1")
    return payload


def layer_payload(layer: ValueLayer, values: np.ndarray, block: Block,
                  column: str | None) -> dict[str, Any]:
    """One value layer of a plane: its description for the page, its drawn range and how many
    cells lie below or above it, and its values as the shown digits (:meth:`Block.digits`)."""
    shown = digits_of_values(values, layer.digits)
    finite = shown[np.isfinite(shown)]
    lo = float(finite.min()) if len(finite) else 0.0
    hi = float(finite.max()) if len(finite) else 1.0
    if layer.scale == "unit":
        lo, hi = 0.0, 1.0
    elif layer.scale == "capped":
        from gearsim.presentation.figures.planes import robust_max

        hi = float(robust_max(shown)) if len(finite) else 1.0
    elif layer.scale == "margin":
        lo, hi = -4.0, 0.0  # log10 of 1 - value
    over = under = 0
    if layer.scale in ("unit", "capped", "full"):
        over, under = int(np.sum(finite > hi)), int(np.sum(finite < lo))
    return {"key": layer.key, "button": layer.button, "readout": layer.readout,
            "title": layer.title.format(reading=KMAX_DEFINITION, column=column),
            "column": column, "cmap": layer.cmap, "scale": layer.scale, "lo": lo, "hi": hi,
            "over": over, "under": under, "values": block.digits(values, layer.digits)}


def digits_of_values(values: np.ndarray, digits: int) -> np.ndarray:
    """The values as the page shows them (rounded to ``digits`` decimals)."""
    q, big = shown_digits(values, digits)
    out = np.where(q == NO_VALUE, np.nan, q / 10.0**digits)
    for k, value in big.items():
        out[int(k)] = value
    return out


def sweep_payload(name: str, df: pd.DataFrame, block: Block,
                  fixed: Mapping[str, float] | None = None,
                  physical: Mapping[str, Any] | None = None,
                  fixed_physical: Mapping[str, Mapping[str, Any]] | None = None
                  ) -> dict[str, Any]:
    """A sweep's bifurcation diagram: every kept Poincare x against the swept value."""
    param = str(df["parameter"].iloc[0]) if "parameter" in df.columns and len(df) else "w"
    xs, Is, ks = [], [], []
    for k, (px, I) in enumerate(zip(df["poincare_x"], df["I"], strict=True)):
        px = np.asarray(px if px is not None else [], dtype=float)[-MAX_SWEEP_POINTS:]
        px = px[np.isfinite(px)]
        xs.append(px)
        Is.append(np.full(len(px), int(I) if pd.notna(I) else -9))
        ks.append(np.full(len(px), k))

    def cat(a):
        return np.concatenate(a) if a else np.zeros(0)

    impacts = sorted({int(i) for i in df["I"].dropna()})
    return {
        "name": name, "parameter": param, "psym": _SYMBOLS.get(param, param),
        "fixed": {k: float(v) for k, v in (fixed or {}).items()
                  if isinstance(v, int | float)},
        "fixed_physical": {k: {**ph, "value": float(fixed[k]) * ph["k"]}
                           for k, ph in (fixed_physical or {}).items() if k in (fixed or {})},
        "physical": dict(physical or {}),
        "values": df["value"].astype(float).tolist(),
        "direction": (df["direction"].astype(str).tolist() if "direction" in df.columns
                      else ["forward"] * len(df)),
        "x": block.quantised(cat(xs)), "I": block.add(cat(Is), "<i1"),
        "k": block.add(cat(ks), "<u4"),
        "labels": [f"{lab} ({npq})" if npq else str(lab) for lab, npq in
                   zip(df["label"].fillna(""), df["label_npq"].fillna(""), strict=True)],
        "dc": df["dc"].astype(float).round(4).tolist(),
        "kmax": (df["kmax"] if "kmax" in df.columns else df[DEFAULT_KMAX]
                 ).astype(float).round(4).tolist(),
        "impacts": impacts,
        "impact_colours": {str(i): style.impact_colour(i) for i in impacts},
        "impact_names": {str(i): style.IMPACT_NAMES.get(i, f"I = {i}") for i in impacts},
    }


def _colorscale(name: str, n: int = 256) -> list[str]:
    """A matplotlib colour map as ``n`` hex colours (the maps look like the figures')."""
    from matplotlib import colormaps
    from matplotlib.colors import to_hex

    cmap = colormaps[name]
    return [to_hex(cmap(k / (n - 1))) for k in range(n)]


_TEMPLATE = Path(__file__).with_name("explorer_page.html")


def _json_safe(o: Any) -> Any:
    if isinstance(o, float):
        return o if np.isfinite(o) else None
    if isinstance(o, dict):
        return {k: _json_safe(v) for k, v in o.items()}
    if isinstance(o, list | tuple):
        return [_json_safe(v) for v in o]
    return o


def render(planes: Sequence[PlaneData], sweeps: Mapping[str, pd.DataFrame], *,
           sweep_fixed: Mapping[str, Mapping[str, float]] | None = None,
           sweep_physical: Mapping[str, Mapping[str, Any]] | None = None,
           sweep_fixed_physical: Mapping[str, Mapping[str, Any]] | None = None,
           title: str = "gearsim explorer", provenance: Mapping[str, Any] | None = None,
           scorecard: Sequence[Mapping[str, Any]] | None = None) -> str:
    """The page (one HTML string)."""
    block = Block()
    cap = points_cap(planes)
    data = {
        "title": title,
        "planes": [plane_payload(p, block, cap) for p in planes],
        "sweeps": [sweep_payload(n, df, block, (sweep_fixed or {}).get(n),
                                 (sweep_physical or {}).get(n),
                                 (sweep_fixed_physical or {}).get(n))
                   for n, df in sweeps.items()],
        "provenance": dict(provenance or {}),
        "scorecard": list(scorecard or []),
        "max_points": cap,
        "missing": MISSING,
        "curve_colours": {kind: st[1] for kind, st in CURVE_STYLE.items()},
        "turbo": _colorscale("turbo"),
        "magma": _colorscale("magma"),
    }
    blob = json.dumps(_json_safe(data), separators=(",", ":"), allow_nan=False
                      ).replace("</", "<\\/")
    page = _TEMPLATE.read_text()
    return (page.replace("%%TITLE%%", _html_escape(title))
            .replace("%%KMAX%%", _html_escape(KMAX_DEFINITION))
            .replace("%%DATA%%", blob).replace("%%BLOCK%%", block.encoded()))


def _html_escape(s: str) -> str:
    return s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def write_explorer(out: str | Path, *, planes: Mapping[str, tuple[str, str]] | Sequence[str],
                   sweeps: Sequence[str], results: str | Path = "results",
                   catalogue: str | Path | None = None,
                   sweep_fixed: Mapping[str, Mapping[str, float]] | None = None,
                   provenance: Mapping[str, Any] | None = None, gear=None,
                   scorecard: Sequence[Mapping[str, Any]] | None = None,
                   title: str = "gearsim explorer") -> Path:
    """Read the study's tables (``results/<plane>/cells.parquet``,
    ``results/sweeps/<sweep>.parquet``, the catalogue's attractors and bifurcation curves when
    present) and write the page to ``out`` (atomically). ``gear``: the study's gear geometry
    (axes in physical units), ``scorecard``: the report's rows."""
    from gearsim.physical.units import physical_factors

    results = Path(results)
    axes = dict(planes) if isinstance(planes, Mapping) else {p: None for p in planes}
    loaded = []
    for name, ax in axes.items():
        cells = pd.read_parquet(results / name / "cells.parquet")
        p = plane_from_cells(name, cells, tuple(ax) if ax else None)
        if catalogue is not None:
            p.attractors, p.n_attractors = read_attractors(catalogue, name,
                                                           int(cells["i"].max()) + 1)
            p.curves = read_curves(catalogue, name)
            p.codim2 = read_codim2(catalogue, name)
        p.physical = physical_factors(gear, [p.xname, p.yname])
        loaded.append(p)
    tables = {s: pd.read_parquet(results / "sweeps" / f"{s}.parquet") for s in sweeps}
    sphys, fphys = {}, {}
    for s, df in tables.items():
        param = str(df["parameter"].iloc[0]) if "parameter" in df.columns and len(df) else "w"
        sphys[s] = physical_factors(gear, [param]).get(param)
        fphys[s] = physical_factors(gear, list((sweep_fixed or {}).get(s) or {}))
    html = render(loaded, tables, sweep_fixed=sweep_fixed, sweep_physical=sphys,
                  sweep_fixed_physical=fphys,
                  provenance=provenance, scorecard=scorecard, title=title)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(html, encoding="utf-8")
    tmp.replace(out)
    return out
