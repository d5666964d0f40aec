"""Reads and writes of the metadata tables, one module per table family."""
