"""Sim-to-real diagnosis: where a nominal model's residual lies, which unmodelled effect explains
it, how far it shrinks, and what no candidate explains (the remainder)."""
