"""The pinhole camera above a flat road: the :class:`Camera` record, :func:`scale_matrix` and the
preset table (:data:`PRESETS`). Reading cameras from files is :mod:`vcprep.camera.files`; where a
``--camera`` comes from (preset, file, per-frame folder) is :mod:`vcprep.camera`.

Conventions (``../shared/docs/method.md``):

* pixel (u, v): u right, v down, origin at the CENTRE of the top-left pixel;
* camera frame x right, y down, z forward; ``K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``;
* ``height`` in metres above the road; ``tilt`` (beta) in degrees, positive = optical axis
  pitched DOWN; ``pan`` (alpha) in degrees, rotation about the vertical axis after the tilt.

Resizing an image by ``s`` maps pixel centres as ``u' = s*(u + 0.5) - 0.5``, so K scales as
``fx' = s*fx`` and ``cx' = s*(cx + 0.5) - 0.5`` (see :func:`scale_matrix`).

Ego-vehicle rows (``ego_rows``): the bottom rows of every image that show the rig's own vehicle
(a bonnet). Everything that warps an image treats them as cut off by an exact bottom crop: same
K and pose, source size ``visible_size`` = (w, h - ego_rows) (:meth:`Camera.without_ego`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError

__all__ = ["Camera", "PRESETS", "scale_matrix"]


def scale_matrix(sx: float, sy: float | None = None) -> np.ndarray:
    """3x3 matrix taking pixel coordinates of an image to those of the same image resized by
    (sx, sy), pixel centres at integers: ``u' = sx*(u + 0.5) - 0.5``."""
    sy = sx if sy is None else sy
    return np.array([[sx, 0.0, 0.5 * (sx - 1.0)], [0.0, sy, 0.5 * (sy - 1.0)], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class Camera:
    """A pinhole camera above a flat road.

    ``size`` is (width, height) in pixels of the images K refers to; ``height`` is the
    mounting height in metres; ``tilt``/``pan`` are the average pose in degrees; the bottom
    ``ego_rows`` rows of every image (at ``size``) show the rig's own vehicle and are never
    warped (an exact bottom crop: K unchanged, see :meth:`without_ego`).
    """

    name: str
    size: tuple[int, int]
    fx: float
    fy: float
    cx: float
    cy: float
    height: float
    tilt: float = 0.0
    pan: float = 0.0
    ego_rows: int = 0
    # the camera file states its ego_rows (an explicit 'ego_rows: 0': it shows no own vehicle, none is
    # searched for); not part of the camera's identity (equality, records, store keys)
    ego_stated: bool = field(default=False, compare=False, repr=False)

    @property
    def K(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def width(self) -> int:
        return self.size[0]

    @property
    def rows(self) -> int:
        return self.size[1]

    @property
    def visible_size(self) -> tuple[int, int]:
        """(w, h - ego_rows): the size of the image once the ego-vehicle rows are cut off."""
        return self.size[0], self.size[1] - self.ego_rows

    def without_ego(self) -> "Camera":
        """The camera of the image with its bottom ``ego_rows`` rows cut off: a bottom crop is
        exact, so K and the pose are unchanged and only the height shrinks (``ego_rows`` 0)."""
        if not self.ego_rows:
            return self
        return replace(self, size=self.visible_size, ego_rows=0)

    def fov_deg(self) -> tuple[float, float]:
        """Horizontal and vertical field of view (degrees), measured to the outer pixel edges."""
        w, h = self.size
        hfov = math.atan((self.cx + 0.5) / self.fx) + math.atan((w - 0.5 - self.cx) / self.fx)
        vfov = math.atan((self.cy + 0.5) / self.fy) + math.atan((h - 0.5 - self.cy) / self.fy)
        return math.degrees(hfov), math.degrees(vfov)

    def resized(self, sx: float, sy: float | None = None, size: tuple[int, int] | None = None) -> "Camera":
        """The same camera for images resized by (sx, sy); K follows the pixel-centre rule."""
        sy = sx if sy is None else sy
        K = scale_matrix(sx, sy) @ self.K
        if size is None:
            size = (int(round(self.size[0] * sx)), int(round(self.size[1] * sy)))
        return replace(self, size=(int(size[0]), int(size[1])), fx=float(K[0, 0]), fy=float(K[1, 1]),
                       cx=float(K[0, 2]), cy=float(K[1, 2]), ego_rows=self._ego_rows_at(sy, int(size[1])))

    def _ego_rows_at(self, sy: float, rows: int) -> int:
        """``ego_rows`` for the image resized by ``sy`` to ``rows`` rows: every new row that
        reaches below the top edge of the ego-vehicle rows (pixel edge ``sy*(h - ego_rows)``), i.e.
        rounded up so that the whole vehicle stays excluded; at least 1, at most ``rows - 1``."""
        if not self.ego_rows:
            return 0
        n = math.ceil(rows - sy * (self.size[1] - self.ego_rows) - 1e-9)
        return int(min(max(n, 1), rows - 1))

    def for_image_size(self, size: tuple[int, int], file: str | Path | None = None) -> "Camera":
        """This camera for images of ``size`` (w, h).

        Equal size: unchanged. A uniform rescale of the calibrated size: K is scaled exactly per
        axis by the true size ratios. Uniform means one factor ``s`` that rounds to both sides
        (``|s*W - w| <= 1/2`` and ``|s*H - h| <= 1/2``: integer rounding of a true rescale, so the
        aspect ratios agree to what rounding can produce) and ``s`` at least :data:`MIN_RESCALE`
        away from 1: sizes alone cannot tell a rescale by a few percent from a crop of a few pixels
        (KITTI's rectified frames, 1224x370 to 1242x375, are crops: same fx, cx and cy shifted), and
        a crop read as a rescale gets a wrong focal length without a word. Anything else raises
        :class:`InputError` naming both sizes and the fix.
        """
        w, h = int(size[0]), int(size[1])
        W, H = self.size
        if (w, h) == (W, H):
            return self
        sx, sy = w / W, h / H
        lo, hi = max((w - 0.5) / W, (h - 0.5) / H), min((w + 0.5) / W, (h + 0.5) / H)
        what = f"image is {w}x{h} but camera '{self.name}' is calibrated for {W}x{H}"
        if lo <= hi and not (1.0 - MIN_RESCALE < lo and hi < 1.0 + MIN_RESCALE):
            return self.resized(sx, sy, size=(w, h))
        if lo <= hi:  # one factor fits, but within a few percent of 1: a crop as likely as a rescale
            raise InputError(
                f"{what}: {abs(1.0 - sx):.1%} {'smaller' if sx < 1 else 'larger'} across, which reads as a crop, not a "
                f"uniform rescale of it (a rescale must change the size by {MIN_RESCALE:.0%} or more)", file,
                f"give a camera file with image_size [{w}, {h}]: a crop keeps fx and fy and shifts cx and cy by the "
                f"columns and rows cut off the left and top; or resize the images to {W}x{H}")
        raise InputError(
            f"{what}, which is not a uniform rescale of it (aspect {w / h:.4f} against {W / H:.4f})", file,
            f"use a camera file calibrated for {w}x{h} images, or crop/resize the images uniformly to {W}x{H} "
            "or a fraction of it")

    def with_pose(self, pan: float | None = None, tilt: float | None = None) -> "Camera":
        return replace(self, pan=self.pan if pan is None else float(pan), tilt=self.tilt if tilt is None else float(tilt))

    def to_dict(self) -> dict[str, Any]:
        """The YAML schema's keys; ``ego_rows`` only when non-zero (so that the records, keys and
        store parameters of cameras without an ego-vehicle are what they were before it existed)."""
        d = {"name": self.name, "image_size": list(self.size), "fx": self.fx, "fy": self.fy, "cx": self.cx,
             "cy": self.cy, "height": self.height, "tilt": self.tilt, "pan": self.pan}
        if self.ego_rows:
            d["ego_rows"] = int(self.ego_rows)
        return d


# a rescale must change the size by at least this share (module text of Camera.for_image_size): the
# datasets here come rescaled by 1/2 (CamVid) to 1/8 (Cityscapes pix2pix) and the tests by 1/3 to 1/10,
# while crops of a few pixels (1 to 2 %: KITTI's rectified frames) are common and look like rescales
MIN_RESCALE = 0.05


# --- presets: the one table of built-in cameras (paper Table 1; virtual fx = 2262, see method.md)
_PRESET_ROWS = [
    # name          w     h     cx    cy    fx    fy   height  tilt
    ("camvid",      960,  720,  485,  365,  862,  1141, 1.21, 0.0),
    ("cityscapes",  2048, 1024, 1082, 514,  2262, 2252, 1.21, 2.4),
    ("kitti",       1242, 375,  610,  173,  721,  721,  1.65, 0.0),
    ("qian",        2048, 1536, 1024, 768,  1845, 1845, 1.50, 0.0),
    ("toronto2020", 1024, 576,  508,  328,  776,  701,  1.35, 0.0),
    ("virtual",     5500, 2800, 2750, 1400, 2262, 2262, 1.38, 0.0),
]
PRESETS: dict[str, Camera] = {
    r[0]: Camera(name=r[0], size=(r[1], r[2]), cx=float(r[3]), cy=float(r[4]), fx=float(r[5]), fy=float(r[6]),
                 height=r[7], tilt=r[8])
    for r in _PRESET_ROWS
}
PRESETS["kitti"] = replace(PRESETS["kitti"], ego_stated=True)  # KITTI's frames show no own vehicle (roof rig)
