"""Durable scan output: atomic files, PLY, depth PNG, preview, the scan directory."""
