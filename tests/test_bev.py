"""vcprep.bev, `vcprep bev` and `vctrain eval --bev` against exact oracles.

- Geometry: a rendered straight road 8 m wide with lane lines (vcprep.synthetic), its ideal road
  probability (the share of each pixel's sub-samples on the road), through cameras 0.8-2.0 m high,
  pitched -3..+8 deg, 40-110 deg wide, one rolled 2 deg: the BEV width within 2 %, the free distance
  to a rendered wall within one cell + 1 % of its distance, a frame pitched 2 deg more than its
  camera file says recovered through its road VP (the detector's) to the same tolerances.
- KITTI: the shipped frame's BEV equals the devkit's transform2BEV cell for cell, and `vctrain eval
  --bev` its MaxF and AP within 1e-6 (tests/fixtures/kitti_devkit_bev.json: the devkit's numbers).
"""
from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from vcprep.bev import BevGrid, BevSource, bev_maps, camera_view, kitti_view, road_in_metres, to_bev
from vcprep.camera import PRESETS, Camera
from vcprep.errors import InputError
from vcprep.labels import decode_label, get_label_format
from vcprep.synthetic import RoadScene, render_road, road_fraction
from vcprep.warp import vp_from_pose

from conftest import run_cli

ROOT = Path(__file__).resolve().parent.parent
KITTI = ROOT / "examples" / "kitti"
DEVKIT = json.loads((Path(__file__).parent / "fixtures" / "kitti_devkit_bev.json").read_text())
GRID = BevGrid()
WIDTH, WALL = 8.0, 9.0  # the road's width; the wall across the corridor, metres ahead
WALL_SCENE = RoadScene(width=WIDTH, obstacle=(-1.5, 1.5, WALL, 1.0))
# (horizontal FOV deg, height m, pitch deg down, roll deg)
CAMERAS = [(40, 0.8, -3, 0), (60, 1.2, 0, 0), (90, 1.5, 4, 0), (110, 2.0, 8, 0), (70, 1.4, 2, 2), (110, 0.8, 8, 0)]


def _camera(hfov: float, height: float, tilt: float, w: int = 480, h: int = 270) -> Camera:
    f = (w / 2) / math.tan(math.radians(hfov / 2))
    return Camera(f"fov{hfov}", (w, h), f, f, (w - 1) / 2, (h - 1) / 2, height, tilt)


