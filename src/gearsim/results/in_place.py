"""The results in place: which configuration made a results folder, and the check that a run of
another configuration does not replace them unasked.

A run records, in ``results/.configuration.json``, the config files it was started with and a
hash of what its outputs depend on (every plane's, sweep's and point set's subtree, the audit
and the orbits). A later run compares itself with that record before any job starts:

* the same content (whatever files gave it, e.g. a cluster file merged over the study): nothing
  is replaced, it runs;
* the same config files with a different content: the user edited the study and asked for it
  (editing one plane re-runs only that plane), it runs;
* other config files and a different content (a file of one's own without ``study:`` or
  ``folder:`` over a finished default run): it stops in one line naming both grids and the ways
  on (a ``folder:`` or ``study:`` name, which runs in ``studies/<name>/``, or
  ``--config replace_results=true``). The fast look, ``config/quick.yaml``, and the GPU run,
  ``config/gpu.yaml``, have their folders. The line names, for each plane or sweep, the
  grids and the settings that differ (``plane wb: multistability.every 3 -> 1``), read from the
  settings each item's hash covers, which the record keeps.

Results written before such records existed are compared by their grids, read from the
Parquet files' metadata (planes and sweeps).

A tile in place that no run of the folder computed (a tile of another configuration written by a
command by hand) is found before any job, and so before Snakemake removes what depends on it
(:func:`check_tiles_in_place`): one line naming the tile, the settings it differs in and the
command that repairs it. The record keeps every configuration hash a run of the folder had, by
plane, so a run interrupted after an edit of the study leaves tiles that still pass (Snakemake
recomputes them).

A command run by hand never replaces a file of such a folder unasked either
(:func:`check_hand_outputs`): where one of the files it would write exists in a results folder
that a run recorded, it stops before any work in one line naming the file, the option that
writes elsewhere and the one that replaces it. The workflow's own jobs pass: Snakemake removes
a job's declared outputs before the job starts, so the files they write do not exist yet.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from gearsim.errors import UsageError
from gearsim.study.config import Study
from gearsim.study.provenance import config_hash, plane_subtree, point_subtree, sweep_subtree

__all__ = [
    "RECORD", "REPLACE_KEY", "check_hand_outputs", "check_in_place", "check_tiles_in_place",
    "partial_kept", "run_record", "workflow_folder", "write_record",
]

#: The record of the configuration that made a results folder (relative to the run's directory).
RECORD = Path("results/.configuration.json")
#: The ``--config`` key with which a run replaces results of another configuration.
REPLACE_KEY = "replace_results"


def _grid(spec: Mapping) -> str:
    """A plane's or sweep's grid in a few words: ``w 0.1..2.5 x b 0..1: 40 x 40``."""
    if "x" in spec:
        x, y = spec["x"], spec["y"]
        return (f"{x['name']} {x['min']:g}..{x['max']:g} x {y['name']} {y['min']:g}..{y['max']:g}"
                f": {x['n']} x {y['n']}")
    return f"{spec['name']} {spec['min']:g}..{spec['max']:g}: {spec['n']} points"


def _file_name(path: str | Path, root: Path) -> str:
    p = Path(path).resolve()
    try:
        return p.relative_to(root.resolve()).as_posix()
    except ValueError:
        return p.as_posix()


def flat_settings(tree: Any, prefix: str = "") -> dict[str, Any]:
    """A nested mapping as ``{"a.b.c": value}`` (lists and scalars are values; an empty
    mapping adds no key)."""
    if not isinstance(tree, Mapping):
        return {prefix or "value": tree}
    out: dict[str, Any] = {}
    for key, value in tree.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, Mapping):
            out.update(flat_settings(value, name))  # an empty mapping sets nothing
        else:
            out[name] = value
    return out


def run_record(study: Study, configfiles: Iterable[str | Path]) -> dict[str, Any]:
    """What a run of ``study`` (started with ``configfiles``) records about itself: the files,
    the hash of every output's subtree and that subtree's settings, and the grid of every plane
    and sweep."""
    cfg = study.config
    trees: dict[str, Any] = {}
    grids: dict[str, str] = {}
    for p in cfg["planes"]:
        trees[f"plane {p}"] = plane_subtree(study, p)
        grids[f"plane {p}"] = _grid(cfg["planes"][p])
    for s in cfg["sweeps"]:
        trees[f"sweep {s}"] = sweep_subtree(study, s)
        grids[f"sweep {s}"] = _grid(cfg["sweeps"][s])
    for f in cfg["points"]:
        trees[f"points {f}"] = point_subtree(study, f)
    trees["audit"] = cfg.get("audit")
    trees["orbits"] = cfg.get("orbits")
    items = {name: config_hash(tree) for name, tree in trees.items()}
    settings = {name: flat_settings(json.loads(json.dumps(tree, default=str)))
                for name, tree in trees.items()}
    return {"files": [_file_name(f, study.root) for f in configfiles],
            "content": config_hash(items), "items": items, "grids": grids,
            "settings": settings}


def setting_changes(before: Mapping[str, Any], after: Mapping[str, Any], most: int = 3) -> str:
    """``multistability.every 3 -> 1, tile_rows 16 -> 400`` (the first ``most`` of the settings
    that differ, in order, then how many more), ``''`` when none differs."""
    names = [k for k in after if before.get(k, _ABSENT) != after[k]]
    names += [k for k in before if k not in after]
    parts = [f"{_short(k)} {_value(before.get(k, _ABSENT))} -> {_value(after.get(k, _ABSENT))}"
             for k in names[:most]]
    more = len(names) - most
    return ", ".join(parts) + (f" and {more} more" if more > 0 else "")


_ABSENT = object()


def _short(name: str) -> str:
    """A setting's name without the item's own top key (``plane.x.n`` -> ``x.n``)."""
    head, _, rest = name.partition(".")
    return rest if rest and head in ("plane", "sweep", "points") else name


def _value(v: Any) -> str:
    if v is _ABSENT:
        return "(unset)"
    return f"{v:g}" if isinstance(v, float) else json.dumps(v) if not isinstance(v, str) else v


def _legacy_grids(folder: Path) -> dict[str, str]:
    """Grids of the planes and sweeps in ``folder`` (a results folder without a record), from the
    Parquet metadata the pipeline writes (empty when there are none)."""
    planes = sorted(folder.glob("*/cells.parquet"))
    sweeps = sorted((folder / "sweeps").glob("*.parquet"))
    if not planes and not sweeps:
        return {}
    from gearsim.results.parquet import PLANE_KEY, read_metadata

    out = {}
    for f in planes:
        rec = read_metadata(f, PLANE_KEY)
        if rec and "x" in rec:
            out[f"plane {f.parent.name}"] = _grid(rec)
    for f in sweeps:
        rec = read_metadata(f) or {}
        spec = (rec.get("subtree") or {}).get("sweep")
        if spec and "name" in spec:
            out[f"sweep {f.stem}"] = _grid(spec)
    return out


def _differences(before: Mapping[str, str], after: Mapping[str, str],
                 changed: Iterable[str] = (), settings: Mapping[str, str] | None = None
                 ) -> list[str]:
    """``name: grid in place -> this run's grid`` for each item whose grid differs,
    ``name: grid (settings that differ)`` for each other item whose content differs
    (``settings``: :func:`setting_changes` by item, where the record in place has them)."""
    out = []
    for name in sorted(set(before) & set(after)):
        if before[name] != after[name]:
            out.append(f"{name}: {before[name]} -> {after[name]}")
    for name in sorted(set(changed) - {o.split(':')[0] for o in out}):
        grid = after.get(name, "")
        what = (settings or {}).get(name) or "other settings"
        out.append(f"{name}: {grid}{' ' if grid else ''}({what})")
    added = sorted(set(after) - set(before))
    if added:
        out.append("added " + ", ".join(added))
    return out


def _summary(lines: list[str], most: int = 3) -> str:
    more = len(lines) - most
    return "; ".join(lines[:most]) + (f"; and {more} more" if more > 0 else "")


def check_in_place(record: Mapping[str, Any], folder: str | Path = "results", *,
                   replace: bool = False) -> None:
    """Raise :class:`UsageError` (one line) when the run described by ``record``
    (:func:`run_record`) would replace results in ``folder`` that another configuration made
    and the run did not ask to replace (``replace``)."""
    folder = Path(folder)
    if replace or not folder.is_dir():
        return
    path = folder / RECORD.name
    files = " + ".join(record["files"])
    ways = ("add `folder: NAME` to its file to run it into studies/NAME/ beside them (or "
            "`study: NAME` to run only its own planes, sweeps and points there), or add "
            f"--config {REPLACE_KEY}=true to replace them")
    if path.is_file():
        try:
            before = json.loads(path.read_text())
            before_files, before_content = before["files"], before["content"]
        except (OSError, ValueError, KeyError, TypeError):
            return  # an unreadable record protects nothing; the run rewrites it
        if before_content == record["content"] or before_files == record["files"]:
            return
        changed = [k for k, v in record["items"].items()
                   if k in before.get("items", {}) and before["items"][k] != v]
        old = before.get("settings") or {}
        what = {k: setting_changes(old[k], record["settings"][k]) for k in changed
                if k in old and k in record.get("settings", {})}
        diff = _differences(before.get("grids", {}), record["grids"], changed, what)
        raise UsageError(
            f"{folder}/ holds the results of {' + '.join(before_files)}; this run of {files} "
            f"would replace them ({_summary(diff) or 'other settings'}): {ways}")
    before_grids = _legacy_grids(folder)
    diff = [d for d in _differences(before_grids, record["grids"]) if "->" in d]
    if diff:
        raise UsageError(f"{folder}/ holds results of other grids; this run of {files} would "
                         f"replace them ({_summary(diff)}): {ways}")


def _read_record(folder: str | Path) -> dict[str, Any] | None:
    try:
        rec = json.loads((Path(folder) / RECORD.name).read_text())
    except (OSError, ValueError):
        return None
    return rec if isinstance(rec, dict) else None


def _history(record: Mapping[str, Any]) -> dict[str, list[str]]:
    """Every hash a run of the folder had, by item (its ``items`` included)."""
    out = {k: set(v) for k, v in (record.get("history") or {}).items() if isinstance(v, list)}
    for k, v in (record.get("items") or {}).items():
        out.setdefault(k, set()).add(v)
    return {k: sorted(v) for k, v in out.items()}


def write_record(record: Mapping[str, Any], folder: str | Path = "results") -> Path:
    """Record ``record`` as the configuration of ``folder`` (atomically), with the hashes of
    every earlier run of the folder (``history``)."""
    path = Path(folder) / RECORD.name
    before = _read_record(folder)
    history = _history({"history": _history(before), "items": record["items"]} if before
                       else record)
    record = {**record, "history": history}
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
    os.replace(tmp, path)
    return path


def workflow_folder(path: str | Path) -> Path | None:
    """The results folder a run recorded (it holds :data:`RECORD`'s file) that the existing file
    ``path`` lies in; None for a file outside one, or no file."""
    p = Path(path)
    if not p.is_file():
        return None
    for folder in p.resolve().parents:
        if (folder / RECORD.name).is_file():
            return folder
    return None


def check_hand_outputs(paths: Iterable[str | Path], *, replace: bool, elsewhere: str,
                       allow: str = "--replace") -> None:
    """Raise :class:`UsageError` (one line) when a command about to write ``paths`` would replace
    a file of a results folder that a run made (:func:`workflow_folder`) and was not asked to
    (``replace``). ``elsewhere``: the option that writes elsewhere (``--out PATH``), ``allow``:
    the one that replaces."""
    if replace:
        return
    made = [Path(p) for p in paths if workflow_folder(p) is not None]
    if not made:
        return
    first = made[0]
    more = f" (and {len(made) - 1} more of its files)" if len(made) > 1 else ""
    raise UsageError(
        f"{first}{more}: made by the workflow (a file of the results of a run in "
        f"{_shown(workflow_folder(first))}/); nothing was written: give {elsewhere} to write "
        f"elsewhere, or {allow} to replace it")


def _shown(folder: Path) -> str:
    """A folder as the user would type it: relative to the working directory when inside it."""
    try:
        return folder.relative_to(Path.cwd().resolve()).as_posix()
    except ValueError:
        return folder.as_posix()


def check_tiles_in_place(record: Mapping[str, Any], folder: str | Path = "results") -> None:
    """Raise :class:`UsageError` (one line) for a tile in ``folder`` that no run of the folder
    computed: its configuration hash is neither this run's (``record``) nor one the folder's
    record has seen (a tile written by hand under another configuration). Nothing is removed;
    the line names the command that repairs it. Without a record in place, nothing is checked."""
    from gearsim.results.parquet import read_metadata

    folder = Path(folder)
    before = _read_record(folder)
    if before is None:
        return
    seen = _history(before)
    for name, current in record["items"].items():
        kind, _, plane = name.partition(" ")
        if kind != "plane":
            continue
        ok = set(seen.get(name, ())) | {current}
        for tile in sorted((folder / plane / "tiles").glob("*.parquet")):
            try:
                prov = read_metadata(tile) or {}
            except Exception:  # noqa: BLE001 - an unreadable tile is the plane job's to report
                continue
            got = prov.get("config_hash")
            if not got or got in ok:
                continue
            theirs = flat_settings(json.loads(json.dumps(prov.get("subtree") or {}, default=str)))
            differ = setting_changes(theirs, record.get("settings", {}).get(name, {}))
            raise UsageError(
                f"{_shown(tile.resolve())}: a tile of another configuration than this study's "
                f"runs (the tile's -> this run's: {differ or 'configuration hash ' + got}; "
                "written by a command by hand?); "
                f"nothing was removed: repair it with `rm {_shown(tile.resolve())}` and run "
                "again (the workflow recomputes it)")


def partial_kept(partial: str | Path, what: str = "cells") -> str:
    """What an interrupted run that checkpoints into ``partial`` keeps, in words: ``the 120
    cells refined so far are kept in X.partial`` (its rows, from the Parquet footer), or that none
    was kept yet."""
    partial = Path(partial)
    try:
        import pyarrow.parquet as pq

        rows = pq.read_metadata(partial).num_rows
    except Exception:  # noqa: BLE001 - no partial table (or a damaged one): nothing kept
        return f"no {what} were kept yet (the first partial table comes after --every of them)"
    return f"the {rows} {what} so far are kept in {partial}"
