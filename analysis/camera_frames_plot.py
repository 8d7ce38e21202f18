"""Plot of what the cameras saw: each camera's first and last frame, with the detector's boxes."""

from pathlib import Path

from maskless.camera_images import BOX_COLOURS, CameraFrame
from maskless.systems.units import m_to_mm

# Inches per camera row, and the width of the two panels together.
_ROW_HEIGHT_IN = 3.6
_WIDTH_IN = 10.0
_DPI = 100
_BOX_LABELS = {"face": "face", "eye": "eyes", "depth_region": "depth region"}


def plot_camera_frames(path: str | Path, frames: dict[str, list[CameraFrame]]) -> Path:
    """Each camera's first and last frame, side by side, one camera a row; returns the path.

    The boxes are drawn in the colours the recording's annotations use (face green, eyes blue,
    depth region yellow); each panel's title gives the camera, the simulated time and the
    measurement in mm, or says "no face" or "not valid".

    Args:
        path: The PNG to write (``frames.png`` beside a run's other plots).
        frames: Camera name -> its frames in time order, as ``recording.read_camera_frames``
            gives them.

    Raises:
        ValueError: If there is no camera, or a camera has no frames (the message names it).
    """
    if not frames:
        raise ValueError("frames: no camera to plot")
    for camera, camera_frames in frames.items():
        if not camera_frames:
            raise ValueError(f"camera {camera!r}: no frames to plot")
    # Imported here: matplotlib is slow to import and only this function needs it. A bare Figure
    # needs no GUI backend and no pyplot.
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    path = Path(path)
    figure = Figure(figsize=(_WIDTH_IN, _ROW_HEIGHT_IN * len(frames)), layout="constrained")
    axes = figure.subplots(len(frames), 2, squeeze=False)
    for row, (camera, camera_frames) in zip(axes, frames.items(), strict=True):
        _draw_frame(row[0], f"{camera}, first frame", camera_frames[0])
        _draw_frame(row[1], f"{camera}, last frame", camera_frames[-1])
    figure.legend(
        handles=[
            Patch(facecolor="none", edgecolor=BOX_COLOURS[role], linewidth=2, label=label)
            for role, label in _BOX_LABELS.items()
        ],
        loc="outside lower center",
        ncol=len(_BOX_LABELS),
        fontsize=8,
    )
    figure.savefig(path, dpi=_DPI)
    return path


def _draw_frame(axis, title: str, frame: CameraFrame) -> None:
    from matplotlib.patches import Rectangle

    axis.imshow(frame.rgb)
    boxes = [("face", frame.face_box), *(("eye", box) for box in frame.eye_boxes)]
    boxes.append(("depth_region", frame.region_box))
    for role, box in boxes:
        if box is None:
            continue
        x, y, width, height = box
        # imshow centres pixel (i, j) on (j, i): a box's outer edge is half a pixel out.
        axis.add_patch(
            Rectangle(
                (x - 0.5, y - 0.5),
                width,
                height,
                fill=False,
                edgecolor=BOX_COLOURS[role],
                linewidth=1.5,
            )
        )
    axis.set_title(
        f"{title}, t = {frame.time_s:.3f} s\n{_measurement(frame)}",
        fontsize=9,
    )
    axis.set_axis_off()


def _measurement(frame: CameraFrame) -> str:
    if frame.face_box is None:
        return "no face"
    if not frame.valid:
        return "not valid"
    return f"{m_to_mm(frame.distance_m):.1f} mm"
