"""Makes the mannequin's face: the texture ``face.png`` on the quad ``face.obj``, ``face.mtl``.

The texture is a crop of the NASA portrait of astronaut Eileen Collins that scikit-image ships as
``skimage.data.astronaut()`` (public domain; see README.md here). A stock Haar cascade finds its
face and both eyes. Run ``python assets/face/make_face.py`` after ``pip install
scikit-image`` to make the files again; they are committed, so nothing else needs scikit-image.
"""

from pathlib import Path

import cv2

# The crop of the 512x512 portrait around the head (rows, columns), found by eye around the face
# box OpenCV's frontal-face cascade reports, (177, 66, 95, 95) as x, y, width, height.
CROP_ROWS = slice(30, 222)
CROP_COLUMNS = slice(148, 308)
TEXTURE_SIZE_PX = (200, 240)  # width, height
# The quad's size (m): the cascade's face box then spans 0.14 m, an adult face's width.
FACE_WIDTH_M = 0.24
FACE_HEIGHT_M = 0.288


def main() -> None:
    """Writes face.png, face.mtl and face.obj beside this file."""
    from skimage import data

    folder = Path(__file__).parent
    crop = data.astronaut()[CROP_ROWS, CROP_COLUMNS]
    texture = cv2.resize(crop, TEXTURE_SIZE_PX, interpolation=cv2.INTER_AREA)
    cv2.imwrite(str(folder / "face.png"), cv2.cvtColor(texture, cv2.COLOR_RGB2BGR))
    (folder / "face.mtl").write_text("newmtl face\nKa 1 1 1\nKd 1 1 1\nmap_Kd face.png\n")
    w, h = FACE_WIDTH_M / 2, FACE_HEIGHT_M / 2
    # A quad facing +z; the texture's top (v = 1) towards +y, the top of the head.
    (folder / "face.obj").write_text(
        "mtllib face.mtl\n"
        f"v {-w} {-h} 0\nv {w} {-h} 0\nv {w} {h} 0\nv {-w} {h} 0\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
        "vn 0 0 1\n"
        "usemtl face\n"
        "f 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n"
    )


if __name__ == "__main__":
    main()
