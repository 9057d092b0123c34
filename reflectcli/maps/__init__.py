"""Precomputed maps: environment (cube, sphere) maps; capture, lookup, cache."""
