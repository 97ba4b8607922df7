"""A figures run: the tables named on the command line read into a :class:`Context`, and the
paper's figures, the plane maps and the sweep diagrams drawn and written, each beside its JSON
record (``figNN.json``, ``planes/<plane>-<kind>.json``, ``sweeps/<sweep>.json``).

:func:`draw` is the whole run of ``gearsim figures``; ``say`` receives one line per file
written."""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from gearsim.errors import UsageError
from gearsim.presentation.figures import data, maps, registry, style
from gearsim.presentation.figures.context import Context
from gearsim.presentation.figures.index import write_index
from gearsim.study.config import Study
from gearsim.study.figure_tables import FIGURE_DATA_KEY
from gearsim.study.preflight import check_folder, write_text_atomic

Say = Callable[[str], None]


@dataclass(frozen=True)
class Tables:
    """The tables given to a figures run, ``{config name: path}`` per kind."""

    sweeps: Mapping[str, str] = field(default_factory=dict)
    planes: Mapping[str, str] = field(default_factory=dict)
    points: Mapping[str, str] = field(default_factory=dict)
    figure_data: Mapping[str, str] = field(default_factory=dict)
    orbits: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class Request:
    """What to draw: paper figures ``numbers`` (``every``: each whose tables are given), the
    maps of every plane (``map_kinds``: these only), the sweeps' diagrams, the index."""

    outdir: Path
    numbers: Sequence[int] = ()
    every: bool = False
    maps: bool = False
    map_kinds: Sequence[str] | None = None
    sweep_diagrams: bool = False
    index: bool = False


def check_request(req: Request, tables: Tables) -> None:
    """One line for a request that cannot run, before anything is read or drawn."""
    if req.map_kinds and not req.maps:
        raise UsageError("--map KIND needs --maps")
    if not (req.numbers or req.every or req.index or req.maps or req.sweep_diagrams):
        raise UsageError("nothing to do: give --fig N, --all, --maps, --sweep-diagrams or "
                         "--index")
    if req.sweep_diagrams and not tables.sweeps:
        raise UsageError("--sweep-diagrams needs at least one --sweep NAME=PATH")
    if req.maps and not tables.planes:
        raise UsageError("--maps needs at least one --plane NAME=PATH")
    registry.figures()  # extensions register their maps on import
    for kind in req.map_kinds or ():
        if kind not in maps.PLANE_MAPS:
            raise UsageError(f"unknown plane map '{kind}'; allowed: {', '.join(maps.PLANE_MAPS)}")


def planned(req: Request, tables: Tables) -> list[Path]:
    """The files a request writes, known before anything is read or drawn: each figure's PNG,
    PDF and JSON record (with the members of its group; with ``every``, the figures whose
    tables are given), each map, each sweep diagram and the index."""
    table = registry.figures()
    if req.every:
        numbers = [n for n in table if all(
            name in getattr(tables, kind) for kind, names in table[n].inputs.tables().items()
            for name in names)]
    else:
        numbers = list(dict.fromkeys(req.numbers))
    stems = [req.outdir / f"fig{m:02d}" for n in numbers
             for m in (table[n].members if n in table else (n,))]
    if req.maps:
        stems += [req.outdir / "planes" / f"{plane}-{kind}" for plane in tables.planes
                  for kind in (req.map_kinds or maps.PLANE_MAPS)]
    if req.sweep_diagrams:
        stems += [req.outdir / "sweeps" / name for name in tables.sweeps]
    out = [stem.with_suffix(ext) for stem in stems for ext in (".png", ".pdf", ".json")]
    if req.index:
        out.append(req.outdir / "README.md")
    return list(dict.fromkeys(out))


