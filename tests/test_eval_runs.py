"""Outputs that never mix (issue 80 item 4): `vctrain eval` scores the perspective masks of the runs a
folder records, never `predict --bev`'s BEV files; a folder holding the frames of two predict runs is
named as such (its runs, `--run`) where some of its frames have no label; a video's frames are
recorded; `eval --bev` takes the poses `predict --bev` gave the frames and says which.

Synthetic roads of known geometry (vcprep.synthetic) through a camera file, predicted by the shipped
resize model (its network is not what is checked: the files, the record and the scores' plumbing).
The BEV scores are checked against an oracle computed here from predict's own masks and the labels
at the recorded VP poses (vcprep.bev, numpy).
"""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from vcprep.bev import BevGrid, BevSource, bev_maps, to_bev
from vcprep.camera import camera_to_yaml
from vcprep.synthetic import RoadScene, render_road

from conftest import assert_one_error_line, run_cli
from test_predict_bev import _camera  # the same synthetic camera (480x270, 70 deg, 1.5 m, 3 deg down)

ROOT = Path(__file__).resolve().parent.parent
MODEL = ROOT / "models" / "road-multicamera" / "road.pt"
GRID_ARGS = ("--range=-8,8,4,36", "--res", "0.1")
GRID = BevGrid(-8.0, 8.0, 4.0, 36.0, 0.1)
FAST = ("--engine", "torch", "--threads", "1", "-q")
FMT = "values:road=1"


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """(camera file, set A (2 frames) with labels, set B (2 frames, no labels here), a 3-frame video)."""
    tmp = tmp_path_factory.mktemp("eval_runs")
    cam = _camera()
    (tmp / "cam.yaml").write_text(camera_to_yaml(cam))
    for d in ("a", "b", "labels_a"):
        (tmp / d).mkdir()
    frames = []
    for i in range(4):
        img, lab = render_road(cam, RoadScene(width=7.0, offset=0.4 * i - 0.6, texture_seed=i), pan=i - 1.5,
                               tilt=cam.tilt + 0.5 * i, supersample=2)
        frames.append(img)
        folder = "a" if i < 2 else "b"
        cv2.imwrite(str(tmp / folder / f"road_{i}.png"), img)
        if folder == "a":
            cv2.imwrite(str(tmp / "labels_a" / f"road_{i}.png"), lab)
    video = tmp / "drive.mp4"
    vw = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, cam.size)
    for img in frames[:3]:
        vw.write(img)
    vw.release()
    return tmp


def _predict(scene, images, out, *extra):
    r = run_cli("predict", MODEL, images, "--camera", scene / "cam.yaml", "--out", out, *FAST, *extra,
                prog="vctrain")
    assert r.returncode == 0, r.stderr
    return r


def _eval(scene, out, *extra):
    return run_cli("eval", out, "--labels", scene / "labels_a", "--label-format", FMT, "--json", "-q", *extra,
                   prog="vctrain")


def test_eval_of_a_fresh_predict_bev_folder_counts_its_perspective_masks_alone(scene, tmp_path):
    out = tmp_path / "p"
    _predict(scene, scene / "a", out, "--bev", *GRID_ARGS)
    assert sorted(p.name for p in out.glob("*_bev_mask.png")) == ["road_0_bev_mask.png", "road_1_bev_mask.png"]
    for extra in ((), ("--bev", "--camera", str(scene / "cam.yaml"), *GRID_ARGS)):
        r = _eval(scene, out, *extra)
        assert r.returncode == 0, r.stderr
        assert "not written by the model" not in r.stderr, r.stderr  # before issue 80: "2 of its 4 masks ..."
    r = run_cli("eval", out, "--labels", scene / "labels_a", "--label-format", FMT, prog="vctrain")
    assert r.stdout.startswith(f"# {out}: 2 frames scored"), r.stdout


