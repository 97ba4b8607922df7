"""Stored results: Parquet tiles, the SQLite catalogue, the column dictionary, exports."""
