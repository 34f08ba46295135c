"""Will a CamVid-trained model work on a new camera? Real and exactly simulated other cameras (issue 14).

    .venv/bin/python benchmarks/real_cameras.py [--seeds 0,1,2] [--epochs N] [--conditions resize,between,within]
                                                [--workdir benchmarks/out/real_cameras] [--threads 2] [--quick]

One ``vctrain crossval`` study, run once per seed (``--seed k``) into WORKDIR/seed<k>/; every run
resumes (crossval skips finished runs), so an interrupted benchmark continues where it stopped.

Data (../shared/data; nothing is tuned on a test set):

* **train** (role train): CamVid train (SegNet release, 480x360, the camvid preset at 1/2) minus
  sequence 0001TP, i.e. 0016E5 + 0006R0 (305 frames; study split ``exclude: 0001TP_*``); the
  checkpoint is chosen on the recipe's validation share of these frames.
* **in-domain** test rows (same camera): ``camvid-val`` (CamVid val, 101 frames of 0016E5) and
  ``camvid-0001TP`` (the unseen sequence 0001TP of CamVid train, 62 frames, never trained on);
  beside them ``camvid-0001TP-ego``: the same frames and labels, the camera with ``ego_rows: 36``
  (``EGO_ROWS``: the rig's bonnet, read as an exact bottom crop and predicted not road; not in
  the target).
* **real other camera**: ``kitti``, the KITTI road frames in kitti_road/training (image_2 with
  the road ground truth of gt_image_2, label format kitti; camera = the per-frame calibration
  folder calib/: P2 gives K, that frame's Tr_cam_to_road its exact height and pitch, so no VP is
  estimated). ``kitti-vp``: the same frames with one camera file and estimated road VPs, reported
  as a row of its own (not in the headline). Other folders found in ../shared/data are listed as
  not used.
* **simulated other cameras**: CamVid val through ``tele``, ``band`` and ``dashcam``, made by
  ``vcprep simulate`` exactly as benchmarks/cross_camera.py makes them (camvid_cameras.py).

Every test set has role test: per condition ONE model is trained on CamVid train and scored on each
test set in its own camera (back-projected, ignore excluded; road IoU = sum TP / sum (TP+FP+FN) over
the set). Conditions (default): ``resize`` (the baseline: images resized to the working size),
``between`` (virtual camera, each camera's average pose), ``within`` (plus each image's estimated
road VP). Available with ``--conditions`` (not run by default): ``prior`` (no training: the
geometric prior p_g of CamVid train in the virtual camera, back-projected, p_g >= 0.5; Table 5's
"Geo-Prior"), ``adapt`` (the within model of the same seed, adapted without labels to each test
set's test images with that prior's tri-mask; crossval trains the within model once for all) and
``adapt-fuse`` (the same, the surrogate labels from the prior fused with the within model's own
prediction). The virtual
camera is designed from all the study's cameras (calibrations only). Training settings:
``vctrain fit``'s defaults (its CPU recipe without a GPU) except ``--epochs``, plus ``--crop``: every
model trains on random full-height windows of 4/9 of the width of its working image, 76800 pixels
a step, and predicts on the whole image of 172800 pixels (``--store-pixels``: the virtual stores'
scale; resize at the same count, CamVid's 4:3 = 480x360 with 213x360 windows). Chosen with
``--dev`` (below): whole 76800-pixel images, 2/3 x 2/3 windows and full-height windows (the
virtual camera's horizon stays on one row of every window) measured, the windows ahead of whole
images and tied with each other; full height kept the position of the road in the image. Virtual camera cropped to 8 degrees above the horizon
(``--above``); otherwise crossval's default unless ``--store-width``.

``--dev``: the split on which settings are chosen, never a test frame: train on CamVid train's
sequence 0016E5 only, score on its sequence 0006R0 and on 0006R0 through the simulated cameras
(KITTI joins only so the virtual camera is designed as in the benchmark; its rows are dropped).

Reported (never asserted), mean +/- std over seeds (sample std, ddof 1) per cell, and the paired
difference within - resize per seed (and adapt - within, adapt-fuse - within, when they ran;
within - between in the JSON). Headline
``within_minus_resize``: the mean over seeds of (the mean over the other-camera test sets kitti,
tele, band, dashcam of within - resize); also KITTI (real) alone and the simulated cameras alone.
Targets checked: in-domain road IoU >= 0.85 on both in-domain rows for every trained condition (not
prior, not adapt); cross-camera within - resize >= 10 IoU points; every model converged (best epoch
before the last, or a plateau: the last quarter of the epochs, at least 2, improves the best
validation IoU by < 0.5 points); data pipeline: the training images/s of each model >= 0.9x a pure
forward + backward + optimiser step on random tensors of the same shape, measured in this process
right after each seed's training (same model args, batch, working size, memory format, optimiser,
device and threads; kept in runs/_all/<condition>/reference.json, so a resumed benchmark reuses the
reference of the training it belongs to).

The camera change alone (simulated cameras, :func:`no_shift_reference`): every trained model's
prediction on the simulations' source frames (CamVid val; ``--dev``: 0006R0) in their own camera,
carried into each simulated camera by the simulation's exact homography and scored against the
simulated labels: the same frames and pixels with no camera change. The score on the simulated
camera minus this is the cost of the camera change alone, per condition; within's no-change score
minus resize's score is within - resize if the virtual camera removed the whole camera shift
(``zero_cost``; over the other cameras with KITTI as measured): what these test sets allow at this
network quality. The recorded homography must carry every source label onto its simulated label
exactly (checked).
Estimated VPs vs the exact pose (:func:`exact_vp_scores`): the within model on the simulated
cameras' frames warped with each frame's exact camera pose (the simulation's vps.csv: the source
camera's nominal pose carried through that frame's simulated rotation, i.e. what a perfect
per-frame calibration gives) instead of its estimated road VP.

Threads: ``--threads T`` (default: all cores) = ``torch.set_num_threads(T)`` and ``cv2.setNumThreads(T)``
here, ``OMP_NUM_THREADS=T`` for the training processes, ``--jobs T`` store builders.
Runtime: seeds x conditions models (9 by default) x minutes_per_model, plus store building and
testing (a few minutes). ``--quick``: a smoke run (a few frames, 1 seed, 1 epoch of 2 steps,
results in WORKDIR/results, not benchmarks/results).

Outputs in benchmarks/results/: ``real_cameras.md`` (the table), ``real_cameras.png`` (bars with
+/- std), ``real_cameras.json`` (headline, every cell per seed, targets, models, settings). The last
stdout line is one JSON object with ``within_minus_resize``, ``in_domain_within``,
``in_domain_resize`` and ``minutes_per_model`` (and a few more figures: ``simulated_shift_cost_<condition>``,
``within_minus_resize_zero_cost``, ``simulated_within_minus_resize_zero_cost``,
``simulated_estimated_minus_exact_pose_within``).
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import shutil
import sys
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from camvid_cameras import BIN, DATA, DESCRIPTION, ROOT, SHARED_DATA, SIMULATED, bar_plot, native_camera, run, simulate

KITTI = SHARED_DATA / "kitti_road" / "training"
UNSEEN = "0001TP"                         # the CamVid sequence held out of training
# The 0001TP rig shows its ego-vehicle: a bonnet up to 36 rows high at the bottom of every frame
# (the height of its ego-vehicle mask, CamVid class 11 connected to the bottom edge; the training
# sequences 0016E5 and 0006R0 show none). The row camvid-0001TP-ego is the same frames and labels
# with the camera saying so (ego_rows: the rig's rows are read as an exact bottom crop and predicted
# "not road"): what a user describes when the camera sees its own car. Not in the in-domain target
# (reported beside it: the 36 rows were read off this sequence's own labels).
EGO_ROWS = 36
DEV_TRAIN, DEV_TEST = "0016E5", "0006R0"  # --dev: train on one CamVid train sequence, score on the other
IN_DOMAIN = ["camvid-val", f"camvid-{UNSEEN}"]
REAL = ["kitti"]
SIM = list(SIMULATED)
OTHER = REAL + SIM                        # the other-camera test sets of the headline
CONDITIONS = ["resize", "between", "within"]     # the default; --conditions may add within-gt, zero, prior,
                                                 # adapt, adapt-fuse
UNTRAINED = ("prior", "adapt", "adapt-fuse")     # no model of their own (no convergence or in-domain target)
ADAPTED = ("adapt", "adapt-fuse")                # reported as paired differences to within
QUICK_TRAIN = {"epochs": 1, "max_steps": 2}


# -- the study -----------------------------------------------------------------------------------
def _link(names: list[str], src: Path, dest: Path) -> Path:
    if dest.exists():
        shutil.rmtree(dest)
    dest.mkdir(parents=True)
    for n in names:
        (dest / n).symlink_to(src / n)
    return dest


def camvid_folders(wd: Path, quick: bool) -> dict[str, Path]:
    """CamVid's train/val image and label folders (quick: a few frames of each sequence, linked)."""
    full = {k: DATA / k for k in ("train", "trainannot", "val", "valannot")}
    if not quick:
        return full
    train = sorted(p.name for p in full["train"].glob("*.png"))
    pick = [n for seq in ("0016E5", "0006R0") for n in [m for m in train if m.startswith(seq)][:3]]
    pick += [n for n in train if n.startswith(UNSEEN)][:2]
    val = sorted(p.name for p in full["val"].glob("*.png"))[:3]
    return {"train": _link(pick, full["train"], wd / "src" / "train"),
            "trainannot": _link(pick, full["trainannot"], wd / "src" / "trainannot"),
            "val": _link(val, full["val"], wd / "src" / "val"),
            "valannot": _link(val, full["valannot"], wd / "src" / "valannot")}


