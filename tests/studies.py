"""Study files for the crossval tests: synthetic datasets of three cameras with exact geometry."""
from __future__ import annotations

import json
from pathlib import Path

import yaml

from vcprep.camera import PRESETS, camera_to_yaml
from vcprep.warp import vp_from_pose

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



def _rows(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]



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


def assert_bad_study_fails(study: Path, edit, out: Path, needle: str) -> None:
    """``edit`` the study file's dict; crossval then ends in one error line with ``needle`` that
    names the study file, and writes nothing to ``out``."""
    d = yaml.safe_load(study.read_text())
    edit(d)
    study.write_text(yaml.safe_dump(d))
    proc = run_cli("crossval", study, "--out", out, prog="vctrain")
    assert_one_error_line(proc, needle)
    assert str(study) in proc.stderr
    assert not out.exists()
