"""Data as it ships (issue 16.3, 16.4): nested dataset trees and per-frame calibration.

Synthetic frames rendered through cameras whose calibration we write ourselves (KITTI
``calib/<stem>.txt`` with ``P2`` and ``Tr_cam_to_road``, Cityscapes ``camera/.../<key>_camera.json``),
so every frame's K, height and pose -- and hence its exact homography -- are known.
"""
from __future__ import annotations

import json
import math
import shutil
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from conftest import PAPER_STORE, assert_one_error_line, run_cli
from vcprep.camera import PRESETS, Camera
from vcprep.warp import apply_homography, virt_H_src, virtual_at_scale, vp_from_pose
from vcprep.store import Store
from vcprep.synthetic import RoadScene, render_road

SCALE = 0.05
KITTI = PRESETS["kitti"].for_image_size((414, 125))
CITY = PRESETS["cityscapes"].for_image_size((256, 128))
# per frame: (height m, tilt deg) -- what each frame's own calibration says
KITTI_POSES = [(1.55, 0.0), (1.65, 1.2), (1.72, -0.8)]
CITY_POSES = {"aachen": [(1.18, 2.4, 0.0), (1.22, 1.6, 1.0)], "bremen": [(1.25, 3.0, -1.5), (1.20, 2.0, 0.5)]}


def _kitti_calib(cam: Camera) -> str:
    """A KITTI road calib file: P2 = [K | 0], Tr_cam_to_road rows = road axes in camera coordinates
    (X right, Y down = (0, cos b, sin b), Z forward) and the camera centre at road (0, -h, 0)."""
    b = math.radians(cam.tilt)
    P2 = [cam.fx, 0, cam.cx, 0, 0, cam.fy, cam.cy, 0, 0, 0, 1, 0]
    T = [1, 0, 0, 0, 0, math.cos(b), math.sin(b), -cam.height, 0, -math.sin(b), math.cos(b), 0]
    line = lambda k, v: f"{k}: " + " ".join(f"{x:.12e}" for x in v)
    return "\n".join([line("P0", P2), line("P2", P2), line("R0_rect", [1, 0, 0, 0, 1, 0, 0, 0, 1]),
                      line("Tr_cam_to_road", T)]) + "\n"


def _kitti_label(lab: np.ndarray) -> np.ndarray:
    """gt_image_2 colours (BGR): magenta road, red not road -- and, as KITTI ships them, the last
    rows red across the whole width, even under the road."""
    out = np.zeros(lab.shape + (3,), np.uint8)
    out[lab == 1] = (255, 0, 255)
    out[lab != 1] = (0, 0, 255)
    out[-3:] = (0, 0, 255)
    return out


def write_kitti_tree(root: Path) -> list[Camera]:
    """``training/{image_2,gt_image_2,calib}`` with one calibration per frame; returns the cameras."""
    cams = []
    for d in ("image_2", "gt_image_2", "calib"):
        (root / d).mkdir(parents=True, exist_ok=True)
    for i, (h, tilt) in enumerate(KITTI_POSES):
        cam = replace(KITTI, name=f"um_{i:06d}", height=h, tilt=tilt)
        img, lab = render_road(cam, RoadScene(texture_seed=i, offset=0.4 * i))
        cv2.imwrite(str(root / "image_2" / f"um_{i:06d}.png"), img)
        cv2.imwrite(str(root / "gt_image_2" / f"um_road_{i:06d}.png"), _kitti_label(lab))
        (root / "calib" / f"um_{i:06d}.txt").write_text(_kitti_calib(cam))
        cams.append(cam)
    return cams


