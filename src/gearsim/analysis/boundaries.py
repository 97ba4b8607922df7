"""Every boundary of a plane's pattern map accounted for (a table reading, no simulation).

A **boundary edge** is a pair of adjacent cells (neighbours along the plane's x axis or its y
axis) whose labels (``I/nT``, or ``chaos`` / ``quasi-periodic`` / ``unsettled`` /
``diverged``) differ. Each edge is put in one **group**:

* ``I changes``: both cells periodic, the impact state ``I`` differs;
* ``I the same``: both periodic, same ``I`` (so the period ``n`` differs);
* ``chaos``: one cell chaotic or quasi-periodic (a bounded settled motion without a period);
* ``other``: any other pair (unsettled or diverged on a side).

and explained by one **mechanism**, the first that applies of:

``grazing``, ``period_doubling``, ``fold``
    a located curve of the plane (:mod:`gearsim.analysis.bifcurves`) lies within
    :data:`NEAR_CELLS` cells of the edge's midpoint (distances in cells: each axis divided by
    its cell width) and its kind matches the change: a period doubling of period ``m`` where
    the periods are ``m`` and ``2 m``; a grazing where ``I`` changes, of the flank whose
    contact is born or lost (:func:`flank_of_change`) and of either cell's period; a fold at
    a jump (the duty cycle or the displacement range jumps, :func:`is_jump`), of either
    cell's period.
``fold_band``
    the edge lies inside a fold's hysteresis band: between two successive crossings of the
    fold curves of one period with the edge's row or column, where two branches coexist and
    the label is that of the branch the chain followed;
``coexist``
    an edge no curve or band explains across which both cells' motions exist and are stable
    on both sides (Newton, :mod:`gearsim.analysis.coexistence`; only where the accounting is
    given the model, :func:`apply_newton`): a hysteresis band whose bounding fold or
    subcritical doubling lies farther away, the label the branch the chain followed;
``chaos_onset``
    a chaotic cell beside a periodic one of period ``n`` with the doubling of period ``n`` (or
    a later one of the cascade) within :data:`NEAR_CELLS`: the rest of the cascade
    accumulates inside the cell gap (the onset, or the exit of an inverse cascade);
``crisis``
    any other edge between a chaotic and a periodic cell across which the motion jumps
    (:func:`is_jump`): the chaotic band ends abruptly, as read from the grid (a crisis; not
    located by a test function);
``near_curve``
    a quasi-periodic, unsettled or diverged cell's edge within :data:`NEAR_CELLS` of any curve
    (next to a doubling a cell's transient decays too slowly to settle in its window:
    docs/orbits.md);
``unexplained``
    none of these: a missed curve or a wrong label; listed with its cells.

``near_any`` records, for every edge, whether any located curve (any kind) is within
:data:`NEAR_CELLS`.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import pandas as pd

#: how close (in cells) a located curve must pass to an edge's midpoint to explain it
NEAR_CELLS = 1.5
#: a jump of the duty cycle across an edge (the landmark finder's default,
#: :func:`gearsim.analysis.landmarks.find_landmarks`)
JUMP_DC = 0.15
#: a jump of the displacement range ``x_max - x_min`` across an edge (relative change)
JUMP_RANGE = 0.2

GROUPS = ("I changes", "I the same", "chaos", "other")
MECHANISMS = ("grazing", "period_doubling", "fold", "fold_band", "coexist", "chaos_onset",
              "crisis", "near_curve", "unexplained")
#: the mechanisms that explain an edge between two periodic cells (the target's)
EXPLAINING = ("grazing", "period_doubling", "fold", "fold_band", "coexist")
#: the columns of an edge table (:func:`classify_edges`)
EDGE_COLUMNS = (
    "plane", "axis", "i0", "j0", "i1", "j1", "x", "y", "label0", "label1", "group",
    "mechanism", "curve", "distance", "near_any",
)
_CELL_COLUMNS = ("label", "motion", "I", "n", "dc", "x_min", "x_max")


@dataclass
class Grid:
    """A plane's cells on their ``(i, j)`` grid: the centres, the cell widths, the labels."""

    x: np.ndarray  # (nx,) cell centres along the plane's x axis
    y: np.ndarray  # (ny,)
    dx: float
    dy: float
    cells: pd.DataFrame  # indexed by (i, j)


