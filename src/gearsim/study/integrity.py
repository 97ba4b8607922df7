"""Integrity of a plane's data: every tile is of the plane's configuration and code, complete, and
the tiles cover every cell ``(i, j)`` of the grid exactly once.

:func:`tile_info` checks one tile file from its Parquet footer (no data read); :class:`Coverage`
is a bitmap of the ``x_n * y_n`` grid (one byte per cell: 4 MB for 2000 x 2000) fed batch by
batch, so a plane of any size is checked while it streams. Every failure is a
:class:`CatalogueError`: one line naming the file and what was expected.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gearsim.errors import CatalogueError, one_line


@dataclass
class TileInfo:
    path: Path
    provenance: dict[str, Any]
    rows: int
    schema: Any  # pyarrow.Schema

    @property
    def first_row(self) -> int:
        rows = self.provenance.get("rows")
        return int(rows[0]) if rows else int(self.provenance.get("tile", 0))


def read_footer(path: str | Path, what: str = "file"):
    """``(ParquetFile metadata, key-value dict)`` of a Parquet file, or a one-line error."""
    import pyarrow.parquet as pq

    path = Path(path)
    if not path.is_file():
        raise CatalogueError(f"{what} {path}: not found")
    if path.stat().st_size == 0:
        raise CatalogueError(f"{what} {path}: empty file (0 bytes)")
    try:
        meta = pq.read_metadata(path)
    except Exception as exc:  # pyarrow raises ArrowInvalid, OSError, ... for a damaged footer
        raise CatalogueError(
            f"{what} {path}: not a readable Parquet file ({one_line(exc)})"
        ) from None
    return meta, dict(meta.metadata or {})


def tile_info(path: str | Path, plane: Mapping[str, Any], key: bytes) -> TileInfo:
    """Check a tile file against its plane record (name, config hash, code version, cell count)."""
    import json

    path = Path(path)
    meta, kv = read_footer(path, "tile")
    raw = kv.get(key)
    if raw is None:
        raise CatalogueError(f"tile {path}: no gearsim provenance in its metadata")
    try:
        prov = json.loads(raw)
    except ValueError:
        raise CatalogueError(f"tile {path}: provenance is not valid JSON") from None
    check_run(prov, plane, f"tile {path}")
    n = meta.num_rows
    if n == 0:
        raise CatalogueError(f"tile {path}: empty (0 cells)")
    recorded = prov.get("cells")
    if recorded is None:
        raise CatalogueError(f"tile {path}: provenance records no cell count")
    if int(recorded) != n:
        raise CatalogueError(
            f"tile {path}: {n} cells stored but {recorded} recorded when it was written "
            "(truncated or altered; re-run its simulate_tile job)"
        )
    return TileInfo(path, prov, n, meta.schema.to_arrow_schema())


def check_run(prov: Mapping[str, Any], plane: Mapping[str, Any], what: str) -> None:
    """A tile's provenance carries the plane's name, configuration hash and code version."""
    if prov.get("kind", "tile") != "tile":
        raise CatalogueError(f"{what}: is a {prov.get('kind')!r} file, not a tile")
    if prov.get("name") != plane["name"]:
        raise CatalogueError(
            f"{what}: belongs to plane {prov.get('name')!r}, not {plane['name']!r}"
        )
    for key, label in (("config_hash", "configuration hash"), ("code_version", "code version")):
        want = plane.get(key)
        got = prov.get(key)
        if want and got != want:
            raise CatalogueError(
                f"{what}: computed under {label} {got}, plane {plane['name']!r} is at {want} "
                "(a tile of another configuration or code; re-run its simulate_tile job)"
            )


class Coverage:
    """Cells seen so far of a plane's ``x_n x y_n`` grid; each must be seen exactly once."""

    def __init__(self, plane: Mapping[str, Any]):
        self.name = plane["name"]
        self.nx = int(plane["x"]["n"])
        self.ny = int(plane["y"]["n"])
        lo, hi = float(plane["x"]["min"]), float(plane["x"]["max"])
        self.xs = lo + (np.arange(self.nx) + 0.5) * (hi - lo) / self.nx
        lo, hi = float(plane["y"]["min"]), float(plane["y"]["max"])
        self.ys = lo + (np.arange(self.ny) + 0.5) * (hi - lo) / self.ny
        self.seen = np.zeros(self.nx * self.ny, dtype=np.int32)  # 1 + index of the source
        self.sources: list[str] = []

    def add(self, i, j, x, y, source: str) -> None:
        """Record a batch of cells from ``source``; refuse out-of-grid, off-centre or repeated."""
        i = np.asarray(i, dtype=np.int64)
        j = np.asarray(j, dtype=np.int64)
        where = f"{source}"
        bad = (i < 0) | (i >= self.nx) | (j < 0) | (j >= self.ny)
        if bad.any():
            k = int(np.argmax(bad))
            raise CatalogueError(
                f"{where}: cell (i, j) = ({i[k]}, {j[k]}) is outside plane {self.name!r} "
                f"(0..{self.nx - 1}, 0..{self.ny - 1})"
            )
        for vals, grid, idx, axis in ((x, self.xs, i, "x"), (y, self.ys, j, "y")):
            v = np.asarray(vals, dtype=float)
            off = ~np.isclose(v, grid[idx], rtol=1e-9, atol=1e-12)
            if off.any():
                k = int(np.argmax(off))
                raise CatalogueError(
                    f"{where}: cell (i, j) = ({i[k]}, {j[k]}) has {axis} = {v[k]!r}, the grid of "
                    f"plane {self.name!r} has {grid[idx[k]]!r} there (another grid)"
                )
        flat = j * self.nx + i
        self.sources.append(source)
        tag = len(self.sources)
        uniq, first, counts = np.unique(flat, return_index=True, return_counts=True)
        dup_in_batch = counts > 1
        if dup_in_batch.any():
            f = int(uniq[np.argmax(dup_in_batch)])
            raise CatalogueError(
                f"{where}: cell (i, j) = ({f % self.nx}, {f // self.nx}) appears "
                f"{int(counts[np.argmax(dup_in_batch)])} times"
            )
        prev = self.seen[uniq]
        if prev.any():
            k = int(np.argmax(prev > 0))
            f = int(uniq[k])
            raise CatalogueError(
                f"{where}: cell (i, j) = ({f % self.nx}, {f // self.nx}) is also in "
                f"{self.sources[int(prev[k]) - 1]} (duplicated tile)"
            )
        self.seen[uniq] = tag

    def finish(self, what: str) -> int:
        """Refuse a grid with cells missing; returns the number of cells."""
        missing = self.seen == 0
        if missing.any():
            f = int(np.argmax(missing))
            raise CatalogueError(
                f"{what}: {int(missing.sum())} of {missing.size} cells of plane {self.name!r} "
                f"missing, first (i, j) = ({f % self.nx}, {f // self.nx}) (a tile is missing "
                "or truncated)"
            )
        return int(missing.size)