def draw(study: Study | None, tables: Tables, req: Request, say: Say) -> None:
    """The whole run: checked (:func:`check_request`, the output folder writable), then the
    sweep diagrams, the maps, the figures and the index, in that order."""
    import matplotlib

    matplotlib.use("Agg")
    check_request(req, tables)
    check_folder(req.outdir, what="--outdir")  # writable, with room, before any drawing
    if req.sweep_diagrams:
        write_sweep_diagrams(study, tables.sweeps, req.outdir, say)
    numbers = list(registry.figures()) if req.every else list(dict.fromkeys(req.numbers))
    if numbers or req.maps:
        ctx = read_context(study, tables)
        if req.maps:
            write_maps(study, ctx, req.outdir, req.map_kinds, say)
        write_figures(numbers, ctx, req.outdir, say, every=req.every)
    if req.index:
        say(f"wrote {write_index(req.outdir)}")


def read_table(path: str, what: str):
    """A table from ``path``, or one line naming it when it is not a readable Parquet file."""
    try:
        return data.read_table(path)
    except OSError:
        raise  # full disk, permission: the CLI names the file and the cause
    except Exception as exc:  # pyarrow: ArrowInvalid, ArrowTypeError, ... for a foreign file
        cause = " ".join(str(exc).split()) or type(exc).__name__
        raise UsageError(f"{what}: {path} is not a readable Parquet table ({cause})") from None


def read_context(study: Study, tables: Tables) -> Context:
    """The figures' :class:`Context`: the study's parameters, settings, point and sweep
    specifications, and every given table read."""
    from gearsim.results.parquet import read_metadata

    config = study.config
    ctx = Context(
        params=study.parameters().model,
        settings=study.settings,
        point_specs=dict(config.get("points") or {}),
        sweep_fixed={k: dict(v.get("fixed") or {}) for k, v in
                     (config.get("sweeps") or {}).items()},
    )
    for name, path in tables.sweeps.items():
        ctx.sweeps[name] = read_table(path, f"--sweep {name}")
    for name, path in tables.planes.items():
        ctx.planes[name] = read_table(path, f"--plane {name}")
    for name, path in tables.points.items():
        ctx.points[name] = read_table(path, f"--points {name}")
    for name, path in tables.figure_data.items():
        df = read_table(path, f"--figure-data {name}")
        df.attrs["figure_data"] = read_metadata(path, FIGURE_DATA_KEY) or {}
        ctx.figure_data[name] = df
    for name, path in tables.orbits.items():
        ctx.orbits[name] = read_table(path, f"--orbits {name}")
        pts = Path(path).with_name(Path(path).stem + "_points.parquet")
        if not name.endswith("_curves") and pts.is_file():
            ctx.orbits[f"{name}_points"] = data.read_table(pts)
        # a plane's codimension-2 points, written beside its curves (docs/orbits.md)
        c2 = Path(path).with_name(name.removesuffix("_curves") + "_codim2.parquet")
        if name.endswith("_curves") and c2.is_file():
            ctx.orbits[name.removesuffix("_curves") + "_codim2"] = data.read_table(c2)
    return ctx


def write_record(path: Path, rec: dict) -> None:
    write_text_atomic(path, json.dumps(rec, indent=1, ensure_ascii=False) + "\n")


def physical_units(study: Study) -> Callable[..., dict]:
    """``(x, y) -> {parameter: {name, unit, k}}`` of the study's gear file (empty without)."""
    from gearsim.physical.units import config_gear, physical_factors

    gear = config_gear(study.config, study.root)
    return lambda *names: physical_factors(gear, names)


def _save(fig, stem: Path) -> list[str]:
    import matplotlib.pyplot as plt

    stem.parent.mkdir(parents=True, exist_ok=True)
    files = [str(f) for f in style.save_figure(fig, stem)]
    plt.close(fig)
    return files