def plane_grid(cells: pd.DataFrame) -> Grid:
    """The grid of a cells table (columns ``i``, ``j``, ``x``, ``y`` and the labels)."""
    need = {"i", "j", "x", "y", *_CELL_COLUMNS} - set(cells.columns)
    if need:
        raise KeyError(f"cells table lacks {sorted(need)}")
    xs = cells.groupby("i")["x"].first().sort_index()
    ys = cells.groupby("j")["y"].first().sort_index()
    dx = float(np.median(np.diff(xs.to_numpy()))) if len(xs) > 1 else 1.0
    dy = float(np.median(np.diff(ys.to_numpy()))) if len(ys) > 1 else 1.0
    return Grid(xs.to_numpy(float), ys.to_numpy(float), dx, dy,
                cells.set_index(["i", "j"]).sort_index())


def _group(m0, m1, i0, i1) -> np.ndarray:
    per0, per1 = m0 == "periodic", m1 == "periodic"
    aperiodic = ("chaos", "quasi-periodic")
    return np.where(per0 & per1, np.where(i0 != i1, GROUPS[0], GROUPS[1]),
                    np.where(np.isin(m0, aperiodic) | np.isin(m1, aperiodic), GROUPS[2],
                             GROUPS[3]))


def label_pairs(i, j, label) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """The boundary edges of cells at grid positions ``(i, j)`` (the rows of one table): per
    axis (``"x"``, then ``"y"``), the rows ``a`` and ``b`` of the neighbours (``b`` one step
    further along the axis) whose labels differ, ``a`` in ``(i, j)`` order. A cell whose
    neighbour is not in the table makes no edge. The one definition of a boundary edge: the
    accounting (:func:`boundary_edges`) and the atlas's seeds
    (:func:`gearsim.analysis.atlas_seeds.boundary_edges`) read it."""
    i = np.asarray(i, dtype=np.int64)
    j = np.asarray(j, dtype=np.int64)
    lab = np.asarray(label, dtype=object)
    if not len(i):
        return [("x", np.zeros(0, np.int64), np.zeros(0, np.int64)),
                ("y", np.zeros(0, np.int64), np.zeros(0, np.int64))]
    i0, j0 = int(i.min()), int(j.min())
    pos = np.full((int(i.max()) - i0 + 2, int(j.max()) - j0 + 2), -1, dtype=np.int64)
    pos[i - i0, j - j0] = np.arange(len(i))
    order = np.lexsort((j, i))
    out = []
    for axis, di, dj in (("x", 1, 0), ("y", 0, 1)):
        b = pos[i[order] - i0 + di, j[order] - j0 + dj]
        ok = b >= 0
        a, b = order[ok], b[ok]
        diff = lab[a] != lab[b]
        out.append((axis, a[diff], b[diff]))
    return out


def boundary_edges(cells: pd.DataFrame, plane: str = "") -> pd.DataFrame:
    """Every boundary edge of a plane's cells (:func:`label_pairs`): ``axis`` (``x``:
    neighbours along x), the two cells ``(i0, j0)``, ``(i1, j1)`` (``i1 >= i0``, ``j1 >=
    j0``), the midpoint ``(x, y)``, both cells' label, motion, ``I``, ``n``, ``dc``,
    ``x_min``, ``x_max`` (suffix 0 / 1) and the ``group``."""
    g = plane_grid(cells)
    c = g.cells
    parts = []
    idx = c.index.to_frame(index=False)
    for axis, ka, kb in label_pairs(idx["i"], idx["j"], c["label"]):
        a, b = c.iloc[ka], c.iloc[kb]
        ia, ja = a.index.get_level_values(0), a.index.get_level_values(1)
        ib, jb = b.index.get_level_values(0), b.index.get_level_values(1)
        df = pd.DataFrame({"plane": plane, "axis": axis, "i0": ia, "j0": ja, "i1": ib,
                           "j1": jb,
                           "x": 0.5 * (g.x[ia] + g.x[ib]), "y": 0.5 * (g.y[ja] + g.y[jb])})
        for col in _CELL_COLUMNS:
            df[f"{col}0"] = a[col].to_numpy()
            df[f"{col}1"] = b[col].to_numpy()
        parts.append(df)
    e = pd.concat(parts, ignore_index=True)
    e["group"] = _group(e["motion0"].to_numpy(), e["motion1"].to_numpy(),
                        e["I0"].to_numpy(), e["I1"].to_numpy())
    return e


