"""The study: configuration and its defaults, grids, provenance, tiles, the dask cluster, integrity
checks."""
