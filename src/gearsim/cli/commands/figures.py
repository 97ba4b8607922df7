"""``gearsim figures``: draw figures of the study from the pipeline's tables.

Examples::

    gearsim figures --fig 4 --sweep standard=results/sweeps/standard.parquet
    gearsim figures --fig 7 12 13 --plane wb=results/wb/cells.parquet
    gearsim figures --fig 9 10 11 --sweep b015=results/sweeps/b015.parquet
    gearsim figures --maps --plane weps=results/weps/cells.parquet   # any axes
    gearsim figures --sweep-diagrams --sweep torque=results/sweeps/torque.parquet
    gearsim figures --index

Each figure is written as ``<outdir>/figNN.png`` (200 dpi) and ``.pdf`` plus ``figNN.json``
(captions and differences from the paper) that ``--index`` collects into ``README.md``. The
figures and what they read: :data:`gearsim.presentation.figures.registry.FIGURES`. ``--maps`` draws
every
registered plane map (pattern, DC, Kmax, ...) of each ``--plane``, whatever its two axes, as
``<outdir>/planes/<plane>-<kind>.{png,pdf,json}``. A paper figure of one plane (e.g. Fig 7)
given one ``--plane`` of another name draws that plane (the paper comparison then says "not
applicable" when the paper has no plane of those axes).
Parameters and integration settings come from the pipeline config (``--configfile``), exactly
as the simulation rules see them.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from gearsim.cli.commands._common import add_config_arguments, study_from_args
from gearsim.errors import UsageError

NAME = "figures"
HELP = "draw figures of the study (PNG + PDF + caption record) or the figure index"


def _pairs(items: list[str], flag: str) -> dict[str, str]:
    out = {}
    for item in items:
        name, sep, path = item.partition("=")
        if not sep or not name or not path:
            raise UsageError(f"{flag} expects NAME=PATH, got {item!r}")
        if not Path(path).is_file():
            raise UsageError(f"{flag} {name}: file not found: {path}")
        out[name] = path
    return out


def _read(read_table, path: str, what: str):
    """A table from ``path``, or one line naming it when it is not a readable Parquet file."""
    try:
        return read_table(path)
    except OSError:
        raise  # full disk, permission: the CLI names the file and the cause
    except Exception as exc:  # pyarrow: ArrowInvalid, ArrowTypeError, ... for a foreign file
        cause = " ".join(str(exc).split()) or type(exc).__name__
        raise UsageError(f"{what}: {path} is not a readable Parquet table ({cause})") from None


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--fig", type=int, nargs="+", action="extend", default=[], metavar="N",
                   help="figure number(s): 1-17 of the paper, higher for later analyses "
                   "(9, 10, 11 are built together)")
    p.add_argument("--all", action="store_true", help="every figure whose inputs are given")
    p.add_argument("--sweep", action="append", default=[], metavar="NAME=PATH",
                   help="a sweep table (results/sweeps/NAME.parquet), repeatable")
    p.add_argument("--plane", action="append", default=[], metavar="NAME=PATH",
                   help="a plane cells table (results/NAME/cells.parquet), repeatable")
    p.add_argument("--points", action="append", default=[], metavar="NAME=PATH",
                   help="a recorded point set (results/points/NAME.parquet), repeatable")
    p.add_argument("--figure-data", action="append", default=[], metavar="NAME=PATH",
                   help="a figure-data table (results/figure_data/NAME.parquet: the simulated "
                   "motions, attractor search or basins a figure draws), repeatable")
    p.add_argument("--outdir", default="results/figures", help="output directory")
    p.add_argument("--orbits", action="append", default=[], metavar="NAME=PATH",
                   help="a continuation table (results/orbits/standard.parquet, "
                   "results/orbits/wb_curves.parquet), repeatable; for 'standard' the located "
                   "points are read from *_points.parquet beside it")
    p.add_argument("--maps", action="store_true",
                   help="draw the maps of every --plane (any two axes) into OUTDIR/planes/")
    p.add_argument("--map", nargs="+", default=None, metavar="KIND",
                   help="with --maps: only these maps (default every registered one: "
                   "pattern, dc, kmax, ...)")
    p.add_argument("--sweep-diagrams", action="store_true",
                   help="draw the bifurcation diagram (section points, DC, Kmax) of every "
                   "--sweep, in the sweep's own units, into OUTDIR/sweeps/")
    p.add_argument("--index", action="store_true",
                   help="write OUTDIR/README.md from the figure records present")
    add_config_arguments(p)


def _context(args, study):
    from gearsim.presentation.figures.context import Context
    from gearsim.presentation.figures.data import read_table
    from gearsim.results.parquet import read_metadata
    from gearsim.study.figure_tables import FIGURE_DATA_KEY

    config = study.config
    ctx = Context(
        params=study.parameters().model,
        settings=study.settings,
        point_specs=dict(config.get("points") or {}),
        sweep_fixed={k: dict(v.get("fixed") or {}) for k, v in
                     (config.get("sweeps") or {}).items()},
    )
    for name, path in _pairs(args.sweep, "--sweep").items():
        ctx.sweeps[name] = _read(read_table, path, f"--sweep {name}")
    for name, path in _pairs(args.plane, "--plane").items():
        ctx.planes[name] = _read(read_table, path, f"--plane {name}")
    for name, path in _pairs(args.points, "--points").items():
        ctx.points[name] = _read(read_table, path, f"--points {name}")
    for name, path in _pairs(args.figure_data, "--figure-data").items():
        df = _read(read_table, path, f"--figure-data {name}")
        df.attrs["figure_data"] = read_metadata(path, FIGURE_DATA_KEY) or {}
        ctx.figure_data[name] = df
    for name, path in _pairs(args.orbits, "--orbits").items():
        ctx.orbits[name] = _read(read_table, path, f"--orbits {name}")
        pts = Path(path).with_name(Path(path).stem + "_points.parquet")
        if not name.endswith("_curves") and pts.is_file():
            ctx.orbits[f"{name}_points"] = read_table(pts)
        # a plane's codimension-2 points, written beside its curves (docs/orbits.md)
        c2 = Path(path).with_name(name.removesuffix("_curves") + "_codim2.parquet")
        if name.endswith("_curves") and c2.is_file():
            ctx.orbits[name.removesuffix("_curves") + "_codim2"] = read_table(c2)
    return ctx


def _bind_single_plane(numbers, ctx, table) -> dict[str, str]:
    """A figure of one plane (e.g. Fig 7 of ``wb``) given exactly one plane of another name
    draws that one: returns ``{paper's plane: given plane}``."""
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


def _write_record(path: Path, rec: dict) -> None:
    from gearsim.study.preflight import write_text_atomic

    write_text_atomic(path, json.dumps(rec, indent=1, ensure_ascii=False) + "\n")


def _physical(config):
    """``(x, y) -> {parameter: {name, unit, k}}`` of the study's gear file (empty without)."""
    from gearsim.physical.units import config_gear, physical_factors
    from gearsim.study.config import study_root

    gear = config_gear(config, study_root())
    return lambda *names: physical_factors(gear, names)


def _sweep_diagrams(args: argparse.Namespace, outdir: Path) -> None:
    """``OUTDIR/sweeps/<sweep>.{png,pdf,json}`` for every ``--sweep``."""
    import matplotlib.pyplot as plt

    from gearsim.presentation.figures.data import read_table
    from gearsim.presentation.figures.style import save_figure
    from gearsim.presentation.figures.sweeps import figure_sweep_diagram, sweep_spec_of

    study = study_from_args(args)
    config = study.config
    for name, path in _pairs(args.sweep, "--sweep").items():
        spec = sweep_spec_of(path, config, name)
        df = read_table(path)
        param = str(df["parameter"].iloc[0]) if len(df) else ""
        fig, caption = figure_sweep_diagram(df, name=name, spec=spec,
                                            physical=_physical(config)(param).get(param))
        stem = outdir / "sweeps" / name
        files = [str(f) for f in save_figure(fig, stem)]
        plt.close(fig)
        _write_record(stem.with_suffix(".json"), {
            "sweep": name, "title": f"Sweep {name}", "files": files, "caption": caption,
            "inputs": [f"sweeps/{name}"], "spec": spec})
        print(f"sweep {name}: wrote {', '.join(files)}", file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from gearsim.presentation.figures import context, maps, registry
    from gearsim.presentation.figures.index import write_index
    from gearsim.presentation.figures.style import physical_axes, save_figure

    outdir = Path(args.outdir)
    table = registry.figures()
    numbers = list(dict.fromkeys(args.fig))
    if args.all:
        numbers = list(table)
    if args.map and not args.maps:
        raise UsageError("--map KIND needs --maps")
    if not numbers and not args.index and not args.maps and not args.sweep_diagrams:
        raise UsageError("nothing to do: give --fig N, --all, --maps, --sweep-diagrams or "
                         "--index")
    if args.sweep_diagrams and not args.sweep:
        raise UsageError("--sweep-diagrams needs at least one --sweep NAME=PATH")
    if args.maps and not args.plane:
        raise UsageError("--maps needs at least one --plane NAME=PATH")
    for kind in args.map or ():
        registry.figures()  # extensions register their maps on import
        if kind not in maps.PLANE_MAPS:
            raise UsageError(f"unknown plane map '{kind}'; allowed: "
                             f"{', '.join(maps.PLANE_MAPS)}")
    from gearsim.study.preflight import check_folder

    check_folder(outdir, what="--outdir")  # writable, with room, before any drawing
    if args.sweep_diagrams:
        _sweep_diagrams(args, outdir)
    if numbers or args.maps:
        study = study_from_args(args)
        config = study.config
        ctx = _context(args, study)
        if args.maps:
            physical = _physical(config)
            for plane, df in ctx.planes.items():
                for spec, fig, caption, notes in maps.build_maps(plane, df, args.map):
                    xname, yname = context._axes(df)
                    units = physical_axes(fig, physical(xname, yname), xname, yname)
                    if units:
                        notes = [*notes, "axes also in " + ", ".join(units) + " (the gear file)"]
                    stem = outdir / "planes" / f"{plane}-{spec.kind}"
                    stem.parent.mkdir(parents=True, exist_ok=True)
                    files = [str(f) for f in save_figure(fig, stem)]
                    plt.close(fig)
                    _write_record(stem.with_suffix(".json"), {
                        "plane": plane, "map": spec.kind, "title": spec.title,
                        "axes": list(context._axes(df)), "files": files, "caption": caption,
                        "notes": notes, "inputs": [f"{plane}/cells"],
                        "parameters": ctx.params.to_dict(),
                        "integration": ctx.settings.to_dict()})
                    print(f"plane {plane} map {spec.kind}: wrote {', '.join(files)}",
                          file=sys.stderr)
        if args.all:  # keep the figures whose tables are present
            numbers = [n for n in numbers if all(
                name in getattr(ctx, kind) for kind, names in table[n].inputs.tables().items()
                for name in names)]
        bound = {} if args.all else _bind_single_plane(numbers, ctx, table)
        for b in registry.build(numbers, ctx):
            for paper, given in bound.items():
                if f"{paper}/cells" in b.inputs:
                    b.inputs = [f"{given}/cells" if i == f"{paper}/cells" else i
                                for i in b.inputs]
                    b.differences.insert(0, f"Drawn for the plane '{given}' (the paper's "
                                         f"figure shows the plane '{paper}').")
                    print(f"figure {b.number}: drawn for plane '{given}'", file=sys.stderr)
            files = [str(f) for f in save_figure(b.figure, outdir / f"fig{b.number:02d}")]
            plt.close(b.figure)
            _write_record(outdir / f"fig{b.number:02d}.json", registry.record(b, files, ctx))
            print(f"figure {b.number}: wrote {', '.join(files)}", file=sys.stderr)
    if args.index:
        path = write_index(outdir)
        print(f"wrote {path}", file=sys.stderr)
    return 0