def _rolled_vp(cam: Camera, roll: float) -> tuple[float, float]:
    """The road VP of ``cam`` turned by ``roll`` about its optical axis: the image of R3 rotated."""
    u, v = vp_from_pose(cam)
    c, s = math.cos(math.radians(roll)), math.sin(math.radians(roll))
    du, dv = (u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy
    return cam.cx + cam.fx * (c * du - s * dv), cam.cy + cam.fy * (s * du + c * dv)


def _bev_mask(prob01: np.ndarray, maps) -> np.ndarray:
    """An ideal road probability onto the grid, then road where P >= 0.5 (unseen 255)."""
    prob = to_bev(np.rint(prob01 * 255).astype(np.uint8), maps, "prob")
    return np.where(maps.valid.astype(bool), prob >= 128, 255).astype(np.uint8)


def _check_road(road: dict, what: str, widths_from: int = 0) -> None:
    widths = [w for d, w in road["width_m"].items() if w is not None and int(d) >= widths_from]
    assert widths, f"{what}: no width in view {road}"
    for w in widths:
        assert abs(w - WIDTH) <= 0.02 * WIDTH, f"{what}: width {w} m for {WIDTH} m ({road['width_m']})"


@pytest.mark.parametrize("hfov,height,tilt,roll", CAMERAS)
def test_width_and_free_distance_through_every_camera(hfov, height, tilt, roll):
    cam = _camera(hfov, height, tilt)
    view = camera_view(cam, _rolled_vp(cam, roll) if roll else None, roll=roll)
    maps = bev_maps(view, GRID)
    road = road_in_metres(_bev_mask(road_fraction(cam, RoadScene(width=WIDTH), roll=roll, supersample=3), maps),
                          GRID, view)
    _check_road(road, f"camera {hfov} deg, {height} m, pitch {tilt}, roll {roll}")
    walled = road_in_metres(_bev_mask(road_fraction(cam, WALL_SCENE, roll=roll, supersample=3), maps), GRID, view)
    assert abs(walled["free_m"] - WALL) <= GRID.res + 0.01 * WALL, walled
    assert road["free_m"] == GRID.z_max  # no wall: free to the grid's far edge


def test_a_label_at_pixel_centres_is_as_exact_as_its_pixels():
    """The binary label (road at each pixel centre) through the nominal pose: widths within 2 % on a
    camera whose pixels are finer than the tolerance (the ideal probability above is finer still)."""
    cam = _camera(60, 1.5, 2, 960, 540)
    view = camera_view(cam)
    road = road_in_metres(to_bev(render_road(cam, RoadScene(width=WIDTH), supersample=1)[1], bev_maps(view, GRID),
                                 "label"), GRID, view)
    _check_road(road, "binary label")
    assert road["pose"]["source"] == "nominal" and road["area_m2"] > 0.9 * WIDTH * (GRID.z_max - 8)


def test_a_frame_pitched_2_deg_is_recovered_through_its_vp(tmp_path):
    """The camera file says pitch 2 deg; the frame was taken at 4 deg. The nominal pose puts the wall
    metres away; the frame's own VP (the detector's, `--within estimate`) brings it back."""
    from vcprep.bev import frame_views
    from vcprep.dataset import Job

    cam, true_tilt = _camera(70, 1.4, 2.0, 640, 360), 4.0
    image, _ = render_road(cam, WALL_SCENE, tilt=true_tilt, supersample=2)
    cv2.imwrite(str(tmp_path / "frame.png"), image)
    walled = road_fraction(cam, WALL_SCENE, tilt=true_tilt, supersample=3)
    jobs = [Job("frame", tmp_path / "frame.png")]
    for within, good in (("none", False), ("estimate", True)):
        view = frame_views(jobs, BevSource(cam), within)["frame"]
        road = road_in_metres(_bev_mask(walled, bev_maps(view, GRID)), GRID, view)
        close = abs(road["free_m"] - WALL) <= GRID.res + 0.01 * WALL
        assert close == good, (within, road)
    assert abs(road["pose"]["tilt_deg"] - true_tilt) < 0.3 and road["pose"]["source"] == "vp"
    open_road = road_fraction(cam, RoadScene(width=WIDTH), tilt=true_tilt, supersample=3)
    _check_road(road_in_metres(_bev_mask(open_road, bev_maps(view, GRID)), GRID, view), "pitched frame via its VP")


def _kitti_arrays():
    gt = cv2.imread(str(KITTI / "gt_image_2" / "um_road_000000.png"), cv2.IMREAD_COLOR)
    h, w = gt.shape[:2]
    v, u = np.mgrid[0:h, 0:w]
    road = (gt[:, :, 0] > 0) & (gt[:, :, 2] > 0)
    prob = (road * 60 + (u * 7 + v * 13) % 196).astype(np.uint8)  # the fixture's probability map
    return gt, prob


def test_kitti_bev_is_the_devkits_cell_for_cell():
    gt, prob = _kitti_arrays()
    maps = bev_maps(kitti_view(KITTI / "calib" / "um_000000.txt", (gt.shape[1], gt.shape[0])), GRID)
    sha = lambda a: hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()  # noqa: E731
    assert sha(to_bev(gt, maps, "image")) == DEVKIT["gt_bev_bgr_array_sha256"]
    assert sha(to_bev(prob, maps, "prob")) == DEVKIT["prob_bev_array_sha256"]
    label = to_bev(decode_label(gt, get_label_format("kitti")), maps, "label")
    assert int(maps.valid.sum()) == DEVKIT["seen_cells"]
    assert (int((label == 1).sum()), int((label == 0).sum())) == (DEVKIT["road_cells"], DEVKIT["not_road_cells"])


def test_vctrain_eval_bev_equals_the_devkit_on_the_kitti_frame(tmp_path):
    _, prob = _kitti_arrays()
    cv2.imwrite(str(tmp_path / "um_000000_prob.png"), prob)
    r = run_cli("eval", str(tmp_path), "--labels", str(KITTI / "gt_image_2"), "--label-format", "kitti", "--bev",
                "--camera", str(KITTI / "calib"), "--json", prog="vctrain")
    assert r.returncode == 0, r.stderr
    bev = json.loads(r.stdout)["bev"]
    assert abs(bev["maxf"] - DEVKIT["MaxF"]) < 1e-6 and abs(bev["ap"] - DEVKIT["AvgPrec"]) < 1e-6
    for ours, theirs in (("precision", "PRE_wp"), ("recall", "REC_wp"), ("fpr", "FPR_wp"), ("fnr", "FNR_wp")):
        assert abs(bev[ours] - DEVKIT[theirs]) < 1e-6, (ours, bev[ours], DEVKIT[theirs])  # the devkit's float32
    assert bev["threshold"] == pytest.approx(DEVKIT["BestThresh"])


def test_vcprep_bev_cli_prints_the_road_in_metres(tmp_path):
    out = tmp_path / "bev"
    r = run_cli("bev", "--camera", str(KITTI / "calib"), "--images", str(KITTI / "image_2"), "--labels",
                str(KITTI / "gt_image_2"), "--label-format", "kitti", "--out", str(out), "--quiet")
    assert r.returncode == 0, r.stderr
    rec = json.loads(r.stdout)
    assert rec["id"] == "um_000000" and set(rec["width_m"]) == {"10", "20", "30"} and rec["pose"]["source"] == "kitti"
    # the label's bottom 4 pixel rows (no road across the frame) are its border: hidden, named, and the
    # corridor runs on past them (before issue 80 they stopped free_m at the grid's first row)
    assert rec["start_why"].startswith("label border (its bottom 4 pixel rows") and rec["free_m"] > 10
    label = cv2.imread(str(out / "um_000000_label.png"), cv2.IMREAD_UNCHANGED)
    assert label.shape == GRID.shape and set(np.unique(label)) <= {0, 1, 255}
    assert rec["area_m2"] == pytest.approx(DEVKIT["road_cells"] * GRID.res ** 2)
    assert cv2.imread(str(out / "um_000000_image.png")).shape == GRID.shape + (3,)


@pytest.mark.parametrize("args,problem", [
    (["--range=-10,10,6,46", "--res", "0.001"], "megacell limit"),
    (["--range=-10,10,-40,-5"], "sees no cell of the grid"),
    (["--camera", "NOHEIGHT"], "missing key 'height'"),
])
def test_bad_input_is_one_error_line(tmp_path, args, problem):
    cam = tmp_path / "cam.yaml"
    cam.write_text("image_size: [640, 360]\nfx: 500\nfy: 500\ncx: 320\ncy: 180\n")
    images = tmp_path / "images"
    images.mkdir()
    cv2.imwrite(str(images / "f.png"), render_road(PRESETS["camvid"].resized(0.5), supersample=1)[0])
    camera = ["--camera", str(cam) if "NOHEIGHT" in args else "camvid"]
    args = [a for a in args if a not in ("--camera", "NOHEIGHT")]
    r = run_cli("bev", *camera, "--images", str(images), "--within", "none", "--out", str(tmp_path / "o"), *args)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1 and len(lines) == 1 and lines[0].startswith("Error: ") and problem in lines[0], r.stderr


def test_grid_convention_far_row_first_and_limits():
    g = BevGrid(-2, 2, 5, 15, 0.5)
    assert g.shape == (20, 8) and g.z_centres()[0] == 14.75 and g.x_centres()[0] == -1.75
    assert g.row_at(14.9) == 0 and g.row_at(5.0) == 19 and g.row_at(4.9) is None
    with pytest.raises(InputError, match="megacell"):
        BevGrid(res=0.0005)
