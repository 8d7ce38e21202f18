"""What a sensor (a camera) may be called: its name is one segment of every topic it publishes.

Its own module because both the recording format and the camera frames check it, and the
recording format reads camera frames: one rule, below both.
"""

import re

# One path segment of a topic: no "/" and no spaces.
_SENSOR_NAME = re.compile(r"[A-Za-z0-9_]+")


def is_sensor_name(name) -> bool:
    """Whether ``name`` can name a sensor's topics: letters, digits and underscores only."""
    return isinstance(name, str) and _SENSOR_NAME.fullmatch(name) is not None
