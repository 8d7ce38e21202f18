"""Stability of the loops: discrete margins, loop robustness, and their plots."""
