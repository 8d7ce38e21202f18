"""The analyses: run metrics, identification, stability, the operating range, and their plots."""
