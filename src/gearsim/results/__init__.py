"""Results: Parquet files with provenance, the SQLite catalogue (schema, migrations), export."""
