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


@pytest.mark.parametrize("offset", [0.0, 1.5])
def test_rays_give_a_low_cameras_near_road_exactly(offset):
    """A camera far lower and steeper than the virtual one (0.8 m, 8 deg down, into a 1.21 m level
    virtual camera's training rectangle): its near road lands below the rectangle. Back-projected
    with the rays from the road VP (backproject_rays), the exact road mask warped into the
    rectangle gives the road of the whole frame (a straight road's edges are lines through the VP);
    plain back-projection loses it, and rays stopped at a smaller rectangle inside (the hybrid rule's
    training rectangle in a grown one) still give it."""
    from vcprep.camera import design_virtual_camera
    from vcprep.store import item_geometry, store_params, warp_arrays
    from vcprep.warp import apply_homography, backproject_rays, vp_from_pose

    low = Camera("low", (160, 160), 154.0, 206.0, 79.5, 79.5, 0.8, tilt=8.0)
    scene = RoadScene(offset=offset, width=6.0)
    img, lab = render_road(low, scene, supersample=1)
    trained = design_virtual_camera([PRESETS["camvid"]], 5, 3, above=6).camera
    grown = trained.to_dict()
    grown.update(image_size=[trained.size[0] + 400, trained.size[1] + 800], cx=trained.cx + 200)
    from vcprep.camera import camera_from_dict

    for virt, inner in ((trained, None), (camera_from_dict(grown), True)):
        p = store_params(virt, 0.25)
        vs = camera_from_dict(p["virtual_scaled"])
        cam, H = item_geometry(low, low.size, vs, None, 0.0, 8.0)
        vp = tuple(apply_homography(H, [vp_from_pose(cam, 0.0, 8.0)])[0])
        rect = None
        if inner:
            t = store_params(trained, 0.25)
            ox = vs.cx - t["virtual_scaled"]["cx"]
            rect = (ox, 0.0, ox + t["store_size"][0] - 1.0, t["store_size"][1] - 1.0)
        item = warp_arrays(img, lab, tuple(p["store_size"]), H, "projective", vp, 0)
        rec = {"H": H.ravel().tolist(), "size": list(low.size), "store_size": p["store_size"]}
        prob = (item.label == 1).astype(np.float32)
        got = backproject_rays(prob, rec, vp, rect=rect) >= 0.5
        truth = lab == 1
        assert (got & truth).sum() / (got | truth).sum() > 0.99
        if inner is None:  # the near road outside the training rectangle: plain back-projection says 'not road'
            plain = backproject_array(prob, rec, "prob") >= 0.5
            assert (plain & truth)[120:].sum() < 0.5 * truth[120:].sum()


@pytest.mark.parametrize("vp", [None, (121.0, 52.0)])
def test_warp_frame_is_the_store_builds_item_bit_for_bit(tmp_path, vp):
    """vcprep.warp_frame (in memory) against the oracle ``vcprep warp`` writes: a store of the same
    frame, camera, virtual camera, scale, completion and pose; its way back is the store's."""
    from dataclasses import replace

    from vcprep.dataset import list_dataset
    from vcprep.io import read_image, write_png
    from vcprep.store import WarpSettings, warp_dataset
    from vcprep.vp import ItemPose
    from vcprep.warp import warp_frame

    cam = replace(PRESETS["camvid"].resized(0.25), ego_rows=10)
    frame = render_road(cam, RoadScene(offset=0.4), pan=1.0, supersample=1)[0]
    (tmp_path / "src").mkdir()
    write_png(tmp_path / "src" / "f.png", frame)
    poses = {"f": ItemPose(vp, "given")} if vp is not None else None
    store, _ = warp_dataset(list_dataset(tmp_path / "src"), tmp_path / "store",
                            WarpSettings(cam, PRESETS["virtual"], 0.05, completion="projective", poses=poses,
                                         progress=False))
    rec = next(iter(store))
    warped = warp_frame(frame, cam, "virtual", 0.05, "projective", vp=vp)
    assert np.array_equal(warped.image, read_image(store.path(rec["image"])).array)
    assert warped.record["H"] == rec["H"] and warped.record["store_size"] == rec["store_size"]
    grey = warped.image[..., 1]
    assert np.array_equal(warped.back(grey), backproject_array(grey, rec, "prob"))
    assert warped.valid.dtype == bool and warped.valid.any() and not warped.valid.all()


def test_warp_frame_refuses_what_is_not_a_frame():
    from vcprep.errors import InputError
    from vcprep.warp import warp_frame

    with pytest.raises(InputError, match="expected H x W"):
        warp_frame(np.zeros((20, 20), np.float32), "camvid")
