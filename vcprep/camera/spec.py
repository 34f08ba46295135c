"""A camera from whatever ``--camera`` takes (:func:`camera_from_spec`): a preset, a camera file, a
folder of per-frame calibration files (:func:`vcprep.camera.sources.load_cameras`) or 'estimate' (from
the frames: :mod:`vcprep.camera.estimate`); the one reader of the commands and the Python face."""
from __future__ import annotations

from pathlib import Path

from ..errors import InputError
from .estimate import estimate_camera, estimated_line
from .pinhole import Camera
from .sources import FrameCameras, load_camera, load_cameras, preset_name

__all__ = ["camera_from_spec"]


def camera_from_spec(spec: "str | Path | Camera", sample_image: str | Path | None = None, per_frame: bool = True,
                     frames=None, needed: bool = True, say=None,
                     size: tuple[int, int] | None = None) -> "Camera | FrameCameras | None":
    """Whatever ``--camera`` takes, loaded (:func:`load_cameras`): a :class:`Camera` as it is, a
    preset, a camera file (calibration files carry no image size: ``sample_image``'s is used), a
    folder of per-frame calibration files where ``per_frame`` (:class:`FrameCameras`), or
    ``estimate``: the camera estimated from ``frames`` (image files, videos (a sample of their
    frames) or decoded arrays; :mod:`vcprep.camera.estimate`), said through ``say`` (given).
    ``needed`` False: the spec is only checked (a file or preset must load; nothing is estimated)
    and None is returned. ``size`` (w, h): the frames' size, where no ``sample_image`` gives it (a
    calibration file's camera is for it)."""
    if isinstance(spec, Camera):
        return spec if needed else None
    if str(spec) != "estimate":
        cam = load_cameras(spec, sample_image, per_frame=per_frame) if size is None or preset_name(spec) is not None \
            or Path(str(spec)).is_dir() else load_camera(str(spec), image_size=size)
        return cam if needed else None
    if not needed:
        return None
    if frames is None:
        raise InputError("this command cannot estimate a camera", None,
                         "run 'vcprep camera estimate FRAMES -o cam.yaml' and give --camera cam.yaml")
    import tempfile

    from ..io.images import write_png
    from ..io.video import frames_of, is_video
    from ..progress import count

    with tempfile.TemporaryDirectory(prefix="vcprep-frames-") as tmp:
        arrays = [f for f in frames if not isinstance(f, (str, Path))]
        for i, f in enumerate(arrays):  # decoded frames: estimated from lossless files of them
            write_png(Path(tmp) / f"frame_{i:06d}.png", f)
        files = frames_of([f for f in frames if isinstance(f, (str, Path))], tmp) + \
            [Path(tmp) / f"frame_{i:06d}.png" for i in range(len(arrays))]
        est = estimate_camera(files, name="estimated")
    videos = [Path(f).name for f in frames if isinstance(f, (str, Path)) and is_video(f)]
    what = count(len(files), "frame") + (f" sampled from {', '.join(videos)}" if videos else "")
    if say is not None:
        say(estimated_line(est, what) + " (write it out with 'vcprep camera estimate')")
    return est.camera
