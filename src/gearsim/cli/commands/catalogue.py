"""``gearsim catalogue``: combine tiles, audit a plane, build the SQLite catalogue.

Subcommands (each is one Snakemake rule):

* ``gearsim catalogue cells --plane wb --tiles T0 T1 ... --out results/wb/cells.parquet``
* ``gearsim catalogue audit --plane wb --cells results/wb/cells.parquet
  --out results/wb/audit.parquet``
* ``gearsim catalogue build --cells C1 C2 --sweeps S1 S2 [--audits A1 A2]
  --out results/catalogue.d/build.sqlite --publish results/catalogue.sqlite``
* ``gearsim catalogue publish --from results/catalogue.d/build.sqlite
  --to results/catalogue.sqlite`` (restore the published copy by hand)
* ``gearsim catalogue migrate results/catalogue.sqlite`` (bring a catalogue of an older schema
  version up to this one, in place and atomically)
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from gearsim.cli.commands._common import add_config_arguments, check_plane, study_from_args
from gearsim.errors import UsageError
from gearsim.study.audit import audit_frame, audit_settings
from gearsim.study.provenance import plane_record

NAME = "catalogue"
HELP = "combine a plane's tiles, audit it, or build results/catalogue.sqlite"


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", required=True, parser_class=type(p))
    c = sub.add_parser("cells", help="combine a plane's tile files into cells.parquet")
    c.add_argument("--plane", required=True, help="plane name (a key of `planes:`)")
    c.add_argument("--tiles", nargs="+", required=True, help="the plane's tile Parquet files")
    c.add_argument("--out", "-o", required=True, help="the plane's cells.parquet to write")
    add_config_arguments(c)
    a = sub.add_parser("audit", help="re-simulate a sample of cells at tightened tolerance")
    a.add_argument("--plane", required=True, help="plane name (a key of `planes:`)")
    a.add_argument("--cells", required=True, help="the plane's cells.parquet")
    a.add_argument("--out", "-o", required=True, help="the plane's audit.parquet to write")
    add_config_arguments(a)
    b = sub.add_parser("build", help="build the SQLite catalogue (one transaction, atomic)")
    b.add_argument("--cells", nargs="*", default=[], help="cells.parquet files")
    b.add_argument("--sweeps", nargs="*", default=[], help="sweep Parquet files")
    b.add_argument("--audits", nargs="*", default=[], help="audit Parquet files")
    b.add_argument("--attractors", nargs="*", default=[],
                   help="attractor tile files (gearsim attractor-tile)")
    b.add_argument("--orbits", nargs="*", default=[],
                   help="bifurcation points / curves and refine-orbits Parquet files "
                   "(docs/orbits.md)")
    b.add_argument("--out", "-o", required=True,
                   help="the catalogue file to write (the rule's output)")
    b.add_argument(
        "--publish",
        metavar="PATH",
        help="then replace PATH atomically by the new catalogue (results/catalogue.sqlite: "
        "readers never see it missing or partial, a failed build keeps the last good one)",
    )
    pub = sub.add_parser(
        "publish", help="check a built catalogue and atomically replace --to by it"
    )
    pub.add_argument("--from", dest="source", required=True, help="a built catalogue")
    pub.add_argument("--to", required=True, help="e.g. results/catalogue.sqlite")
    mig = sub.add_parser(
        "migrate", help="bring a catalogue of an older schema version up to this gearsim's"
    )
    mig.add_argument("path", nargs="+", help="catalogue file(s), e.g. results/catalogue.sqlite")


def _cells(args) -> int:
    from gearsim.results import catalogue

    study = study_from_args(args)
    check_plane(study, args.plane)
    out = catalogue.combine_tiles(args.tiles, args.out, plane_record(study, args.plane))
    print(f"plane {args.plane}: {len(args.tiles)} tiles -> {out}", file=sys.stderr)
    return 0


def _audit(args) -> int:
    import pandas as pd

    from gearsim.cli.commands._progress import Progress
    from gearsim.results import catalogue
    from gearsim.study import provenance

    study = study_from_args(args)
    config = study.config
    check_plane(study, args.plane)
    from gearsim.study.preflight import check_output

    check_output(args.out)  # writable, with room, before any simulation
    cells = pd.read_parquet(args.cells)
    started = catalogue.now_iso()
    t0 = time.perf_counter()
    progress = Progress(
        f"audit {args.plane}", max(1, int(config["audit"]["fraction"] * len(cells)))
    )
    df = audit_frame(study, args.plane, cells, progress)
    progress.close()
    agreement = float(df["agree"].mean()) if len(df) else float("nan")
    threshold = float(config["audit"]["threshold"])
    subtree = {**provenance.plane_subtree(study, args.plane), "audit": dict(config["audit"])}
    prov = provenance.provenance(
        subtree,
        kind="audit",
        name=args.plane,
        study=study,
        started=started,
        finished=catalogue.now_iso(),
        wall_s=time.perf_counter() - t0,
        cells=len(df),
        audit_seed=int(config["audit"]["seed"]),
        agreement=agreement,
        threshold=threshold,
        settings=audit_settings(study).to_dict(),
        workers="in-process",
    )
    catalogue.write_parquet(df, args.out, {catalogue.PROVENANCE_KEY: prov})
    verdict = "PASS" if len(df) == 0 or agreement >= threshold else "BELOW THRESHOLD"
    print(
        f"audit {args.plane}: {len(df)} cells, agreement {agreement:.3f} "
        f"(threshold {threshold}) {verdict}",
        file=sys.stderr,
    )
    return 0


def _build(args) -> int:
    from gearsim.results import catalogue

    for f in [*args.cells, *args.sweeps, *args.audits, *args.orbits]:
        if not Path(f).is_file():
            raise UsageError(f"input file not found: {f}")
    t0 = time.perf_counter()
    counts = catalogue.build_catalogue(
        args.out, args.cells, args.sweeps, args.audits, publish_to=args.publish,
        attractor_files=args.attractors,
        orbit_files=args.orbits,
    )
    summary = ", ".join(f"{k}={v}" for k, v in counts.items())
    where = f" -> {args.publish}" if args.publish else ""
    print(
        f"catalogue {args.out}{where}: {summary} ({time.perf_counter() - t0:.1f} s)",
        file=sys.stderr,
    )
    return 0


def _publish(args) -> int:
    from gearsim.results import catalogue

    catalogue.publish(args.source, args.to)
    print(f"catalogue {args.source} -> {args.to}", file=sys.stderr)
    return 0


def _migrate(args) -> int:
    from gearsim.results import catalogue

    for path in args.path:
        old, new = catalogue.migrate_catalogue(path)
        done = "already at" if old == new else f"migrated from version {old} to"
        print(f"catalogue {path}: {done} schema version {new}", file=sys.stderr)
    return 0


def run(args: argparse.Namespace) -> int:
    actions = {"cells": _cells, "audit": _audit, "build": _build, "publish": _publish,
               "migrate": _migrate}
    return actions[args.action](args)