def write_cityscapes_tree(root: Path) -> dict[str, Camera]:
    """``leftImg8bit/train/<city>/``, ``gtFine/train/<city>/`` and ``camera/train/<city>/``."""
    cams = {}
    for city, poses in CITY_POSES.items():
        for i, (h, tilt, pan) in enumerate(poses):
            key = f"{city}_000000_{i:06d}"
            cam = replace(CITY, name=f"{key}_camera", height=h, tilt=tilt, pan=pan)
            img, lab = render_road(cam, RoadScene(texture_seed=7 + i, offset=-0.3 * i))
            ids = np.where(lab == 1, 7, 0).astype(np.uint8)
            ids[-4:] = 1  # ego vehicle: ignore
            for d in ("leftImg8bit", "gtFine", "camera"):
                (root / d / "train" / city).mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(root / "leftImg8bit" / "train" / city / f"{key}_leftImg8bit.png"), img)
            cv2.imwrite(str(root / "gtFine" / "train" / city / f"{key}_gtFine_labelIds.png"), ids)
            doc = {"extrinsic": {"baseline": 0.22, "pitch": math.radians(tilt), "roll": 0.0, "yaw": math.radians(pan),
                                 "x": 1.7, "y": 0.1, "z": h},
                   "intrinsic": {"fx": cam.fx, "fy": cam.fy, "u0": cam.cx, "v0": cam.cy}}
            (root / "camera" / "train" / city / f"{key}_camera.json").write_text(json.dumps(doc))
            cams[key] = cam
    return cams


@pytest.fixture(scope="module")
def kitti(tmp_path_factory):
    root = tmp_path_factory.mktemp("kitti") / "training"
    return root, write_kitti_tree(root)


@pytest.fixture(scope="module")
def city(tmp_path_factory):
    root = tmp_path_factory.mktemp("cityscapes")
    return root, write_cityscapes_tree(root)


def _warp(camera, images, out, labels=None, fmt=None, *extra):
    args = ["warp", "--camera", camera, "--images", images, "--out", out, *PAPER_STORE, "--scale", SCALE, "--jobs", "1", "-q"]
    if labels is not None:
        args += ["--labels", labels, "--label-format", fmt]
    return run_cli(*args, *extra)


def _records(store: Path) -> dict[str, dict]:
    return {r["id"]: r for r in Store.open(store)}


# -- per-frame calibration -------------------------------------------------------------------------

def test_kitti_calib_folder_gives_every_frame_its_own_exact_pose(kitti, tmp_path):
    root, cams = kitti
    out = tmp_path / "store"
    proc = _warp(root / "calib", root / "image_2", out, root / "gt_image_2", "kitti")
    assert proc.returncode == 0, proc.stderr
    recs = _records(out)
    vs = virtual_at_scale(PRESETS["virtual"], SCALE)
    assert sorted(recs) == [c.name for c in cams]
    for cam in cams:
        rec = recs[cam.name]
        assert rec["vp_status"] == "calibrated"
        assert rec["camera"] == "calib" and rec["camera_file"] == str(root / "calib" / f"{cam.name}.txt")
        p = rec["camera_params"]
        assert p["height"] == pytest.approx(cam.height, abs=1e-12)
        assert p["tilt"] == pytest.approx(cam.tilt, abs=1e-9) and p["pan"] == 0
        assert [p["fx"], p["fy"], p["cx"], p["cy"]] == pytest.approx([cam.fx, cam.fy, cam.cx, cam.cy], abs=1e-9)
        # the exact homography of this frame's known camera and pose
        H = np.asarray(rec["H"]).reshape(3, 3)
        np.testing.assert_allclose(H, virt_H_src(cam, vs, 0.0, cam.tilt), rtol=1e-9, atol=1e-9)
        # ... which sends the frame's true road VP to the virtual principal point
        np.testing.assert_allclose(apply_homography(H, [vp_from_pose(cam)])[0], [vs.cx, vs.cy], atol=1e-6)
        # and is exactly what '--camera thatframe.txt' gives for that frame alone
        single = tmp_path / f"single_{cam.name}"
        (single / "images").mkdir(parents=True)
        shutil.copy(root / "image_2" / f"{cam.name}.png", single / "images")
        alone = tmp_path / f"alone_{cam.name}"
        proc = _warp(root / "calib" / f"{cam.name}.txt", single / "images", alone)
        assert proc.returncode == 0, proc.stderr
        ref = _records(alone)[cam.name]
        assert ref["H"] == rec["H"] and ref["camera_params"] == rec["camera_params"]
        assert ref["vp_status"] == "camera"  # one file for the whole folder: its pose is the camera's
        assert (alone / ref["image"]).read_bytes() == (out / rec["image"]).read_bytes()
        # the label's red bottom rim is not completed: the road continues below the frame
        lab = cv2.imread(str(out / rec["label"]), cv2.IMREAD_UNCHANGED)
        valid = cv2.imread(str(out / rec["valid"]), cv2.IMREAD_UNCHANGED)
        u = int(round(rec["completion_centre"][0]))
        below = lab[int(np.flatnonzero(valid[:, u])[-1]) + 1:, u]
        assert len(below) > 20 and (below == 1).all()
    # the frames really differ: one camera for all would have been wrong for two of them
    assert len({tuple(r["H"]) for r in recs.values()}) == len(cams)
    # re-running does nothing; changing one frame's calibration redoes exactly that frame
    proc = _warp(root / "calib", root / "image_2", out, root / "gt_image_2", "kitti")
    assert proc.returncode == 0 and out.joinpath("manifest.jsonl").read_text() == \
        "".join(json.dumps(recs[k], separators=(",", ":")) + "\n" for k in sorted(recs))
    calib = tmp_path / "calib2"
    shutil.copytree(root / "calib", calib)
    (calib / "um_000001.txt").write_text(_kitti_calib(replace(cams[1], height=1.9)))
    proc = run_cli("warp", "--camera", calib, "--images", root / "image_2", "--labels", root / "gt_image_2",
                   "--label-format", "kitti", "--out", out, "--scale", SCALE, "--jobs", "1")
    assert proc.returncode == 0 and "1 built, 2 up to date" in proc.stderr, proc.stderr
    assert _records(out)["um_000001"]["camera_params"]["height"] == pytest.approx(1.9)


