"""vctrain crossval: leave-one-dataset-out over synthetic datasets from three different cameras."""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest
import yaml

from vcprep.camera import PRESETS, camera_to_yaml
from vcprep.homography import vp_from_pose
from vcprep.store import Store

from conftest import assert_one_error_line, run_cli, write_synthetic_dataset

CONDS = ["resize", "between", "within", "within-gt", "zero"]
CAMS = {
    "camvid": PRESETS["camvid"].for_image_size((240, 180)),
    "kitti": PRESETS["kitti"].for_image_size((414, 125)),
    "cityscapes": PRESETS["cityscapes"].for_image_size((256, 128)),
}
# per-image poses (pan, tilt) relative to each camera's average pose: the given VPs follow exactly
OFFSETS = [(0.0, 0.0), (4.0, -2.0), (-3.0, 1.5), (2.0, 2.5)]


def _dataset(root: Path, name: str, cam, n: int, first: int, vps: bool) -> dict:
    poses = [(cam.pan + dp, cam.tilt + dt) for dp, dt in (OFFSETS * 3)[first:first + n]]
    images, labels = write_synthetic_dataset(root / name, cam, n=n, poses=poses, bonnet_rows=3)
    split = {"images": str(images.relative_to(root)), "labels": str(labels.relative_to(root))}
    if vps:
        rows = ["id,u,v"] + [f"{p.stem},{u:.6f},{v:.6f}" for p, (u, v) in
                             zip(sorted(images.iterdir()), (vp_from_pose(cam, pa, ti) for pa, ti in poses))]
        (root / name / "vps.csv").write_text("\n".join(rows) + "\n")
        split["vps"] = f"{name}/vps.csv"
    return split