# ------------------------------------------------------------------------------- the curves
def curve_polylines(curves: pd.DataFrame, x_name: str) -> list[dict]:
    """Each curve of a curves table as a polyline in the plane's ``(x, y)``: ``{"curve",
    "kind", "period", "boundary", "xy"}`` (``xy``: (k, 2), in curve order). The table's
    ``name`` is the curves' first parameter; where it is not the plane's x axis the two
    swap."""
    out = []
    if curves is None or not len(curves):
        return out
    for cid, c in curves.groupby("curve", sort=True):
        r = c.iloc[0]
        xs, ys = c["value"].to_numpy(float), c["value2"].to_numpy(float)
        if str(r["name"]) != x_name:
            xs, ys = ys, xs
        out.append({"curve": int(cid), "kind": str(r["kind"]), "period": int(r["period"]),
                    "boundary": str(r.get("boundary", "") or ""),
                    "xy": np.column_stack([xs, ys])})
    return out


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of each point ``p`` (E, 2) to the nearest of the segments ``a -> b`` (S, 2)."""
    ab = b - a  # (S, 2)
    L2 = np.maximum((ab ** 2).sum(1), 1e-300)
    out = np.full(len(p), np.inf)
    step = max(1, 2_000_000 // max(len(a), 1))
    for k in range(0, len(p), step):
        q = p[k:k + step, None, :] - a[None, :, :]  # (e, S, 2)
        t = np.clip((q * ab[None]).sum(2) / L2[None], 0.0, 1.0)
        d = q - t[..., None] * ab[None]
        out[k:k + step] = np.sqrt((d ** 2).sum(2)).min(1)
    return out


def curve_distances(edges: pd.DataFrame, lines: list[dict], dx: float, dy: float
                    ) -> np.ndarray:
    """(E, C): the distance in cells from each edge's midpoint to each curve (a single point
    is a zero-length segment; inf where the curve is farther than a bounding-box test)."""
    p = np.column_stack([edges["x"].to_numpy(float) / dx, edges["y"].to_numpy(float) / dy])
    out = np.full((len(p), len(lines)), np.inf)
    for c, line in enumerate(lines):
        xy = line["xy"] / np.array([dx, dy])
        xy = xy[np.all(np.isfinite(xy), axis=1)]
        if not len(xy):
            continue
        lo, hi = xy.min(0) - 2 * NEAR_CELLS, xy.max(0) + 2 * NEAR_CELLS
        near = np.all((p >= lo) & (p <= hi), axis=1)
        if not near.any():
            continue
        a, b = (xy[:-1], xy[1:]) if len(xy) > 1 else (xy, xy)
        out[near, c] = _segment_distance(p[near], a, b)
    return out


def flank_of_change(i0: int, i1: int) -> str | None:
    """The flank whose contact is born or lost between impact states ``i0`` and ``i1``:
    ``face`` (``x = +b``: 0 <-> 1, -1 <-> 2), ``back`` (``x = -b``: 0 <-> -1, 1 <-> 2), or
    None (both flanks change, or a state never in contact)."""
    face = {0: False, 1: True, -1: False, 2: True}
    back = {0: False, 1: False, -1: True, 2: True}
    if i0 not in face or i1 not in face:
        return None
    df, db = face[i0] != face[i1], back[i0] != back[i1]
    if df and not db:
        return "face"
    if db and not df:
        return "back"
    return None


def boundary_flank(boundary: str) -> str | None:
    """``face`` for a grazing of ``x = +b``, ``back`` for ``x = -b``, else None (a bearing
    clearance, or unnamed)."""
    b = boundary.replace(" ", "")
    if b.startswith("x=+") or b == "x=b":
        return "face"
    if b.startswith("x=-"):
        return "back"
    return None


def is_jump(dc0: float, dc1: float, r0: float, r1: float) -> bool:
    """Whether an edge is a jump: the duty cycle changes by :data:`JUMP_DC` or more, or the
    displacement range by :data:`JUMP_RANGE` of the larger or more."""
    if np.isfinite(dc0) and np.isfinite(dc1) and abs(dc1 - dc0) >= JUMP_DC:
        return True
    if np.isfinite(r0) and np.isfinite(r1) and max(r0, r1) > 0:
        return abs(r1 - r0) >= JUMP_RANGE * max(r0, r1)
    return False


def _is_doubling(n0: int, n1: int, m: int) -> bool:
    return {n0, n1} == {m, 2 * m}


def _matches(row, line: dict) -> str | None:
    """The mechanism a curve gives an edge of two periodic cells, or None."""
    kind, m = line["kind"], line["period"]
    n0, n1 = int(row.n0), int(row.n1)
    if kind == "period_doubling":
        return "period_doubling" if _is_doubling(n0, n1, m) else None
    if kind == "grazing":
        if int(row.I0) == int(row.I1) or m not in (n0, n1):
            return None
        want, got = flank_of_change(int(row.I0), int(row.I1)), boundary_flank(line["boundary"])
        return "grazing" if (want is None or got is None or want == got) else None
    if kind == "fold":
        r0, r1 = row.x_max0 - row.x_min0, row.x_max1 - row.x_min1
        if m in (n0, n1) and is_jump(row.dc0, row.dc1, r0, r1):
            return "fold"
    return None


def fold_bands(lines: list[dict], axis: str, at: float) -> dict[int, list[tuple[float, float]]]:
    """Per period, the hysteresis bands of the fold curves along the line where the plane's
    other axis equals ``at`` (``axis = "x"``: a row of fixed y; ``"y"``: a column of fixed x):
    the successive crossings of that period's fold curves, paired in order."""
    k_along, k_fixed = (0, 1) if axis == "x" else (1, 0)
    cross: dict[int, list[float]] = {}
    for line in lines:
        if line["kind"] != "fold":
            continue
        xy = line["xy"]
        f = xy[:, k_fixed] - at
        for s in range(len(xy) - 1):
            if f[s] == 0.0 or f[s] * f[s + 1] < 0:
                t = 0.0 if f[s] == 0.0 else f[s] / (f[s] - f[s + 1])
                v = xy[s, k_along] + t * (xy[s + 1, k_along] - xy[s, k_along])
                cross.setdefault(line["period"], []).append(float(v))
    return {m: [(v[k], v[k + 1]) for k in range(0, len(v) - 1, 2)]
            for m, v in ((m, sorted(vs)) for m, vs in cross.items())}


