"""Ground-plane homographies against independent oracles: ray casting on the road plane and the
sign conventions of method.md."""
from __future__ import annotations

import math

import numpy as np
import pytest

from vcprep.camera import PRESETS, Camera
from vcprep.errors import GeometryError
from vcprep.warp import apply_homography, check_not_folded, pose_axes, pose_from_vp, road_magnification, virt_H_src, \
    virtual_at_scale, vp_from_pose
from vcprep.synthetic import ground_points
from vcprep.warp import build_maps


def project(cam: Camera, X, Z, pan, tilt):
    """World road point -> pixel by the definition P_cam = R P + t, t = h R2 (independent of G)."""
    R1, R2, R3 = pose_axes(pan, tilt)
    R = np.column_stack([R1, R2, R3])
    P = np.stack([X.ravel(), np.zeros(X.size), Z.ravel()])
    Pc = R @ P + (cam.height * R2)[:, None]
    p = cam.K @ Pc
    shape = X.shape
    with np.errstate(divide="ignore", invalid="ignore"):  # points behind the camera: depth <= 0, masked later
        return (p[0] / p[2]).reshape(shape), (p[1] / p[2]).reshape(shape), Pc[2].reshape(shape)


def test_pose_axes_is_a_rotation_with_world_origin_below_camera():
    for pan, tilt in [(0, 0), (12, -7), (-20, 15)]:
        R = np.column_stack(pose_axes(pan, tilt))
        assert np.allclose(R.T @ R, np.eye(3)) and np.isclose(np.linalg.det(R), 1)
    R1, R2, R3 = pose_axes(0, 0)
    assert np.allclose([R1, R2, R3], np.eye(3))


def test_virtual_to_itself_is_identity():
    v = PRESETS["virtual"]
    H = virt_H_src(v, v)
    assert np.allclose(H / H[2, 2], np.eye(3), atol=1e-12)


def test_level_camera_horizon_lands_on_virtual_horizon_row():
    v = virtual_at_scale(PRESETS["virtual"], 0.125)
    for name in ("camvid", "kitti", "qian", "toronto2020"):
        cam = PRESETS[name]
        H = virt_H_src(cam, v)
        pts = np.array([[u, cam.cy] for u in np.linspace(0, cam.size[0] - 1, 7)])
        assert np.allclose(apply_homography(H, pts)[:, 1], v.cy, atol=1e-9)


def test_cityscapes_tilt_puts_vp_above_principal_point():
    cs = PRESETS["cityscapes"]
    u, v = vp_from_pose(cs)
    assert u == pytest.approx(cs.cx)
    assert v == pytest.approx(cs.cy - cs.fy * math.tan(math.radians(2.4)))
    # the ray tracer agrees: rows at or above the VP row see no ground, the row below does
    X, Z, hit = ground_points(cs)
    row = int(math.floor(v))
    assert not hit[row, int(cs.cx)] and hit[row + 1, int(cs.cx)]


def test_vp_pose_round_trip_and_vp_maps_to_virtual_principal_point():
    v = virtual_at_scale(PRESETS["virtual"], 0.125)
    cam = PRESETS["camvid"].for_image_size((480, 360))
    for pan, tilt in [(0, 0), (15, -10), (-19, 14), (7, 3)]:
        vp = vp_from_pose(cam, pan, tilt)
        assert pose_from_vp(cam, vp) == pytest.approx((pan, tilt), abs=1e-9)
        H = virt_H_src(cam, v, pan, tilt)
        assert apply_homography(H, [vp])[0] == pytest.approx([v.cx, v.cy], abs=1e-6)


@pytest.mark.parametrize("name, pan, tilt", [("camvid", 0, 0), ("kitti", 8, -3), ("cityscapes", -12, 6),
                                             ("toronto2020", 18, 12)])
def test_warp_maps_are_exact_on_the_road_plane(name, pan, tilt):
    """For every virtual pixel that sees the road, the map must point at the source pixel that
    sees the same road point (found by ray casting + projection, not through G)."""
    src = PRESETS[name].for_image_size((PRESETS[name].size[0] // 2, PRESETS[name].size[1] // 2))
    v = virtual_at_scale(PRESETS["virtual"], 0.1)
    H = virt_H_src(src, v, pan, tilt)
    maps = build_maps(H, src.size, v.size)
    X, Z, hit = ground_points(v, supersample=1)
    u, w, depth = project(src, X, Z, pan, tilt)
    inside = hit & (depth > 0) & (u > 0) & (u < src.size[0] - 1) & (w > 0) & (w < src.size[1] - 1)
    assert inside.sum() > 1000
    err = np.hypot(maps.map_x[inside] - u[inside], maps.map_y[inside] - w[inside])
    assert err.max() < 2e-3  # float32 maps: exact to ~1e-4 px
    assert maps.valid[inside].all()


def test_folded_homography_is_refused():
    wide = Camera("wide", (720, 720), 200.0, 200.0, 359.5, 359.5, 1.5, tilt=40.0)  # sees behind its own foot
    v = virtual_at_scale(PRESETS["virtual"], 0.125)
    with pytest.raises(GeometryError, match="fold"):
        check_not_folded(virt_H_src(wide, v), wide.size, "wide")
    check_not_folded(virt_H_src(PRESETS["camvid"], v), PRESETS["camvid"].size)


def test_virtual_at_scale_keeps_square_pixels_and_pixel_centres():
    v8 = virtual_at_scale(PRESETS["virtual"], 0.125)
    assert v8.size == (688, 350)
    assert v8.fx == v8.fy == pytest.approx(2262 / 8)
    assert v8.cx == pytest.approx(0.125 * 2750.5 - 0.5)


@pytest.mark.parametrize("fs, hs, size", [(500.0, 1.2, (640, 480)), (160.0, 1.4, (320, 227)), (900.0, 2.4, (1280, 720))])
def test_road_magnification_of_level_cameras_is_the_closed_form(fs, hs, size):
    """Level cameras with the VP on the principal point: a road point (X, Z) is at u = c_x + f X / Z,
    v = c_y + f h / Z in each, so the virtual image of the road is the source's stretched by f_v / f_s
    across and f_v h_v / (f_s h_s) down: linear magnification (f_v / f_s) sqrt(h_v / h_s) everywhere."""
    v = virtual_at_scale(PRESETS["virtual"], 0.125)
    src = Camera("s", size, fs, fs, (size[0] - 1) / 2, (size[1] - 1) / 2, hs, 0.0, 0.0)
    H = virt_H_src(src, v)
    want = (v.fx / fs) * math.sqrt(v.height / hs)
    assert road_magnification(H, size, vp_from_pose(src)[1]) == pytest.approx(want, rel=1e-9)
    assert road_magnification(virt_H_src(v, v), v.size, vp_from_pose(v)[1]) == pytest.approx(1.0, rel=1e-12)
