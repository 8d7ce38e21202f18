"""Makes the mannequin's face: the texture ``face.png`` on a relief mesh, ``face.obj``/``.mtl``.

The texture is a crop of the NASA portrait of astronaut Eileen Collins that scikit-image ships as
``skimage.data.astronaut()`` (public domain; see README.md here). The mesh is a height field under
it shaped like a face (an assumed shape, not a scan): a dome whose sides fall 6 cm away, a nose
ridge 2 cm high and eye sockets 8 mm deep, placed where OpenCV's stock cascades find the face and
eyes in the texture. Its zero is the eye band's surface (the box spanning both eyes, where
``face_detection`` reads the depth, by the statistic it reads it with), so a head at height h puts
the eye band h above the table, and the distance a camera should read there is its mount height
minus h.

``python assets/face/make_face.py`` makes all three files (the texture needs ``pip install
scikit-image``); ``--mesh-only`` makes the mesh from the committed texture with numpy and OpenCV.
"""

import argparse
from pathlib import Path

import cv2
import numpy as np
from scipy.stats import trim_mean

from maskless.systems.sensing.face_detection import TRIM_FRACTION, FaceFinder, depth_region

FOLDER = Path(__file__).parent
# The crop of the 512x512 portrait around the head (rows, columns), found by eye around the face
# box OpenCV's frontal-face cascade reports, (177, 66, 95, 95) as x, y, width, height.
CROP_ROWS = slice(30, 222)
CROP_COLUMNS = slice(148, 308)
TEXTURE_SIZE_PX = (200, 240)  # width, height
# The face's size (m): the cascade's face box then spans 0.14 m, an adult face's width.
FACE_WIDTH_M = 0.24
FACE_HEIGHT_M = 0.288
# Mesh vertices across and along the face: ~7.5 mm apart, finer than a camera pixel on the face.
GRID = (33, 39)
# The assumed face shape (m).
DOME_SEMI_AXES_M = (0.085, 0.125)
DOME_DEPTH_M = 0.06
NOSE_HEIGHT_M = 0.02
NOSE_STD_M = (0.009, 0.02)
NOSE_BELOW_EYES_M = 0.025
EYE_SOCKET_DEPTH_M = 0.008
EYE_SOCKET_STD_M = 0.012


def make_texture() -> None:
    """Writes face.png, the crop of the portrait."""
    from skimage import data

    crop = data.astronaut()[CROP_ROWS, CROP_COLUMNS]
    texture = cv2.resize(crop, TEXTURE_SIZE_PX, interpolation=cv2.INTER_AREA)
    cv2.imwrite(str(FOLDER / "face.png"), cv2.cvtColor(texture, cv2.COLOR_RGB2BGR))


def _to_metres(column: float, row: float, shape) -> tuple[float, float]:
    """A texture pixel's centre on the face (m): x to the right, y towards the top of the head."""
    rows, columns = shape[:2]
    return (
        (column + 0.5) / columns * FACE_WIDTH_M - FACE_WIDTH_M / 2,
        FACE_HEIGHT_M / 2 - (row + 0.5) / rows * FACE_HEIGHT_M,
    )


def face_landmarks() -> tuple[tuple, list[tuple], tuple]:
    """The face box centre, the eye centres, and the eye band's corners on the face (m)."""
    gray = cv2.cvtColor(cv2.imread(str(FOLDER / "face.png")), cv2.COLOR_BGR2GRAY)
    finder = FaceFinder()
    face = finder.find_face(gray, None)
    eyes = finder.find_eyes(gray, face)
    if face is None or len(eyes) != 2:
        raise RuntimeError(f"the cascades found face {face} and eyes {eyes} in face.png")
    x, y, w, h = face
    centre = _to_metres(x + w / 2, y + h / 2, gray.shape)
    eye_centres = [_to_metres(ex + ew / 2, ey + eh / 2, gray.shape) for ex, ey, ew, eh in eyes]
    bx, by, bw, bh = depth_region(eyes)
    band = (_to_metres(bx, by + bh, gray.shape), _to_metres(bx + bw, by, gray.shape))
    return centre, eye_centres, band


def relief_m(x, y, centre, eye_centres):
    """The face's height above its dome's apex plane (m) at (x, y) (m); arrays broadcast."""
    a, b = DOME_SEMI_AXES_M
    inside = np.clip(1 - ((x - centre[0]) / a) ** 2 - ((y - centre[1]) / b) ** 2, 0, None)
    z = DOME_DEPTH_M * (np.sqrt(inside) - 1)
    nose_x = np.mean([e[0] for e in eye_centres])
    nose_y = np.mean([e[1] for e in eye_centres]) - NOSE_BELOW_EYES_M
    z = z + NOSE_HEIGHT_M * np.exp(
        -((x - nose_x) ** 2) / (2 * NOSE_STD_M[0] ** 2)
        - (y - nose_y) ** 2 / (2 * NOSE_STD_M[1] ** 2)
    )
    for ex, ey in eye_centres:
        z = z - EYE_SOCKET_DEPTH_M * np.exp(
            -((x - ex) ** 2 + (y - ey) ** 2) / (2 * EYE_SOCKET_STD_M**2)
        )
    return z


def make_mesh() -> None:
    """Writes face.obj (the textured height field) and face.mtl."""
    centre, eyes, ((left, bottom), (right, top)) = face_landmarks()
    band_x, band_y = np.meshgrid(np.linspace(left, right, 60), np.linspace(bottom, top, 30))
    # The statistic the depth is read with (face_detection.region_distance_m), noise-free.
    zero = trim_mean(relief_m(band_x, band_y, centre, eyes).ravel(), TRIM_FRACTION)
    xs = np.linspace(-FACE_WIDTH_M / 2, FACE_WIDTH_M / 2, GRID[0])
    ys = np.linspace(-FACE_HEIGHT_M / 2, FACE_HEIGHT_M / 2, GRID[1])
    x, y = np.meshgrid(xs, ys)
    z = relief_m(x, y, centre, eyes) - zero
    slope_y, slope_x = np.gradient(z, ys, xs)
    normals = np.stack([-slope_x, -slope_y, np.ones_like(z)], axis=-1)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    lines = ["mtllib face.mtl"]
    lines += [f"v {a:.4f} {b:.4f} {c:.4f}" for a, b, c in zip(x.flat, y.flat, z.flat, strict=True)]
    lines += [
        f"vt {(a / FACE_WIDTH_M + 0.5):.4f} {(b / FACE_HEIGHT_M + 0.5):.4f}"
        for a, b in zip(x.flat, y.flat, strict=True)
    ]
    lines += [f"vn {a:.3f} {b:.3f} {c:.3f}" for a, b, c in normals.reshape(-1, 3)]
    lines.append("usemtl face")
    columns = GRID[0]
    for row in range(GRID[1] - 1):
        for column in range(columns - 1):
            a = row * columns + column + 1  # OBJ indices count from 1
            b, c, d = a + 1, a + columns + 1, a + columns
            lines.append(f"f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}")
            lines.append(f"f {a}/{a}/{a} {c}/{c}/{c} {d}/{d}/{d}")
    (FOLDER / "face.obj").write_text("\n".join(lines) + "\n")
    (FOLDER / "face.mtl").write_text("newmtl face\nKa 1 1 1\nKd 1 1 1\nmap_Kd face.png\n")


def main() -> None:
    """Writes face.png (unless --mesh-only), face.obj and face.mtl beside this file."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--mesh-only", action="store_true", help="keep the committed face.png")
    if not parser.parse_args().mesh_only:
        make_texture()
    make_mesh()


if __name__ == "__main__":
    main()
