"""Canvases of one virtual camera: design with a given focal length, and the extension that holds a
wider or steeper camera (vcprep.camera.virtual), checked against exact projections of the frames."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from vcprep.camera import PRESETS
from vcprep.warp import apply_homography, virt_H_src
from vcprep.camera import design_virtual_camera, extend_canvas, same_camera_other_canvas

CAMVID = PRESETS["camvid"].for_image_size((240, 180))
KITTI = PRESETS["kitti"].for_image_size((414, 125))   # 81 deg wide against CamVid's 58


def _lower_half_grid(cam, step=3):
    w, h = cam.visible_size
    ys, xs = np.mgrid[(h - 1) // 2:h:step, 0:w:step]
    return np.stack([xs.ravel(), ys.ravel()], 1).astype(float)


def _train_canvas():
    return design_virtual_camera([CAMVID], 5, 3, above=8, f=600.0, height=1.3).camera


def test_design_with_a_given_focal_length_and_height_keeps_them():
    v = _train_canvas()
    assert v.fx == v.fy == 600.0 and v.height == 1.3 and v.tilt == v.pan == 0.0
    # a canvas of the same camera holding more cameras: only the rectangle differs, the top edge too is the same
    both = design_virtual_camera([CAMVID, KITTI], 5, 3, above=8, f=600.0, height=1.3).camera
    assert same_camera_other_canvas(both.to_dict(), v.to_dict())
    assert both.size[0] > v.size[0] and both.cy == pytest.approx(v.cy)
    assert not same_camera_other_canvas(replace(both, fx=601.0, fy=601.0).to_dict(), v.to_dict())


def test_a_camera_the_canvas_holds_leaves_it_unchanged():
    v = _train_canvas()
    assert extend_canvas(v, [(CAMVID, 0.0, 0.0), (CAMVID, 2.0, -1.0)]) is v


@pytest.mark.parametrize("pan, tilt", [(0.0, 0.0), (6.0, 2.0), (-4.0, 5.0)])
def test_a_wider_steeper_camera_extends_the_canvas_minimally_and_exactly(pan, tilt):
    v = _train_canvas()
    steep = replace(KITTI, tilt=KITTI.tilt + tilt, ego_rows=10)
    ext = extend_canvas(v, [(steep, steep.pan + pan, steep.tilt)])
    assert same_camera_other_canvas(ext.to_dict(), v.to_dict())
    # the training rectangle is a window of the extension: the same rows above the horizon, and
    # the old columns shifted by the growth on the left
    assert ext.cy == pytest.approx(v.cy) and ext.size[0] >= v.size[0] and ext.size[1] >= v.size[1]
    grow_l = ext.cx - v.cx
    assert grow_l == int(grow_l) and 0 <= grow_l <= ext.size[0] - v.size[0]
    # every pixel of the visible lower half, projected exactly at the frame's pose, is inside ...
    p = apply_homography(virt_H_src(steep.without_ego(), ext, steep.pan + pan, steep.tilt), _lower_half_grid(steep))
    assert p[:, 0].min() >= -0.5 and p[:, 0].max() <= ext.size[0] - 0.5 and p[:, 1].max() <= ext.size[1] - 0.5
    # ... and each grown side reaches no further than 2 px (the size multiple) past the extreme pixel
    corners = apply_homography(virt_H_src(steep.without_ego(), ext, steep.pan + pan, steep.tilt),
                               np.array([[-0.5, (steep.visible_size[1] - 1) / 2], [steep.visible_size[0] - 0.5,
                                         (steep.visible_size[1] - 1) / 2],
                                         [-0.5, steep.visible_size[1] - 0.5],
                                         [steep.visible_size[0] - 0.5, steep.visible_size[1] - 0.5]]))
    if grow_l:
        assert corners[:, 0].min() - (-0.5) < 2.0
    if ext.size[0] - v.size[0] - grow_l:
        assert (ext.size[0] - 0.5) - corners[:, 0].max() < 2.0
    if ext.size[1] > v.size[1]:
        assert (ext.size[1] - 0.5) - corners[:, 1].max() < 2.0
    # the own vehicle's rows are not held: with them the bottom would reach further
    full = extend_canvas(v, [(replace(steep, ego_rows=0), steep.pan + pan, steep.tilt)])
    assert full.size[1] > ext.size[1] if ext.size[1] > v.size[1] else full.size[1] >= ext.size[1]


def test_median_extent_holds_the_middle_camera_and_cuts_the_extremes():
    """extent='median' over three cameras (CamVid, a steep LUMS-like low camera, KITTI's 81 deg):
    sideways and downward the rectangle reaches as far as the median camera does, checked against
    the exact projection of each camera's lower half."""
    low = replace(CAMVID, name="low", height=0.8, tilt=8.0)
    cams = [CAMVID, low, KITTI]
    v = design_virtual_camera(cams, 5, 3, above=8, f=600.0, height=1.2, extent="median").camera
    full = design_virtual_camera(cams, 5, 3, above=8, f=600.0, height=1.2).camera
    assert same_camera_other_canvas(v.to_dict(), full.to_dict()) and v.cy == pytest.approx(full.cy)

    def reach(cam):  # half width and lowest row reached by the lower half's pixel edges, with the pose margins
        w, h = cam.size
        edges = np.array([[-0.5, (h - 1) / 2], [w - 0.5, (h - 1) / 2], [w - 0.5, h - 0.5], [-0.5, h - 0.5]])
        p = apply_homography(virt_H_src(cam, v), edges)
        return np.abs(p[:, 0] - v.cx).max() + 600 * np.tan(np.radians(5)), p[:, 1].max() + 600 * np.tan(np.radians(3))

    sides, depths = zip(*(reach(c) for c in cams))
    assert max(sides) > np.median(sides) + 50 and max(depths) > np.median(depths) + 50  # the extremes are cut
    # centred, sides rounded up to the size multiple (2 px); the bottom edge just below the median's lowest row
    assert 0 <= v.size[0] / 2 - np.median(sides) < 1 and 0 <= (v.size[1] - 0.5) - np.median(depths) < 2
    assert 0 <= full.size[0] / 2 - max(sides) < 1 and 0 <= (full.size[1] - 0.5) - max(depths) < 2
    with pytest.raises(Exception, match="extent"):
        design_virtual_camera(cams, 5, 3, extent="mean")