def _study(root: Path, vps_for=("camvid", "kitti", "cityscapes")) -> Path:
    root.mkdir(parents=True, exist_ok=True)
    datasets = []
    for name, cam in CAMS.items():
        (root / f"{name}.yaml").write_text(camera_to_yaml(cam))
        datasets.append({"name": name, "camera": f"{name}.yaml", "label_format": "camvid",
                         "train": _dataset(root, f"{name}_train", cam, 4, 0, name in vps_for),
                         "test": _dataset(root, f"{name}_test", cam, 2, 4, name in vps_for)})
    # tiny stores: the design uncropped (above: null), unlike a study's 8-degree default
    study = {"datasets": datasets, "store_width": 128, "above": None, "pan_range": 5, "tilt_range": 3,
             "train": {"epochs": 1, "max_steps": 2, "batch_size": 2, "arch": "segnet-narrow", "base_width": 4,
                       "val_fraction": 0, "seed": 0}}
    path = root / "study.yaml"
    path.write_text(yaml.safe_dump(study, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def study_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("crossval")
    study = _study(root / "data")
    out = root / "out"
    proc = run_cli("crossval", study, "--out", out, "--json", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    return study, out, proc


def test_table_has_every_heldout_and_condition(study_run):
    _, out, proc = study_run
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert list(summary) == CONDS
    assert all(0.0 <= v <= 1.0 for v in summary.values())
    rows = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert {(r["heldout"], r["condition"]) for r in rows} == {(h, c) for h in CAMS for c in CONDS}
    for r in rows:
        assert r["test_items"] == 2                       # the held-out TEST split, nothing else
        assert r["heldout"] not in r["train_datasets"] and len(r["train_datasets"]) == 2
        assert r["train_items"] == 8
    table = (out / "table.md").read_text().splitlines()
    assert table[2] == "| held out | " + " | ".join(CONDS) + " |"
    assert [ln.split("|")[1].strip() for ln in table[4:]] == list(CAMS) + ["mean"]
    csv = (out / "table.csv").read_text().splitlines()
    assert csv[0] == "held out," + ",".join(CONDS) and len(csv) == len(CAMS) + 2
    # the mean row is the mean of the column (cells are rounded to 0.1: the mean of the rounded
    # cells and the rounded mean can each be 0.05 off the true mean)
    for j, c in enumerate(CONDS, 1):
        col = [float(line.split(",")[j]) for line in csv[1:-1]]
        assert float(csv[-1].split(",")[j]) == pytest.approx(sum(col) / len(col), abs=0.1001)
        assert summary[c] * 100 == pytest.approx(float(csv[-1].split(",")[j]), abs=0.051)


def test_each_condition_trains_in_its_own_domain(study_run):
    import torch

    _, out, _ = study_run
    ck = {c: torch.load(out / "runs" / "kitti" / c / "model.pt", map_location="cpu", weights_only=False) for c in CONDS}
    assert ck["resize"]["data"]["mode"] == "resize"
    stored = {c: ck[c]["config"]["stores"] for c in CONDS}
    for c in ("between", "within", "within-gt", "zero"):
        assert ck[c]["data"]["mode"] == "virtual"
        assert all("/kitti/" not in s for s in stored[c])   # never the held-out camera
    assert ck["between"]["data"]["vp_status"] == ["camera"]
    assert set(ck["within"]["data"]["vp_status"]) <= {"accepted", "fallback"}
    assert ck["within-gt"]["data"]["vp_status"] == ["given"]
    assert ck["within"]["data"]["completion"] == "projective" and ck["zero"]["data"]["completion"] == "zero"
    # the given VPs reach the records exactly
    s = Store.open(out / "stores" / "camvid" / "train" / "within-gt")
    cam = CAMS["camvid"]
    for rec, (dp, dt) in zip(sorted(s, key=lambda r: r["id"]), OFFSETS):
        assert rec["vp"] == pytest.approx(vp_from_pose(cam, cam.pan + dp, cam.tilt + dt), abs=1e-5)
    # one virtual camera (designed from the three) for every store, at the study's width
    sizes = {tuple(Store.open(p).store_size) for p in (out / "stores").glob("*/*/*")}
    assert len(sizes) == 1 and next(iter(sizes))[0] == 128


def test_heldout_score_matches_predict_and_eval(study_run, tmp_path):
    """The study's held-out figure equals what the public predict + eval commands give."""
    _, out, _ = study_run
    for cond, geom in (("within", "within"), ("resize", "between")):
        preds = tmp_path / cond
        p = run_cli("predict", out / "runs" / "cityscapes" / cond / "model.pt", "--store",
                    out / "stores" / "cityscapes" / "test" / geom, "--out", preds, "-q", "--device", "cpu",
                    prog="vctrain")
        assert p.returncode == 0, p.stderr
        e = run_cli("eval", preds, "--labels", out.parent / "data" / "cityscapes_test" / "labels", "-f", "camvid",
                    "--json", "-q", prog="vctrain")
        assert e.returncode == 0, e.stderr
        got = json.loads((out / "runs" / "cityscapes" / cond / "result.json").read_text())
        assert got["iou"] == pytest.approx(json.loads(e.stdout)["iou"], abs=2e-3)


def test_rerun_resumes_without_training(study_run):
    study, out, proc = study_run
    models = sorted((out / "runs").glob("*/*/model.pt"))
    before = {p: p.stat().st_mtime_ns for p in models}
    again = run_cli("crossval", study, "--out", out, "--json", prog="vctrain")
    assert again.returncode == 0, again.stderr
    assert "done earlier" in again.stderr
    assert again.stdout.strip().splitlines()[-1] == proc.stdout.strip().splitlines()[-1]
    assert {p: p.stat().st_mtime_ns for p in models} == before


def test_changed_settings_redo_the_runs(study_run, tmp_path):
    study, out, _ = study_run
    import shutil

    copy = tmp_path / "out"
    shutil.copytree(out, copy)
    proc = run_cli("crossval", study, "--out", copy, "--heldout", "kitti", "--conditions", "between", "--epochs", "2",
                   "--json", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert "settings changed" in proc.stderr and "done earlier" not in proc.stderr
    assert json.loads((copy / "runs" / "kitti" / "between" / "result.json").read_text())["epochs"] == 2


def test_a_changed_virtual_camera_rebuilds_the_studys_stores(study_run, tmp_path):
    """Another store width (or datasets that change the designed virtual camera) makes the study's
    stores obsolete: they are built afresh for the new camera and scale, never mixed, never an error."""
    study, out, _ = study_run
    import shutil

    copy = tmp_path / "out"
    shutil.copytree(out, copy)
    edited = study.parent / "study_width96.yaml"  # beside the study: its relative paths hold
    d = yaml.safe_load(study.read_text())
    d["store_width"] = 96
    edited.write_text(yaml.safe_dump(d, sort_keys=False))
    proc = run_cli("crossval", edited, "--out", copy, "--heldout", "kitti", "--conditions", "between", "--epochs", "1",
                   "--json", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert "built for another virtual camera or scale; building it afresh" in proc.stderr
    for d_ in ("camvid", "cityscapes", "kitti"):
        split = "test" if d_ == "kitti" else "train"
        st = Store.open(copy / "stores" / d_ / split / "between")
        assert st.store_size[0] == 96 and all(r["store_size"][0] == 96 for r in st)
    assert json.loads((copy / "runs" / "kitti" / "between" / "result.json").read_text())["epochs"] == 1


def test_within_gt_is_skipped_without_given_vps(tmp_path):
    study = _study(tmp_path / "data", vps_for=("camvid", "kitti"))
    proc = run_cli("crossval", study, "--out", tmp_path / "out", "--conditions", "within-gt", "--heldout", "camvid",
                   prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert "skipped (no given VPs for cityscapes)" in proc.stderr
    assert "| camvid | - |" in proc.stdout


@pytest.mark.parametrize("edit, needle", [
    (lambda d: d.pop("datasets"), "missing key 'datasets'"),
    (lambda d: d.update(datasets=d["datasets"][:1]), "at least two datasets"),
    (lambda d: d.update(conditions=["within", "magic"]), "unknown condition 'magic'"),
    (lambda d: d["datasets"][1].update(name=d["datasets"][0]["name"]), "two datasets named"),
    (lambda d: d["datasets"][0]["train"].update(images="nowhere"), "not found"),
    (lambda d: d["datasets"][0].update(label_format="nope"), "nope"),
    (lambda d: d.update(store_width=10), "store_width"),
    (lambda d: d["train"].update(learning_rate=1), "unknown key 'learning_rate'"),
    (lambda d: d.update(extra=1), "unknown key 'extra'"),
    (lambda d: d.update(canvas="round"), "'canvas' must be one of shared, footprint"),
    (lambda d: d.update(canvas="footprint", virtual="virtual", above=None), "'canvas' sizes a designed virtual camera"),
    (lambda d: d.update(canvas="footprint", conditions=["prior"]), "conditions prior, adapt and adapt-fuse"),
])
def test_bad_study_files_give_one_error_line(tmp_path, edit, needle):
    study = _study(tmp_path / "data")
    d = yaml.safe_load(study.read_text())
    edit(d)
    study.write_text(yaml.safe_dump(d))
    out = tmp_path / "out"
    proc = run_cli("crossval", study, "--out", out, prog="vctrain")
    assert_one_error_line(proc, needle)
    assert str(study) in proc.stderr
    assert not out.exists()


# -- test-only datasets ('role') and split selection ('include' / 'exclude') ----------------------
MIXED_CONDS = ["resize", "within"]


def _mixed_study(root: Path) -> Path:
    """camvid: role train (one frame excluded); kitti: role both; cityscapes and camvid2 (another
    camvid-camera set): role test, never trained on. cityscapes is scored on one selected frame."""
    root.mkdir(parents=True, exist_ok=True)
    for name, cam in CAMS.items():
        (root / f"{name}.yaml").write_text(camera_to_yaml(cam))
    camvid_train = {**_dataset(root, "camvid_train", CAMS["camvid"], 4, 0, False), "exclude": "seq_0003"}
    city_test = {**_dataset(root, "cityscapes_test", CAMS["cityscapes"], 2, 4, False), "include": ["seq_0001"]}
    datasets = [
        {"name": "camvid", "role": "train", "camera": "camvid.yaml", "label_format": "camvid", "train": camvid_train},
        {"name": "kitti", "camera": "kitti.yaml", "label_format": "camvid",
         "train": _dataset(root, "kitti_train", CAMS["kitti"], 4, 0, False),
         "test": _dataset(root, "kitti_test", CAMS["kitti"], 2, 4, False)},
        {"name": "cityscapes", "role": "test", "camera": "cityscapes.yaml", "label_format": "camvid",
         "test": city_test},
        {"name": "camvid2", "role": "test", "camera": "camvid.yaml", "label_format": "camvid",
         "test": _dataset(root, "camvid2_test", CAMS["camvid"], 3, 1, False)},
    ]
    study = {"datasets": datasets, "conditions": MIXED_CONDS, "store_width": 128, "above": None, "pan_range": 5, "tilt_range": 3,
             "train": {"epochs": 1, "max_steps": 2, "batch_size": 2, "arch": "segnet-narrow", "base_width": 4,
                       "val_fraction": 0}}
    path = root / "study.yaml"
    path.write_text(yaml.safe_dump(study, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def mixed_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("crossval_mixed")
    study = _mixed_study(root / "data")
    out = root / "out"
    proc = run_cli("crossval", study, "--out", out, "--json", "--seed", "3", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    return study, out, proc


def _rows(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]


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
    # the designed virtual camera covers every camera of the study, test-role ones included
    assert len({tuple(Store.open(p).store_size) for p in (out / "stores").glob("*/*/*")}) == 1


def test_settings_the_study_leaves_out_are_vctrain_fits_defaults(mixed_run, tmp_path):
    """A study trains exactly as `vctrain fit` does with the same few options (the project's recipe),
    its default training windows (DEFAULT_TRAIN) given to fit as --crop."""
    import torch

    from vctrain.study import DEFAULT_TRAIN

    _, out, _ = mixed_run
    ck = torch.load(out / "runs" / "_all" / "within" / "model.pt", map_location="cpu", weights_only=False)
    assert ck["config"]["seed"] == 3                                   # --seed
    fit = run_cli("fit", *ck["config"]["stores"], "--out", tmp_path / "m.pt", "--epochs", "1", "--batch-size", "2",
                  "--model", "segnet-narrow", "--width", "4", "--val-fraction", "0", "--seed", "3", "--quiet",
                  "--crop", "x".join(repr(float(v)) for v in DEFAULT_TRAIN["crop"]), prog="vctrain")
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
    d = yaml.safe_load(study.read_text())
    edit(d)
    study.write_text(yaml.safe_dump(d))
    out = tmp_path / "out"
    proc = run_cli("crossval", study, "--out", out, prog="vctrain")
    assert_one_error_line(proc, needle)
    assert str(study) in proc.stderr
    assert not out.exists()


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
    (not the union with a wider test camera); a wider test-only camera gets the same virtual
    camera extended to its own footprint, so its frames are predicted where the training
    rectangle would cut them off (and score them 'not road'), and the model runs there unresized."""
    import math

    import cv2
    import numpy as np

    from vcprep.backproject import backproject_array
    from vcprep.camera import camera_from_dict
    from vcprep.homography import virt_H_src
    from vcprep.labels import decode_label, get_label_format
    from vcprep.virtual_camera import design_virtual_camera, same_camera_other_canvas
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
        # ... in kitti's own canvas it is inside the virtual image (all but the few pixels at the
        # frame's edge that a 4-deg pan moves further than the design's first-order 'shift' margin)
        cover = backproject_array(np.full(tuple(reversed(kvs.size)), 255, np.uint8), rec, "mask") > 0
        assert cover[held].mean() > 0.99
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
    assert info["canvas"] == "footprint" and info["canvases"]["kitti"] == list(kv.size)
    assert math.isclose(info["scale"], train.params["scale"])
    # a test-only camera changed: its results are redone, nothing is retrained, the others are kept
    (study.parent / "kitti.yaml").write_text(camera_to_yaml(replace(CAMS["kitti"], height=CAMS["kitti"].height * 1.3)))
    again = run_cli("crossval", study, "--out", out, prog="vctrain")
    assert again.returncode == 0, again.stderr
    assert again.stderr.count("model trained earlier") == 2 and "training on" not in again.stderr
    assert again.stderr.count("settings changed") == 2                    # kitti: resize and within
    assert all(f"tested on camvid2, {c}: done earlier" in again.stderr for c in ("resize", "within"))


# -- conditions prior (Table 5 "Geo-Prior") and adapt (the within model adapted without labels) ----
GEO_CONDS = ["prior", "adapt"]


def _geo_study(root: Path) -> Path:
    """The mixed study (kitti role both; cityscapes, camvid2 role test) with conditions prior and
    adapt; camvid2 gives an unlabelled split of its own (other frames, images only)."""
    study = _mixed_study(root)
    d = yaml.safe_load(study.read_text())
    images, _ = write_synthetic_dataset(root / "camvid2_unlabelled", CAMS["camvid"], n=2,
                                        poses=[(CAMS["camvid"].pan + 2.0, CAMS["camvid"].tilt - 1.0)] * 2)
    d["datasets"][3]["unlabelled"] = {"images": str(images.relative_to(root))}
    d["conditions"] = GEO_CONDS
    study.write_text(yaml.safe_dump(d, sort_keys=False))
    return study


@pytest.fixture(scope="module")
def geo_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("crossval_geo")
    study = _geo_study(root / "data")
    out = root / "out"
    proc = run_cli("crossval", study, "--out", out, "--json", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    return study, out, proc


def _own_prior(stores: list[Path]):
    """p_g by hand: per store pixel, (labels == 1) / (labels != 255) over the stores' label PNGs."""
    import cv2
    import numpy as np

    road = known = 0
    for s in map(Store.open, stores):
        for rec in s:
            lab = cv2.imread(str(s.path(rec["label"])), cv2.IMREAD_UNCHANGED)
            road, known = road + (lab == 1), known + (lab != 255)
    return np.where(known > 0, road / np.maximum(known, 1), 0.0).astype(np.float32)


def test_prior_condition_equals_an_independent_computation(geo_run):
    import cv2
    import numpy as np

    _, out, _ = geo_run
    rows = {(r["heldout"], r["condition"]): r for r in _rows(out)}
    assert set(rows) == {(h, c) for h in ("kitti", "cityscapes", "camvid2") for c in GEO_CONDS}
    cases = {"kitti": ["camvid"], "cityscapes": ["camvid", "kitti"], "camvid2": ["camvid", "kitti"]}
    data = out.parent / "data"
    for held, train in cases.items():
        row = rows[held, "prior"]
        assert row["train_datasets"] == train and row["epochs"] == 0
        prior = _own_prior([out / "stores" / t / "train" / "within" for t in train])
        tp = fp = fn = 0
        test = Store.open(out / "stores" / held / "test" / "within")  # per-image estimated VPs, as the paper
        assert {r["vp_status"] for r in test} <= {"accepted", "fallback"}
        for rec in test:
            w, h = rec["size"]
            H = np.asarray(rec["H"], np.float64).reshape(3, 3)          # source pixel -> store pixel
            p = cv2.warpPerspective(prior, H, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                    borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            raw = cv2.imread(str(data / f"{held}_test" / "labels" / f"{rec['id']}.png"), cv2.IMREAD_UNCHANGED)
            pred, road, keep = p >= 0.5, raw == 3, raw != 11            # camvid ids: 3 road, 11 void
            tp += np.count_nonzero(pred & road & keep)
            fp += np.count_nonzero(pred & ~road & keep)
            fn += np.count_nonzero(~pred & road & keep)
        assert row["test_items"] == len(test)
        assert row["iou"] == pytest.approx(tp / (tp + fp + fn), abs=1e-4)
        run = "kitti" if held == "kitti" else "_all"
        assert not (out / "runs" / run / "prior" / "model.pt").exists()       # no training
        saved = np.load(out / "runs" / run / "prior" / "prior.npy")
        assert np.abs(saved - prior).max() < 1e-6


def test_prior_and_adapt_put_every_store_in_one_rectangle(geo_run):
    """The prior is an image of the training rectangle: a study with prior/adapt that does not set
    'canvas' gets the shared rectangle (said in study.json), every store the same size."""
    _, out = geo_run[:2]
    assert json.loads((out / "study.json").read_text())["canvas"] == "shared"
    assert len({tuple(Store.open(p).store_size) for p in (out / "stores").glob("*/*/*")}) == 1


def test_adapt_reuses_the_within_model_and_never_reads_test_labels(geo_run):
    import numpy as np
    import torch

    from vcprep.imageio import read_image
    from vcprep.prior import surrogate_labels

    _, out, proc = geo_run
    # one within model per run, trained once (adapt's source); no other training
    assert proc.stderr.count("training on") == 2 and proc.stderr.count("within: training on") == 2
    for run, targets in (("kitti", {"kitti": out / "runs" / "kitti" / "adapt"}),
                         ("_all", {t: out / "runs" / "_all" / "adapt" / t for t in ("cityscapes", "camvid2")})):
        src = out / "runs" / run / "within" / "model.pt"
        assert json.loads((out / "runs" / run / "within" / "train.json").read_text())["train_items"] > 0
        prior = np.load(out / "runs" / run / "adapt" / "prior.npy")
        for ds, adir in targets.items():
            ck = torch.load(adir / "model.pt", map_location="cpu", weights_only=False)
            assert ck["adapted"]["from"] == str(src) and ck["config"]["init"] == str(src)
            rec = json.loads((adir / "adapt.json").read_text())
            assert rec["target"] == ("unlabelled" if ds == "camvid2" else "test")
            store = Store.open(adir / "target.store")
            assert ck["config"]["stores"] == [str(store.root)]
            folder = out.parent / "data" / (f"{ds}_unlabelled" if ds == "camvid2" else f"{ds}_test") / "images"
            assert len(store) == rec["target_items"] > 0
            for item in store:
                assert Path(item["source"]).parent == folder and not item.get("label_source")
                assert item["label_kind"] == "surrogate"
                lab = read_image(store.path(item["label"]), label=True).array
                # the labels trained on are the prior's tri-mask, the same for every image: no test label
                assert np.array_equal(lab, surrogate_labels(prior, 0.25, 0.75))
            row = json.loads(((out / "runs" / run / "adapt") /
                              ("result.json" if ds == run else f"result-{ds}.json")).read_text())
            assert row["adapt_target"] == rec["target"] and row["train_datasets"] == (
                ["camvid"] if run == "kitti" else ["camvid", "kitti"])
            assert row["test_items"] == {"kitti": 2, "cityscapes": 1, "camvid2": 3}[ds]


def test_prior_and_adapt_resume_and_share_the_within_model(geo_run, tmp_path):
    import shutil

    study, out, proc = geo_run
    copy = tmp_path / "out"
    shutil.copytree(out, copy)
    models = sorted(copy.glob("runs/**/model.pt"))
    assert len(models) == 5                          # 2 within + 3 adapted
    before = {p: p.stat().st_mtime_ns for p in models}
    lost = copy / "runs" / "_all" / "adapt" / "result-camvid2.json"
    iou = json.loads(lost.read_text())["iou"]
    lost.unlink()
    again = run_cli("crossval", study, "--out", copy, "--conditions", "within,prior,adapt", "--json", prog="vctrain")
    assert again.returncode == 0, again.stderr
    assert "training on" not in again.stderr and "adapting" not in again.stderr
    assert again.stderr.count("model trained earlier") == 3      # within (2 runs) and adapt's source for camvid2
    assert "adapted earlier" in again.stderr and again.stderr.count("done earlier") == 5
    assert {p: p.stat().st_mtime_ns for p in models} == before
    assert json.loads(lost.read_text())["iou"] == pytest.approx(iou)
    summary = json.loads(again.stdout.strip().splitlines()[-1])
    assert list(summary) == ["within", "prior", "adapt"]
    assert summary["prior"] == pytest.approx(json.loads(proc.stdout.strip().splitlines()[-1])["prior"])


def test_adapt_fuse_fuses_the_prior_with_the_within_models_own_prediction(geo_run, tmp_path):
    """Condition adapt-fuse: the same within model (no training), adapted with surrogate labels
    = tri-mask of p_g p_n / (p_g p_n + (1 - p_g)(1 - p_n)), p_n the within model's own P(road)
    on each target image, computed here by hand from the predictor."""
    import shutil

    import numpy as np
    import torch

    from vcprep.imageio import read_image
    from vcprep.prior import surrogate_labels
    from vctrain.data import vp_in_store
    from vctrain.predict import Predictor

    study, out, proc = geo_run
    copy = tmp_path / "out"
    shutil.copytree(out, copy)
    again = run_cli("crossval", study, "--out", copy, "--conditions", "within,adapt-fuse", "--json", prog="vctrain")
    assert again.returncode == 0, again.stderr
    assert "training on" not in again.stderr and again.stderr.count("adapting the within model") == 3
    summary = json.loads(again.stdout.strip().splitlines()[-1])
    assert list(summary) == ["within", "adapt-fuse"]
    for run, ds in (("kitti", "kitti"), ("_all", "cityscapes"), ("_all", "camvid2")):
        adir = copy / "runs" / run / "adapt-fuse" / ("" if ds == run else ds)
        src = copy / "runs" / run / "within" / "model.pt"
        ck = torch.load(adir / "model.pt", map_location="cpu", weights_only=False)
        assert ck["adapted"]["combine"] == "fuse" and ck["adapted"]["from"] == str(src)
        prior = np.load(copy / "runs" / run / "adapt-fuse" / "prior.npy")
        pred = Predictor(src, "cpu")
        store = Store.open(adir / "target.store")
        differs = False
        for item in store:
            pn = pred.road_probability(read_image(store.path(item["image"])).array, vp_in_store(item, store))
            a, b = prior.astype(np.float64) * pn, (1 - prior.astype(np.float64)) * (1 - pn)
            fused = np.divide(a, a + b, out=np.full(a.shape, 0.5), where=(a + b) > 0)
            lab = read_image(store.path(item["label"]), label=True).array
            np.testing.assert_array_equal(lab, surrogate_labels(fused.astype(np.float32), 0.25, 0.75))
            differs |= not np.array_equal(lab, surrogate_labels(prior, 0.25, 0.75))
        assert differs  # the network's own evidence changed the labels somewhere
    row = json.loads((copy / "runs" / "_all" / "adapt-fuse" / "result-cityscapes.json").read_text())
    assert row["condition"] == "adapt-fuse" and row["train_datasets"] == ["camvid", "kitti"]


@pytest.mark.parametrize("edit, needle", [
    (lambda d, root: (root / "empty").mkdir() or d["datasets"][3].update(unlabelled={"images": "empty"}),
     "dataset 'camvid2' unlabelled: no images"),
    (lambda d, root: d["datasets"][0].update(unlabelled={"images": "camvid_train/images"}),
     "'unlabelled' split would never be used"),
    (lambda d, root: d["datasets"][3].update(unlabelled={"images": "camvid2_test/images", "labels": "x"}),
     "unknown key 'labels' in dataset 'camvid2' unlabelled"),
])
def test_bad_adapt_input_gives_one_error_line(tmp_path, edit, needle):
    root = tmp_path / "data"
    study = _mixed_study(root)
    d = yaml.safe_load(study.read_text())
    edit(d, root)
    d["conditions"] = ["adapt"]
    study.write_text(yaml.safe_dump(d))
    out = tmp_path / "out"
    proc = run_cli("crossval", study, "--out", out, prog="vctrain")
    assert_one_error_line(proc, needle)
    assert not out.exists()


# -- the own vehicle, found from the labels (ego: auto; issue 24.2) --------------------------------

def _ego_study(root: Path, ego=None) -> Path:
    """camvid (role train, no own vehicle in its labels) and car (role test, the camvid camera; its
    labels ignore the bottom 8 rows of every frame, as CamVid's 0001TP ignores its bonnet)."""
    root.mkdir(parents=True, exist_ok=True)
    (root / "camvid.yaml").write_text(camera_to_yaml(CAMS["camvid"]))
    images, labels = write_synthetic_dataset(root / "car", CAMS["camvid"], n=6, bonnet_rows=8)
    car = {"name": "car", "role": "test", "camera": "camvid.yaml", "label_format": "camvid",
           "test": {"images": str(images.relative_to(root)), "labels": str(labels.relative_to(root))}}
    if ego is not None:
        car["ego"] = ego
    datasets = [{"name": "camvid", "role": "train", "camera": "camvid.yaml", "label_format": "camvid",
                 "train": _dataset(root, "camvid_train", CAMS["camvid"], 4, 0, False)}, car]
    study = {"datasets": datasets, "conditions": ["between"], "store_width": 128, "above": None,
             "train": {"epochs": 1, "max_steps": 1, "batch_size": 2, "arch": "segnet-narrow", "base_width": 4,
                       "val_fraction": 0}}
    path = root / "study.yaml"
    path.write_text(yaml.safe_dump(study, sort_keys=False))
    return path


def _store_ego_rows(out: Path, dataset: str) -> set:
    from vcprep.store import Store
    stores = [m.parent for m in (out / "stores" / dataset).rglob("manifest.jsonl")]
    assert stores
    return {r.get("ego_rows", 0) for s in stores for r in Store.open(s)}


@pytest.mark.parametrize("ego, rows", [(None, 8), ("auto", 8), ("none", 0), (5, 5)])
def test_the_own_vehicle_is_found_from_the_labels(tmp_path, ego, rows):
    study = _ego_study(tmp_path / "data", ego)
    out = tmp_path / "out"
    proc = run_cli("crossval", study, "--out", out, "--json", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert _store_ego_rows(out, "car") == {rows}          # every item of car is warped without its bonnet rows
    assert _store_ego_rows(out, "camvid") == {0}          # nothing found where nothing is
    found = json.loads((out / "study.json").read_text()).get("ego_found", {})
    if ego in (None, "auto"):
        assert found["car"]["ego_rows"] == 8 and found["car"]["frames"] == 6 and found["camvid"]["ego_rows"] == 0
        assert "car: own vehicle in the bottom 8 of 180 rows" in proc.stderr
    else:
        assert "car" not in found and "own vehicle in the bottom" not in proc.stderr


@pytest.mark.parametrize("ego", [-1, "maybe", True, 2.5])
def test_a_bad_ego_value_is_one_error_line(tmp_path, ego):
    proc = run_cli("crossval", _ego_study(tmp_path / "data", ego), "--out", tmp_path / "out", prog="vctrain")
    assert_one_error_line(proc, "dataset 'car' has ego", "ego: auto")


def test_camera_estimate_in_a_study(tmp_path):
    """camera: estimate -- the test camera estimated from its own frames once, kept beside the
    stores, said, noted in the table, and reused on a rerun (issue 25)."""
    import math

    from vcprep.camera import Camera, read_camera_yaml

    f = 120 / math.tan(math.radians(30))  # the assumed 60-degree lens, so the estimated tilt is the true one
    true = Camera("car", (240, 180), f, f, 119.5, 89.5, 1.4, tilt=3.0)
    root = tmp_path / "data"
    study = _ego_study(root)
    d = yaml.safe_load(study.read_text())
    images, labels = write_synthetic_dataset(root / "car_est", true, n=6, bonnet_rows=8,
                                             poses=[(p, 3.0) for p in (0, 1, -1, 0.5, -0.5, 0)])
    d["datasets"][1].update(camera="estimate", test={"images": str(images), "labels": str(labels)})
    study.write_text(yaml.safe_dump(d, sort_keys=False))
    out = tmp_path / "out"
    proc = run_cli("crossval", study, "--out", out, "--json", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    cam = read_camera_yaml(out / "cameras" / "car.yaml")
    assert cam.tilt == pytest.approx(3.0, abs=0.3) and cam.ego_rows == 8 and cam.size == (240, 180)
    assert "car: camera ESTIMATED from its frames" in proc.stderr and "fx assumed" in proc.stderr
    assert "ASSUMED" in (out / "cameras" / "car.yaml").read_text()
    assert json.loads((out / "study.json").read_text())["cameras_estimated"]["car"]["tilt"] == cam.tilt
    assert "Camera of car ESTIMATED" in (out / "table.md").read_text()
    assert _store_ego_rows(out, "car") == {8}
    proc = run_cli("crossval", study, "--out", out, "--json", prog="vctrain")  # resumes: estimated once
    assert proc.returncode == 0, proc.stderr
    assert "estimating its camera" not in proc.stderr and "camera ESTIMATED" in proc.stderr
    assert "building it afresh" not in proc.stderr and "training on" not in proc.stderr
    # the first estimate is the camera as its YAML reads back (not the unrounded one), so a resumed
    # study designs the very same virtual camera and its finished stores stay finished
    from vctrain.study import Resolution, load_study

    fresh = tmp_path / "fresh"
    first, again = (Resolution(load_study(study), fresh) for _ in range(2))
    car = load_study(study).dataset("car")
    cam1 = first.camera(car)
    assert cam1 == again.camera(car) == read_camera_yaml(fresh / "cameras" / "car.yaml")
    assert first.virtual() == again.virtual()


def test_a_study_camera_that_is_both_a_preset_and_a_folder_is_an_error_naming_both(tmp_path):
    """The one naming rule in a study (issue 26.5): a dataset folder kitti/ next to the study and
    camera: kitti is an error naming both readings; preset:kitti is the preset, ./kitti the folder."""
    from vctrain.study import load_study

    study = _study(tmp_path / "data")
    d = yaml.safe_load(study.read_text())
    (tmp_path / "data" / "kitti").mkdir()
    d["datasets"][1]["camera"] = "kitti"
    study.write_text(yaml.safe_dump(d))
    proc = run_cli("crossval", study, "--out", tmp_path / "out", prog="vctrain")
    assert_one_error_line(proc, "dataset 'kitti' camera 'kitti' is both the camera preset kitti and the folder",
                          "preset:kitti", "./kitti")
    assert not (tmp_path / "out").exists()
    d["datasets"][1]["camera"] = "preset:kitti"
    study.write_text(yaml.safe_dump(d))
    assert load_study(study).datasets[1].camera == "preset:kitti"
    d["datasets"][1]["camera"] = "./kitti"
    study.write_text(yaml.safe_dump(d))
    assert load_study(study).datasets[1].camera == str(tmp_path / "data" / "kitti")
    (tmp_path / "data" / "kitti").rmdir()
    d["datasets"][1]["camera"] = "kitti"          # no such folder: the preset
    study.write_text(yaml.safe_dump(d))
    assert load_study(study).datasets[1].camera == "preset:kitti"
    d["datasets"][1]["camera"] = "preset:nope"
    study.write_text(yaml.safe_dump(d))
    assert_one_error_line(run_cli("crossval", study, "--out", tmp_path / "out", prog="vctrain"),
                          "unknown camera preset 'nope'")


def test_a_study_that_sets_nothing_gets_the_measured_design(tmp_path):
    """No store_width/store_pixels/above/crop/canvas: the 172800-px budget, the virtual camera cropped
    to 8 deg above the horizon, its rectangle sized by the trainable cameras (canvas: footprint) and
    full-height 4/9-width training windows (issue 24's measured best);
    store_width alone still sets the scale, 'above: null' leaves the design uncropped, and an
    explicit crop wins over the default."""
    import math

    from vctrain.study import DEFAULT_ABOVE, DEFAULT_CANVAS, DEFAULT_STORE_PIXELS, Resolution, load_study, training_settings

    study = _study(tmp_path / "data")
    d = yaml.safe_load(study.read_text())
    del d["store_width"], d["above"]
    d["train"].pop("crop", None)
    study.write_text(yaml.safe_dump(d))
    s = load_study(study)
    assert s.above == DEFAULT_ABOVE == 8.0 and s.store_pixels is None and s.store_width is None
    assert s.canvas is None and DEFAULT_CANVAS == "footprint"
    b = Resolution(s, tmp_path / "out")
    assert b.canvas == "footprint"
    v = b.virtual()
    f = v.K[0][0]
    # rows above the horizon: f (tan 8 deg + tan tilt_range 3 deg)
    assert v.K[1][2] + 0.5 == pytest.approx(f * (math.tan(math.radians(8)) + math.tan(math.radians(3))), rel=1e-6)
    w, h = v.size
    assert (w * b.scale()) * (h * b.scale()) == pytest.approx(DEFAULT_STORE_PIXELS, rel=1e-9)
    assert training_settings(s)["crop"] == pytest.approx([4 / 9, 1.0])

    d["store_width"], d["above"], d["train"]["crop"] = 200, None, 0.5
    study.write_text(yaml.safe_dump(d))
    s = load_study(study)
    b = Resolution(s, tmp_path / "out2")
    assert s.above is None and b.scale() == pytest.approx(200 / b.virtual().size[0])
    assert b.virtual().size[1] > v.size[1]  # uncropped: taller than the 8-degree design
    assert training_settings(s)["crop"] == 0.5