def _in_band(row, bands_of, dx: float, dy: float) -> bool:
    """Whether the edge's midpoint lies in a fold band of either cell's period, along its row
    and along its column (within :data:`NEAR_CELLS`)."""
    periods = {int(row.n0), int(row.n1)} - {0}
    for axis, along, fixed, d in (("x", row.x, row.y, dx), ("y", row.y, row.x, dy)):
        for m, bands in bands_of(axis, fixed).items():
            if periods and m not in periods:
                continue
            if any(lo - NEAR_CELLS * d <= along <= hi + NEAR_CELLS * d for lo, hi in bands):
                return True
    return False


def classify_edges(cells: pd.DataFrame, curves: pd.DataFrame | None, plane: str = "",
                   x_name: str = "w") -> pd.DataFrame:
    """Every boundary edge of the plane with its group and mechanism (module docstring):
    columns :data:`EDGE_COLUMNS` (``curve``: the explaining curve, -1 if none; ``distance``:
    its distance in cells, else the nearest curve's) then the two cells' columns."""
    g = plane_grid(cells)
    e = boundary_edges(cells, plane)
    lines = curve_polylines(curves, x_name)
    dist = curve_distances(e, lines, g.dx, g.dy) if lines else np.full((len(e), 0), np.inf)
    near = dist <= NEAR_CELLS
    e["near_any"] = near.any(axis=1) if lines else False
    cache: dict[tuple[str, float], dict] = {}

    def bands_of(axis: str, at: float) -> dict:
        key = (axis, round(at, 12))
        if key not in cache:
            cache[key] = fold_bands(lines, "x" if axis == "x" else "y", at)
        return cache[key]

    mech, which, how_far = [], [], []
    for k, row in enumerate(e.itertuples(index=False)):
        order = np.argsort(dist[k]) if lines else []
        best = (-1, float(dist[k].min()) if lines and len(lines) else np.inf)
        found = None
        if row.group in ("I changes", "I the same"):
            for c in order:
                if not near[k, c]:
                    break
                found = _matches(row, lines[c])
                if found:
                    best = (lines[c]["curve"], float(dist[k, c]))
                    break
            if found is None and _in_band(row, bands_of, g.dx, g.dy):
                found = "fold_band"
        elif row.group == "chaos" and "chaos" in (row.motion0, row.motion1) and "periodic" in (
                row.motion0, row.motion1):
            n = int(row.n1 if row.motion0 == "chaos" else row.n0)
            for c in order:
                if not near[k, c]:
                    break
                line = lines[c]
                if line["kind"] == "period_doubling" and n > 0 and line["period"] >= n:
                    found = "chaos_onset"
                    best = (line["curve"], float(dist[k, c]))
                    break
            if found is None and is_jump(row.dc0, row.dc1, row.x_max0 - row.x_min0,
                                         row.x_max1 - row.x_min1):
                found = "crisis"
        else:
            found = "near_curve" if e["near_any"].iat[k] else None
            if found:
                c = int(order[0])
                best = (lines[c]["curve"], float(dist[k, c]))
        mech.append(found or "unexplained")
        which.append(best[0])
        how_far.append(best[1])
    e["mechanism"] = mech
    e["curve"] = np.asarray(which, dtype=int)
    e["distance"] = np.asarray(how_far, dtype=float)
    rest = [c for c in e.columns if c not in EDGE_COLUMNS]
    return e[[*EDGE_COLUMNS, *rest]]


