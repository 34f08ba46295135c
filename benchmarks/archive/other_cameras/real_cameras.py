"""Will a CamVid-trained model work on a new camera? Real and exactly simulated other cameras (issue 14).

    .venv/bin/python benchmarks/archive/other_cameras/real_cameras.py [--seeds 0,1,2] [--epochs N] [--conditions resize,between,within]
                                                              [--workdir benchmarks/out/real_cameras] [--threads 2] [--quick]

One ``vctrain crossval`` study, run once per seed (``--seed k``) into WORKDIR/seed<k>/; every run
resumes (crossval skips finished runs), so an interrupted benchmark continues where it stopped.
This script sets the study up, runs it and reports; the measuring code (statistics over seeds, the
reference training step, the camera change alone, tables and plot) is in the ``measure`` package.

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
  ``vcprep simulate`` exactly as benchmarks/archive/other_cameras/cross_camera.py makes them (measure.data).

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

The camera change alone (simulated cameras, :func:`measure.camera_change.no_shift_reference`): every trained model's
prediction on the simulations' source frames (CamVid val; ``--dev``: 0006R0) in their own camera,
carried into each simulated camera by the simulation's exact homography and scored against the
simulated labels: the same frames and pixels with no camera change. The score on the simulated
camera minus this is the cost of the camera change alone, per condition; within's no-change score
minus resize's score is within - resize if the virtual camera removed the whole camera shift
(``zero_cost``; over the other cameras with KITTI as measured): what these test sets allow at this
network quality. The recorded homography must carry every source label onto its simulated label
exactly (checked).
Estimated VPs vs the exact pose (:func:`measure.camera_change.exact_vp_scores`): the within model on the simulated
cameras' frames warped with each frame's exact camera pose (the simulation's vps.csv: the source
camera's nominal pose carried through that frame's simulated rotation, i.e. what a perfect
per-frame calibration gives) instead of its estimated road VP.

Threads: ``--threads T`` (default: all cores) = ``torch.set_num_threads(T)`` and ``cv2.setNumThreads(T)``
here, ``OMP_NUM_THREADS=T`` for the training processes, ``--jobs T`` store builders.
Runtime: seeds x conditions models (9 by default) x minutes_per_model, plus store building and
testing (a few minutes). ``--quick``: a smoke run (a few frames, 1 seed, 1 epoch of 2 steps,
results in WORKDIR/results, not benchmarks/other_cameras/results).

Outputs in benchmarks/other_cameras/results/: ``real_cameras.md`` (the table), ``real_cameras.png`` (bars with
+/- std), ``real_cameras.json`` (headline, every cell per seed, targets, models, settings). The last
stdout line is one JSON object with ``within_minus_resize``, ``in_domain_within``,
``in_domain_resize`` and ``minutes_per_model`` (and a few more figures: ``simulated_shift_cost_<condition>``,
``within_minus_resize_zero_cost``, ``simulated_within_minus_resize_zero_cost``,
``simulated_estimated_minus_exact_pose_within``).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.camera_change import exact_vp_scores, no_shift_reference, shift_costs, vp_costs
from benchmarks.measure.data import (BIN, DATA, DESCRIPTION, KITTI, ROOT, SHARED_DATA, SIM, ego_camera, kitti_datasets, link_files,
                          native_camera, run, simulate)
from benchmarks.measure.report import results_dir
from benchmarks.measure.models import collect_seed
from benchmarks.measure.stats import UNTRAINED, aggregate
from benchmarks.measure.tables import bar_plot, seed_table, shift_table
from vctrain.study import CONDITIONS as AVAILABLE

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
OTHER = REAL + SIM                        # the other-camera test sets of the headline
CONDITIONS = ["resize", "between", "within"]     # the default; --conditions may add within-gt, zero, prior,
                                                 # adapt, adapt-fuse
QUICK_TRAIN = {"epochs": 1, "max_steps": 2}


# -- the study -----------------------------------------------------------------------------------
def camvid_folders(wd: Path, quick: bool) -> dict[str, Path]:
    """CamVid's train/val image and label folders (quick: a few frames of each sequence, linked)."""
    full = {k: DATA / k for k in ("train", "trainannot", "val", "valannot")}
    if not quick:
        return full
    train = sorted(p.name for p in full["train"].glob("*.png"))
    pick = [n for seq in ("0016E5", "0006R0") for n in [m for m in train if m.startswith(seq)][:3]]
    pick += [n for n in train if n.startswith(UNSEEN)][:2]
    val = sorted(p.name for p in full["val"].glob("*.png"))[:3]
    return {"train": link_files(pick, full["train"], wd / "src" / "train"),
            "trainannot": link_files(pick, full["trainannot"], wd / "src" / "trainannot"),
            "val": link_files(val, full["val"], wd / "src" / "val"),
            "valannot": link_files(val, full["valannot"], wd / "src" / "valannot")}


def dev_datasets(wd: Path, f: dict[str, Path], cam: Path, camvid) -> tuple[list[dict], dict]:
    """--dev: a split for choosing settings without any test frame. Train on CamVid train's
    sequence DEV_TRAIN alone; score on its sequence DEV_TEST (never trained on here) and on
    DEV_TEST through the same simulated cameras (named like the benchmark's, so they form the
    'other cameras' group). KITTI joins the study only so the virtual camera is designed exactly
    as in the benchmark; its rows are dropped from the dev report."""
    names = sorted(p.name for p in f["train"].glob(f"{DEV_TEST}_*.png"))
    images = link_files(names, f["train"], wd / "src" / "dev" / "images")
    labels = link_files(names, f["trainannot"], wd / "src" / "dev" / "labels")
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


