"""A study's number is the number a user gets: a crossval study's test of a model and `vctrain predict
--engine torch` of that model on the same frames with the same camera file give the same masks, so
`vctrain eval` gives the study's IoU; `vctrain predict` with its default engine (OpenVINO, else
onnxruntime, where installed: the same network exported, P(road) within float rounding) gives the
study's road IoU within STUDY_IOU_TOLERANCE (vctrain.predict.settings), on every split.

The study (tests/studies.py's mixed study: camvid role train; kitti role both; cityscapes and camvid2
role test) exercises every way the two roads could part: kitti's labels show an own vehicle that the
study finds (ego: auto; predict is told with --ego, as the study's result records), camvid2's label a
bonnet the study does not cut off (its ignore border must not shape the test image's completion:
predict has no label), one camvid2 frame's VP lies outside the study's pose range (the detector's
default range would accept it; the model's recorded rule rejects it, as the study did), and the test
frames at their poses reach past the training rectangle (extended for them on both roads). A second
study does the same on the shipped examples (CamVid's 0001TP rig and the KITTI frame, tested).
"""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
import yaml

from vcprep.store import Store

from conftest import EXAMPLES, run_cli
from studies import _mixed_study

CONDS = ["resize", "between", "within", "resize-vp"]
# (resize reads the store's sources; resize-vp also the within store's per-frame VPs)
GEOMETRY = {"resize": "between", "between": "between", "within": "within", "resize-vp": "within"}
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


def _run_result(out, run: str, name: str, cond: str) -> dict:
    folder = out / "runs" / run / cond
    return json.loads((folder / ("result.json" if run == name else f"result-{name}.json")).read_text())


def _result(out, name: str, cond: str) -> dict:
    return _run_result(out, "kitti" if name == "kitti" else "_all", name, cond)


def _assert_predict_gives_the_studys(out, run: str, name: str, cond: str, frames: list, camera, labels, fmt: str,
                                     ego: int, preds) -> None:
    """`vctrain predict --engine torch` of the study's ``run``/``cond`` model on ``frames`` with ``camera``
    (and ``--ego``) writes the masks (and probabilities) the study scored its test store with, and
    `vctrain eval` of them against ``labels`` gives the study's IoU; predict with its default engine
    gives the study's IoU within STUDY_IOU_TOLERANCE (its masks the same but for a pixel or two at P = 0.5),
    through the exported network where a runtime is installed (the engine predict.json records)."""
    from vctrain.predict import DEFAULT_ENGINE, STUDY_IOU_TOLERANCE, Predictor

    model = out / "runs" / run / cond / "model.pt"
    # a resize model reads frames as they are: the study's resize condition cuts no own vehicle, and
    # predict cuts one from such a model only when --ego asks (a dashcam user's bonnet)
    ego_args = [] if cond == "resize" else ["--ego", str(ego)]
    for engine in ("torch", None):  # --engine torch, and the default
        folder = preds / (engine or "default")
        proc = run_cli("predict", model, *frames, "--camera", camera, "--out", folder, *ego_args, "--device", "cpu",
                       *(["--engine", engine] if engine else []), prog="vctrain")
        assert proc.returncode == 0, proc.stderr
    predictor = Predictor(model, device="cpu")
    store = Store.open(out / "stores" / name / "test" / GEOMETRY[cond])
    for rec in store:  # the study's own masks: its predictor on its test store, as it scored them
        prob = predictor.store_item(store, rec)
        mask = cv2.imread(str(preds / "torch" / f"{rec['id']}_mask.png"), cv2.IMREAD_UNCHANGED) > 0
        assert np.array_equal(mask, prob >= 0.5), f"{name} {cond} {rec['id']}: {np.sum(mask != (prob >= 0.5))} px"
        p8 = np.clip(np.rint(prob * 255.0), 0, 255).astype(np.uint8)
        assert np.array_equal(cv2.imread(str(preds / "torch" / f"{rec['id']}_prob.png"), cv2.IMREAD_UNCHANGED), p8)
        # the same network (ties in a SegNet's max-pooling may go the other way: a few pixels, never a score)
        fast = cv2.imread(str(preds / "default" / f"{rec['id']}_mask.png"), cv2.IMREAD_UNCHANGED) > 0
        assert np.mean(fast != (prob >= 0.5)) <= 1e-3, f"{name} {cond} {rec['id']}: {np.sum(fast != (prob >= 0.5))} px"
    iou = {}
    for engine in ("torch", "default"):
        ev = run_cli("eval", preds / engine, "--labels", labels, "-f", fmt, "--json", "-q", prog="vctrain")
        assert ev.returncode == 0, ev.stderr
        iou[engine] = json.loads(ev.stdout)["iou"]
    fast = json.loads((preds / "default" / "predict.json").read_text())["engine"]
    assert fast.endswith("exported in memory") or not any(map(_installed, ("openvino", "onnxruntime"))), fast
    study_iou = _run_result(out, run, name, cond)["iou"]
    assert iou["torch"] == pytest.approx(study_iou, abs=1e-9)
    assert abs(iou["default"] - study_iou) <= STUDY_IOU_TOLERANCE, (name, cond, iou, study_iou, DEFAULT_ENGINE)


def _installed(module: str) -> bool:
    from vctrain.deploy.runtime import installed

    return installed(module)