# ---------------------------------------------------------------------------- the summaries
def near_table(edges: pd.DataFrame) -> pd.DataFrame:
    """Per group: edges and the share with any located curve within :data:`NEAR_CELLS`
    (``all`` first)."""
    rows = [{"group": "all", "edges": len(edges),
             "near": int(edges["near_any"].sum())}]
    for grp in GROUPS:
        sub = edges[edges["group"] == grp]
        rows.append({"group": grp, "edges": len(sub), "near": int(sub["near_any"].sum())})
    t = pd.DataFrame(rows)
    t["share"] = t["near"] / t["edges"].where(t["edges"] > 0)
    return t


def mechanism_table(edges: pd.DataFrame) -> pd.DataFrame:
    """Boundary length by mechanism: edges (each one cell side long) per group and mechanism,
    with each mechanism's share of its group."""
    t = (edges.groupby(["group", "mechanism"]).size().rename("edges").reset_index())
    t["share"] = t["edges"] / t.groupby("group")["edges"].transform("sum")
    order = {g: k for k, g in enumerate(GROUPS)}
    morder = {m: k for k, m in enumerate(MECHANISMS)}
    t = t.sort_values(["group", "mechanism"], key=lambda s: s.map(
        order if s.name == "group" else morder)).reset_index(drop=True)
    return t


def explained_share(edges: pd.DataFrame, groups: Iterable[str] = ("I changes", "I the same")
                    ) -> dict[str, tuple[int, int]]:
    """Per group: (explained, all) edges, explained meaning on a matching curve, in a fold
    band or across coexisting motions (the periodic groups' target)."""
    ok = set(EXPLAINING)
    return {g: (int(edges.loc[edges["group"] == g, "mechanism"].isin(ok).sum()),
                int((edges["group"] == g).sum())) for g in groups}


