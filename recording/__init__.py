"""Walks kept and played back: MCAP files with the wire's JSON Schemas (open in Foxglove)."""
