"""The README's route is the measured design (issue 52): `vcprep warp --camera CAM` with no other flag
builds what `vctrain crossval` trains on for one camera, and `vctrain fit STORE` trains as crossval does
(tests/test_study_roles.py checks fit's settings against a study's)."""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from conftest import run_cli
from vcprep.camera import PRESETS
from vcprep.store import Store
from vcprep.synthetic import RoadScene, render_road
from vcprep.warp import apply_homography, virtual_at_scale, vp_from_pose

CAM = PRESETS["camvid"].for_image_size((480, 360))
FMT = "values:road=1;ignore=255"
POSES = [(6.0, -3.0), (-7.0, 2.5), (2.0, 4.0), (-3.0, -1.5), (8.0, 1.0)]  # inside the design's +/-10, +/-5 deg


@pytest.fixture(scope="module")
def frames(tmp_path_factory) -> Path:
    """Five synthetic road frames through CamVid's camera at known poses (the truth: their VPs)."""
    root = tmp_path_factory.mktemp("route")
    (root / "images").mkdir()
    (root / "labels").mkdir()
    for i, (pan, tilt) in enumerate(POSES):
        img, lab = render_road(CAM, RoadScene(texture_seed=i), pan=pan, tilt=tilt, supersample=1)
        cv2.imwrite(str(root / "images" / f"seq_{i:04d}.png"), img)
        cv2.imwrite(str(root / "labels" / f"seq_{i:04d}.png"), lab)
    cam = root / "cam.yaml"
    cam.write_text(yaml.safe_dump(CAM.to_dict(), sort_keys=False))
    return root


def test_warp_with_no_flags_builds_crossvals_one_camera_store(frames, tmp_path):
    from vctrain.study import load_study
    from vctrain.study import Resolution

    study = tmp_path / "study.yaml"
    kitti = Path(__file__).resolve().parent.parent / "examples" / "kitti"
    study.write_text(yaml.safe_dump({"datasets": [
        {"name": "mine", "camera": str(frames / "cam.yaml"), "role": "train", "label_format": FMT,
         "train": {"images": str(frames / "images"), "labels": str(frames / "labels")}},
        {"name": "other", "camera": str(kitti / "calib"), "role": "test", "label_format": "kitti",
         "test": {"images": str(kitti / "image_2"), "labels": str(kitti / "gt_image_2")}}]}))
    res = Resolution(load_study(study), tmp_path / "study")
    ds = res.study.datasets[0]
    virt, scale = res.training_virtual(), res.scale()

    out = tmp_path / "store"
    proc = run_cli("warp", "--camera", frames / "cam.yaml", "--images", frames / "images", "--labels",
                   frames / "labels", "--label-format", FMT, "--out", out)
    assert proc.returncode == 0, proc.stderr
    assert "virtual camera designed from camvid: pan +/-10 deg, tilt +/-5 deg, 8 deg above the horizon" in proc.stderr
    assert "road VPs: 5 accepted" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
    store = Store.open(out)
    # the study's training store: its virtual camera (name aside), its scale, so its size
    mine, theirs = store.params["virtual"], virt.to_dict()
    assert mine["image_size"] == theirs["image_size"]
    assert {k: v for k, v in mine.items() if k not in ("name", "image_size")} == pytest.approx(
        {k: v for k, v in theirs.items() if k not in ("name", "image_size")})
    assert store.scale == pytest.approx(scale, rel=1e-12)
    assert tuple(store.store_size) == tuple(virtual_at_scale(virt, scale).size)
    assert store.store_size[0] * store.store_size[1] == pytest.approx(172800, rel=0.01)
    # each frame's own pose from its road VP (within estimate), by the study's VP rule
    vs = store.virtual
    for rec in sorted(store, key=lambda r: r["id"]):
        pan, tilt = POSES[int(rec["id"][-4:])]
        assert rec["vp_status"] == "accepted"
        assert rec["vp_rule"] == res.vp_rule(ds).to_dict()
        assert rec["pan_deg"] == pytest.approx(pan, abs=0.5) and rec["tilt_deg"] == pytest.approx(tilt, abs=0.5)
        assert np.hypot(*np.subtract(rec["vp"], vp_from_pose(CAM, pan, tilt))) < 8.0
        H = np.array(rec["H"]).reshape(3, 3)
        assert apply_homography(H, [rec["vp"]])[0] == pytest.approx((vs.cx, vs.cy), abs=1e-6)


def test_a_store_keeps_its_virtual_camera_for_another_camera(frames, tmp_path):
    out = tmp_path / "store"
    assert run_cli("warp", "--camera", frames / "cam.yaml", "--images", frames / "images", "--out", out, "-q").returncode == 0
    before = json.loads((out / "store.json").read_text())
    root = Path(__file__).resolve().parent.parent / "examples" / "kitti"
    proc = run_cli("warp", "--camera", root / "calib", "--images", root / "image_2", "--out", out, "-q")
    assert proc.returncode == 0, proc.stderr
    assert json.loads((out / "store.json").read_text()) == before
    rec = Store.open(out).get("um_000000")
    assert rec["camera"] == "calib" and rec["vp_status"] == "calibrated"  # per-frame calibration: its exact pose
    # a virtual camera given that is not the store's is refused, the store untouched
    proc = run_cli("warp", "--camera", frames / "cam.yaml", "--images", frames / "images", "--out", out,
                   "--virtual", "virtual", "-q")
    assert proc.returncode == 1 and "one store holds one virtual camera" in proc.stderr
    assert json.loads((out / "store.json").read_text()) == before


def test_the_papers_store_on_request(frames, tmp_path):
    out = tmp_path / "store"
    proc = run_cli("warp", "--camera", frames / "cam.yaml", "--images", frames / "images", "--out", out,
                   "--virtual", "virtual", "--scale", "0.125", "--within", "none", "-q")
    assert proc.returncode == 0, proc.stderr
    store = Store.open(out)
    assert tuple(store.store_size) == (688, 350)
    assert all(r["vp_status"] == "camera" for r in store)  # every frame at the camera's average pose