def islands(cells: pd.DataFrame) -> set[tuple[int, int]]:
    """The cells whose label differs from that of at least three of their (up to four)
    neighbours, and of all when they have fewer: a label no region around it shares."""
    g = plane_grid(cells)
    lab = g.cells["label"]
    differ = pd.Series(0, index=lab.index)
    have = pd.Series(0, index=lab.index)
    idx = lab.index.to_frame(index=False)
    for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        nb = pd.MultiIndex.from_arrays([idx["i"] + di, idx["j"] + dj])
        ok = nb.isin(lab.index)
        other = pd.Series(lab.reindex(nb).to_numpy(), index=lab.index)
        have += ok.astype(int)
        differ += (ok & (other.to_numpy() != lab.to_numpy())).astype(int)
    return set(lab.index[(differ >= np.minimum(3, have)) & (have > 0)])


def unexplained(edges: pd.DataFrame, cells: pd.DataFrame | None = None) -> pd.DataFrame:
    """The unexplained edges with their cells, grouped by the pair of labels, most frequent
    first; with ``cells``, each named (``verdict``) a ``wrong label`` where Newton refutes a
    cell's label (:func:`newton_refuted`) or one of its cells is an island (:func:`islands`:
    a label no neighbour region shares), else a ``missed curve`` (the edge is part of a
    boundary no located curve follows); ``evidence`` says which (``Newton``, ``island``)."""
    u = edges[(edges["mechanism"] == "unexplained")].copy()
    u["pair"] = [" | ".join(sorted((a, b))) for a, b in zip(u["label0"], u["label1"],
                                                            strict=True)]
    if cells is not None and len(u):
        isl = islands(cells)
        wrong = np.array([(a, b) in isl or (c, d) in isl for a, b, c, d in
                          zip(u["i0"], u["j0"], u["i1"], u["j1"], strict=True)], dtype=bool)
        refuted = newton_refuted(u)
        u["verdict"] = np.where(wrong | refuted, "wrong label", "missed curve")
        u["evidence"] = np.where(refuted, "Newton", np.where(wrong, "island", ""))
    freq = u["pair"].map(u["pair"].value_counts())
    return u.assign(pair_edges=freq).sort_values(["pair_edges", "pair", "j0", "i0"],
                                                 ascending=[False, True, True, True])


# ------------------------------------------------------------------------ Newton's verdicts
NEWTON_COLUMNS = ("newton_n0", "newton_n1", "coexist")


def apply_newton(edges: pd.DataFrame, newton) -> pd.DataFrame:
    """The edges with Newton's reading of the unexplained periodic ones: ``newton(sub)``
    (:func:`gearsim.analysis.coexistence.newton_edges`) gives, per edge, the least periods
    Newton finds from the two cells' states and whether both motions coexist; a coexisting
    edge becomes ``coexist``. Columns :data:`NEWTON_COLUMNS` are added (0, 0, False where
    not tested)."""
    e = edges.assign(newton_n0=0, newton_n1=0, coexist=False)
    sel = (e["mechanism"] == "unexplained") & e["group"].isin(("I changes", "I the same"))
    if sel.any():
        r = newton(e[sel])
        for c in NEWTON_COLUMNS:
            e.loc[sel, c] = r[c].to_numpy()
        e.loc[sel & e["coexist"].astype(bool), "mechanism"] = "coexist"
    return e


def newton_refuted(edges: pd.DataFrame) -> np.ndarray:
    """Per edge, whether Newton refutes one of its labels: from the cell's simulated state
    it converges to a stable orbit of a smaller least period than the label's (the reading
    was a slowly decaying transient)."""
    if "newton_n0" not in edges:
        return np.zeros(len(edges), dtype=bool)
    out = np.zeros(len(edges), dtype=bool)
    for side in ("0", "1"):
        got, n = edges[f"newton_n{side}"].to_numpy(), edges[f"n{side}"].to_numpy()
        out |= (got > 0) & (got < n)
    return out