def ego_camera(wd: Path, rows: int) -> Path:
    """wd/native-ego.yaml: the native camera with its bottom ``rows`` rows marked as the rig's own
    vehicle (``ego_rows``: every tool reads the frames as their exact bottom crop)."""
    from vcprep.camera import PRESETS, camera_to_yaml

    path = wd / "native-ego.yaml"
    path.write_text(camera_to_yaml(replace(PRESETS["camvid"].for_image_size((480, 360)), ego_rows=rows)))
    return path


def kitti_datasets() -> list[dict]:
    """The KITTI road frames with road ground truth, twice: ``kitti`` with every frame's own
    calibration (calib/: P2 and that frame's Tr_cam_to_road, the exact pose; what a user with
    KITTI's files gets), and ``kitti-vp`` with one camera (the first frame's file) and poses from
    estimated road VPs (the method without calibration; a row of its own, not in the headline)."""
    images = sorted((KITTI / "image_2").glob("*.png")) if (KITTI / "image_2").is_dir() else []
    if not images:
        return []
    test = {"images": str(KITTI / "image_2"), "labels": str(KITTI / "gt_image_2")}
    return [{"name": "kitti", "role": "test", "camera": str(KITTI / "calib"), "label_format": "kitti", "test": test},
            {"name": "kitti-vp", "role": "test", "camera": str(KITTI / "calib" / f"{images[0].stem}.txt"),
             "label_format": "kitti", "test": test}]


def dev_datasets(wd: Path, f: dict[str, Path], cam: Path, camvid) -> tuple[list[dict], dict]:
    """--dev: a split for choosing settings without any test frame. Train on CamVid train's
    sequence DEV_TRAIN alone; score on its sequence DEV_TEST (never trained on here) and on
    DEV_TEST through the same simulated cameras (named like the benchmark's, so they form the
    'other cameras' group). KITTI joins the study only so the virtual camera is designed exactly
    as in the benchmark; its rows are dropped from the dev report."""
    names = sorted(p.name for p in f["train"].glob(f"{DEV_TEST}_*.png"))
    images = _link(names, f["train"], wd / "src" / "dev" / "images")
    labels = _link(names, f["trainannot"], wd / "src" / "dev" / "labels")
    datasets = [camvid("camvid", "train", f["train"], f["trainannot"], include=f"{DEV_TRAIN}_*"),
                camvid(f"camvid-{DEV_TEST}", "test", images, labels)]
    datasets += kitti_datasets()
    for name in SIM:
        split = simulate(cam, images, labels, wd / "sim" / name, name)
        datasets.append({"name": name, "role": "test", "camera": str(wd / "sim" / name / "camera.yaml"),
                         "label_format": "camvid", "test": split})
    return datasets, {"dataset": f"camvid-{DEV_TEST}", "camera": cam, "images": images, "labels": labels}


