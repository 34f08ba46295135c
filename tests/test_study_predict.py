"""A study's number is the number a user gets: a crossval study's test of a model and `vctrain predict`
of that model on the same frames with the same camera file give the same masks, so `vctrain eval`
gives the study's IoU.

The study (tests/studies.py's mixed study: camvid role train; kitti role both; cityscapes and camvid2
role test) exercises every way the two roads could part: kitti's labels show an own vehicle that the
study finds (ego: auto; predict is told with --ego, as the study's result records), camvid2's label a
bonnet the study does not cut off (its ignore border must not shape the test image's completion:
predict has no label), one camvid2 frame's VP lies outside the study's pose range (the detector's
default range would accept it; the model's recorded rule rejects it, as the study did), and the test
frames at their poses reach past the training rectangle (extended for them on both roads).
"""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
import yaml

from vcprep.store import Store

from conftest import run_cli
from studies import _mixed_study

CONDS = ["resize", "between", "within"]
GEOMETRY = {"resize": "between", "between": "between", "within": "within"}  # (resize reads the store's sources)
CAMERAS = {"kitti": "kitti.yaml", "cityscapes": "cityscapes.yaml", "camvid2": "camvid.yaml"}


@pytest.fixture(scope="module")
def study_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("study_predict")
    study = _mixed_study(root / "data")
    d = yaml.safe_load(study.read_text())
    d["conditions"] = CONDS
    study.write_text(yaml.safe_dump(d, sort_keys=False))
    out = root / "out"
    proc = run_cli("crossval", study, "--out", out, "--quiet", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    return study, out


def _frames(study, name: str) -> list:
    """The image files of dataset ``name``'s test split, as the study selects them."""
    from vctrain.study import Resolution, load_study

    s = load_study(study)
    return [j.image for j in Resolution(s, study.parent / "unused").items(s.dataset(name), "test")]


def _result(out, name: str, cond: str) -> dict:
    run = out / "runs" / ("kitti" if name == "kitti" else "_all") / cond
    return json.loads((run / ("result.json" if name == "kitti" else f"result-{name}.json")).read_text())


@pytest.mark.parametrize("cond", CONDS)
@pytest.mark.parametrize("name", list(CAMERAS))
def test_predict_gives_the_studys_masks_and_iou(study_run, tmp_path, name, cond):
    from vctrain.predict import Predictor

    study, out = study_run
    model = out / "runs" / ("kitti" if name == "kitti" else "_all") / cond / "model.pt"
    # the own vehicle the study found from the labels (study.json), given as the user would give it
    ego = json.loads((out / "study.json").read_text())["ego_found"][name]["ego_rows"]
    preds = tmp_path / "preds"
    proc = run_cli("predict", model, *_frames(study, name), "--camera", study.parent / CAMERAS[name], "--out", preds,
                   "--ego", str(ego), "--device", "cpu", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    # the study's own masks: its predictor on its test store, as it scored them
    predictor = Predictor(model, device="cpu")
    store = Store.open(out / "stores" / name / "test" / GEOMETRY[cond])
    for rec in store:
        prob = predictor.store_item(store, rec)
        mask = cv2.imread(str(preds / f"{rec['id']}_mask.png"), cv2.IMREAD_UNCHANGED)
        assert np.array_equal(mask > 0, prob >= 0.5), f"{name} {cond} {rec['id']}: {np.sum((mask > 0) != (prob >= 0.5))} px"
        p8 = cv2.imread(str(preds / f"{rec['id']}_prob.png"), cv2.IMREAD_UNCHANGED)
        assert np.array_equal(p8, np.clip(np.rint(prob * 255.0), 0, 255).astype(np.uint8))
    labels = study.parent / f"{name}_test" / "labels"
    ev = run_cli("eval", preds, "--labels", labels, "-f", "camvid", "--json", "-q", prog="vctrain")
    assert ev.returncode == 0, ev.stderr
    assert json.loads(ev.stdout)["iou"] == pytest.approx(_result(out, name, cond)["iou"], abs=1e-9)


def test_the_result_records_the_rule_predict_says_it_used(study_run, tmp_path):
    """The study's result records what its test frames were warped with (VP statuses and rule, own
    vehicle, rectangle); `vctrain predict` says the same on stderr, and the model remembers the rule."""
    import torch

    study, out = study_run
    row = _result(out, "camvid2", "within")
    warp = row["test_warp"]
    assert warp["vp_rule"] == {"pan_range": 5.0, "tilt_range": 3.0, "smooth": 0}  # the study's ranges, no smoothing
    assert warp["vp_status"] == {"accepted": 2, "fallback": 1} and warp["ego_rows"] == [0]
    ck = torch.load(out / "runs" / "_all" / "within" / "model.pt", map_location="cpu", weights_only=True)
    assert ck["data"]["vp_rule"] == warp["vp_rule"]
    proc = run_cli("predict", out / "runs" / "_all" / "within" / "model.pt", *_frames(study, "camvid2"),
                   "--camera", study.parent / "camvid.yaml", "--out", tmp_path / "p", "--device", "cpu", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    said = proc.stderr
    assert "VPs: 2 accepted, 1 fallback (the model's rule: pan within 5 deg and tilt within 3 deg" in said
    assert f"virtual rectangle {warp['rectangle'][0]}x{warp['rectangle'][1]}" in said
    assert _result(out, "kitti", "within")["test_warp"]["ego_rows"] == [3]
    # the detector's default range would have accepted the third frame: another rule, other masks
    other = run_cli("predict", out / "runs" / "_all" / "within" / "model.pt", *_frames(study, "camvid2"),
                    "--camera", study.parent / "camvid.yaml", "--out", tmp_path / "q", "--device", "cpu",
                    "--vp-range", "20", "15", prog="vctrain")
    assert other.returncode == 0, other.stderr
    assert "VPs: 3 accepted (the given rule: pan within 20 deg and tilt within 15 deg" in other.stderr