def write_sweep_diagrams(study: Study, sweeps: Mapping[str, str], outdir: Path, say: Say) -> None:
    """``OUTDIR/sweeps/<sweep>.{png,pdf,json}`` for every sweep, in the sweep's own units."""
    from gearsim.presentation.figures.sweeps import figure_sweep_diagram, sweep_spec_of

    physical = physical_units(study)
    for name, path in sweeps.items():
        spec = sweep_spec_of(path, study.config, name)
        df = data.read_table(path)
        param = str(df["parameter"].iloc[0]) if len(df) else ""
        fig, caption = figure_sweep_diagram(df, name=name, spec=spec,
                                            physical=physical(param).get(param))
        stem = outdir / "sweeps" / name
        files = _save(fig, stem)
        write_record(stem.with_suffix(".json"), {
            "sweep": name, "title": f"Sweep {name}", "files": files, "caption": caption,
            "inputs": [f"sweeps/{name}"], "spec": spec})
        say(f"sweep {name}: wrote {', '.join(files)}")


def write_maps(study: Study, ctx: Context, outdir: Path, kinds: Sequence[str] | None,
               say: Say) -> None:
    """``OUTDIR/planes/<plane>-<kind>.{png,pdf,json}``: every registered map (or ``kinds``)
    of every plane of ``ctx``, whatever its two axes (also in the gear file's units)."""
    physical = physical_units(study)
    for plane, df in ctx.planes.items():
        xname, yname = data.plane_axes(df)
        for spec, fig, caption, notes in maps.build_maps(plane, df, kinds):
            units = style.physical_axes(fig, physical(xname, yname), xname, yname)
            if units:
                notes = [*notes, "axes also in " + ", ".join(units) + " (the gear file)"]
            stem = outdir / "planes" / f"{plane}-{spec.kind}"
            files = _save(fig, stem)
            write_record(stem.with_suffix(".json"), {
                "plane": plane, "map": spec.kind, "title": spec.title, "axes": [xname, yname],
                "files": files, "caption": caption, "notes": notes,
                "inputs": [f"{plane}/cells"], "parameters": ctx.params.to_dict(),
                "integration": ctx.settings.to_dict()})
            say(f"plane {plane} map {spec.kind}: wrote {', '.join(files)}")


def bind_single_plane(numbers: Sequence[int], ctx: Context) -> dict[str, str]:
    """A figure of one plane (e.g. Fig 7 of ``wb``) given exactly one plane of another name
    draws that one: returns ``{paper's plane: given plane}``."""
    table = registry.figures()
    bound: dict[str, str] = {}
    if len(ctx.planes) != 1:
        return bound
    (given, df), = ctx.planes.items()
    for n in numbers:
        wanted = table[n].inputs.planes if n in table else ()
        if len(wanted) == 1 and wanted[0] not in ctx.planes:
            ctx.planes[wanted[0]] = df
            bound[wanted[0]] = given
    return bound


def write_figures(numbers: Sequence[int], ctx: Context, outdir: Path, say: Say, *,
                  every: bool = False) -> None:
    """``OUTDIR/figNN.{png,pdf,json}`` of each figure of ``numbers``; with ``every``, only
    those whose tables ``ctx`` holds."""
    table = registry.figures()
    if every:
        numbers = [n for n in numbers if all(
            name in getattr(ctx, kind) for kind, names in table[n].inputs.tables().items()
            for name in names)]
    bound = {} if every else bind_single_plane(numbers, ctx)
    for b in registry.build(numbers, ctx):
        for paper, given in bound.items():
            if f"{paper}/cells" in b.inputs:
                b.inputs = [f"{given}/cells" if i == f"{paper}/cells" else i for i in b.inputs]
                b.differences.insert(0, f"Drawn for the plane '{given}' (the paper's figure "
                                     f"shows the plane '{paper}').")
                say(f"figure {b.number}: drawn for plane '{given}'")
        files = _save(b.figure, outdir / f"fig{b.number:02d}")
        write_record(outdir / f"fig{b.number:02d}.json", registry.record(b, files, ctx))
        say(f"figure {b.number}: wrote {', '.join(files)}")
