"""How one frame's pixels meet the road plane: :class:`GroundView` (the road-plane -> image
homography, the image size, which pose it came from) and where it comes from for a ``--camera``
(:class:`BevSource`): a camera at its nominal pose or at a frame's pose from its road vanishing
point, or a KITTI calibration file's ``Tr_cam_to_road``, exactly as the road benchmark's devkit
(``BirdsEyeView``) projects it.

Conventions: ``image_H_ground`` maps a road point (x, z, 1) (metres, x right, z forward, y = 0 the
road; :mod:`vcprep.bev.grid`) to homogeneous pixels (u, v, 1); for a :class:`~vcprep.camera.Camera`
it is :func:`vcprep.warp.ground_to_image` (pixel centres at integers, world origin on the road
straight below the camera). A KITTI view (``devkit`` True) is the devkit's
``P2 . R0_rect . inv(Tr_cam_to_road)`` with the road frame's y column dropped; its pixels are the
devkit's (1-based: it samples pixel ``floor(u) - 1``), and its z is measured in the road frame,
whose origin lies ``origin_z`` metres behind the camera's foot (``Tr_cam_to_road``'s z translation).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..camera.files import read_kitti_entries
from ..camera.pinhole import Camera
from ..camera.sources import FrameCameras, load_cameras
from ..errors import InputError
from ..warp.homography import ground_to_image, pose_from_vp

__all__ = ["GroundView", "camera_view", "kitti_view", "BevSource"]


@dataclass(frozen=True)
class GroundView:
    """One frame's road plane -> image mapping (hashable: the maps are cached by it).

    ``H`` (9 floats, row-major ``image_H_ground``), ``size`` (w, h) of the image, ``devkit``: the
    KITTI devkit's pixel rule, ``origin_z``: the camera's foot in the grid's z (metres), ``pose``:
    which pose was used, as :meth:`pose_dict` says it."""

    H: tuple[float, ...]
    size: tuple[int, int]
    devkit: bool = False
    origin_z: float = 0.0
    pose: tuple[tuple[str, Any], ...] = ()

    @property
    def image_H_ground(self) -> np.ndarray:
        return np.array(self.H, dtype=np.float64).reshape(3, 3)

    def pose_dict(self) -> dict[str, Any]:
        """``{"source": "vp"|"nominal"|"calibration"|"kitti", "pan_deg", "tilt_deg", "vp", "vp_status"}``."""
        return dict(self.pose)


def _roll_matrix(cam: Camera, roll: float) -> np.ndarray:
    """``K Rz K^-1``: pixels of ``cam`` turned by ``roll`` degrees about the optical axis (positive:
    the image turns clockwise, as :func:`vcprep.synthetic.render_road`'s ``roll``)."""
    c, s = np.cos(np.radians(roll)), np.sin(np.radians(roll))
    return cam.K @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.linalg.inv(cam.K)


def camera_view(cam: Camera, vp: tuple[float, float] | None = None, vp_status: str | None = None,
                source: str | None = None, roll: float = 0.0) -> GroundView:
    """``cam`` (at the frame's size) at its nominal pose, or at the pan and tilt its road vanishing
    point ``vp`` (u, v source pixels) implies (:func:`vcprep.warp.pose_from_vp`, the warp's rule).
    ``roll`` (degrees, known from the mounting: frames do not tell it) turns the camera about its
    optical axis after pan and tilt; the VP is read in the un-rolled image."""
    rolled = _roll_matrix(cam, roll) if roll else np.eye(3)
    if vp is not None and roll:
        p = np.linalg.inv(rolled) @ np.array([vp[0], vp[1], 1.0])
        pan, tilt = pose_from_vp(cam, (p[0] / p[2], p[1] / p[2]))
    else:
        pan, tilt = (cam.pan, cam.tilt) if vp is None else pose_from_vp(cam, vp)
    H = rolled @ ground_to_image(cam, pan, tilt)
    pose = (("source", source or ("nominal" if vp is None else "vp")), ("pan_deg", round(float(pan), 4)),
            ("tilt_deg", round(float(tilt), 4)), ("roll_deg", float(roll)), ("height_m", float(cam.height)),
            ("vp", None if vp is None else [round(float(vp[0]), 2), round(float(vp[1]), 2)]), ("vp_status", vp_status))
    return GroundView(tuple(float(v) for v in H.ravel()), (int(cam.size[0]), int(cam.size[1])), pose=pose)


def _matrix(entries: dict, key: str, n: int, path: Path) -> np.ndarray:
    if key not in entries or entries[key].size != n:
        raise InputError(f"no '{key}' line of {n} values", path, "use the KITTI road release's calib/<frame>.txt")
    return entries[key]


def kitti_view(path: str | Path, size: tuple[int, int]) -> GroundView | None:
    """The devkit's view of a KITTI road calibration file (None where it has no ``Tr_cam_to_road``):
    ``image_H_ground`` = columns (x, z, 1) of ``P2 @ R0_rect @ inv(Tr_cam_to_road)`` (4x4 forms)."""
    path = Path(path)
    entries = read_kitti_entries(path)
    if "Tr_cam_to_road" not in entries:
        return None
    P2 = _matrix(entries, "P2", 12, path).reshape(3, 4)
    R0 = np.eye(4)
    R0[:3, :3] = _matrix(entries, "R0_rect", 9, path).reshape(3, 3)
    road_T_cam = np.eye(4)
    road_T_cam[:3, :] = _matrix(entries, "Tr_cam_to_road", 12, path).reshape(3, 4)
    H = (P2 @ R0 @ np.linalg.inv(road_T_cam))[:, [0, 2, 3]]
    pose = (("source", "kitti"), ("calibration", path.name), ("height_m", round(-float(road_T_cam[1, 3]), 4)))
    return GroundView(tuple(float(v) for v in H.ravel()), (int(size[0]), int(size[1])), devkit=True,
                      origin_z=float(road_T_cam[2, 3]), pose=pose)


@dataclass(frozen=True)
class BevSource:
    """Where a ``--camera`` puts the road plane for each frame: one camera (``camera``, a
    :class:`Camera`), a folder of per-frame calibration files (a :class:`FrameCameras`), or one
    KITTI calibration file (``calib``: its devkit view for every frame, when it has ``Tr_cam_to_road``)."""

    camera: Camera | FrameCameras
    calib: Path | None = None

    @classmethod
    def from_spec(cls, spec: str, sample_image: Path | None = None) -> "BevSource":
        """A preset, a camera file or a folder of per-frame calibration files (:func:`vcprep.camera.load_cameras`)."""
        return cls.of(load_cameras(spec, sample_image, per_frame=True), spec)

    @classmethod
    def of(cls, camera: Camera | FrameCameras, spec: str | Path | None = None) -> "BevSource":
        """The source of a camera already loaded from ``spec`` (a KITTI ``.txt`` file: its devkit view)."""
        calib = Path(spec) if isinstance(camera, Camera) and str(spec or "").lower().endswith(".txt") else None
        return cls(camera, calib)

    @property
    def calibrated(self) -> bool:
        """Every frame's pose comes from its calibration (per-frame folder or KITTI file): no VP needed."""
        return isinstance(self.camera, FrameCameras) or self.calib is not None

    def view(self, image: str | Path, size: tuple[int, int], vp: tuple[float, float] | None = None,
             vp_status: str | None = None, roll: float = 0.0) -> GroundView:
        """The view of ``image`` (of ``size`` (w, h)): a KITTI file's devkit view, else its camera at
        ``vp``'s pose (None: the camera's nominal pose, or the frame's calibrated one), turned by ``roll``."""
        calib = self.calib
        if isinstance(self.camera, FrameCameras):
            calib = self.camera.file_for(image)
        if calib is not None and calib.suffix.lower() == ".txt":
            view = kitti_view(calib, size)
            if view is not None:
                return view
        if isinstance(self.camera, FrameCameras):
            return camera_view(self.camera.for_image(image, size), source="calibration", roll=roll)
        return camera_view(self.camera.for_image_size(size, image), vp, vp_status, roll=roll)
