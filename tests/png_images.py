"""PNG files for the plot tests, read back by Pillow (matplotlib's own image dependency)."""

from pathlib import Path

import numpy as np
from PIL import Image

# The eight bytes every PNG file starts with (the PNG specification, section 5.2).
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def assert_png(path, width: int, height: int) -> None:
    """``path`` is a whole PNG of ``width`` x ``height`` pixels with something drawn on it."""
    path = Path(path)
    assert path.read_bytes()[:8] == PNG_SIGNATURE
    with Image.open(path) as image:
        assert image.format == "PNG"
        assert image.size == (width, height)
        pixels = np.asarray(image.convert("RGB"))  # decodes every row: a truncated file raises
    assert pixels.shape == (height, width, 3)
    assert (pixels != pixels[0, 0]).any()  # something drawn on the background
