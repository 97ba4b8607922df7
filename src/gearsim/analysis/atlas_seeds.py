"""The boundaries of a plane's pattern map as seeds of bifurcation curves, and which of them a
followed curve already passes.

A boundary edge is a pair of side-by-side cells (next in x or in y) whose labels differ. Between
two periodic cells the labels say which bifurcation to look for (:func:`edge_hints`):

- the period doubles (``n -> 2n``): a period doubling of the period-``n`` orbit, located from
  the period-``n`` cell;
- the same period, the contacts change: a grazing, of the face flank (``x = +b``) where the face
  contacts change (``p``, or ``I`` between 0 and the rest) and of the back flank (``x = -b``)
  where the back contacts ``q`` change; located from either cell;
- anything else (a jump): a fold, or several bifurcations within one cell, found by a short
  continuation from the cell the chain came from.

The edges are the accounting's (:func:`gearsim.analysis.boundaries.label_pairs`), those
between two periodic cells. Distances are in cells: an edge sits at the midpoint of its two
cell centres in the grid's index coordinates ``(i, j)``, a curve point at ``((w - x_min) / dx -
1/2, (y - y_min) / dy - 1/2)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from gearsim.analysis.boundaries import label_pairs

EDGE_COLUMNS = (
    "i", "j", "i2", "j2", "axis", "label_a", "label_b", "n_a", "n_b", "ci", "cj",
)

FACE, BACK = "x=+b", "x=-b"


@dataclass(frozen=True)
class Grid:
    """The plane's grid: axis names, ranges and cell counts (cell centres at ``min + (k +
    1/2) (max - min) / n``)."""

    x_name: str
    y_name: str
    x_min: float
    x_max: float
    nx: int
    y_min: float
    y_max: float
    ny: int

    @property
    def dx(self) -> float:
        return (self.x_max - self.x_min) / self.nx

    @property
    def dy(self) -> float:
        return (self.y_max - self.y_min) / self.ny

    def x_of(self, i: float) -> float:
        return self.x_min + (i + 0.5) * self.dx

    def y_of(self, j: float) -> float:
        return self.y_min + (j + 0.5) * self.dy

    def index(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """``(ci, cj)`` index coordinates of parameter points (rows)."""
        return np.column_stack([(np.asarray(x) - self.x_min) / self.dx - 0.5,
                                (np.asarray(y) - self.y_min) / self.dy - 0.5])


def _periodic(cells: pd.DataFrame) -> np.ndarray:
    return (cells["motion"].to_numpy() == "periodic") & (cells["n"].to_numpy() > 0)


def boundary_edges(cells: pd.DataFrame) -> pd.DataFrame:
    """Every boundary edge between two periodic cells (the accounting's edges,
    :func:`gearsim.analysis.boundaries.label_pairs`, of its periodic groups; columns
    :data:`EDGE_COLUMNS` plus the cells' ``impact``, ``p``, ``q`` and, where the cells table
    has them, ``dc``, ``x_min``, ``x_max`` as ``*_a``, ``*_b``); ``a`` is the cell with the
    smaller index along the edge's axis."""
    i = cells["i"].to_numpy(dtype=np.int64)
    j = cells["j"].to_numpy(dtype=np.int64)
    lab = cells["label"].to_numpy()
    per = _periodic(cells)
    # the impact state is the cells table's column I
    cols = {c: cells["I" if c == "impact" else c].fillna(0).to_numpy(dtype=np.int64)
            for c in ("n", "impact", "p", "q")}
    # the readings a jump is told by (:func:`gearsim.analysis.boundaries.is_jump`)
    reads = {c: pd.to_numeric(cells[c], errors="coerce").to_numpy(dtype=float)
             for c in ("dc", "x_min", "x_max") if c in cells}
    out = []
    for axis, a, b in label_pairs(i, j, lab):
        keep = per[a] & per[b]
        a, b = a[keep], b[keep]
        d = {"i": i[a], "j": j[a], "i2": i[b], "j2": j[b], "axis": axis,
             "label_a": lab[a], "label_b": lab[b],
             "ci": 0.5 * (i[a] + i[b]), "cj": 0.5 * (j[a] + j[b])}
        for c, arr in (cols | reads).items():
            d[f"{c}_a"], d[f"{c}_b"] = arr[a], arr[b]
        out.append(pd.DataFrame(d))
    return pd.concat(out, ignore_index=True)


