"""`vctrain predict --bev` against the library's oracle (vcprep.bev).

No trained model is exact, so the plumbing is checked, not the network: synthetic roads of known
geometry (vcprep.synthetic, one pitched 2 degrees off its camera file, one with a wall across the
road) through a camera file, predicted by the shipped resize model; each frame's BEV mask must be
vcprep.bev.to_bev of predict's own perspective mask under the view vcprep.bev gives that frame
(its road VP by the model's VP rule; --within none: the nominal pose), its BEV probability the same of
its _prob.png, and its JSON line road_in_metres of that mask, key for key. A video's frames get one
line each, in order; --bev without a camera is one error line naming the fix. A virtual-camera model:
tests/test_vctrain.py (its trained fixture), with the same check.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from vcprep.bev import BevGrid, BevSource, bev_maps, camera_view, frame_views, road_in_metres, to_bev
from vcprep.camera import Camera, camera_to_yaml
from vcprep.dataset import collect_images
from vcprep.synthetic import RoadScene, render_road

from conftest import run_cli

ROOT = Path(__file__).resolve().parent.parent
MODEL = ROOT / "models" / "road-multicamera" / "road.pt"
GRID = BevGrid(-8.0, 8.0, 4.0, 36.0, 0.1)  # --range=-8,8,4,36 --res 0.1: not the default, so it is passed on
BEV_ARGS = ("--bev", "--range=-8,8,4,36", "--res", "0.1", "--corridor", "2.0", "--engine", "torch", "--threads", "1")


def _camera() -> Camera:
    w, h, hfov = 480, 270, 70.0
    f = (w / 2) / math.tan(math.radians(hfov / 2))
    return Camera("synthetic", (w, h), f, f, (w - 1) / 2, (h - 1) / 2, 1.5, 3.0)


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """(camera file, folder of 2 frames: one as the file says, one pitched 2 deg more with a wall 12 m
    ahead; a 3-frame video of the same camera)."""
    tmp = tmp_path_factory.mktemp("predict_bev")
    cam = _camera()
    (tmp / "cam.yaml").write_text(camera_to_yaml(cam))
    frames = tmp / "frames"
    frames.mkdir()
    road = RoadScene(width=7.0)
    images = [render_road(cam, road, supersample=2)[0],
              render_road(cam, RoadScene(width=7.0, obstacle=(-1.5, 1.5, 12.0, 1.0)), tilt=cam.tilt + 2,
                          supersample=2)[0]]
    for i, img in enumerate(images):
        cv2.imwrite(str(frames / f"road_{i}.png"), img)
    video = tmp / "drive.mp4"
    vw = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, cam.size)
    for img in images + images[:1]:
        vw.write(img)
    vw.release()
    return tmp / "cam.yaml", frames, video


def _lines(stdout: str) -> list[dict]:
    return [json.loads(line) for line in stdout.splitlines() if line.strip()]


def _check_frame(out: Path, stem: str, record: dict, view) -> None:
    """The frame's BEV PNGs and JSON line against vcprep.bev on predict's own perspective outputs."""
    maps = bev_maps(view, GRID)
    mask = cv2.imread(str(out / f"{stem}_mask.png"), cv2.IMREAD_UNCHANGED)
    prob = cv2.imread(str(out / f"{stem}_prob.png"), cv2.IMREAD_UNCHANGED)
    want = to_bev((mask != 0).astype(np.uint8), maps, "label")
    got = cv2.imread(str(out / f"{stem}_bev_mask.png"), cv2.IMREAD_UNCHANGED)
    assert got.shape == GRID.shape and set(np.unique(got)) <= {0, 1, 255}
    assert np.array_equal(got, want), f"{stem}: BEV mask is not to_bev of the perspective mask"
    assert (want == 1).any() and (want == 255).any()  # road seen, and cells the camera does not see
    assert np.array_equal(cv2.imread(str(out / f"{stem}_bev_prob.png"), cv2.IMREAD_UNCHANGED),
                          to_bev(prob, maps, "prob"))
    oracle = road_in_metres(want, GRID, view, corridor=2.0)
    assert {k: v for k, v in record.items() if k not in ("id", "frame")} == json.loads(json.dumps(oracle))


def test_folder_bev_equals_the_library_on_predicts_own_masks(scene, tmp_path):
    from vctrain.predict.road import model_vp_rule
    from vctrain.training import CheckpointData, load_checkpoint

    cam_file, frames, _ = scene
    out = tmp_path / "out"
    r = run_cli("predict", MODEL, frames, "--camera", cam_file, "--out", out, "--overlay", "-q", *BEV_ARGS,
                prog="vctrain")
    assert r.returncode == 0, r.stderr
    records = _lines(r.stdout)
    assert [x["id"] for x in records] == ["road_0", "road_1"]  # one line a frame, in order, nothing else
    for x in records:  # the keys and their types
        assert set(x) == {"id", "free_m", "width_m", "area_m2", "pose", "free_to_edge", "free_stop", "start_m",
                          "start_why", "edges_m", "others_m"}
        assert isinstance(x["free_to_edge"], bool)
        assert x["free_m"] is None or isinstance(x["free_m"], float)
        assert set(x["width_m"]) == {"10", "20", "30"}
        assert all(w is None or isinstance(w, float) for w in x["width_m"].values())
        assert isinstance(x["area_m2"], float) and x["pose"]["source"] == "vp"
    # the oracle's views: each frame's road VP by the model's rule, as vcprep bev finds them
    jobs = collect_images([frames])
    rule = model_vp_rule(CheckpointData.from_dict(load_checkpoint(MODEL)["data"]))[0]
    views = frame_views(jobs, BevSource.from_spec(str(cam_file)), "estimate", rule)
    for x in records:
        _check_frame(out, x["id"], x, views[x["id"]])
    # the pitched frame's pose is its own: 2 deg more tilt than the file's (the detector's VP, within 0.5 deg)
    assert abs(records[1]["pose"]["tilt_deg"] - (_camera().tilt + 2)) < 0.5, records[1]["pose"]
    inset = cv2.imread(str(out / "road_0_overlay.png"))[4:4 + 90, -4 - 45:-4]  # the inset: top right corner
    assert (np.abs(inset.astype(int) - (0, 200, 0)).sum(axis=2) == 0).any()  # its road drawn


def test_video_frames_get_one_line_each_in_order_at_the_nominal_pose(scene, tmp_path):
    cam_file, _, video = scene
    out = tmp_path / "out"
    r = run_cli("predict", MODEL, video, "--camera", cam_file, "--out", out, "--within", "none", "--overlay", "-q",
                *BEV_ARGS, prog="vctrain")
    assert r.returncode == 0, r.stderr
    records = _lines(r.stdout)
    assert [(x["id"], x["frame"]) for x in records] == [(f"drive_{i:06d}", i) for i in range(3)]
    view = camera_view(_camera())  # --within none: the camera file's pose for every frame
    for x in records:
        assert x["pose"]["source"] == "nominal"
        _check_frame(out / "drive", x["id"], x, view)
    assert (out / "drive_overlay.mp4").stat().st_size > 0


def test_bev_without_a_camera_is_one_error_line(scene, tmp_path):
    _, frames, _ = scene
    r = run_cli("predict", MODEL, frames, "--out", tmp_path / "out", "--bev", prog="vctrain")
    assert r.returncode == 1
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error:") and "--bev needs the frames' camera" in lines[0]
    assert "add --camera" in lines[0] and not r.stdout and not (tmp_path / "out").exists()


def test_store_items_get_their_bev_too(scene, tmp_path):
    from vcprep.camera import PRESETS, read_camera_yaml
    from vcprep.store import WarpSettings, warp_dataset

    cam_file, frames, _ = scene
    cam = read_camera_yaml(cam_file)
    warp_dataset(collect_images([frames]), tmp_path / "store", WarpSettings(cam, PRESETS["virtual"], 0.02,
                                                                              progress=False))
    out = tmp_path / "out"
    r = run_cli("predict", MODEL, "--store", tmp_path / "store", "--camera", cam_file, "--out", out, "-q", *BEV_ARGS,
                prog="vctrain")
    assert r.returncode == 0, r.stderr
    records = _lines(r.stdout)
    assert [x["id"] for x in records] == ["road_0", "road_1"]
    for x in records:  # a store built at the camera's pose: its items' BEV at that pose
        assert x["pose"]["source"] == "nominal"
        _check_frame(out, x["id"], x, camera_view(cam))