@pytest.mark.parametrize("cond", CONDS)
@pytest.mark.parametrize("name", list(CAMERAS))
def test_predict_gives_the_studys_masks_and_iou(study_run, tmp_path, name, cond):
    study, out = study_run
    # the own vehicle the study found from the labels (study.json), given as the user would give it
    ego = json.loads((out / "study.json").read_text())["ego_found"][name]["ego_rows"]
    _assert_predict_gives_the_studys(out, "kitti" if name == "kitti" else "_all", name, cond, _frames(study, name),
                                     study.parent / CAMERAS[name], study.parent / f"{name}_test" / "labels", "camvid",
                                     ego, tmp_path / "preds")


@pytest.fixture(scope="module")
def examples_run(tmp_path_factory):
    """The shipped examples: CamVid's 0016E5 and 0006R0 frames trained on, its 0001TP frame (another
    rig, its own vehicle in the bottom 36 of 720 rows), the same frame at 64x48 (the warp enlarges it:
    the network runs it at a smaller working size) and the KITTI frame (its calibration file) tested."""
    root = tmp_path_factory.mktemp("examples_study")
    cv = {"images": str(EXAMPLES / "camvid" / "images"), "labels": str(EXAMPLES / "camvid" / "labels")}
    for sub, interp in (("images", cv2.INTER_AREA), ("labels", cv2.INTER_NEAREST)):  # 0001TP at 64x48
        (root / "small" / sub).mkdir(parents=True)
        img = cv2.imread(str(EXAMPLES / "camvid" / sub / "0001TP_007170.png"), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(root / "small" / sub / "0001TP_007170.png"), cv2.resize(img, (64, 48), interpolation=interp))
    study = {"datasets": [
        {"name": "camvid", "role": "train", "camera": "camvid", "label_format": "camvid",
         "train": {**cv, "exclude": "0001TP_*"}},
        {"name": "0001TP", "role": "test", "camera": "camvid", "label_format": "camvid", "ego": 36,
         "test": {**cv, "include": "0001TP_*"}},
        {"name": "0001TP-small", "role": "test", "camera": "camvid", "label_format": "camvid", "ego": 36,
         "test": {"images": str(root / "small" / "images"), "labels": str(root / "small" / "labels")}},
        {"name": "kitti", "role": "test", "camera": str(EXAMPLES / "kitti" / "calib" / "um_000000.txt"),
         "label_format": "kitti", "test": {"images": str(EXAMPLES / "kitti" / "image_2"),
                                           "labels": str(EXAMPLES / "kitti" / "gt_image_2")}}],
        "conditions": CONDS, "store_width": 160,
        "train": {"epochs": 1, "max_steps": 2, "batch_size": 2, "arch": "segnet-narrow", "base_width": 4,
                  "val_fraction": 0, "seed": 0}}
    (root / "study.yaml").write_text(yaml.safe_dump(study, sort_keys=False))
    proc = run_cli("crossval", root / "study.yaml", "--out", root / "out", "--quiet", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    return root / "out"


@pytest.mark.parametrize("cond", CONDS)
@pytest.mark.parametrize("name", ["0001TP", "0001TP-small", "kitti"])
def test_predict_gives_the_studys_masks_and_iou_on_the_examples(examples_run, tmp_path, name, cond):
    small = examples_run.parent / "small"
    frames = {"0001TP": [EXAMPLES / "camvid" / "images" / "0001TP_007170.png"],
              "0001TP-small": [small / "images" / "0001TP_007170.png"],
              "kitti": [EXAMPLES / "kitti" / "image_2" / "um_000000.png"]}[name]
    camera = "camvid" if name.startswith("0001TP") else EXAMPLES / "kitti" / "calib" / "um_000000.txt"
    labels, fmt = {"0001TP": (EXAMPLES / "camvid" / "labels", "camvid"), "0001TP-small": (small / "labels", "camvid"),
                   "kitti": (EXAMPLES / "kitti" / "gt_image_2", "kitti")}[name]
    # ego: 36 of the preset's 720 rows, at the 360-row frame's size; the same 36 at the 48-row frame's size
    ego = {"0001TP": 18, "0001TP-small": 3, "kitti": 0}[name]
    if name == "0001TP-small" and cond in ("between", "within"):  # the frame is enlarged: a smaller working size
        from vctrain.predict import Predictor
        from vcprep.store import record_magnification

        st = Store.open(examples_run / "stores" / name / "test" / cond)
        assert Predictor(examples_run / "runs" / "_all" / cond / "model.pt", "cpu").density_scale(
            record_magnification(next(iter(st)), st.virtual)) < 0.7
    if cond not in ("resize", "resize-vp"):
        assert _run_result(examples_run, "_all", name, cond)["test_warp"]["ego_rows"] == [ego]
    _assert_predict_gives_the_studys(examples_run, "_all", name, cond, frames, camera, labels, fmt, ego,
                                     tmp_path / "preds")


def test_the_result_records_the_rule_predict_says_it_used(study_run, tmp_path):
    """The study's result records what its test frames were warped with (VP statuses and rule, own
    vehicle, rectangle); `vctrain predict` says the same on stderr, and the model remembers the rule."""
    import torch

    study, out = study_run
    row = _result(out, "camvid2", "within")
    warp = row["test_warp"]
    # the study's ranges, no smoothing, sequences by file name
    assert warp["vp_rule"] == {"pan_range": 5.0, "tilt_range": 3.0, "smooth": 0, "sequences": "name"}
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
    bad = run_cli("predict", out / "runs" / "_all" / "within" / "model.pt", *_frames(study, "camvid2"), "--camera",
                  study.parent / "camvid.yaml", "--out", tmp_path / "r", "--vp-sequences", "drive", prog="vctrain")
    assert bad.returncode == 1 and "unknown VP sequence rule 'drive'" in bad.stderr