@dataclass(frozen=True)
class Hint:
    """What an edge's labels say to look for: ``kind`` (``period_doubling``, ``grazing``,
    ``fold``), the orbit's ``period``, the grazing ``boundary``, and the cell (``"a"`` or
    ``"b"``) whose simulated state starts Newton."""

    kind: str
    period: int
    boundary: str
    start: str

    @property
    def key(self) -> tuple[str, int, str]:
        return (self.kind, self.period, self.boundary)


def edge_hints(e: pd.Series | dict) -> list[Hint]:
    """The bifurcations an edge's labels point to (see the module docstring)."""
    na, nb = int(e["n_a"]), int(e["n_b"])
    if nb == 2 * na:
        return [Hint("period_doubling", na, "", "a")]
    if na == 2 * nb:
        return [Hint("period_doubling", nb, "", "b")]
    if na == nb:
        pa, pb, qa, qb = (int(e[k]) for k in ("p_a", "p_b", "q_a", "q_b"))
        ia, ib = int(e["impact_a"]), int(e["impact_b"])
        out = []
        # the cell with fewer contacts first: its orbit is the smooth side of the grazing
        first = "a" if pa + qa <= pb + qb else "b"
        if pa != pb or (ia == 0) != (ib == 0):
            out.append(Hint("grazing", na, FACE, first))
        if qa != qb:
            out.append(Hint("grazing", na, BACK, first))
        if not out:  # same period and contacts, another label: a jump
            out.append(Hint("fold", na, "", "a"))
        return out
    lo, start = (na, "a") if na < nb else (nb, "b")
    out = [Hint("fold", na, "", "a")]
    if max(na, nb) == 4 * lo:  # two doublings inside one cell
        out += [Hint("period_doubling", lo, "", start), Hint("period_doubling", 2 * lo, "", start)]
    return out


def matches(hint_key: tuple[str, int, str], curve_key: tuple[str, int, str]) -> bool:
    """A curve of ``curve_key`` explains an edge of ``hint_key``: the same kind, period and
    boundary (a fold explains a jump of any period)."""
    if hint_key[0] == "fold":
        return curve_key[0] == "fold"
    return hint_key == curve_key


def distance_to_polyline(p: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance of each point ``p`` (rows) to the polygon through ``poly`` (rows)."""
    p = np.atleast_2d(p)
    if len(poly) == 1:
        return np.linalg.norm(p - poly[0], axis=1)
    a, b = poly[:-1], poly[1:]
    ab = b - a
    L2 = np.maximum((ab * ab).sum(axis=1), 1e-300)
    ap = p[:, None, :] - a[None, :, :]
    s = np.clip((ap * ab[None]).sum(axis=2) / L2[None], 0.0, 1.0)
    q = a[None] + s[..., None] * ab[None]
    return np.sqrt(((p[:, None, :] - q) ** 2).sum(axis=2)).min(axis=1)


def covered(points: np.ndarray, curves: Sequence[np.ndarray], radius: float) -> np.ndarray:
    """Which ``points`` lie within ``radius`` of any of ``curves`` (polylines, cell units)."""
    hit = np.zeros(len(points), dtype=bool)
    for poly in curves:
        if len(points) == 0 or len(poly) == 0:
            continue
        lo, hi = poly.min(axis=0) - radius, poly.max(axis=0) + radius
        near = ~hit & np.all((points >= lo) & (points <= hi), axis=1)
        if near.any():
            hit[near] = distance_to_polyline(points[near], poly) <= radius
    return hit
