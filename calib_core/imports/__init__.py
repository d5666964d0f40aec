"""Corner files written by other tools, read as observations."""
