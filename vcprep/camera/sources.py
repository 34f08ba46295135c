"""Where a camera comes from: a preset (:func:`preset_name`), a camera file
(:func:`load_camera`), or a folder of per-frame calibration files (:class:`FrameCameras`);
:func:`load_cameras` is the ``--camera`` option. The camera itself (:class:`Camera`, the presets,
:func:`scale_matrix`) is :mod:`vcprep.camera.pinhole`; the file readers are :mod:`vcprep.camera.files`.
Every name of both stays importable from here.

Per-frame calibration (:class:`FrameCameras`): a folder of calibration files, one per image,
matched by file stem (KITTI road ``calib/um_000000.txt`` for ``image_2/um_000000.png``;
Cityscapes ``camera/.../X_camera.json`` for ``leftImg8bit/.../X_leftImg8bit.png``).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

from .files import (read_camera_yaml, read_cityscapes_camera,
                           read_kitti_calib)
from ..errors import InputError, one_of
from .pinhole import PRESETS, Camera


PRESET_PREFIX = "preset:"


def preset_name(spec: str | Path) -> str | None:
    """The one rule for a camera spec that may be a preset or a path: ``preset:NAME`` is the
    preset; a bare preset name is the preset unless a file or folder of that name exists where
    it is read (the current folder; a study: the study file's folder) -- then it is ambiguous, an
    error naming both readings; a name with a path separator (``./kitti``, ``cams/kitti``) or any
    other name is a path. Returns the preset's name, or None for a path."""
    if isinstance(spec, Path):
        return None
    s = str(spec)
    if s.startswith(PRESET_PREFIX):
        name = s[len(PRESET_PREFIX):]
        if name not in PRESETS:
            raise InputError(f"unknown camera preset '{name}'", s, one_of(name, PRESETS))
        return name
    if s in PRESETS:
        if os.path.lexists(s):
            kind = "folder" if os.path.isdir(s) else "file"
            raise InputError(f"'{s}' is both the camera preset {s} and the {kind} ./{s}", s,
                             f"write preset:{s} for the preset, or ./{s} for the {kind}")
        return s
    return None


def load_camera(spec: str | Path, image_size: tuple[int, int] | None = None) -> Camera:
    """A preset (see :func:`preset_name`), or a file: ``.yaml``/``.yml`` (our schema), ``.txt``
    (KITTI calibration), ``.json`` (Cityscapes camera). ``image_size`` is used for calibration
    files, which carry none."""
    s = str(spec)
    preset = preset_name(spec)
    if preset is not None:
        return PRESETS[preset]
    path = Path(s)
    if not path.exists():
        raise InputError("not a camera preset and no such file", s,
                         one_of(s, PRESETS, "or a camera YAML file"))
    suffix = path.suffix.lower()
    if suffix in (".yaml", ".yml"):
        return read_camera_yaml(path)
    if suffix == ".txt":
        return read_kitti_calib(path, image_size or (1242, 375))
    if suffix == ".json":
        return read_cityscapes_camera(path, image_size or (2048, 1024))
    raise InputError(f"unknown camera file type '{suffix}'", path,
                     "use .yaml (camera schema), .txt (KITTI calib) or .json (Cityscapes camera)")


# --- per-frame calibration ------------------------------------------------------------------------
# calibration file suffix -> what its stem carries after the image's key (Cityscapes: X_camera.json)
CALIB_FILES = {".txt": "", ".json": "_camera", ".yaml": "", ".yml": ""}
IMAGE_KEY_SUFFIXES = ("_leftImg8bit",)  # image stem suffixes its calibration file's name drops (Cityscapes)


def _calib_key(path: Path) -> str:
    tail = CALIB_FILES[path.suffix.lower()]
    stem = path.stem
    return stem[: -len(tail)] if tail and stem.endswith(tail) else stem


def _image_keys(image: Path) -> list[str]:
    stem = Path(image).stem
    return [stem] + [stem[: -len(s)] for s in IMAGE_KEY_SUFFIXES if stem.endswith(s) and len(stem) > len(s)]


@dataclass(frozen=True)
class FrameCameras:
    """Per-frame calibration: every image has its own camera file in ``folder`` (searched
    recursively), matched by stem: ``<stem>.txt`` (KITTI: ``P2`` and this frame's
    ``Tr_cam_to_road``), ``<stem>.yaml`` (our schema), or ``<key>_camera.json`` (Cityscapes, for
    the image ``<key>_leftImg8bit.png``). ``files`` maps each key to its file."""

    folder: Path
    files: Mapping[str, Path]

    @property
    def name(self) -> str:
        """What store records call the camera: the folder's name (``calib``, ``camera``)."""
        return Path(os.path.abspath(self.folder)).name

    @classmethod
    def from_folder(cls, folder: str | Path) -> "FrameCameras":
        folder = Path(folder)
        files: dict[str, Path] = {}
        for top, dirs, names in os.walk(folder, followlinks=True):
            dirs[:] = sorted(d for d in dirs if not d.startswith("."))
            for n in sorted(names):
                p = Path(top) / n
                if n.startswith(".") or p.suffix.lower() not in CALIB_FILES:
                    continue
                key = _calib_key(p)
                if key in files:
                    raise InputError(f"two calibration files for frame '{key}' (also {files[key]})", p,
                                     "keep one calibration file per frame in the folder")
                files[key] = p
        if not files:
            raise InputError("folder holds no calibration files (.txt KITTI, .json Cityscapes, .yaml)", folder,
                             "give the folder of per-frame calibration files, or one camera file or preset")
        return cls(folder, files)

    def file_for(self, image: str | Path) -> Path:
        """The calibration file of ``image``; none is an :class:`InputError` naming the image."""
        keys = _image_keys(Path(image))
        for k in keys:
            if k in self.files:
                return self.files[k]
        raise InputError(f"no calibration file for this image in {self.folder} (looked for "
                         f"{keys[-1]}.txt, {keys[-1]}_camera.json or {keys[-1]}.yaml)", image,
                         "add the frame's calibration file, or remove the image")

    def for_image(self, image: str | Path, size: tuple[int, int]) -> Camera:
        """The camera of ``image`` (of ``size`` (w, h)) from its own calibration file."""
        return load_camera(self.file_for(image), image_size=size).for_image_size(size, image)


def camera_of_image(camera: "Camera | FrameCameras", image: str | Path, size: tuple[int, int]) -> Camera:
    """The camera of one image of ``size``: ``camera`` at that size, or its own calibration file."""
    if isinstance(camera, FrameCameras):
        return camera.for_image(image, size)
    return camera.for_image_size(size, image)


def load_cameras(spec: str | Path, sample_image: str | Path | None = None,
                 per_frame: bool = True) -> "Camera | FrameCameras":
    """``--camera``: a preset, a camera file (KITTI and Cityscapes files carry no image size: the
    size of ``sample_image`` is used), or, with ``per_frame``, a folder of per-frame calibration
    files (:class:`FrameCameras`)."""
    s = str(spec)
    if preset_name(spec) is not None:
        return load_camera(spec)
    if Path(s).is_dir():
        if not per_frame:
            raise InputError("is a folder of per-frame calibration files; this command needs one camera", s,
                             "give one camera file or preset (per-frame folders work in warp, predict and crossval)")
        return FrameCameras.from_folder(s)
    size = None
    if sample_image is not None and Path(s).suffix.lower() in (".txt", ".json"):
        from ..io.images import image_size_from_header

        try:
            with open(sample_image, "rb") as f:
                size = image_size_from_header(f.read(262144))
        except OSError:
            size = None
    return load_camera(s, image_size=size)

