"""maskless: simulate, identify and control a soft-robot head positioner."""