def make_study(wd: Path, args: argparse.Namespace, conditions: list[str]) -> tuple[dict, list[str], dict]:
    """The study (camvid role train, every other set role test), its reported test-set names and
    the source of the simulated cameras ({dataset, camera, images, labels}: the in-domain test set
    they are made from)."""
    cam = native_camera(wd)
    f = camvid_folders(wd, args.quick)

    def camvid(name: str, role: str, images: Path, labels: Path, **select) -> dict:
        split = "train" if role == "train" else "test"
        return {"name": name, "role": role, "camera": str(cam), "label_format": "camvid",
                split: {"images": str(images), "labels": str(labels), **select}}

    if args.dev:
        datasets, source = dev_datasets(wd, f, cam, camvid)
        return _study(datasets, args, conditions), [d["name"] for d in datasets
                                                    if d["role"] == "test" and not d["name"].startswith("kitti")], source
    datasets = [camvid("camvid", "train", f["train"], f["trainannot"], exclude=f"{UNSEEN}_*"),
                camvid("camvid-val", "test", f["val"], f["valannot"]),
                camvid(f"camvid-{UNSEEN}", "test", f["train"], f["trainannot"], include=f"{UNSEEN}_*")]
    ego = camvid(f"camvid-{UNSEEN}-ego", "test", f["train"], f["trainannot"], include=f"{UNSEEN}_*")
    datasets.append({**ego, "camera": str(ego_camera(wd, EGO_ROWS))})
    k = kitti_datasets()
    if not k:
        print(f"note: no KITTI road frames in {KITTI}: no real other camera", file=sys.stderr)
    datasets += k
    for name in SIM:
        split = simulate(cam, f["val"], f["valannot"], wd / "sim" / name, name)
        datasets.append({"name": name, "role": "test", "camera": str(wd / "sim" / name / "camera.yaml"),
                         "label_format": "camvid", "test": split})
    return (_study(datasets, args, conditions), [d["name"] for d in datasets if d["role"] == "test"],
            {"dataset": "camvid-val", "camera": cam, "images": f["val"], "labels": f["valannot"]})


def _study(datasets: list[dict], args: argparse.Namespace, conditions: list[str]) -> dict:
    study: dict = {"datasets": datasets, "conditions": conditions, "virtual": "design", "pan_range": 10,
                   "tilt_range": 5}
    if args.store_width:
        study["store_width"] = args.store_width
    if args.store_pixels:
        study["store_pixels"] = args.store_pixels
    if args.above is not None and args.above >= 0:
        study["above"] = args.above
    train = dict(QUICK_TRAIN) if args.quick else {}
    if args.device:
        train["device"] = args.device
    if args.crop and args.crop != 1.0 and args.crop != [1.0, 1.0]:
        train["crop"] = args.crop
    if train:
        study["train"] = train
    return study


def unused_data() -> list[str]:
    if not SHARED_DATA.is_dir():
        return []
    return sorted(p.name for p in SHARED_DATA.iterdir() if p.is_dir() and p.name not in ("camvid", "kitti_road"))


# -- measurements --------------------------------------------------------------------------------
def reference_images_per_s(ck: dict, threads: int, seconds: float, min_steps: int) -> float:
    """Images/s of a pure training step (forward, cross-entropy, backward, optimiser step) on random
    tensors shaped like the checkpoint's training batches: the same model args, batch, working size,
    memory format, optimiser and device as ``vctrain fit`` used, no data loading."""
    import torch
    from torch.nn import functional as F

    from vctrain.model import build_model
    from vctrain.train import resolve_device

    torch.set_num_threads(threads)
    cfg, margs = ck["config"], ck["model_args"]
    device = resolve_device(cfg.get("device") or "auto")
    w, h = ck["data"].get("crop_size") or ck["data"]["input_size"]  # the training batches' shape
    batch = int(cfg.get("batch_size") or 8)
    fmt = torch.channels_last if margs["arch"] == "resfpn" else torch.contiguous_format
    torch.manual_seed(0)
    model = build_model(margs).to(device, memory_format=fmt).train()
    lr, wd, mom = cfg.get("lr") or 1e-3, cfg.get("weight_decay") or 0.0, cfg.get("momentum") or 0.9
    if cfg.get("optimizer") == "adamw":
        opt = torch.optim.AdamW(model.parameters(), lr=lr, betas=(mom, 0.999), weight_decay=wd)
    else:
        opt = torch.optim.SGD(model.parameters(), lr=lr, momentum=mom, weight_decay=wd)
    x = torch.randn(batch, margs["in_channels"], h, w, device=device).contiguous(memory_format=fmt)
    y = torch.randint(0, margs["num_classes"], (batch, h, w), device=device)

    def step() -> None:
        loss = F.cross_entropy(model(x), y, ignore_index=255)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()

    for _ in range(2):  # warm-up (allocator, kernels)
        step()
    n, t0 = 0, time.perf_counter()
    while n < min_steps or time.perf_counter() - t0 < seconds:
        step()
        n += 1
    if device.type == "cuda":
        torch.cuda.synchronize()
    return batch * n / (time.perf_counter() - t0)


