"""Data: the paper's numbers as printed, the plant's parameters, the default scenario (YAML)."""
