"""Parquet files with provenance: atomic writes, key-value metadata, a plane's tiles combined.

``results/<plane>/tiles/<tile>.parquet`` holds one row per cell of a tile, its provenance under
the key ``gearsim.study.provenance`` of the Parquet key-value metadata;
``results/<plane>/cells.parquet`` all tiles of a plane (list columns ``poincare_x``,
``poincare_v``), its metadata the plane record and the provenance of every tile. Every writer
writes a temporary name in the target folder and renames it, after checking the folder
(:func:`gearsim.study.preflight.check_output`): a reader never sees a half-written file, and a
full disk keeps the previous one.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import pandas as pd

from gearsim.errors import CatalogueError, UsageError, one_line

PROVENANCE_KEY = b"gearsim.study.provenance"
PLANE_KEY = b"gearsim.plane"
TILES_KEY = b"gearsim.study.tiles"


def _tmp_name(path: Path) -> Path:
    return path.with_name(f".{path.name}.tmp-{os.getpid()}")


def _prepare_dir(out: Path, need: int = 0) -> None:
    """Create ``out``'s directory, clear dead writers' temporary files and check that a file
    can be written there with ``need`` bytes free (:func:`gearsim.study.preflight.check_output`),
    or one line."""
    from gearsim.study.preflight import check_output

    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        _remove_stale_tmp(out)
    except OSError as exc:
        raise CatalogueError(f"cannot write {out} ({_fault(exc)})") from None
    try:
        check_output(out, need=need, what="output")
    except UsageError as exc:
        raise CatalogueError(str(exc)) from None


def _size(paths: Iterable[str | Path]) -> int:
    """Bytes of the files ``paths`` (missing ones count 0): the estimate of an output's size."""
    return sum(Path(p).stat().st_size for p in paths if Path(p).is_file())


def _remove_stale_tmp(path: Path) -> None:
    """Delete temporary files of ``path`` left by writers that were killed (their pid is gone)."""
    for f in path.parent.glob(f".{path.name}.tmp-*"):
        # .NAME.tmp-PID, and SQLite's .NAME.tmp-PID-journal / -wal / -shm beside it
        pid = f.name[len(path.name) + 6 :].split("-", 1)[0]
        if not pid.isdigit() or int(pid) == os.getpid():
            continue
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            f.unlink(missing_ok=True)
        except PermissionError:  # alive, another user's
            pass


