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
        help="catalogue file (default results/catalogue.sqlite)",
    )


def run(args: argparse.Namespace) -> int:
    from gearsim.results.export import check_out, plane_dataset, write

    check_out(args.out, args.format)
    ds = plane_dataset(args.catalogue, args.plane)
    out = write(ds, args.out, args.format)
    dims = " x ".join(f"{d} {n}" for d, n in ds.sizes.items())
    print(
        f"export {args.plane}: {dims} cells, {len(ds.data_vars)} variables -> {out}",
        file=sys.stderr,
    )
    return 0
