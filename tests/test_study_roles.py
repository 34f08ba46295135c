"""vctrain crossval: test-only datasets, split selection, pixel budget and crop, the footprint canvas."""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest
import yaml

from vcprep.camera import camera_to_yaml
from vcprep.store import Store

from conftest import assert_one_error_line, run_cli
from studies import assert_bad_study_fails, CAMS, MIXED_CONDS, _dataset, _mixed_study, _rows, _study


@pytest.fixture(scope="module")
def mixed_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("crossval_mixed")
    study = _mixed_study(root / "data")
    out = root / "out"
    proc = run_cli("crossval", study, "--out", out, "--json", "--seed", "3", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    return study, out, proc


def test_test_role_datasets_are_scored_never_trained_on(mixed_run):
    _, out, proc = mixed_run
    rows = _rows(out)
    # one row per (evaluated dataset, condition), in table order; camvid (role train) is never evaluated
    assert [(r["heldout"], r["condition"]) for r in rows] == [
        (h, c) for h in ("kitti", "cityscapes", "camvid2") for c in MIXED_CONDS]
    by = {(r["heldout"], r["condition"]): r for r in rows}
    for c in MIXED_CONDS:
        # kitti (role both) is held out: trained on the other trainable dataset only
        assert by["kitti", c]["train_datasets"] == ["camvid"] and by["kitti", c]["run"] == "kitti"
        assert by["kitti", c]["train_items"] == 3             # camvid's 4 frames minus the excluded one
        # the test-role datasets share ONE model, trained on every trainable dataset
        for h in ("cityscapes", "camvid2"):
            assert by[h, c]["train_datasets"] == ["camvid", "kitti"] and by[h, c]["run"] == "_all"
            assert by[h, c]["train_items"] == 3 + 4 and by[h, c]["role"] == "test"
        assert by["cityscapes", c]["test_items"] == 1          # 'include' picks one of its two frames
        assert by["camvid2", c]["test_items"] == 3
        assert by["kitti", c]["test_items"] == 2
        run_dir = out / "runs" / "_all" / c
        assert sorted(p.name for p in run_dir.glob("*.json")) == ["result-camvid2.json", "result-cityscapes.json",
                                                                   "train.json"]
        assert len(list(run_dir.glob("model.pt"))) == 1
    assert sorted(p.name for p in (out / "runs").iterdir()) == ["_all", "kitti"]
    # no store of a test-role dataset's images is ever trained on: none is even built for training
    assert not (out / "stores" / "cityscapes" / "train").exists()
    assert not (out / "stores" / "camvid2" / "train").exists()
    assert not (out / "stores" / "camvid" / "test").exists()
    assert len(Store.open(out / "stores" / "camvid" / "train" / "between")) == 3
    # --json: {condition: mean IoU over the three evaluated datasets}
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert list(summary) == MIXED_CONDS
    for c in MIXED_CONDS:
        assert summary[c] == pytest.approx(sum(by[h, c]["iou"] for h in ("kitti", "cityscapes", "camvid2")) / 3)
    table = (out / "table.md").read_text().splitlines()
    assert [ln.split("|")[1].strip() for ln in table[4:]] == ["kitti", "cityscapes", "camvid2", "mean"]


def test_test_role_models_never_see_test_data(mixed_run):
    import torch

    _, out, _ = mixed_run
    for c in MIXED_CONDS:
        ck = torch.load(out / "runs" / "_all" / c / "model.pt", map_location="cpu", weights_only=False)
        stores = ck["config"]["stores"]
        assert len(stores) == 2 and all("/train/" in s for s in stores)
        assert not any("/cityscapes/" in s or "/camvid2/" in s for s in stores)
    study = json.loads((out / "study.json").read_text())
    assert study["roles"] == {"camvid": "train", "kitti": "both", "cityscapes": "test", "camvid2": "test"}
    # the designed virtual camera covers every camera of the study, test-role ones included: one rectangle for
    # every training store, and a test split's only where a frame at its pose reaches past it (as vctrain predict
    # extends it: here by the pixel the design's first-order pose margin leaves out)
    stores = {p: Store.open(p) for p in (out / "stores").glob("*/*/*")}
    assert len({tuple(s.store_size) for p, s in stores.items() if p.parent.name == "train"}) == 1
    (w, h), = {tuple(s.store_size) for p, s in stores.items() if p.parent.name == "train"}
    assert all(s.store_size[0] - w in (0, 1) and s.store_size[1] - h in (0, 1) for s in stores.values())


def test_settings_the_study_leaves_out_are_vctrain_fits_defaults(mixed_run, tmp_path):
    """A study trains exactly as `vctrain fit` does with the same few options (the project's recipe):
    its default training windows (DEFAULT_TRAIN) are fit's too (issue 52: the README's route)."""
    import torch

    _, out, _ = mixed_run
    ck = torch.load(out / "runs" / "_all" / "within" / "model.pt", map_location="cpu", weights_only=False)
    assert ck["config"]["seed"] == 3                                   # --seed
    fit = run_cli("fit", *ck["config"]["stores"], "--out", tmp_path / "m.pt", "--epochs", "1", "--batch-size", "2",
                  "--model", "segnet-narrow", "--width", "4", "--val-fraction", "0", "--seed", "3", "--quiet",
                  prog="vctrain")
    assert fit.returncode == 0, fit.stderr
    direct = torch.load(tmp_path / "m.pt", map_location="cpu", weights_only=False)
    per_run = {"stores", "out", "log", "progress", "max_steps", "size", "workers"}
    assert {k: v for k, v in ck["config"].items() if k not in per_run} == \
        {k: v for k, v in direct["config"].items() if k not in per_run}
    assert ck["model_args"] == direct["model_args"]


def test_mixed_study_resumes_and_reuses_a_trained_model(mixed_run, tmp_path):
    import shutil

    study, out, proc = mixed_run
    copy = tmp_path / "out"
    shutil.copytree(out, copy)
    models = sorted((copy / "runs").glob("*/*/model.pt"))
    before = {p: p.stat().st_mtime_ns for p in models}
    lost = copy / "runs" / "_all" / "within" / "result-camvid2.json"
    iou = json.loads(lost.read_text())["iou"]
    lost.unlink()
    again = run_cli("crossval", study, "--out", copy, "--json", "--seed", "3", prog="vctrain")
    assert again.returncode == 0, again.stderr
    assert "model trained earlier" in again.stderr and "training on" not in again.stderr
    assert again.stderr.count("done earlier") == 5
    assert {p: p.stat().st_mtime_ns for p in models} == before
    assert json.loads(lost.read_text())["iou"] == pytest.approx(iou)
    assert again.stdout.strip().splitlines()[-1] == proc.stdout.strip().splitlines()[-1]
    # another seed is another study: everything is retrained
    other = run_cli("crossval", study, "--out", copy, "--heldout", "camvid2", "--conditions", "resize", "--json",
                    "--seed", "4", prog="vctrain")
    assert other.returncode == 0, other.stderr
    assert "settings changed" in other.stderr and "training on camvid, kitti" in other.stderr
    assert json.loads(other.stdout.strip().splitlines()[-1]).keys() == {"resize"}


def test_split_selection_globs():
    from vctrain.study import Split

    s = Split(Path("i"), Path("l"), include=("0016E5_*", "0006R0_*"), exclude=("0016E5_0800*",))
    assert s.selects("0016E5_07959") and s.selects("0006R0_f01000")
    assert not s.selects("0001TP_006690") and not s.selects("0016E5_08001")
    assert Split(Path("i"), Path("l")).selects("anything")
    assert not Split(Path("i"), Path("l"), exclude=("*",)).selects("x")


def test_study_train_section_takes_any_trainconfig_field(tmp_path):
    from vctrain.study import load_study

    study = _mixed_study(tmp_path / "data")
    d = yaml.safe_load(study.read_text())
    d["train"]["vp_channel"] = False        # a TrainConfig field outside the usual list
    study.write_text(yaml.safe_dump(d))
    assert load_study(study).train["vp_channel"] is False


def test_a_split_that_selects_nothing_is_one_error_line(tmp_path):
    study = _mixed_study(tmp_path / "data")
    d = yaml.safe_load(study.read_text())
    d["datasets"][2]["test"]["include"] = "nothing_*"
    study.write_text(yaml.safe_dump(d))
    proc = run_cli("crossval", study, "--out", tmp_path / "out", prog="vctrain")
    assert_one_error_line(proc, "dataset 'cityscapes' test: no image of", "include/exclude")


@pytest.mark.parametrize("edit, needle", [
    (lambda d: d["datasets"][0].update(role="magic"), "unknown role 'magic'"),
    (lambda d: d["datasets"][2].update(train=d["datasets"][1]["train"]), "'train' split would never be used"),
    (lambda d: d["datasets"][0].update(test=d["datasets"][1]["test"]), "'test' split would never be used"),
    (lambda d: d["datasets"][2].pop("test"), "missing key 'test' in dataset 'cityscapes' (role test)"),
    (lambda d: d["datasets"][0].pop("train"), "missing key 'train' in dataset 'camvid' (role train)"),
    (lambda d: d.update(datasets=d["datasets"][2:]), "no dataset may be trained on"),
    (lambda d: d.update(datasets=[d["datasets"][0], {**d["datasets"][1], "role": "train", "test": None}]),
     "no dataset is tested on"),
    (lambda d: d.update(datasets=d["datasets"][1:3]), "only one that may be trained on"),
    (lambda d: d["datasets"][0]["train"].update(include=3), "'include' in dataset 'camvid' train must be a glob"),
    (lambda d: d["datasets"][0]["train"].update(exclude=[]), "'exclude' in dataset 'camvid' train must be a glob"),
    (lambda d: d["train"].update(stores=["x"]), "unknown key 'stores' in 'train'"),
    (lambda d: d["train"].update(schedule="wavy"), "'train': unknown schedule 'wavy'"),
])
def test_bad_roles_and_selections_give_one_error_line(tmp_path, edit, needle):
    study = _mixed_study(tmp_path / "data")
    assert_bad_study_fails(study, edit, tmp_path / "out", needle)


def test_heldout_must_name_an_evaluated_dataset(tmp_path):
    study = _mixed_study(tmp_path / "data")
    out = tmp_path / "out"
    proc = run_cli("crossval", study, "--out", out, "--heldout", "camvid", prog="vctrain")
    assert_one_error_line(proc, "dataset 'camvid' has role train: it is never tested")
    assert not out.exists()


def test_pixel_budget_crop_and_resize_aspect(tmp_path):
    """store_pixels sets the scale of a virtual camera cropped to 'above' degrees over the horizon;
    the resize baseline gets the same pixel count at its training images' own aspect (4:3 here);
    a crop share in 'train' gives each condition windows of its own working size."""
    import math

    import torch

    study = _study(tmp_path / "data")
    d = yaml.safe_load(study.read_text())
    d.update(store_pixels=6000, above=6, conditions=["resize", "between"])
    d.setdefault("train", {})["crop"] = 0.9
    del d["store_width"]
    study.write_text(yaml.safe_dump(d))
    out = tmp_path / "out"
    proc = run_cli("crossval", study, "--out", out, "--heldout", "kitti", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    info = json.loads((out / "study.json").read_text())
    v = info["virtual"]
    f = v["fx"]
    # rows above the horizon: f (tan 6 deg + tan tilt_range 3 deg); the horizon row is cy
    assert v["cy"] + 0.5 == pytest.approx(f * (math.tan(math.radians(6)) + math.tan(math.radians(3))), rel=1e-6)
    assert v["cy"] < v["image_size"][1] / 3  # most of the image is below the horizon
    w, h = Store.open(out / "stores" / "camvid" / "train" / "between").store_size
    assert abs(w * h - 6000) < 0.02 * 6000
    ck = {c: torch.load(out / "runs" / "kitti" / c / "model.pt", map_location="cpu", weights_only=False)
          for c in ("resize", "between")}
    assert ck["between"]["data"]["input_size"] == [w, h]
    rw, rh = ck["resize"]["data"]["input_size"]
    assert rw / rh == pytest.approx(4 / 3, rel=0.03) and abs(rw * rh - w * h) < 0.03 * w * h
    # train: {crop: share}: every condition trains on windows of that share of its own working size
    assert ck["between"]["config"]["crop"] == 0.9
    assert ck["between"]["data"]["crop_size"] == [round(0.9 * w), round(0.9 * h)]
    assert ck["resize"]["data"]["crop_size"] == [round(0.9 * rw), round(0.9 * rh)]


@pytest.mark.parametrize("edit, needle", [
    (lambda d: d.update(store_pixels=100), "store_pixels"),
    (lambda d: d.update(above=75), "'above' must be degrees"),
    (lambda d: d.update(above=5, virtual="virtual"), "'above' crops a designed virtual camera"),
])
def test_bad_budget_and_crop_give_one_error_line(tmp_path, edit, needle):
    study = _study(tmp_path / "data")
    d = yaml.safe_load(study.read_text())
    edit(d)
    study.write_text(yaml.safe_dump(d))
    proc = run_cli("crossval", study, "--out", tmp_path / "out", prog="vctrain")
    assert_one_error_line(proc, needle)


# -- canvas: footprint (the training rectangle holds the trainable cameras; a test camera extends it) --
def _footprint_study(root: Path) -> Path:
    """camvid trains; kitti (81 deg wide, against camvid's 58) and camvid2 (camvid's camera) are
    test-only, so kitti's canvas must extend the training rectangle and camvid2's must not."""
    root.mkdir(parents=True, exist_ok=True)
    for name in ("camvid", "kitti"):
        (root / f"{name}.yaml").write_text(camera_to_yaml(CAMS[name]))
    datasets = [
        {"name": "camvid", "role": "train", "camera": "camvid.yaml", "label_format": "camvid",
         "train": _dataset(root, "camvid_train", CAMS["camvid"], 4, 0, False)},
        {"name": "kitti", "role": "test", "camera": "kitti.yaml", "label_format": "camvid",
         "test": _dataset(root, "kitti_test", CAMS["kitti"], 2, 4, False)},
        {"name": "camvid2", "role": "test", "camera": "camvid.yaml", "label_format": "camvid",
         "test": _dataset(root, "camvid2_test", CAMS["camvid"], 2, 1, False)},
    ]
    study = {"datasets": datasets, "conditions": ["resize", "within"], "canvas": "footprint", "store_pixels": 6000,
             "above": 6, "pan_range": 5, "tilt_range": 3,
             "train": {"epochs": 1, "max_steps": 2, "batch_size": 2, "arch": "segnet-narrow", "base_width": 4,
                       "val_fraction": 0, "seed": 0}}
    path = root / "study.yaml"
    path.write_text(yaml.safe_dump(study, sort_keys=False))
    return path


def test_footprint_canvas_keeps_the_budget_for_training_and_covers_every_test_pixel(tmp_path):
    """canvas: footprint -- the pixel budget sizes the rectangle that holds the TRAINING camera
    (not the union with a wider test camera); a wider test-only camera gets it extended to hold its
    frames at their poses (as vctrain predict extends it), so they are predicted where the training
    rectangle would cut them off (and score them 'not road'), and the model runs there unresized."""
    import math

    import cv2
    import numpy as np

    from vcprep.warp import backproject_array
    from vcprep.camera import camera_from_dict
    from vcprep.warp import virt_H_src
    from vcprep.labels import decode_label, get_label_format
    from vcprep.camera import design_virtual_camera, same_camera_other_canvas
    from vctrain.predict import Predictor

    study = _footprint_study(tmp_path / "data")
    out = tmp_path / "out"
    proc = run_cli("crossval", study, "--out", out, "--json", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    stores = {n: Store.open(out / "stores" / n / s / "within")
              for n, s in (("camvid", "train"), ("kitti", "test"), ("camvid2", "test"))}
    train, kitti, camvid2 = stores["camvid"], stores["kitti"], stores["camvid2"]
    # the budget sizes the training rectangle; the same camera's test canvas of the same camera is that rectangle
    w, h = train.store_size
    assert abs(w * h - 6000) < 0.02 * 6000
    assert camvid2.params["virtual"] == train.params["virtual"]
    # independent oracle: the training rectangle is the virtual camera a design of camvid alone gives
    # (focal length and height too: no test camera shapes the training)
    tv = camera_from_dict(train.params["virtual"])
    alone = design_virtual_camera([CAMS["camvid"].without_ego()], 5, 3, above=6).camera
    assert alone.size == tv.size and alone.cy == pytest.approx(tv.cy)
    assert (alone.fx, alone.height) == pytest.approx((tv.fx, tv.height))
    # kitti: one camera, another rectangle: wider, same top edge, same scale
    kv = camera_from_dict(kitti.params["virtual"])
    assert same_camera_other_canvas(kitti.params["virtual"], train.params["virtual"])
    assert kitti.params["scale"] == train.params["scale"]
    assert kv.size[0] > tv.size[0] * 1.2 and kv.cy == pytest.approx(tv.cy)
    kvs = camera_from_dict(kitti.params["virtual_scaled"])
    tvs = camera_from_dict(train.params["virtual_scaled"])
    for rec in kitti:
        label = decode_label(cv2.imread(rec["label_source"], cv2.IMREAD_UNCHANGED), get_label_format("camvid"))
        # what the design holds of every camera: the labelled lower half of the frame (bonnet rows excluded)
        held = np.zeros(label.shape, bool)
        held[label.shape[0] // 2 + 1:] = True
        held &= label != 255
        assert (held & (label == 1)).sum() > 0
        src = camera_from_dict(rec["camera_params"])
        # in the training rectangle some of it would fall outside (and be scored 'not road') ...
        H = virt_H_src(src, tvs, rec["pan_deg"], rec["tilt_deg"])
        ys, xs = np.nonzero(held)
        p = H @ np.stack([xs, ys, np.ones_like(xs)]).astype(float)
        u = p[0] / p[2]
        assert ((u < -0.5) | (u > tvs.size[0] - 0.5)).mean() > 0.05
        # ... in kitti's own rectangle (extended for its frames at their poses) all of it is inside
        cover = backproject_array(np.full(tuple(reversed(kvs.size)), 255, np.uint8), rec, "mask") > 0
        assert cover[held].mean() > 0.999
    # the model runs on the wider canvas at the training's pixels per degree (no resize)
    pred = Predictor(out / "runs" / "_all" / "within" / "model.pt", device="cpu")
    assert pred.working_size(tuple(kitti.store_size)) == tuple(kitti.store_size)
    assert pred.working_size(tuple(train.store_size)) == tuple(pred.size)
    rec = next(iter(kitti))
    assert pred.store_item(kitti, rec).shape == tuple(reversed(rec["size"]))
    rows = _rows(out)
    assert {(r["heldout"], r["condition"]) for r in rows} == {(n, c) for n in ("kitti", "camvid2")
                                                              for c in ("resize", "within")}
    assert all(0.0 <= r["iou"] <= 1.0 for r in rows)
    info = json.loads((out / "study.json").read_text())
    assert info["canvas"] == "footprint" and math.isclose(info["scale"], train.params["scale"])
    within = {r["heldout"]: r for r in rows if r["condition"] == "within"}  # its rectangle, as predict says it
    assert within["kitti"]["test_warp"]["rectangle"] == list(kv.size)
    # a test-only camera changed: its results are redone, nothing is retrained, the others are kept
    (study.parent / "kitti.yaml").write_text(camera_to_yaml(replace(CAMS["kitti"], height=CAMS["kitti"].height * 1.3)))
    again = run_cli("crossval", study, "--out", out, prog="vctrain")
    assert again.returncode == 0, again.stderr
    assert again.stderr.count("model trained earlier") == 2 and "training on" not in again.stderr
    assert again.stderr.count("settings changed") == 2                    # kitti: resize and within
    assert all(f"tested on camvid2, {c}: done earlier" in again.stderr for c in ("resize", "within"))


# -- conditions prior (Table 5 "Geo-Prior") and adapt (the within model adapted without labels) ----


def test_an_interrupted_training_resumes_after_its_last_epoch(tmp_path):
    """A study's model whose training stopped (no train.json; model.last.pt of the same request, fewer epochs
    than asked) resumes after that epoch instead of starting afresh; one of other settings starts afresh."""
    import torch

    from studies import _mixed_study
    from vctrain.training import save_checkpoint

    study = _mixed_study(tmp_path / "data")
    out = tmp_path / "out"
    args = ("crossval", study, "--out", out, "--heldout", "kitti", "--conditions", "resize", "--epochs", "2", "--seed", "3")
    first = run_cli(*args, prog="vctrain")
    assert first.returncode == 0, first.stderr
    run_dir = out / "runs" / "kitti" / "resize"
    last = run_dir / "model.last.pt"
    done = torch.load(last, map_location="cpu", weights_only=False)
    assert done["epoch"] == 2 and len(done["history"]) == 2

    def interrupt(**request) -> None:  # the state a training stopped after epoch 1 (of 1,000 s) leaves
        first = {**done["history"][0], "seconds": 900.0, "val_seconds": 100.0}
        ck = {**done, "epoch": 1, "history": [first], "request": {**done["request"], **request}}
        save_checkpoint(last, ck)
        for f in ("train.json", "result.json", "model.pt"):
            (run_dir / f).unlink(missing_ok=True)

    interrupt()
    again = run_cli(*args, prog="vctrain")
    assert again.returncode == 0, again.stderr
    assert "resumed after epoch 1" in again.stderr
    ck = torch.load(last, map_location="cpu", weights_only=False)
    assert ck["epoch"] == 2 and [h["epoch"] for h in ck["history"]] == [1, 2]  # epoch 1 kept, epoch 2 trained again
    assert json.loads((run_dir / "result.json").read_text())["iou"] is not None
    # its time is the whole training's: epoch 1's 1,000 s before the interruption, and this invocation's
    record = json.loads((run_dir / "train.json").read_text())
    second = ck["history"][1]["seconds"] + ck["history"][1].get("val_seconds", 0.0)
    assert record["resumed_after"] == 1 and record["train_seconds"] >= round(1000.0 + second, 1) - 0.1
    assert record["train_seconds"] < 1000.0 + 600  # (and not counted twice)
    interrupt(lr=0.5)  # another run's checkpoint: afresh
    other = run_cli(*args, prog="vctrain")
    assert other.returncode == 0, other.stderr
    assert "training on" in other.stderr and "resumed" not in other.stderr
    assert torch.load(last, map_location="cpu", weights_only=False)["request"] == done["request"]
    assert "resumed_after" not in json.loads((run_dir / "train.json").read_text())
