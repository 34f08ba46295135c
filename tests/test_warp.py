"""Image-level exactness of the warp and back-projection on synthetic roads (known geometry)."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from vcprep.camera import PRESETS, Camera
from vcprep.warp import virt_H_src, virtual_at_scale
from vcprep.synthetic import RoadScene, render_road
from vcprep.warp import build_maps, warp_image, warp_label
from vcprep.warp import backproject_array

SCENE = RoadScene(offset=0.4, texture_seed=3)
# a virtual camera at 1/6 scale (917x467): finer than the narrow sources it receives
VIRT = virtual_at_scale(PRESETS["virtual"], 1 / 6)


def _interior(mask: np.ndarray, r: int = 2) -> np.ndarray:
    return cv2.erode(mask.astype(np.uint8), np.ones((2 * r + 1, 2 * r + 1), np.uint8)).astype(bool)


@pytest.fixture(scope="module")
def virtual_render():
    return render_road(VIRT, SCENE, supersample=3)


def _warp(cam, pan, tilt):
    img, lab = render_road(cam, SCENE, pan=pan, tilt=tilt, supersample=3)
    H = virt_H_src(cam, VIRT, pan, tilt)
    maps = build_maps(H, cam.size, VIRT.size)
    return warp_image(img, maps, exact=True), warp_label(lab, maps), maps.valid.astype(bool)


CAMS = {
    "camvid-like": (PRESETS["camvid"].for_image_size((480, 360)), 6.0, -2.0),
    "kitti-like": (PRESETS["kitti"].for_image_size((621, 188)), -9.0, 4.0),
}


@pytest.mark.parametrize("name", list(CAMS))
def test_warped_render_matches_virtual_render_on_road(name, virtual_render):
    vimg, vlab = virtual_render
    cam, pan, tilt = CAMS[name]
    wimg, wlab, valid = _warp(cam, pan, tilt)
    # compare well inside the road and away from the source border (interpolation rim)
    road = _interior(vlab == 1) & _interior(valid, 3)
    assert road.sum() > 2000
    diff = np.abs(wimg.astype(float) - vimg.astype(float))[road]
    assert diff.mean() < 2.5, diff.mean()  # grey levels; the road texture has ~40 levels of contrast
    # label: the warped road mask equals the virtual road mask except on a 1-pixel boundary band
    lab_area = _interior(valid, 1)
    k = np.ones((3, 3), np.uint8)
    band = cv2.dilate(vlab, k) != cv2.erode(vlab, k)  # pixels next to the road edge
    disagree = (wlab != vlab) & lab_area & ~band
    assert disagree.sum() / lab_area.sum() < 0.001


def test_two_cameras_agree_with_each_other(virtual_render):
    a_img, a_lab, a_valid = _warp(*CAMS["camvid-like"])
    b_img, b_lab, b_valid = _warp(*CAMS["kitti-like"])
    both = _interior(a_valid & b_valid, 3) & _interior(virtual_render[1] == 1)
    assert both.sum() > 1000
    assert np.abs(a_img.astype(float) - b_img.astype(float))[both].mean() < 3.0


def test_misregistration_would_be_detected(virtual_render):
    """The tolerance above is meaningful: a 1-degree pan error breaks it."""
    vimg, vlab = virtual_render
    cam, pan, tilt = CAMS["camvid-like"]
    img, _ = render_road(cam, SCENE, pan=pan, tilt=tilt, supersample=3)
    maps = build_maps(virt_H_src(cam, VIRT, pan + 1.0, tilt), cam.size, VIRT.size)
    wimg = warp_image(img, maps, exact=True)
    road = _interior(vlab == 1) & _interior(maps.valid.astype(bool), 3)
    assert np.abs(wimg.astype(float) - vimg.astype(float))[road].mean() > 5.0


def test_warp_then_backproject_returns_source():
    cam, pan, tilt = CAMS["camvid-like"]
    img, lab = render_road(cam, SCENE, pan=pan, tilt=tilt, supersample=3)
    v = virtual_at_scale(PRESETS["virtual"], 0.25)  # finer than the source: little information lost
    H = virt_H_src(cam, v, pan, tilt)
    maps = build_maps(H, cam.size, v.size)
    rec = {"H": H.ravel().tolist(), "size": list(cam.size), "store_size": list(v.size)}
    back_img = backproject_array(warp_image(img, maps), rec, kind="prob")
    back_lab = backproject_array(warp_label(lab, maps), rec, kind="mask")
    inner = np.zeros(lab.shape, bool)
    inner[2:-2, 2:-2] = True
    # rows far above the horizon map outside the virtual view: compare where the round trip is defined
    back_valid = build_maps(np.linalg.inv(H), v.size, cam.size).valid.astype(bool) & inner
    assert back_valid.mean() > 0.6
    assert np.abs(back_img.astype(float) - img.astype(float))[back_valid].mean() < 1.5
    assert (back_lab[back_valid] == lab[back_valid]).mean() > 0.995


@pytest.mark.parametrize("dtype, channels", [(np.uint8, 1), (np.uint16, 1), (np.uint16, 3)])
def test_greyscale_and_16bit_are_kept(dtype, channels):
    cam = Camera("c", (64, 48), 60.0, 60.0, 31.5, 23.5, 1.4)
    v = Camera("v", (96, 48), 60.0, 60.0, 47.5, 23.5, 1.4)
    img = np.random.default_rng(0).integers(0, np.iinfo(dtype).max, (48, 64) + ((channels,) if channels > 1 else ()),
                                            dtype=dtype)
    out = warp_image(img, build_maps(virt_H_src(cam, v), cam.size, v.size))
    assert out.dtype == dtype and out.shape[:2] == (48, 96) and out.ndim == img.ndim
    # same height and focal: a pure shift by 16 px
    assert np.array_equal(out[:, 16:80], img)
    assert not out[:, :16].any()
