"""``gearsim export --plane wb --format netcdf --out wb.nc``: one catalogue plane as an xarray
Dataset on its grid (NetCDF, Zarr), or as a table with the same units and provenance (CSV with a
``.json`` sidecar, Parquet with key-value metadata). See :mod:`gearsim.results.export`."""

from __future__ import annotations

import argparse
import sys

NAME = "export"
HELP = "write one plane of the catalogue as NetCDF, Zarr, CSV or Parquet (xarray Dataset)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    from gearsim.results.export import FORMATS

    p.add_argument("--plane", required=True, help="plane name (planes.name in the catalogue)")
    p.add_argument(
        "--format", choices=FORMATS, default="netcdf", help="output format (default netcdf)"
    )
    p.add_argument("--out", "-o", required=True, help="output file (a directory for zarr)")
    p.add_argument(
        "--catalogue",
        "--db",
        dest="catalogue",
        default="results/catalogue.sqlite",
        help="catalogue file (default results/catalogue.sqlite), or a database URL with --study",
    )
    p.add_argument("--study", help="with a database URL: the study to read")


def run(args: argparse.Namespace) -> int:
    from gearsim.results.export import check_out, plane_dataset, write
    from gearsim.results.server_read import catalogue_name, readable_catalogue

    check_out(args.out, args.format)
    ds = plane_dataset(readable_catalogue(args.catalogue, args.study), args.plane,
                       source=catalogue_name(args.catalogue, args.study))
    out = write(ds, args.out, args.format)
    dims = " x ".join(f"{d} {n}" for d, n in ds.sizes.items())
    print(
        f"export {args.plane}: {dims} cells, {len(ds.data_vars)} variables -> {out}",
        file=sys.stderr,
    )
    return 0
