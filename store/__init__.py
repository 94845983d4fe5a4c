"""The Zarr cube store: layout, chunking, metadata schema, dtype policy, integrity (issue: Cube store)."""