def test_eval_bev_takes_the_poses_predict_bev_kept_and_says_so(scene, tmp_path):
    out = tmp_path / "p"
    _predict(scene, scene / "a", out, "--bev", *GRID_ARGS)
    poses = json.loads((out / "predict.json").read_text())["bev_poses"]
    assert sorted(poses) == ["road_0", "road_1"] and all(p["source"] == "vp" for p in poses.values())
    r = run_cli("eval", out, "--labels", scene / "labels_a", "--label-format", FMT, "--json", "--bev", "--camera",
                scene / "cam.yaml", *GRID_ARGS, prog="vctrain")
    assert r.returncode == 0, r.stderr
    assert "BEV poses: each frame's pose from its road VP (2 frames), as 'vctrain predict --bev' found them" \
        in r.stderr, r.stderr
    # the oracle: IoU over both frames of predict's masks and the labels, on the grid at the kept VP poses
    source, tp, union = BevSource.from_spec(str(scene / "cam.yaml")), 0, 0
    for stem, pose in poses.items():
        label = cv2.imread(str(scene / "labels_a" / f"{stem}.png"), cv2.IMREAD_UNCHANGED)
        mask = cv2.imread(str(out / f"{stem}_mask.png"), cv2.IMREAD_UNCHANGED)
        view = source.view(Path(f"{stem}.png"), (label.shape[1], label.shape[0]), tuple(pose["vp"]), pose["vp_status"])
        maps = bev_maps(view, GRID)
        bl, bm = to_bev(label, maps, "label"), to_bev((mask != 0).astype(np.uint8), maps, "label")
        seen = bl != 255
        tp += int(((bm == 1) & (bl == 1) & seen).sum())
        union += int((((bm == 1) | (bl == 1)) & seen).sum())
    assert json.loads(r.stdout)["bev"]["iou"] == pytest.approx(tp / union, abs=1e-9)
    nominal = run_cli("eval", out, "--labels", scene / "labels_a", "--label-format", FMT, "--json", "--bev",
                      "--camera", scene / "cam.yaml", "--within", "none", *GRID_ARGS, prog="vctrain")
    assert "BEV poses: the camera's nominal pose (--within none)" in nominal.stderr
    assert json.loads(nominal.stdout)["bev"]["iou"] != json.loads(r.stdout)["bev"]["iou"]  # the frames are pitched


def test_a_folder_of_two_runs_is_named_as_such_and_run_scores_one(scene, tmp_path):
    out = tmp_path / "p"
    _predict(scene, scene / "a", out)
    _predict(scene, scene / "b", out)  # the same model, another frame set, the same folder
    record = json.loads((out / "predict.json").read_text())
    assert [r["inputs"] for r in record["runs"]] == [[str(scene / "a")], [str(scene / "b")]]
    assert [r["frames"] for r in record["runs"]] == [["road_0", "road_1"], ["road_2", "road_3"]]
    assert record["frames"] == ["road_0", "road_1", "road_2", "road_3"]  # the key as before: every frame
    r = _eval(scene, out)
    assert_one_error_line(r, "holds the frames of 2 predict runs of one model", "run 1: 2 frame(s) of",
                          "run 2: 2 frame(s) of", "2 of its frames (road_2, road_3) have no label", "--run N")
    r = _eval(scene, out, "--run", "1")
    assert r.returncode == 0, r.stderr
    assert _eval(scene, out, "--run", "3").returncode == 1
    _predict(scene, scene / "b", out)  # the same inputs again: that run is replaced, not added
    assert len(json.loads((out / "predict.json").read_text())["runs"]) == 2


def test_a_videos_predict_json_lists_its_frames(scene, tmp_path):
    out = tmp_path / "v"
    _predict(scene, scene / "drive.mp4", out, "--within", "none")
    record = json.loads((out / "predict.json").read_text())
    assert record["frames"] == [f"drive/drive_{i:06d}" for i in range(3)]
    assert record["runs"][0]["inputs"] == [str(scene / "drive.mp4")]