def convergence(log: list[dict], epochs: int, best_epoch: int) -> tuple[bool, str]:
    """Converged: the best epoch is not the last, or the validation IoU plateaued (the last quarter
    of the epochs, at least 2, improves the best before it by < 0.5 IoU points)."""
    if 0 < best_epoch < epochs:
        return True, f"best epoch {best_epoch} of {epochs}"
    vals = [r["val_iou"] for r in log if "val_iou" in r]
    k = max(2, len(vals) // 4)
    if len(vals) < k + 2:
        return False, f"best epoch is the last of {epochs}; too few epochs to see a plateau"
    gain = max(vals[-k:]) - max(vals[:-k])
    if gain < 0.005:
        return True, f"plateau: the last {k} epochs gain {100 * gain:.2f} IoU points"
    return False, f"still improving: the last {k} epochs gain {100 * gain:.2f} IoU points"


def collect_seed(sd: Path, conditions: list[str], threads: int, quick: bool) -> tuple[dict, list[dict]]:
    """{(test set, condition): row} and one record per model (timings, convergence, pipeline ratio)."""
    import torch

    rows = {(r["heldout"], r["condition"]): r
            for r in map(json.loads, (sd / "results.jsonl").read_text().splitlines())}
    models, refs = [], {}
    for c in conditions:
        run_dir = sd / "runs" / "_all" / c
        if not (run_dir / "train.json").exists():
            continue
        tj = json.loads((run_dir / "train.json").read_text())
        ck = torch.load(run_dir / "model.pt", map_location="cpu", weights_only=False)
        log = [json.loads(line) for line in (run_dir / "model.log.jsonl").read_text().splitlines()]
        shape = json.dumps([ck["model_args"], ck["data"].get("crop_size") or ck["data"]["input_size"],
                            ck["config"].get("batch_size"),
                            ck["config"].get("optimizer"), ck["config"].get("device"), threads], sort_keys=True)
        # the reference is measured right after the training it belongs to and kept with it, so a
        # resumed benchmark reuses it; one per distinct shape (resize and virtual share the working size)
        cache = run_dir / "reference.json"
        key = hashlib.sha256(((run_dir / "train.json").read_text() + shape).encode()).hexdigest()[:16]
        old = json.loads(cache.read_text()) if cache.exists() else {}
        if old.get("key") == key:
            ref = old["images_per_s"]
        else:
            if shape not in refs:
                refs[shape] = reference_images_per_s(ck, threads, 2.0 if quick else 20.0, 3 if quick else 10)
            ref = refs[shape]
            cache.write_text(json.dumps({"key": key, "images_per_s": ref}) + "\n")
        ok, why = convergence(log, tj["epochs"], tj["best_epoch"])
        models.append({"condition": c, "train_minutes": tj["train_seconds"] / 60, "epochs": tj["epochs"],
                       "best_epoch": tj["best_epoch"], "best_val_iou": tj["best_val_iou"],
                       "train_items": tj["train_items"], "val_items": tj["val_items"],
                       "input_size": tj["input_size"], "crop_size": ck["data"].get("crop_size"),
                       "model_args": ck["model_args"],
                       "batch_size": ck["config"].get("batch_size"), "optimizer": ck["config"].get("optimizer"),
                       "train_images_per_s": tj["train_images_per_s"], "reference_images_per_s": ref,
                       "pipeline_ratio": tj["train_images_per_s"] / ref, "converged": ok,
                       "convergence": why, "val_iou_per_epoch": [r.get("val_iou") for r in log]})
    return rows, models


# -- the camera change alone ---------------------------------------------------------------------
def no_shift_reference(sd: Path, wd: Path, source: dict, conditions: list[str], sets: list[str]) -> dict:
    """{(simulated set, condition): {"iou", "test_items"}}: each trained model's prediction on the
    simulations' SOURCE frames in their own camera (the in-domain test set, e.g. CamVid val),
    carried into the simulated camera by the simulation's exact homography (each frame's
    ``out_H_src`` as the simulation recorded it, :func:`vcprep.simulate.recorded_homographies`;
    P(road) bilinear, like the images) and scored against the simulated labels. Same frames, same
    pixels, no camera change: the score the model would get on that camera if the change cost
    nothing, so (simulated score - this) is the cost of the camera change alone. Checked against
    the files: every source label carried over must equal the simulated label, or the benchmark
    stops. Kept in runs/_all/<condition>/no_shift.json (keyed by the training and the simulations)."""
    from vcprep.build import list_dataset
    from vcprep.imageio import read_image
    from vcprep.labels import decode_label, get_label_format
    from vcprep.simulate import recorded_homographies, simulate_arrays
    from vcprep.store import Store
    from vctrain.crossval import CONDITIONS as MODES
    from vctrain.metrics import RoadMetrics
    from vctrain.predict import Predictor

    sims = [n for n in SIM if n in sets]
    fmt = get_label_format("camvid")
    jobs = {j.id: j for j in list_dataset(source["images"], source["labels"], fmt)}
    Hs, sizes, labels = {}, {}, {}
    for n in sims:
        Hs[n] = recorded_homographies(wd / "sim" / n)
        sizes[n] = tuple(json.loads((wd / "sim" / n / "simulate.json").read_text())["camera"]["image_size"])
        for iid in Hs[n]:  # the exact-geometry check: the recorded H reproduces the simulated label
            raw = read_image(jobs[iid].label, label=True).array
            mine = simulate_arrays(raw, raw, Hs[n][iid], sizes[n])[1]
            sim_file = wd / "sim" / n / "labels" / jobs[iid].label.name
            theirs = read_image(sim_file, label=True).array
            if not np.array_equal(mine, theirs):
                sys.exit(f"{sim_file}: the recorded homography does not reproduce this label; "
                         f"delete {wd / 'sim'} and run again")
            labels[n, iid] = decode_label(theirs, fmt, sim_file)
    out: dict[tuple[str, str], dict] = {}
    key_sims = json.dumps({n: (wd / "sim" / n / "simulate.json").read_text() for n in sims}, sort_keys=True)
    for c in conditions:
        run_dir = sd / "runs" / "_all" / c
        if c in UNTRAINED or not (run_dir / "train.json").exists():
            continue
        key = hashlib.sha256(((run_dir / "train.json").read_text() + key_sims).encode()).hexdigest()[:16]
        cache = run_dir / "no_shift.json"
        old = json.loads(cache.read_text()) if cache.exists() else {}
        if old.get("key") != key:
            store = Store.open(sd / "stores" / source["dataset"] / "test" / MODES[c][0])
            pred = Predictor(run_dir / "model.pt", device="cpu")
            probs = {rec["id"]: pred.store_item(store, rec).astype(np.float32) for rec in store}
            res = {}
            for n in sims:
                m = RoadMetrics()
                for iid, H in Hs[n].items():
                    m.add(simulate_arrays(probs[iid], None, H, sizes[n])[0] >= 0.5, labels[n, iid])
                res[n] = {**m.result(), "test_items": len(Hs[n])}
            old = {"key": key, "results": res}
            cache.write_text(json.dumps(old, indent=1) + "\n")
        for n, r in old["results"].items():
            out[n, c] = r
    return out


def exact_vp_scores(sd: Path, wd: Path, sets: list[str], threads: int) -> dict:
    """{simulated set: {"iou", "test_items"}}: the seed's within model on each simulated camera's
    test frames warped with each frame's EXACT camera pose (the simulation's vps.csv, status
    'given': the source camera's nominal pose through the frame's simulated rotation, what a
    perfect per-frame calibration gives) instead of its estimated road VP, into the same virtual
    camera and scale (stores under ``exact_vp/<set>``). Kept in runs/_all/within/exact_vp.json
    (keyed by the training and the VP files)."""
    from vcprep.build import ItemPose, WarpSettings, list_dataset, warp_dataset
    from vcprep.camera import camera_from_dict, load_camera
    from vcprep.labels import get_label_format
    from vcprep.vanishing_point import vps_for_items
    from vctrain.crossval import evaluate_heldout

    run_dir = sd / "runs" / "_all" / "within"
    sims = [n for n in SIM if n in sets]
    if not sims or not (run_dir / "train.json").exists():
        return {}
    key = hashlib.sha256(((run_dir / "train.json").read_text() + json.dumps(
        {n: (wd / "sim" / n / "vps.csv").read_text() for n in sims}, sort_keys=True)).encode()).hexdigest()[:16]
    cache = run_dir / "exact_vp.json"
    old = json.loads(cache.read_text()) if cache.exists() else {}
    if old.get("key") == key:
        return old["results"]
    study = json.loads((sd / "study.json").read_text())
    virtual, fmt = camera_from_dict(study["virtual"]), get_label_format("camvid")
    res = {}
    for n in sims:
        d = wd / "sim" / n
        jobs = list_dataset(d / "images", d / "labels", fmt)
        cam = load_camera(str(d / "camera.yaml"))
        vps = vps_for_items([j.image for j in jobs], [j.id for j in jobs], cam, str(d / "vps.csv"))
        poses = {j.id: ItemPose((r.vp[0], r.vp[1]), r.status) for j, r in zip(jobs, vps)}
        store = sd / "exact_vp" / n
        warp_dataset(jobs, store, WarpSettings(cam, virtual, study["scale"], fmt, completion="projective", poses=poses,
                                               workers=threads, progress=False))
        res[n] = evaluate_heldout(run_dir / "model.pt", store)
    cache.write_text(json.dumps({"key": key, "results": res}, indent=1) + "\n")
    return res


# -- aggregation ---------------------------------------------------------------------------------
def stats(v: list[float]) -> dict:
    a = np.asarray(v, float)
    return {"mean": float(a.mean()) if len(a) else None, "std": float(a.std(ddof=1)) if len(a) > 1 else 0.0,
            "per_seed": [float(x) for x in a]}


def fmt(s: dict | None, scale: float = 100.0, signed: bool = False) -> str:
    if not s or s["mean"] is None:
        return "-"
    return f"{scale * s['mean']:{'+' if signed else ''}.1f} ± {scale * s['std']:.1f}"


def paired(per_seed: dict[int, dict], sets: list[str], groups: dict[str, list[str]], a: str, b: str) -> dict:
    """Paired differences a - b of road IoU per seed (mean, std, per seed), per test set and group
    (a group's difference per seed is the mean over its members)."""
    seeds = sorted(per_seed)
    diff: dict[str, dict] = {}
    for s in sets:
        diff[s] = stats([per_seed[k][s, a]["iou"] - per_seed[k][s, b]["iou"] for k in seeds
                         if (s, a) in per_seed[k] and (s, b) in per_seed[k]])
    for g, members in groups.items():
        if members:
            diff[g] = stats([float(np.mean([per_seed[k][m, a]["iou"] - per_seed[k][m, b]["iou"] for m in members]))
                             for k in seeds if all((m, c) in per_seed[k] for m in members for c in (a, b))])
    return diff


def aggregate(per_seed: dict[int, dict], sets: list[str], conditions: list[str]) -> dict:
    """Cells (mean, std, per seed) and paired within - resize (and adapt - within) differences, per
    test set and group."""
    seeds = sorted(per_seed)
    others = [s for s in OTHER if s in sets]
    groups = {"other cameras": others, "kitti (real)": [s for s in REAL if s in sets],
              "simulated": [s for s in SIM if s in sets]}
    cells: dict[str, dict[str, dict]] = {}
    for s in sets:
        cells[s] = {c: stats([per_seed[k][s, c]["iou"] for k in seeds if (s, c) in per_seed[k]]) for c in conditions}
    for g, members in groups.items():
        if members:
            cells[g] = {c: stats([float(np.mean([per_seed[k][m, c]["iou"] for m in members])) for k in seeds
                                  if all((m, c) in per_seed[k] for m in members)]) for c in conditions}
    diff = paired(per_seed, sets, groups, "within", "resize") if {"within", "resize"} <= set(conditions) else {}
    adapt = {c: paired(per_seed, sets, groups, c, "within") for c in ADAPTED if {c, "within"} <= set(conditions)}
    vp = paired(per_seed, sets, groups, "within", "between") if {"within", "between"} <= set(conditions) else {}
    return {"cells": cells, "within_minus_resize": diff, "adapt_minus_within": adapt, "within_minus_between": vp,
            "groups": groups}


def shift_costs(per_seed: dict[int, dict], no_shift: dict[int, dict], sets: list[str], conditions: list[str]) -> dict:
    """The camera change alone, per simulated set and condition (mean, std, per seed): ``reference``
    (:func:`no_shift_reference`: the same pixels seen by the model in the source camera), ``cost``
    = score on the simulated camera - reference (and per group), and ``zero_cost``: within -
    resize if the within model lost nothing to the camera change (within's reference - resize's
    score; what these test sets allow at this network quality), per simulated set, over the
    simulated sets, and over the other cameras with the real ones (no reference) as measured."""
    seeds = [k for k in sorted(per_seed) if no_shift.get(k)]
    sims = [n for n in SIM if n in sets]
    trained = [c for c in conditions if c not in UNTRAINED]
    ref: dict[str, dict] = {n: {} for n in sims}
    cost: dict[str, dict] = {n: {} for n in sims}
    for n in sims:
        for c in trained:
            ks = [k for k in seeds if (n, c) in no_shift[k] and (n, c) in per_seed[k]]
            if ks:
                ref[n][c] = stats([no_shift[k][n, c]["iou"] for k in ks])
                cost[n][c] = stats([per_seed[k][n, c]["iou"] - no_shift[k][n, c]["iou"] for k in ks])
    if sims:
        cost["simulated"] = {c: stats([float(np.mean([per_seed[k][n, c]["iou"] - no_shift[k][n, c]["iou"]
                                                       for n in sims])) for k in seeds])
                             for c in trained if all(c in cost[n] for n in sims)}
    zero: dict[str, dict] = {}
    if {"within", "resize"} <= set(trained) and sims and all("within" in ref[n] for n in sims):
        def gap(k: int, n: str) -> float:
            if n in sims:
                return no_shift[k][n, "within"]["iou"] - per_seed[k][n, "resize"]["iou"]
            return per_seed[k][n, "within"]["iou"] - per_seed[k][n, "resize"]["iou"]

        for n in sims:
            zero[n] = stats([gap(k, n) for k in seeds])
        zero["simulated"] = stats([float(np.mean([gap(k, n) for n in sims])) for k in seeds])
        others = [n for n in OTHER if n in sets]
        if all((n, c) in per_seed[k] for k in seeds for n in others for c in ("within", "resize")):
            zero["other cameras"] = stats([float(np.mean([gap(k, n) for n in others])) for k in seeds])
    return {"reference": ref, "cost": cost, "zero_cost": zero, "seeds": seeds}


def vp_costs(per_seed: dict[int, dict], exact: dict[int, dict]) -> dict:
    """Per simulated set (and their mean): within with each frame's exact pose (``exact``, mean,
    std, per seed) and ``cost`` = within with estimated road VPs - that."""
    seeds = [k for k in sorted(exact) if exact[k]]
    sims = [n for n in SIM if all(n in exact[k] and (n, "within") in per_seed[k] for k in seeds)] if seeds else []
    out = {n: {"exact": stats([exact[k][n]["iou"] for k in seeds]),
               "cost": stats([per_seed[k][n, "within"]["iou"] - exact[k][n]["iou"] for k in seeds])} for n in sims}
    if sims:
        out["simulated"] = {"exact": stats([float(np.mean([exact[k][n]["iou"] for n in sims])) for k in seeds]),
                            "cost": stats([float(np.mean([per_seed[k][n, "within"]["iou"] - exact[k][n]["iou"]
                                                          for n in sims])) for k in seeds])}
    return out


def shift_table(shift: dict, conditions: list[str]) -> list[str]:
    """Markdown lines: the camera change alone (empty without simulated sets)."""
    sims = [n for n in shift["reference"] if shift["reference"][n]]
    if not sims:
        return []
    trained = [c for c in conditions if c not in UNTRAINED and all(c in shift["reference"][n] for n in sims)]
    lines = ["The camera change alone: each model's prediction on the simulations' source frames in their own "
             "camera, carried into the simulated camera by the exact simulation homography and scored there "
             "(same frames, same pixels, no camera change), and the cost of the change = the score on the "
             "camera − that (road IoU points, mean ± std over seeds):", "",
             "| simulated set | " + " | ".join(f"{c}: no change | {c}: cost" for c in trained) + " |",
             "|---|" + "---|---|" * len(trained)]
    for n in sims + (["simulated"] if "simulated" in shift["cost"] else []):
        row = [n if n in sims else "**simulated** (mean)"]
        for c in trained:
            row += [fmt(shift["reference"][n].get(c)) if n in sims else "",
                    fmt(shift["cost"][n].get(c), signed=True)]
        lines.append("| " + " | ".join(row) + " |")
    b = shift["zero_cost"]
    if b:
        parts = [f"{n} {fmt(b[n], signed=True)}" for n in sims if n in b]
        lines += ["", "within − resize if the within model lost nothing to the camera change (within's no-change "
                  "score − resize's score; what these test sets allow at this network quality): " + ", ".join(parts)
                  + (f"; simulated mean **{fmt(b['simulated'], signed=True)}**" if "simulated" in b else "")
                  + (f"; other cameras (KITTI as measured) **{fmt(b['other cameras'], signed=True)}**"
                     if "other cameras" in b else "") + "."]
    v = shift.get("exact_vp") or {}
    if v:
        lines += ["", "within with each frame's EXACT camera pose (the simulation's, as a perfect per-frame "
                  "calibration gives) instead of its estimated road VP (same model, same virtual camera): " + ", ".join(f"{n} {fmt(v[n]['exact'])} (estimated − exact: {fmt(v[n]['cost'], signed=True)})"
                                                  for n in v) + "."]
    return lines + [""]


def table(agg: dict, sets: list[str], conditions: list[str], items: dict[str, int]) -> str:
    diff, adapt = bool(agg["within_minus_resize"]), list(agg["adapt_minus_within"])
    header = (["test set", "frames"] + conditions + (["within − resize"] if diff else [])
              + [f"{c} − within" for c in adapt])
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for s in sets + [g for g in agg["groups"] if agg["groups"][g]]:
        row = [s if s in sets else f"**{s}** (mean)", str(items.get(s, "")) if s in sets else ""]
        row += [fmt(agg["cells"][s][c]) for c in conditions]
        if diff:
            row.append(fmt(agg["within_minus_resize"].get(s), signed=True))
        for c in adapt:
            row.append(fmt(agg["adapt_minus_within"][c].get(s), signed=True))
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines) + "\n"


