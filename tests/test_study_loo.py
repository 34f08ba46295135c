"""vctrain crossval: leave-one-dataset-out over synthetic datasets from three different cameras."""
from __future__ import annotations

import json

import pytest
import yaml

from vcprep.warp import vp_from_pose
from vcprep.store import Store

from conftest import run_cli
from studies import assert_bad_study_fails, CAMS, CONDS, OFFSETS, _study


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
    # one virtual camera (designed from the three) for every store, at the study's width: one rectangle for
    # every training store; a test split's extended only where a frame at its pose reaches past it (as vctrain
    # predict extends it: here by the pixel the design's first-order pose margin leaves out)
    stores = {p: Store.open(p) for p in (out / "stores").glob("*/*/*")}
    (w, h), = {tuple(s.store_size) for p, s in stores.items() if p.parent.name == "train"}
    assert w == 128 and all(s.store_size[0] - w in (0, 1) and s.store_size[1] - h in (0, 1) for s in stores.values())


def test_heldout_score_matches_predict_and_eval(study_run, tmp_path):
    """The study's held-out figure equals what the public predict + eval commands give (``--engine torch``:
    the engine studies score; the default engine's masks differ where P is within float rounding of 0.5,
    which on these two tiny frames of a barely trained model moves the IoU by ~0.01)."""
    _, out, _ = study_run
    for cond, geom in (("within", "within"), ("resize", "between")):
        preds = tmp_path / cond
        p = run_cli("predict", out / "runs" / "cityscapes" / cond / "model.pt", "--store",
                    out / "stores" / "cityscapes" / "test" / geom, "--out", preds, "-q", "--device", "cpu", "--engine", "torch",
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
    (lambda d: d.update(canvas="footprint", conditions=["prior"]), "conditions prior, adapt, adapt-fuse and adapt-self"),
    (lambda d: d.update(extent="mean"), "'extent' must be one of max, median"),
    (lambda d: d.update(extent="median", virtual="virtual", above=None), "'extent' sizes a designed virtual camera"),
])
def test_bad_study_files_give_one_error_line(tmp_path, edit, needle):
    study = _study(tmp_path / "data")
    assert_bad_study_fails(study, edit, tmp_path / "out", needle)


# the training settings a study's model keys were made of when its models were last trained; a TrainConfig
# field added since must enter SETTINGS_ADDED with the value that trains as before, or every finished study
# would be trained again (a fold of issue 73's calibrated leave-one-out was, for --val-images)
KEYED = {"arch", "balance", "base_width", "batch_size", "class_weights", "color_aug", "crop", "device", "epochs",
         "force_labels", "greyscale", "hflip", "init", "l2sp", "lr", "max_steps", "momentum", "optimizer", "pretrained",
         "recipe", "scale_aug", "schedule", "seed", "shading_aug", "shift_aug", "val_fraction", "vp_channel",
         "weight_decay"}


def test_a_training_setting_added_at_its_default_keeps_the_studys_keys(tmp_path):
    from vctrain.study import load_study, training_settings

    settings = training_settings(load_study(_study(tmp_path / "data")))
    new = sorted(set(settings) - KEYED)
    assert not new, f"{new}: add them to vctrain.study.conditions.SETTINGS_ADDED with their default"
