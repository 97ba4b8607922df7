"""``gearsim catalogue``: combine tiles, audit a plane, build and publish the catalogue.

``cells`` (a plane's tiles into ``cells.parquet``), ``audit``, ``build`` (the SQLite catalogue,
published with ``--publish``), ``publish --from BUILT --to results/catalogue.sqlite`` or ``--to
postgresql://user@host/lab --study paper`` (a lab's database: the study's schema swapped in one
transaction; docs/pipeline.md), ``migrate FILE`` or ``migrate URL --study NAME``.
"""

from __future__ import annotations

import argparse
import sys
import time

from gearsim.cli.commands._common import add_config_arguments, check_plane, study_from_args
from gearsim.study.provenance import plane_record

NAME = "catalogue"
HELP = "combine a plane's tiles, audit it, build results/catalogue.sqlite or publish it"


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", required=True, parser_class=type(p))
    for name, help_, more in (("cells", "combine a plane's tile files into cells.parquet",
                               ("--tiles", "the plane's tile Parquet files")),
                              ("audit", "re-simulate a sample of cells at tightened tolerance",
                               ("--cells", "the plane's cells.parquet"))):
        c = sub.add_parser(name, help=help_)
        c.add_argument("--plane", required=True, help="plane name (a key of `planes:`)")
        c.add_argument(more[0], required=True, nargs="+" if name == "cells" else None,
                       help=more[1])
        c.add_argument("--out", "-o", required=True, help=f"the plane's {name} file to write")
        add_config_arguments(c)
    b = sub.add_parser("build", help="build the SQLite catalogue (one transaction, atomic)")
    for flag, what in (("--cells", "cells.parquet files"), ("--sweeps", "sweep Parquet files"),
                       ("--audits", "audit Parquet files"),
                       ("--attractors", "attractor tile files (gearsim attractor-tile)"),
                       ("--orbits", "bifurcation points / curves and refine-orbits Parquet "
                        "files (docs/orbits.md)")):
        b.add_argument(flag, nargs="*", default=[], help=what)
    b.add_argument("--out", "-o", required=True, help="the catalogue file to write")
    b.add_argument("--publish", metavar="PATH",
                   help="then replace PATH atomically by the new catalogue (readers never see "
                   "it missing or partial, a failed build keeps the last good one)")
    pub = sub.add_parser("publish", help="publish a built catalogue: a file, or a study")
    pub.add_argument("--from", dest="source", required=True, help="a built catalogue")
    pub.add_argument("--to", required=True, help="a file (results/catalogue.sqlite) or a "
                     "database URL (postgresql://user@host/lab; the password from ~/.pgpass)")
    pub.add_argument("--study", help="with a URL: the study's name (its schema there)")
    mig = sub.add_parser("migrate", help="bring an older schema version up to this one")
    mig.add_argument("path", nargs="+", help="catalogue file(s), or one database URL")
    mig.add_argument("--study", help="with a URL: the study to migrate")


def _cells(args) -> int:
    from gearsim.results import catalogue

    study = study_from_args(args)
    check_plane(study, args.plane)
    out = catalogue.combine_tiles(args.tiles, args.out, plane_record(study, args.plane))
    print(f"plane {args.plane}: {len(args.tiles)} tiles -> {out}", file=sys.stderr)
    return 0


def _audit(args) -> int:
    from gearsim.cli.commands._progress import Progress
    from gearsim.results.audit_file import audit_plane
    from gearsim.study.preflight import check_output

    study = study_from_args(args)
    check_plane(study, args.plane)
    check_output(args.out)  # writable, with room, before any simulation
    n, agreement, threshold = audit_plane(study, args.plane, args.cells, args.out,
                                          lambda total: Progress(f"audit {args.plane}", total))
    verdict = "PASS" if n == 0 or agreement >= threshold else "BELOW THRESHOLD"
    print(f"audit {args.plane}: {n} cells, agreement {agreement:.3f} (threshold {threshold}) "
          f"{verdict}", file=sys.stderr)
    return 0


def _build(args) -> int:
    from gearsim.results import catalogue

    t0 = time.perf_counter()
    counts = catalogue.build_catalogue(
        args.out, args.cells, args.sweeps, args.audits, publish_to=args.publish,
        attractor_files=args.attractors, orbit_files=args.orbits)
    summary = ", ".join(f"{k}={v}" for k, v in counts.items())
    where = f" -> {args.publish}" if args.publish else ""
    print(f"catalogue {args.out}{where}: {summary} ({time.perf_counter() - t0:.1f} s)",
          file=sys.stderr)
    return 0


def _publish(args) -> int:
    from gearsim.results import catalogue

    t0 = time.perf_counter()
    where = catalogue.publish_anywhere(args.source, args.to, args.study)
    print(f"catalogue {args.source} -> {where} ({time.perf_counter() - t0:.1f} s)",
          file=sys.stderr)
    return 0


def _migrate(args) -> int:
    from gearsim.results import catalogue

    for path, (old, new) in catalogue.migrate_anywhere(args.path, args.study):
        done = "already at" if old == new else f"migrated from version {old} to"
        print(f"catalogue {path}: {done} schema version {new}", file=sys.stderr)
    return 0


def run(args: argparse.Namespace) -> int:
    return {"cells": _cells, "audit": _audit, "build": _build, "publish": _publish,
            "migrate": _migrate}[args.action](args)