def test_a_frame_without_calibration_is_an_error_naming_it(kitti, tmp_path):
    root, _ = kitti
    calib = tmp_path / "calib"
    shutil.copytree(root / "calib", calib)
    (calib / "um_000002.txt").unlink()
    proc = _warp(calib, root / "image_2", tmp_path / "store")
    assert_one_error_line(proc, str(root / "image_2" / "um_000002.png"), "no calibration file", str(calib),
                          "um_000002.txt")
    # the frames before it are kept (as for any bad item)
    assert sorted(_records(tmp_path / "store")) == ["um_000000", "um_000001"]
    # a folder that holds no calibration at all, and --within with a folder
    empty = tmp_path / "empty"
    empty.mkdir()
    assert_one_error_line(_warp(empty, root / "image_2", tmp_path / "s2"), str(empty), "no calibration files")
    assert_one_error_line(_warp(root / "calib", root / "image_2", tmp_path / "s3", None, None, "--within", "estimate"),
                          "--within needs one camera")
    # commands that need one camera say so
    assert_one_error_line(run_cli("vp", "--camera", root / "calib", root / "image_2"), "per-frame", "one camera")


def test_cityscapes_nested_tree_with_per_frame_camera_json(city, tmp_path):
    root, cams = city
    out = tmp_path / "store"
    proc = _warp(root / "camera" / "train", root / "leftImg8bit" / "train", out, root / "gtFine" / "train", "cityscapes")
    assert proc.returncode == 0, proc.stderr
    recs = _records(out)
    assert sorted(recs) == sorted(cams)  # ids: stems without _leftImg8bit, from every city folder
    vs = virtual_at_scale(PRESETS["virtual"], SCALE)
    for key, cam in cams.items():
        rec, city_ = recs[key], key.split("_")[0]
        assert rec["source"] == str(root / "leftImg8bit" / "train" / city_ / f"{key}_leftImg8bit.png")
        assert rec["label_source"] == str(root / "gtFine" / "train" / city_ / f"{key}_gtFine_labelIds.png")
        assert rec["camera_file"] == str(root / "camera" / "train" / city_ / f"{key}_camera.json")
        assert rec["vp_status"] == "calibrated"
        assert rec["pan_deg"] == pytest.approx(cam.pan) and rec["tilt_deg"] == pytest.approx(cam.tilt)
        H = np.asarray(rec["H"]).reshape(3, 3)
        np.testing.assert_allclose(H, virt_H_src(cam, vs, cam.pan, cam.tilt), rtol=1e-9, atol=1e-9)
        # the warped label is right: road where the virtual camera, rendered directly, sees road
        lab = cv2.imread(str(out / rec["label"]), cv2.IMREAD_UNCHANGED)
        valid = cv2.imread(str(out / rec["valid"]), cv2.IMREAD_UNCHANGED) == 1
        _, direct = render_road(vs, RoadScene(texture_seed=0, offset=-0.3 * int(key[-1])), pan=0.0, tilt=0.0)
        known = valid & (lab != 255)
        assert (lab[known] == direct[known]).mean() > 0.98
    # the same frames copied into flat folders give byte-identical stored files
    flat = tmp_path / "flat"
    for d in ("leftImg8bit", "gtFine", "camera"):
        (flat / d).mkdir(parents=True)
        for f in (root / d / "train").rglob("*.*"):
            shutil.copy(f, flat / d)
    proc = _warp(flat / "camera", flat / "leftImg8bit", tmp_path / "flatstore", flat / "gtFine", "cityscapes")
    assert proc.returncode == 0, proc.stderr
    frecs = _records(tmp_path / "flatstore")
    for key in cams:
        for k in ("image", "label", "valid"):
            assert (tmp_path / "flatstore" / frecs[key][k]).read_bytes() == (out / recs[key][k]).read_bytes()
        assert frecs[key]["H"] == recs[key]["H"]


