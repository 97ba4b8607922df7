"""SQL views that speak the study's names: one per plane and one per sweep.

A plane's view is named after the plane and has its axis names as columns, so a reader writes
``select w, b, label from wb where w between 1.0 and 1.01`` instead of joining ``cells`` to
``planes`` and filtering on ``x`` / ``y``. With a gear file (docs/units.md) an axis with a
physical meaning (w, Fm, Fe, b) adds its physical column (``speed_rpm``, ``torque_Nm``, ...,
from the plane record's ``physical`` factors or an axis given in those units). A sweep's view is
named after the sweep, with the swept parameter's name for ``value``. Every view
column gets a row in ``column_dictionary``. A name taken by a table (or by a plane, for a
sweep) gets the prefix ``plane_`` / ``sweep_``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from gearsim.results.columns import CATALOGUE, PARAMETERS, RESULT, VIEWS

#: columns of ``cells`` / ``sweep_points`` a view leaves out (row ids and foreign keys) or renames
_CELL_HIDDEN = ("id", "plane_id", "run_id", "i", "j", "x", "y")
_POINT_HIDDEN = ("id", "sweep_id", "k", "value")


def _quote(name: str) -> str:
    return '"' + str(name).replace('"', '""') + '"'


def _physical(spec: Any) -> tuple[str, str, float] | None:
    """``(name, unit, factor)`` of an axis given in physical units (``value_phys = factor *
    value``), read off the axis record :func:`gearsim.physical.units.dimensionless_axis` keeps."""
    if not isinstance(spec, Mapping) or not isinstance(spec.get("physical"), Mapping):
        return None
    phys = spec["physical"]
    ref = "max" if float(spec.get("max", 0.0) or 0.0) != 0.0 else "min"
    try:
        factor = float(phys[ref]) / float(spec[ref])
    except (KeyError, TypeError, ValueError, ZeroDivisionError):
        return None
    return str(phys["name"]), str(phys.get("unit", "")), factor


def _by_name(records: Iterable[Any], axes) -> dict[str, Any]:
    """``name -> axes`` of the build's plane records / sweep provenance records."""
    out: dict[str, Any] = {}
    for rec in records:
        if isinstance(rec, Mapping) and rec.get("name"):
            out[str(rec["name"])] = axes(rec)
    return out


def _columns(con, table: str) -> list[str]:
    return [r[1] for r in con.exec_driver_sql(f"PRAGMA table_info({_quote(table)})")]


def _doc(table: str, column: str) -> tuple[str, str]:
    if column in PARAMETERS:
        return PARAMETERS[column]
    if column in RESULT:
        return RESULT[column]
    return CATALOGUE.get((table, column), ("", column))


def create_views(con, plane_records: Iterable[Any] = (),
                 sweep_records: Iterable[Any] = ()) -> list[tuple[str, str, str]]:
    """Create the view of every plane and sweep in the catalogue open on ``con`` (a SQLAlchemy
    connection inside the build) and document their columns. ``plane_records`` /
    ``sweep_records``: the plane records and sweep provenance records of the build's inputs
    (their axes tell which were given in physical units). Returns ``(view, kind, name)``."""
    from gearsim.physical.units import COLUMNS as PHYSICAL

    taken = {r[0] for r in con.exec_driver_sql(
        "SELECT name FROM sqlite_master WHERE type IN ('table', 'view')")}
    made: list[tuple[str, str, str]] = []
    docs: list[tuple[str, str, str, str]] = []

    def name_for(name: str, prefix: str) -> str:
        view = name if name not in taken else f"{prefix}_{name}"
        while view in taken:
            view = f"{prefix}_{view}"
        taken.add(view)
        return view

    cell_cols = _columns(con, "cells")
    plane_axes = _by_name(plane_records, lambda r: {"x": r.get("x"), "y": r.get("y"),
                                                    "physical": r.get("physical")})
    for pid, pname, x_name, y_name in con.exec_driver_sql(
            "SELECT id, name, x_name, y_name FROM planes ORDER BY id").fetchall():
        view = name_for(pname, "plane")
        select = ["c.i", "c.j", f"c.x AS {_quote(x_name)}", f"c.y AS {_quote(y_name)}"]
        cols = ["i", "j", x_name, y_name]
        gear_axes = (plane_axes.get(pname) or {}).get("physical") or {}
        for axis, col, param in (("x", "c.x", x_name), ("y", "c.y", y_name)):
            phys = _physical((plane_axes.get(pname) or {}).get(axis))
            if phys is None and isinstance(gear_axes.get(param), Mapping):
                g = gear_axes[param]
                phys = (str(g["name"]), str(g["unit"]), float(g["k"]))
            _add_physical(select, cols, col, phys)
        _create_view(con, view, select, cols, (cell_cols, _CELL_HIDDEN), "cells c",
                     f"c.plane_id = {int(pid)}")
        made.append((view, "plane", pname))
        docs.append((view, "*", "", VIEWS["plane"].format(name=pname, x=x_name, y=y_name)))
        docs += [(view, c, *_physical_doc(c, PHYSICAL, "cells")) for c in cols]

    point_cols = _columns(con, "sweep_points")
    sweep_axes = _by_name(sweep_records, lambda r: (r.get("subtree") or {}).get("sweep"))
    for sid, sname, param in con.exec_driver_sql(
            "SELECT id, name, parameter FROM sweeps ORDER BY id").fetchall():
        view = name_for(sname, "sweep")
        select = ["s.k", f"s.value AS {_quote(param)}"]
        cols = ["k", param]
        _add_physical(select, cols, "s.value", _physical(sweep_axes.get(sname)))
        _create_view(con, view, select, cols, (point_cols, _POINT_HIDDEN), "sweep_points s",
                     f"s.sweep_id = {int(sid)}")
        made.append((view, "sweep", sname))
        docs.append((view, "*", "", VIEWS["sweep"].format(name=sname, parameter=param)))
        docs += [(view, c, *_physical_doc(c, PHYSICAL, "sweep_points")) for c in cols]

    if docs:
        con.exec_driver_sql(
            "INSERT INTO column_dictionary (table_name, column_name, unit, meaning) "
            "VALUES " + ", ".join("(?, ?, ?, ?)" for _ in docs),
            tuple(v for row in docs for v in row))
    return made


def _add_physical(select: list[str], cols: list[str], col: str, phys) -> None:
    """An axis column ``col`` in physical units (``phys = (name, unit, factor)``) once."""
    if phys and phys[0] not in cols:
        select.append(f"{col} * {phys[2]!r} AS {_quote(phys[0])}")
        cols.append(phys[0])


def _create_view(con, view: str, select: list[str], cols: list[str], source, table: str,
                 where: str) -> None:
    """The view ``view``: the ``select`` columns, then every column of the table's ``source =
    (columns, hidden)`` neither hidden nor selected yet (``cols`` grows by them)."""
    table_cols, hidden = source
    alias = table.split()[-1]
    rest = [c for c in table_cols if c not in hidden and c not in cols]
    select += [f"{alias}.{_quote(c)}" for c in rest]
    cols += rest
    con.exec_driver_sql(f"CREATE VIEW {_quote(view)} AS SELECT {', '.join(select)} "
                        f"FROM {table} WHERE {where}")


def _physical_doc(column: str, physical: Mapping[str, tuple[str, str]], table: str
                  ) -> tuple[str, str]:
    if column in physical:
        return physical[column]
    return _doc(table, column)