def targets(agg: dict, models: list[dict], conditions: list[str]) -> dict:
    cells, diff = agg["cells"], agg["within_minus_resize"]
    in_dom = {f"{s} {c}": cells[s][c]["mean"] for s in IN_DOMAIN if s in cells for c in conditions
              if c not in UNTRAINED and cells[s][c]["mean"] is not None}
    cross = diff.get("other cameras", {}).get("mean")
    ratios = [m["pipeline_ratio"] for m in models]
    return {
        "in_domain_iou_ge_0.85": {"pass": bool(in_dom) and min(in_dom.values()) >= 0.85, "values": in_dom},
        "cross_camera_within_minus_resize_ge_10_points": {"pass": cross is not None and cross >= 0.10,
                                                          "value": cross},
        "converged": {"pass": bool(models) and all(m["converged"] for m in models),
                      "models": f"{sum(m['converged'] for m in models)}/{len(models)}"},
        "pipeline_ratio_ge_0.9": {"pass": bool(ratios) and min(ratios) >= 0.9,
                                  "min": min(ratios) if ratios else None,
                                  "median": float(np.median(ratios)) if ratios else None},
    }


def _crop_share(text: str) -> float | list[float]:
    """--crop: one share of each side ('0.67') or shares of width and height ('0.4444x1'), parsed
    as ``vctrain fit --crop`` parses them (shares only: every condition has its own working size)."""
    from vcprep.errors import InputError
    from vctrain.cli import _parse_crop

    try:
        crop = _parse_crop(text)
    except InputError as e:
        raise argparse.ArgumentTypeError(e.problem) from None
    if not all(isinstance(v, float) and 0 < v <= 1 for v in ([crop] if isinstance(crop, float) else crop)):
        raise argparse.ArgumentTypeError(f"'{text}': give a share in (0, 1] or two as WxH")
    return crop if isinstance(crop, float) else list(crop)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default=None, help="comma-separated training seeds (default 0,1,2; --quick: 0)")
    ap.add_argument("--epochs", type=int, default=None, help="training epochs (default: vctrain fit's recipe)")
    from vctrain.crossval import CONDITIONS as AVAILABLE

    ap.add_argument("--conditions", default=",".join(CONDITIONS),
                    help=f"comma-separated, from {','.join(AVAILABLE)} (default: {','.join(CONDITIONS)})")
    ap.add_argument("--store-width", type=int, default=None, help="working width (default: crossval's)")
    ap.add_argument("--store-pixels", type=int, default=172800,
                    help="working pixel count of every model's whole image (default 172800: 480x360 for resize; "
                         "with --crop 2/3 the training windows hold 76800 = 320x240)")
    ap.add_argument("--crop", type=_crop_share, default=[4 / 9, 1.0],
                    help="train every model on random windows of this share of each side of its working image, "
                         "or of its width and height ('0.4444x1': full-height windows) (vctrain fit --crop; "
                         "default 4/9x1: full-height windows of 4/9 the width; 1: whole images)")
    ap.add_argument("--dev", action="store_true",
                    help=f"development split for choosing settings: train on sequence {DEV_TRAIN} of CamVid train, "
                         f"score on {DEV_TEST} and its simulated cameras (no test frame; results in WORKDIR/results)")
    ap.add_argument("--above", type=float, default=8.0,
                    help="crop the designed virtual camera to this many degrees above the horizon (default 8; "
                         "-1: the paper's uncropped rectangle)")
    ap.add_argument("--device", default=None, help="training device (default: vctrain fit's, auto)")
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1, help="threads (default: all cores)")
    ap.add_argument("--workdir", type=Path, default=None,
                    help="default benchmarks/out/real_cameras (--quick: benchmarks/out/real_cameras_quick)")
    ap.add_argument("--results", type=Path, default=None, help="default benchmarks/results (--quick: WORKDIR/results)")
    ap.add_argument("--quick", action="store_true", help="smoke run: a few frames, 1 seed, 1 epoch of 2 steps")
    args = ap.parse_args()
    if not DATA.is_dir():
        sys.exit(f"{DATA} not found: this benchmark needs the CamVid train/val folders of ../shared/data")
    import torch

    T = args.threads
    torch.set_num_threads(T)
    cv2.setNumThreads(T)
    seeds = [int(s) for s in (args.seeds or ("0" if args.quick else "0,1,2")).split(",") if s.strip()]
    conditions = [c for c in args.conditions.split(",") if c]
    if not conditions or any(c not in AVAILABLE for c in conditions):
        sys.exit(f"--conditions: choose from {', '.join(AVAILABLE)}")
    wd = (args.workdir or ROOT / "benchmarks" / "out" / ("real_cameras_quick" if args.quick else
                                                         "real_cameras_dev" if args.dev else "real_cameras"))
    wd = wd.resolve()
    res = (args.results or (wd / "results" if args.quick or args.dev else ROOT / "benchmarks" / "results")).resolve()
    wd.mkdir(parents=True, exist_ok=True)
    res.mkdir(parents=True, exist_ok=True)
    print(f"threads: {T} (torch.set_num_threads, cv2.setNumThreads; OMP_NUM_THREADS={T} for training; "
          f"--jobs {T} store builds); seeds {seeds}; workdir {wd}", file=sys.stderr, flush=True)
    for name in unused_data():
        print(f"note: ../shared/data/{name} is not used (no reader for it in this benchmark)", file=sys.stderr)
    import yaml

    t0 = time.perf_counter()
    study, sets, source = make_study(wd, args, conditions)
    (wd / "study.yaml").write_text(yaml.safe_dump(study, sort_keys=False))
    env = {"OMP_NUM_THREADS": str(T), "MKL_NUM_THREADS": str(T)}
    per_seed, models, no_shift, exact = {}, [], {}, {}
    for k in seeds:
        sd = wd / f"seed{k}"
        print(f"seed {k}: vctrain crossval -> {sd}", file=sys.stderr, flush=True)
        cmd = [BIN / "vctrain", "crossval", wd / "study.yaml", "--out", sd, "--seed", k, "--json", "--jobs", T]
        if args.epochs:
            cmd += ["--epochs", args.epochs]
        run(*cmd, stream=True, env=env)
        rows, ms = collect_seed(sd, conditions, T, args.quick)  # the reference right after this seed's training
        per_seed[k] = rows
        models += [{"seed": k, **m} for m in ms]
        no_shift[k] = no_shift_reference(sd, wd, source, conditions, sets)
        exact[k] = exact_vp_scores(sd, wd, sets, T) if "within" in conditions else {}
    total = time.perf_counter() - t0
    shift = shift_costs(per_seed, no_shift, sets, conditions)
    shift["exact_vp"] = vp_costs(per_seed, exact)

    agg = aggregate(per_seed, sets, conditions)
    items = {s: per_seed[seeds[0]][s, conditions[0]]["test_items"] for s in sets if (s, conditions[0]) in per_seed[seeds[0]]}
    tg = targets(agg, models, conditions)
    diff, cells = agg["within_minus_resize"], agg["cells"]

    def mean_of(d: dict | None) -> float | None:
        return None if not d or d.get("mean") is None else round(d["mean"], 4)

    minutes = float(np.mean([m["train_minutes"] for m in models])) if models else None
    headline = {
        "within_minus_resize": mean_of(diff.get("other cameras")),
        "in_domain_within": mean_of(cells.get("camvid-val", {}).get("within")),
        "in_domain_resize": mean_of(cells.get("camvid-val", {}).get("resize")),
        "minutes_per_model": None if minutes is None else round(minutes, 2),
        "within_minus_resize_std": round(diff["other cameras"]["std"], 4) if "other cameras" in diff else None,
        "kitti_within_minus_resize": mean_of(diff.get("kitti (real)")),
        "simulated_within_minus_resize": mean_of(diff.get("simulated")),
        "unseen_sequence_within": mean_of(cells.get(f"camvid-{UNSEEN}", {}).get("within")),
        "unseen_sequence_resize": mean_of(cells.get(f"camvid-{UNSEEN}", {}).get("resize")),
        "pipeline_ratio_min": None if tg["pipeline_ratio_ge_0.9"]["min"] is None
        else round(tg["pipeline_ratio_ge_0.9"]["min"], 3),
        "converged": tg["converged"]["models"], "seeds": len(seeds), "quick": args.quick,
    }
    for c, d in agg["adapt_minus_within"].items():
        headline[f"{c.replace('-', '_')}_minus_within"] = mean_of(d.get("other cameras"))
    for c, d in shift["cost"].get("simulated", {}).items():
        headline[f"simulated_shift_cost_{c}"] = mean_of(d)
    if "simulated" in shift["exact_vp"]:
        headline["simulated_estimated_minus_exact_pose_within"] = mean_of(shift["exact_vp"]["simulated"]["cost"])
    for g in ("simulated", "other cameras"):
        if g in shift["zero_cost"]:
            headline[f"{'simulated_' if g == 'simulated' else ''}within_minus_resize_zero_cost"] = mean_of(shift["zero_cost"][g])
    study_json = json.loads((wd / f"seed{seeds[0]}" / "study.json").read_text())
    virt, m0 = study_json["virtual"], (models[0] if models else {})
    md = ["# Real new cameras: train on CamVid, test on other cameras (benchmarks/real_cameras.py)", "",
          f"Road IoU (%) on each test set in its own camera, mean ± std over {len(seeds)} seeds {seeds}"
          + (" (QUICK SMOKE RUN: numbers mean nothing)" if args.quick else "") + ".", "",
          table(agg, sets, conditions, items),
          *shift_table(shift, conditions),
          "Targets (reported, not asserted):", ""]
    md += [f"- {name}: {'PASS' if t['pass'] else 'FAIL'} "
           f"({json.dumps({k: v for k, v in t.items() if k != 'pass'}, default=str)})" for name, t in tg.items()]
    md += ["", "Setup:", "",
           f"- Training: CamVid train minus sequence {UNSEEN} ({m0.get('train_items')} + {m0.get('val_items')} "
           f"validation frames), vctrain fit defaults{'' if not args.epochs else f', {args.epochs} epochs'}: "
           f"{(m0.get('model_args') or {}).get('arch')}, {m0.get('optimizer')}, batch {m0.get('batch_size')}, "
           f"{m0.get('epochs')} epochs, working size {m0.get('input_size')} (training windows "
           f"{m0.get('crop_size') or m0.get('input_size')}); "
           f"{minutes if minutes is None else round(minutes, 1)} min per model; device "
           f"{study_json['train'].get('device')}; {platform.processor() or platform.machine()}, {T} threads.",
           f"- Virtual camera (designed from every camera of the study, pan ±10°, tilt ±5°): "
           f"{virt['image_size'][0]}x{virt['image_size'][1]}, f {virt['fx']:.1f}, height {virt['height']:.2f} m, "
           f"store scale {study_json['scale']:.4f}.",
           f"- In-domain: camvid-val = CamVid val; camvid-{UNSEEN} = the unseen sequence (never trained on); "
           f"camvid-{UNSEEN}-ego = the same frames and labels, the camera with ego_rows: {EGO_ROWS} (the rig's "
           "bonnet, read as an exact bottom crop and predicted not road; not in the target).",
           "- Real other camera: kitti = KITTI road frames, every frame with its own calibration (calib/: exact "
           "pose, nothing estimated); kitti-vp = the same frames with one camera (the first frame's file) and "
           "estimated road VPs (not in the headline).",
           *[f"- Simulated from CamVid val: {n} = {DESCRIPTION[n]}." for n in SIM if n in sets],
           f"- Headline within − resize: mean over the other cameras ({', '.join(agg['groups']['other cameras'])}) "
           "per seed, then mean ± std over seeds.",
           f"- Wall time: {total / 60:.1f} min in this invocation (finished runs are resumed, not redone).", ""]
    md += ["Models:", "", "| seed | condition | minutes | best epoch | converged | train img/s | reference img/s | ratio |",
           "|---|---|---|---|---|---|---|---|"]
    md += [f"| {m['seed']} | {m['condition']} | {m['train_minutes']:.1f} | {m['best_epoch']}/{m['epochs']} | "
           f"{m['convergence']} | {m['train_images_per_s']:.1f} | {m['reference_images_per_s']:.1f} | "
           f"{m['pipeline_ratio']:.2f} |" for m in models]
    (res / "real_cameras.md").write_text("\n".join(md) + "\n")
    groups = sets + [g for g in ("other cameras",) if g in cells]
    cell = {(g, c): cells[g][c]["mean"] for g in groups for c in conditions if cells[g][c]["mean"] is not None}
    spread = {(g, c): cells[g][c]["std"] for g in groups for c in conditions if cells[g][c]["mean"] is not None}
    cv2.imwrite(str(res / "real_cameras.png"),
                bar_plot(cell, groups, conditions, f"road IoU (%) per test set, trained on CamVid (mean +/- std over "
                                                  f"{len(seeds)} seeds)", spread))
    (res / "real_cameras.json").write_text(json.dumps(
        {"headline": headline, "cells": cells, "within_minus_resize": diff,
         "adapt_minus_within": agg["adapt_minus_within"], "within_minus_between": agg["within_minus_between"],
         "groups": agg["groups"], "no_shift": shift,
         "test_frames": items, "targets": tg, "models": models, "seeds": seeds, "conditions": conditions,
         "threads": T, "study": study, "virtual": virt, "scale": study_json["scale"],
         "train_settings": study_json["train"], "wall_minutes": total / 60}, indent=1, default=str) + "\n")
    print(table(agg, sets, conditions, items), file=sys.stderr)
    print(json.dumps(headline))


if __name__ == "__main__":
    main()