# -- results -------------------------------------------------------------------------------------
def report_groups(sets: list[str]) -> dict[str, list[str]]:
    """The groups of test sets reported as means: the other cameras (the headline), KITTI, the
    simulated cameras (each: those of ``sets``)."""
    return {"other cameras": [s for s in OTHER if s in sets], "kitti (real)": [s for s in REAL if s in sets],
            "simulated": [s for s in SIM if s in sets]}


def targets(agg: dict, models: list[dict], conditions: list[str]) -> dict:
    """The benchmark's targets (module docstring), each with ``pass`` and the values it was judged on."""
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


def parse_args() -> argparse.Namespace:
    """The options."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default=None, help="comma-separated training seeds (default 0,1,2; --quick: 0)")
    ap.add_argument("--epochs", type=int, default=None, help="training epochs (default: vctrain fit's recipe)")
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
    ap.add_argument("--results", type=Path, default=None, help="default benchmarks/other_cameras/results (--quick: WORKDIR/results)")
    ap.add_argument("--quick", action="store_true", help="smoke run: a few frames, 1 seed, 1 epoch of 2 steps")
    args = ap.parse_args()
    return args


def run_seeds(wd: Path, args: argparse.Namespace, conditions: list[str], seeds: list[int], sets: list[str],
              source: dict) -> tuple[dict, list, dict, dict]:
    """The study once per seed (resumed where it stopped), and each seed's rows, models, scores without
    the camera change and with exact poses."""
    T = args.threads
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
    return per_seed, models, no_shift, exact


def mean_of(d: dict | None) -> float | None:
    """A statistic's mean to 4 places (None without one)."""
    return None if not d or d.get("mean") is None else round(d["mean"], 4)


def headline(agg: dict, shift: dict, models: list, tg: dict, seeds: list[int], quick: bool) -> dict:
    """The figures the results page and the README show."""
    diff, cells = agg["within_minus_resize"], agg["cells"]
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
        "converged": tg["converged"]["models"], "seeds": len(seeds), "quick": quick,
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
    return headline


def report_md(agg: dict, shift: dict, models: list, tg: dict, seeds: list[int], sets: list[str], items: dict,
              conditions: list[str], study_json: dict, args: argparse.Namespace, total: float) -> list[str]:
    """The markdown report: the table, the camera change alone, the targets, the setup and the models."""
    T = args.threads
    minutes = float(np.mean([m["train_minutes"] for m in models])) if models else None
    virt, m0 = study_json["virtual"], (models[0] if models else {})
    md = ["# Real new cameras: train on CamVid, test on other cameras (benchmarks/archive/other_cameras/real_cameras.py)", "",
          f"Road IoU (%) on each test set in its own camera, mean ± std over {len(seeds)} seeds {seeds}"
          + (" (QUICK SMOKE RUN: numbers mean nothing)" if args.quick else "") + ".", "",
          seed_table(agg, sets, conditions, items),
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
    return md


def main() -> None:
    args = parse_args()
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
    res = (args.results or (wd / "results" if args.quick or args.dev else results_dir(__file__))).resolve()
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
    per_seed, models, no_shift, exact = run_seeds(wd, args, conditions, seeds, sets, source)
    total = time.perf_counter() - t0
    groups = report_groups(sets)
    shift = shift_costs(per_seed, no_shift, sets, conditions, groups["other cameras"])
    shift["exact_vp"] = vp_costs(per_seed, exact)

    agg = aggregate(per_seed, sets, conditions, groups)
    items = {s: per_seed[seeds[0]][s, conditions[0]]["test_items"] for s in sets if (s, conditions[0]) in per_seed[seeds[0]]}
    tg = targets(agg, models, conditions)
    diff, cells = agg["within_minus_resize"], agg["cells"]
    head = headline(agg, shift, models, tg, seeds, args.quick)
    study_json = json.loads((wd / f"seed{seeds[0]}" / "study.json").read_text())
    md = report_md(agg, shift, models, tg, seeds, sets, items, conditions, study_json, args, total)
    (res / "real_cameras.md").write_text("\n".join(md) + "\n")
    groups = sets + [g for g in ("other cameras",) if g in cells]
    cell = {(g, c): cells[g][c]["mean"] for g in groups for c in conditions if cells[g][c]["mean"] is not None}
    spread = {(g, c): cells[g][c]["std"] for g in groups for c in conditions if cells[g][c]["mean"] is not None}
    cv2.imwrite(str(res / "real_cameras.png"),
                bar_plot(cell, groups, conditions, f"road IoU (%) per test set, trained on CamVid (mean +/- std over "
                                                  f"{len(seeds)} seeds)", spread))
    (res / "real_cameras.json").write_text(json.dumps(
        {"headline": head, "cells": cells, "within_minus_resize": diff,
         "adapt_minus_within": agg["adapt_minus_within"], "within_minus_between": agg["within_minus_between"],
         "groups": agg["groups"], "no_shift": shift,
         "test_frames": items, "targets": tg, "models": models, "seeds": seeds, "conditions": conditions,
         "threads": T, "study": study, "virtual": study_json["virtual"], "scale": study_json["scale"],
         "train_settings": study_json["train"], "wall_minutes": total / 60}, indent=1, default=str) + "\n")
    print(seed_table(agg, sets, conditions, items), file=sys.stderr)
    print(json.dumps(head))


if __name__ == "__main__":
    main()
