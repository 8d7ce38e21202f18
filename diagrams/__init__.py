"""The library: the scenario, the closed loop, and one module per command."""