def test_nested_tree_errors_name_the_files(city, tmp_path):
    root, cams = city
    tree = tmp_path / "cs"
    shutil.copytree(root, tree)
    img = tree / "leftImg8bit" / "train"
    lab = tree / "gtFine" / "train"
    # a label in another city's folder is not this image's label (the trees must mirror)
    moved = lab / "aachen" / "aachen_000000_000001_gtFine_labelIds.png"
    moved.rename(lab / "bremen" / moved.name)
    proc = _warp("cityscapes", img, tmp_path / "s1", lab, "cityscapes")
    assert_one_error_line(proc, str(img / "aachen" / "aachen_000000_000001_leftImg8bit.png"),
                          "no label 'aachen/aachen_000000_000001_gtFine_labelIds.png'", str(lab))
    (lab / "bremen" / moved.name).rename(moved)
    # two images with one id in two folders
    (img / "zurich").mkdir()
    shutil.copy(img / "aachen" / "aachen_000000_000000_leftImg8bit.png", img / "zurich")
    proc = _warp("cityscapes", img, tmp_path / "s2")
    assert_one_error_line(proc, "duplicate image id 'aachen_000000_000000_leftImg8bit'",
                          str(img / "zurich" / "aachen_000000_000000_leftImg8bit.png"),
                          "aachen/aachen_000000_000000_leftImg8bit.png")


def test_label_tree_inside_the_image_tree_is_not_read_as_images(kitti, tmp_path):
    root, cams = kitti
    tree = tmp_path / "t"
    shutil.copytree(root / "image_2", tree)
    shutil.copytree(root / "gt_image_2", tree / "gt")
    (tree / ".hidden").mkdir()
    shutil.copy(root / "image_2" / "um_000000.png", tree / ".hidden" / "um_000000.png")
    proc = _warp(root / "calib", tree, tmp_path / "store", tree / "gt", "kitti")
    assert proc.returncode == 0, proc.stderr
    assert sorted(_records(tmp_path / "store")) == [c.name for c in cams]


# -- the same in vctrain: crossval, predict, the resize baseline ----------------------------------------

