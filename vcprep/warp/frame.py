"""One frame into the virtual camera and back, in memory: what ``vcprep warp`` does to an image file
(:func:`vcprep.store.build.warp_arrays`, the body of the store build: the same pixels a store
holds), without a store, and the way back of anything computed on the warped image
(:func:`vcprep.warp.backproject.backproject_array`).

Conventions: ``frame`` is H x W (x 3) uint8 as ``cv2.imread`` gives it (BGR); ``vp`` is (u, v) in
frame pixels, origin at the centre of the top-left pixel; ``H`` (``virt_H_src``) maps frame pixels
to virtual-image pixels (homogeneous, x right, y down).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..camera.pinhole import PRESETS, Camera
from ..errors import InputError
from .backproject import backproject_array
from .homography import apply_homography, pose_from_vp, vp_from_pose

__all__ = ["WarpedFrame", "warp_frame", "frame_pose", "warp_at_pose"]


@dataclass(frozen=True)
class WarpedFrame:
    """A frame in the virtual camera: ``image`` (store-sized, what a store built with the same
    settings holds for the frame, bit for bit), ``valid`` (bool: pixels the frame itself covers,
    the rest completed), ``virt_H_src`` (3 x 3) and the store ``record`` fields that describe it
    (``H``, ``size``, ``store_size``, ``vp``, ``pan_deg``, ``tilt_deg``)."""

    image: np.ndarray
    valid: np.ndarray
    virt_H_src: np.ndarray
    record: dict[str, Any]

    def back(self, array: np.ndarray, kind: str = "prob", fill: int = 0) -> np.ndarray:
        """``array`` (store-sized: a mask or P(road) computed on :attr:`image`) in the frame's own
        pixels: ``kind`` 'prob' bilinear, 'mask' nearest; ``fill`` where the virtual image does not
        reach (above the horizon)."""
        return backproject_array(array, self.record, kind, fill)


def warp_frame(frame: np.ndarray, camera: Camera | str, virtual: Camera | str = "virtual", scale: float = 0.125,
               completion: str = "projective", vp: tuple[float, float] | None = None) -> WarpedFrame:
    """``frame`` of ``camera`` (a :class:`Camera` or anything ``--camera`` takes but 'estimate'; at
    any uniform rescale of its calibrated size) in the ``virtual`` camera (a preset name or a
    Camera) at ``scale``, its uncovered pixels filled by ``completion`` ('projective', 'zero',
    'replicate', 'none'), at the pose of the road VP ``vp`` (None: the camera's average pose).
    The camera's ``ego_rows`` (its own vehicle) are never warped."""
    from ..camera.spec import camera_from_spec
    from ..store.build import store_params

    if not isinstance(frame, np.ndarray) or frame.ndim not in (2, 3) or frame.dtype != np.uint8:
        raise InputError(f"frame is {getattr(frame, 'dtype', type(frame).__name__)} "
                         f"{getattr(frame, 'shape', '')}, expected H x W (x 3) uint8", None,
                         "give a decoded frame: cv2.imread(path)")
    size = (frame.shape[1], frame.shape[0])
    cam = camera_from_spec(camera, None, per_frame=False, size=size).for_image_size(size)
    virtual = PRESETS[virtual] if isinstance(virtual, str) and virtual in PRESETS else \
        camera_from_spec(virtual, None, per_frame=False)
    params = store_params(virtual, scale)
    store_size = (int(params["store_size"][0]), int(params["store_size"][1]))
    vp, pan, tilt = frame_pose(cam, vp)
    item, H, record = warp_at_pose(frame, cam, virtual_scaled(params), store_size, completion, vp, pan, tilt)
    return WarpedFrame(item.image, item.valid != 0, np.array(H), record)


def frame_pose(camera: Camera, vp: tuple[float, float] | None = None) -> tuple[tuple[float, float], float, float]:
    """(vp, pan, tilt) of a frame of ``camera`` (at the frame's size) warped at its road VP ``vp``
    (None: the camera's average pose, and the VP of that pose)."""
    if vp is None:
        return vp_from_pose(camera, camera.pan, camera.tilt), camera.pan, camera.tilt
    vp = (float(vp[0]), float(vp[1]))
    pan, tilt = pose_from_vp(camera, vp)
    return vp, pan, tilt


def warp_at_pose(frame: np.ndarray, camera: Camera, virtual_scaled: Camera, store_size: tuple[int, int],
                 completion: str, vp: tuple[float, float], pan: float, tilt: float) -> tuple[Any, np.ndarray, dict]:
    """(the warped item (:class:`vcprep.store.build.WarpedItem`), ``virt_H_src``, the store record fields
    ``H``, ``size``, ``store_size``, ``vp``, ``pan_deg``, ``tilt_deg``) of ``frame`` of ``camera`` at
    (pan, tilt), its road VP ``vp``: :func:`vcprep.store.build.build_item`'s geometry and body, in memory
    (the numbers of a store's item, bit for bit)."""
    from ..store.build import item_geometry, warp_arrays

    size = (frame.shape[1], frame.shape[0])
    cam, H = item_geometry(camera, size, virtual_scaled, None, pan, tilt)
    vp_store = tuple(apply_homography(H, [vp])[0])
    item = warp_arrays(frame, None, store_size, H, completion, vp_store, cam.ego_rows)
    record = {"H": H.ravel().tolist(), "size": list(cam.size), "store_size": list(store_size),
              "vp": [vp[0], vp[1]], "pan_deg": pan, "tilt_deg": tilt}
    return item, H, record


def virtual_scaled(params: dict[str, Any]) -> Camera:
    """The scaled virtual camera exactly as a store holds it (``store_params``' ``virtual_scaled``)."""
    from ..camera.files import camera_from_dict

    return camera_from_dict(params["virtual_scaled"])
