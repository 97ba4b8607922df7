"""Storage: Parquet files with provenance, and the SQLite catalogue (SQLAlchemy 2).

The names the rest of gearsim uses, from the modules that hold them:

* :mod:`gearsim.results.parquet`: tile and plane files (``write_parquet``, ``read_metadata``,
  ``combine_tiles``, the metadata keys);
* :mod:`gearsim.results.schema`: the catalogue's tables, ``SCHEMA_VERSION``, ``open_catalogue``
  (every reader's way in), ``migrate_catalogue``;
* :mod:`gearsim.results.ingest`: ``build_catalogue``;
* :mod:`gearsim.results.publish`: ``publish``, ``set_aside_damaged``, ``publish_anywhere`` and
  ``migrate_anywhere`` (a file, or a study on a database server: :mod:`gearsim.results.server`).

Files (see docs/pipeline.md)
----------------------------
``results/<plane>/tiles/<tile>.parquet``
    One row per cell of a tile; provenance under the key ``gearsim.study.provenance`` of the
    Parquet key-value metadata.
``results/<plane>/cells.parquet``
    All tiles of a plane (list columns ``poincare_x``, ``poincare_v``); metadata holds the plane
    record and the provenance of every tile.
``results/sweeps/<name>.parquet``
    One row per sweep value (the columns of :func:`gearsim.cell.sweep.orbit_diagram`).
``results/catalogue.sqlite``
    The tables of :mod:`gearsim.results.schema`; written by one rule, in one transaction, to a
    temporary file renamed into place.
"""

from __future__ import annotations

from gearsim.errors import CatalogueError
from gearsim.results import schema
from gearsim.results.ingest import build_catalogue
from gearsim.results.parquet import (
    PLANE_KEY,
    PROVENANCE_KEY,
    TILES_KEY,
    combine_tiles,
    now_iso,
    read_metadata,
    write_parquet,
)
from gearsim.results.publish import (
    migrate_anywhere,
    publish,
    publish_anywhere,
    set_aside_damaged,
)
from gearsim.results.schema import *  # noqa: F403 (the names of schema.__all__)

__all__ = [
    *schema.__all__, "CatalogueError", "PLANE_KEY", "PROVENANCE_KEY", "TILES_KEY",
    "build_catalogue", "combine_tiles", "migrate_anywhere", "now_iso", "publish",
    "publish_anywhere", "read_metadata",
    "set_aside_damaged", "write_parquet",
]