@pytest.fixture(scope="module")
def study_run(kitti, city, tmp_path_factory):
    """A two-dataset study: KITTI-like frames with a calib folder, Cityscapes-like nested frames
    with per-frame camera json."""
    kroot, _ = kitti
    croot, _ = city
    study = {"datasets": [
        {"name": "kitti", "camera": str(kroot / "calib"), "label_format": "kitti",
         "train": {"images": str(kroot / "image_2"), "labels": str(kroot / "gt_image_2")}},
        {"name": "city", "camera": str(croot / "camera" / "train"), "label_format": "cityscapes",
         "train": {"images": str(croot / "leftImg8bit" / "train"), "labels": str(croot / "gtFine" / "train")}}],
        "conditions": ["resize", "between", "within"], "store_width": 96, "above": None, "pan_range": 5, "tilt_range": 5,
        "train": {"epochs": 1, "max_steps": 2, "batch_size": 2, "arch": "segnet-narrow", "base_width": 4,
                  "val_fraction": 0, "seed": 0}}
    root = tmp_path_factory.mktemp("study")
    path = root / "study.yaml"
    path.write_text(yaml.safe_dump(study, sort_keys=False))
    out = root / "out"
    proc = run_cli("crossval", path, "--out", out, "--json", "--jobs", "1", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    return out, proc


def test_crossval_reads_nested_trees_and_per_frame_calibration(study_run, kitti, city):
    out, proc = study_run
    rows = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    assert {(r["heldout"], r["condition"]) for r in rows} == {(h, c) for h in ("kitti", "city")
                                                              for c in ("resize", "between", "within")}
    n = {"kitti": len(kitti[1]), "city": len(city[1])}
    for r in rows:
        assert r["test_items"] == n[r["heldout"]]
    for name, cams in (("kitti", {c.name: c for c in kitti[1]}), ("city", city[1])):
        for geometry in ("between", "within"):
            recs = _records(out / "stores" / name / "train" / geometry)
            assert sorted(recs) == sorted(cams)
            # every geometry uses each frame's calibrated pose (nothing to estimate)
            for key, rec in recs.items():
                assert rec["vp_status"] == "calibrated"
                assert rec["tilt_deg"] == pytest.approx(cams[key].tilt) and rec["pan_deg"] == pytest.approx(cams[key].pan)


def test_predict_with_a_calib_folder_equals_one_file_per_frame(study_run, kitti, tmp_path):
    out, _ = study_run
    root, cams = kitti
    model = out / "runs" / "kitti" / "between" / "model.pt"
    # a nested copy of image_2 (the folder is read recursively)
    nested = tmp_path / "nested"
    for i, cam in enumerate(cams):
        (nested / f"drive{i % 2}").mkdir(parents=True, exist_ok=True)
        shutil.copy(root / "image_2" / f"{cam.name}.png", nested / f"drive{i % 2}")
    proc = run_cli("predict", model, "--camera", root / "calib", nested, "--out", tmp_path / "all", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    stems = sorted(p.name[: -len("_prob.png")] for p in (tmp_path / "all").glob("*_prob.png"))
    assert stems == [c.name for c in cams]
    for cam in cams:
        one = tmp_path / cam.name
        proc = run_cli("predict", model, "--camera", root / "calib" / f"{cam.name}.txt",
                       root / "image_2" / f"{cam.name}.png", "--out", one, prog="vctrain")
        assert proc.returncode == 0, proc.stderr
        assert (one / f"{cam.name}_prob.png").read_bytes() == (tmp_path / "all" / f"{cam.name}_prob.png").read_bytes()


def test_resize_baseline_reads_a_nested_tree(city, tmp_path):
    root, cams = city
    proc = run_cli("fit", "--baseline", "resize", "--images", root / "leftImg8bit" / "train", "--labels",
                   root / "gtFine" / "train", "--label-format", "cityscapes", "--size", "64x32", "--epochs", "1",
                   "--batch-size", "2", "--model", "segnet-narrow", "--width", "4", "--val-fraction", "0",
                   "--out", tmp_path / "resize.pt", "--json", "--quiet", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert summary["data"]["train_items"] == len(cams)
    # predict the nested tree and evaluate against the nested label tree
    preds = tmp_path / "preds"
    proc = run_cli("predict", tmp_path / "resize.pt", root / "leftImg8bit" / "train", "--out", preds, prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert len(list(preds.glob("*_mask.png"))) == len(cams)
    proc = run_cli("eval", preds, "--labels", root / "gtFine" / "train", "--label-format", "cityscapes", "--json",
                   prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert 0.0 <= json.loads(proc.stdout)["iou"] <= 1.0


# -- IDD as shipped (issue 24.4) -------------------------------------------------------------------

def write_idd_tree(root: Path, cam: Camera) -> dict[str, np.ndarray]:
    """``leftImg8bit/train/<drive>/<id>_image.jpg`` + ``gtFine/train/<drive>/<id>_label.png`` with
    IDD level-1 ids (0 drivable, 1 non-drivable, 6 sky, 255 void in the bottom rows); the same file
    id in two drives, as IDD-Lite has. Returns item id -> the expected decoded label."""
    want = {}
    for d, (drive, fid) in enumerate([("0", "000123"), ("7", "000123"), ("7", "frame0005")]):
        img, lab = render_road(cam, RoadScene(texture_seed=d, offset=0.3 * d), supersample=1)
        ids = np.where(lab == 1, 0, 1).astype(np.uint8)
        ids[:10] = 6
        ids[-4:] = 255
        for sub, name, arr in (("leftImg8bit", f"{fid}_image.jpg", img), ("gtFine", f"{fid}_label.png", ids)):
            (root / sub / "train" / drive).mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(root / sub / "train" / drive / name), arr)
        want[f"{drive}_{fid}"] = np.where(ids == 0, 1, np.where(ids == 255, 255, 0)).astype(np.uint8)
    return want


def test_idd_tree_as_shipped(tmp_path):
    from vcprep.dataset import list_dataset
    from vcprep.labels import decode_label, get_label_format
    from vcprep.vp import sequence_key

    root = tmp_path / "idd"
    want = write_idd_tree(root, KITTI)
    fmt = get_label_format("idd")
    jobs = list_dataset(root / "leftImg8bit" / "train", root / "gtFine" / "train", fmt)
    # ids carry the drive (file ids repeat between drives); the drive is the id's sequence (one mount)
    assert sorted(j.id for j in jobs) == sorted(want)
    for j in jobs:
        drive, fid = j.id.split("_", 1)
        assert sequence_key(j.id) == drive
        assert j.label == root / "gtFine" / "train" / drive / f"{fid}_label.png"
        got = decode_label(cv2.imread(str(j.label), cv2.IMREAD_UNCHANGED), fmt, j.label)
        np.testing.assert_array_equal(got, want[j.id])  # 0 drivable -> road, 255 void -> ignore, else not road
    # the whole command: every item stored under its drive-prefixed id
    out = tmp_path / "store"
    proc = _warp("kitti", root / "leftImg8bit" / "train", out, root / "gtFine" / "train", "idd")
    assert proc.returncode == 0, proc.stderr
    assert sorted(_records(out)) == sorted(want)


def test_idd_eval_finds_labels_by_item_id(tmp_path):
    """Predictions named by item id (``<drive>_<id>``) meet their labels in the drive folders."""
    root = tmp_path / "idd"
    want = write_idd_tree(root, KITTI)
    preds = tmp_path / "preds"
    preds.mkdir()
    tp = fp = fn = 0
    for k, (iid, lab) in enumerate(sorted(want.items())):  # drive 7's frame0005 predicts no road at all
        pred = np.where(lab == 1, 255, 0).astype(np.uint8) if k < 2 else np.zeros_like(lab)
        cv2.imwrite(str(preds / f"{iid}_mask.png"), pred)
        tp += int(((pred > 0) & (lab == 1)).sum())
        fn += int(((pred == 0) & (lab == 1)).sum())
    proc = run_cli("eval", preds, "--labels", root / "gtFine" / "train", "--label-format", "idd", "--json",
                   prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert fn > 0 and json.loads(proc.stdout.strip().splitlines()[-1])["iou"] == pytest.approx(tp / (tp + fp + fn))


def test_list_dataset_names_the_missing_images_before_the_labels(tmp_path):
    """A caller that skips the CLI's check (a study) is told about the images folder first."""
    from vcprep.dataset import list_dataset
    from vcprep.errors import InputError
    from vcprep.labels import get_label_format

    with pytest.raises(InputError) as e:
        list_dataset(tmp_path / "no_images", tmp_path / "no_labels", get_label_format("camvid"))
    assert e.value.file == tmp_path / "no_images" or str(e.value.file) == str(tmp_path / "no_images")