def write_parquet(df: pd.DataFrame, path: str | Path, metadata: Mapping[bytes, Any]) -> Path:
    """Write ``df`` with JSON-encoded key-value ``metadata`` atomically (temp name + rename)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    table = pa.Table.from_pandas(df, preserve_index=False)
    meta = dict(table.schema.metadata or {})
    for k, v in metadata.items():
        meta[k] = v if isinstance(v, bytes) else json.dumps(v, default=_json_default).encode()
    table = table.replace_schema_metadata(meta)
    tmp = _tmp_name(path)
    try:
        pq.write_table(table, tmp)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


def read_metadata(path: str | Path, key: bytes = PROVENANCE_KEY) -> Any:
    """A JSON value from the Parquet key-value metadata (``None`` when absent)."""
    import pyarrow.parquet as pq

    meta = pq.read_schema(path).metadata or {}
    raw = meta.get(key)
    return None if raw is None else json.loads(raw)


def _json_default(o: Any) -> Any:
    try:
        return float(o)
    except (TypeError, ValueError):
        return str(o)


def combine_tiles(paths: Iterable[str | Path], out: str | Path, plane_record: Mapping) -> Path:
    """Check a plane's tile files and stream them into ``cells.parquet`` (sorted by j, i).

    Every tile must carry the plane's configuration hash and code version and as many cells as
    its provenance recorded; together the tiles must cover each cell ``(i, j)`` of the grid
    exactly once (:mod:`gearsim.study.integrity`). Otherwise :class:`CatalogueError` names the tile
    and nothing is written. One tile is in memory at a time.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    from gearsim.study.integrity import Coverage, tile_info

    infos = [tile_info(p, plane_record, PROVENANCE_KEY) for p in paths]
    if not infos:
        raise CatalogueError(f"plane {plane_record['name']!r}: no tiles given")
    infos.sort(key=lambda t: (t.first_row, str(t.path)))
    try:
        schema = pa.unify_schemas([t.schema for t in infos], promote_options="permissive")
    except (pa.ArrowInvalid, pa.ArrowTypeError) as exc:
        raise CatalogueError(
            f"plane {plane_record['name']!r}: tiles with incompatible columns ({one_line(exc)})"
        ) from None
    provs = [{**t.provenance, "file": str(t.path)} for t in infos]
    meta = {k: v for k, v in (schema.metadata or {}).items() if k == b"pandas"}
    meta[PLANE_KEY] = json.dumps(dict(plane_record), default=_json_default).encode()
    meta[TILES_KEY] = json.dumps(provs, default=_json_default).encode()
    schema = schema.with_metadata(meta)
    coverage = Coverage(plane_record)
    out = Path(out)
    _prepare_dir(out, need=_size(t.path for t in infos))
    tmp = _tmp_name(out)
    try:
        with pq.ParquetWriter(tmp, schema) as writer:
            for t in infos:
                try:
                    table = pq.read_table(t.path)
                except Exception as exc:  # damaged pages behind a valid footer
                    raise CatalogueError(
                        f"tile {t.path}: not a readable Parquet file ({one_line(exc)})"
                    ) from None
                missing = [c for c in ("i", "j", "x", "y") if c not in table.column_names]
                if missing:
                    raise CatalogueError(f"tile {t.path}: no column {missing[0]!r}")
                table = table.sort_by([("j", "ascending"), ("i", "ascending")])
                coverage.add(
                    table["i"].to_numpy(),
                    table["j"].to_numpy(),
                    table["x"].to_numpy(),
                    table["y"].to_numpy(),
                    f"tile {t.path}",
                )
                cols = []
                for field in schema:
                    if field.name in table.column_names:
                        cols.append(table[field.name].cast(field.type))
                    else:
                        cols.append(pa.nulls(len(table), field.type))
                writer.write_table(pa.Table.from_arrays(cols, schema=schema))
        coverage.finish(f"plane {plane_record['name']!r}")
        os.replace(tmp, out)
    except OSError as exc:  # full disk, vanished directory: one line, the old file stays
        raise CatalogueError(f"cannot write {out} ({_fault(exc)})") from None
    finally:
        if tmp.exists():
            tmp.unlink()
    return out


def _fault(exc: BaseException) -> str:
    """The cause of a write fault in a few words: SQLite's own message without SQLAlchemy's
    statement and link, an OSError's cause without its errno."""
    orig = getattr(exc, "orig", None)
    if isinstance(orig, BaseException):
        exc = orig
    if isinstance(exc, OSError):
        from gearsim.study.preflight import os_cause

        return os_cause(exc)
    return one_line(exc)


def now_iso() -> str:
    """:func:`gearsim.study.provenance.now_iso` (the one clock of the records)."""
    from gearsim.study.provenance import now_iso as now

    return now()


def read_partial(path: str | Path, inputs: str) -> tuple[pd.DataFrame | None, str]:
    """The rows of the partial table ``path`` when it was computed from the same ``inputs``
    (the key under ``inputs`` in its provenance), else ``None`` and why it is not resumed
    (``""``: there is none)."""
    path = Path(path)
    if not path.is_file():
        return None, ""
    try:
        meta = read_metadata(path) or {}
        if meta.get("inputs") == inputs:
            return pd.read_parquet(path), ""
    except Exception as exc:  # noqa: BLE001 - a damaged partial table is recomputed
        return None, f"{path} unreadable ({type(exc).__name__}): starting afresh"
    return None, f"{path} holds cells of other inputs: starting afresh"
