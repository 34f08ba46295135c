"""Shared measuring code of the benchmarks: every ``benchmarks/*.py`` script imports what it needs
from here and keeps only its own run (arguments, the run, printing and writing its results).

* **data and tools**: the shared data folders (``SHARED_DATA``: CamVid as ``DATA``, ``KITTI``) and
  :func:`run` (a tool as a subprocess);
* **cameras made EXACTLY from real CamVid frames** with ``vcprep simulate`` (crop/scale = a new K;
  rotation about the optical centre = the homography K' R K^-1, exact for any scene; only fully
  covered output pixels are kept): :data:`SIMULATED`, :func:`native_camera`, :func:`ego_camera`,
  :func:`simulate`; and study datasets (:func:`link_files`, :func:`kitti_datasets`);
* **statistics over seeds** (:func:`seed_stats`, :func:`paired`, :func:`aggregate`) and the
  markdown tables and bar plot of them (:func:`format_stat`, :func:`seed_table`,
  :func:`shift_table`, :func:`bar_plot`: OpenCV, no matplotlib);
* **the models of a study**: training images/s against a pure training step of the same shape
  (:func:`reference_images_per_s`), :func:`convergence`, :func:`collect_seed`;
* **the camera change alone** (simulated cameras): :func:`no_shift_reference`,
  :func:`exact_vp_scores`, :func:`shift_costs`, :func:`vp_costs`;
* **road vanishing points**: the plain LSD + RANSAC baseline (:func:`baseline_vp`), the reference
  VP from a road label (:func:`reference_vp`, rule in benchmarks/vp.py), the VP sets, their errors
  in % of the width (:func:`evaluate_vps`) and the paired scene-block bootstrap
  (:func:`scene_bootstrap`).
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import re
import shutil
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
BIN = Path(sys.executable).parent                   # the tools (vcprep, vctrain) beside this Python
SHARED_DATA = ROOT.parent / "shared" / "data"
DATA = SHARED_DATA / "camvid"                       # CamVid, SegNet release (480x360)
KITTI = SHARED_DATA / "kitti_road" / "training"     # KITTI road: image_2, gt_image_2, calib
CS_FORMAT = "values:road=1;ignore=255;max=255"  # ../shared/data/cityscapes_pix2pix (its README)
LUMS_FORMAT = "values:road=2;max=4"              # ../shared/data/lums_road (its README)
sys.path.insert(0, str(ROOT))                       # this repository's vcprep and vctrain

from vcprep.homography import vp_from_pose  # noqa: E402
from vcprep.synthetic import RoadScene, render_road  # noqa: E402
from vcprep.vanishing_point import (VPConfig, apply_reliability, estimate_vp, prior_window,  # noqa: E402
                                    score_vps, sequence_key, to_gray)

__all__ = ["ROOT", "BIN", "SHARED_DATA", "DATA", "KITTI", "SIMULATED", "DESCRIPTION", "SIM", "UNTRAINED", "ADAPTED",
           "TAIL_PCT", "run", "native_camera", "ego_camera", "simulate", "link_files", "kitti_datasets", "seed_stats",
           "format_stat", "paired", "aggregate", "shift_table", "seed_table", "bar_plot", "reference_images_per_s",
           "convergence", "collect_seed", "no_shift_reference", "exact_vp_scores", "shift_costs", "vp_costs",
           "baseline_vp", "reference_vp", "kitti_reference_vp", "reference_from_masks", "synthetic_vp_set",
           "camvid_vp_set", "simulated_vp_sets", "kitti_vp_set", "vp_errors", "error_summary", "scenes",
           "scene_bootstrap", "evaluate_vps", "fallback_loo", "camera_consistency"]

# simulated camera -> `vcprep simulate` arguments, applied to CamVid frames through the native camera
SIMULATED: dict[str, list[str]] = {
    "tele": ["--size", "320x240", "--hfov", "35", "--tilt", "3"],
    "band": ["--size", "480x146"],
    "dashcam": ["--size", "400x225", "--hfov", "40", "--pan-jitter", "8", "--tilt-jitter", "4", "--seed", "1"],
}
DESCRIPTION = {
    "native": "CamVid as released (480x360, the camvid preset at 1/2: 58 deg HFOV)",
    "tele": "telephoto crop, 35 deg HFOV, tilted down 3 deg, 320x240",
    "band": "wide short band with KITTI's aspect ratio, 480x146, widest covered FOV",
    "dashcam": "re-mounted 16:9 dashcam, 400x225, 40 deg HFOV, per-image pan +/-8, tilt +/-4 deg",
}
SIM = list(SIMULATED)
# crossval conditions without a model of their own (no convergence, no in-domain target, no no-change reference)
UNTRAINED = ("prior", "adapt", "adapt-fuse")
ADAPTED = ("adapt", "adapt-fuse")  # reported as paired differences to within
STATIC = np.array([0, 1, 4, 5, 7])  # CamVid classes whose border with road is a real road edge (reference VP)
TAIL_PCT = 1.0  # the tail: errors above this (% width), split into search misses and lines-elsewhere
SCENE_GAP = 30  # frames of one sequence at most this many frame numbers apart are one scene (1 s at 30 fps)


# -- data and tools ----------------------------------------------------------------------------

def run(*args, stream: bool = False, env: dict[str, str] | None = None) -> str:
    """Run a command; its stdout, or exit with its stderr tail on failure (stream: stderr passes through)."""
    proc = subprocess.run([str(a) for a in args], stdout=subprocess.PIPE, stderr=None if stream else subprocess.PIPE,
                          text=True, env=None if env is None else {**os.environ, **env})
    if proc.returncode != 0:
        sys.exit(f"failed: {' '.join(map(str, args))}\n{(proc.stderr or '')[-3000:]}")
    return proc.stdout


# -- cameras and study datasets ----------------------------------------------------------------

def native_camera(wd: Path) -> Path:
    """wd/native.yaml: the camvid preset at the 480x360 size of the SegNet release."""
    from vcprep.camera import PRESETS, camera_to_yaml

    path = wd / "native.yaml"
    path.write_text(camera_to_yaml(PRESETS["camvid"].for_image_size((480, 360))))
    return path


def ego_camera(wd: Path, rows: int) -> Path:
    """wd/native-ego.yaml: the native camera with its bottom ``rows`` rows marked as the rig's own
    vehicle (``ego_rows``: every tool reads the frames as their exact bottom crop)."""
    from vcprep.camera import PRESETS, camera_to_yaml

    path = wd / "native-ego.yaml"
    path.write_text(camera_to_yaml(replace(PRESETS["camvid"].for_image_size((480, 360)), ego_rows=rows)))
    return path


def simulate(camera: Path, images: Path, labels: Path, dst: Path, name: str) -> dict[str, str]:
    """CamVid frames (``images``, ``labels``) through the simulated camera ``name``: a study split
    ({images, labels, vps}) under ``dst``; the camera file is ``dst/camera.yaml``."""
    run(BIN / "vcprep", "simulate", "--camera", camera, "--images", images, "--labels", labels, "--label-format",
        "camvid", "--out", dst, "--name", name, "--quiet", *SIMULATED[name])
    return {"images": str(dst / "images"), "labels": str(dst / "labels"), "vps": str(dst / "vps.csv")}


def link_files(names: list[str], src: Path, dest: Path) -> Path:
    """``dest`` afresh, holding a symbolic link to ``src/<name>`` for each of ``names``."""
    if dest.exists():
        shutil.rmtree(dest)
    dest.mkdir(parents=True)
    for n in names:
        (dest / n).symlink_to(src / n)
    return dest


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


# -- statistics over seeds ---------------------------------------------------------------------

def seed_stats(v: list[float]) -> dict:
    """Mean, sample std (ddof 1; 0 for one value) and the values of ``v``, one per seed."""
    a = np.asarray(v, float)
    return {"mean": float(a.mean()) if len(a) else None, "std": float(a.std(ddof=1)) if len(a) > 1 else 0.0,
            "per_seed": [float(x) for x in a]}


def format_stat(s: dict | None, scale: float = 100.0, signed: bool = False) -> str:
    """A :func:`seed_stats` as 'mean ± std' x ``scale`` (IoU points), '-' where there is none."""
    if not s or s["mean"] is None:
        return "-"
    return f"{scale * s['mean']:{'+' if signed else ''}.1f} ± {scale * s['std']:.1f}"


def paired(per_seed: dict[int, dict], sets: list[str], groups: dict[str, list[str]], a: str, b: str) -> dict:
    """Paired differences a - b of road IoU per seed (mean, std, per seed), per test set and group
    (a group's difference per seed is the mean over its members)."""
    seeds = sorted(per_seed)
    diff: dict[str, dict] = {}
    for s in sets:
        diff[s] = seed_stats([per_seed[k][s, a]["iou"] - per_seed[k][s, b]["iou"] for k in seeds
                              if (s, a) in per_seed[k] and (s, b) in per_seed[k]])
    for g, members in groups.items():
        if members:
            diff[g] = seed_stats([float(np.mean([per_seed[k][m, a]["iou"] - per_seed[k][m, b]["iou"]
                                                 for m in members]))
                                  for k in seeds if all((m, c) in per_seed[k] for m in members for c in (a, b))])
    return diff


def aggregate(per_seed: dict[int, dict], sets: list[str], conditions: list[str],
              groups: dict[str, list[str]]) -> dict:
    """Cells (mean, std, per seed) and paired within - resize (and adapt - within) differences, per
    test set and group (``groups``: name -> its test sets; a group's value per seed is the mean over
    them)."""
    seeds = sorted(per_seed)
    cells: dict[str, dict[str, dict]] = {}
    for s in sets:
        cells[s] = {c: seed_stats([per_seed[k][s, c]["iou"] for k in seeds if (s, c) in per_seed[k]])
                    for c in conditions}
    for g, members in groups.items():
        if members:
            cells[g] = {c: seed_stats([float(np.mean([per_seed[k][m, c]["iou"] for m in members])) for k in seeds
                                       if all((m, c) in per_seed[k] for m in members)]) for c in conditions}
    diff = paired(per_seed, sets, groups, "within", "resize") if {"within", "resize"} <= set(conditions) else {}
    adapt = {c: paired(per_seed, sets, groups, c, "within") for c in ADAPTED if {c, "within"} <= set(conditions)}
    vp = paired(per_seed, sets, groups, "within", "between") if {"within", "between"} <= set(conditions) else {}
    return {"cells": cells, "within_minus_resize": diff, "adapt_minus_within": adapt, "within_minus_between": vp,
            "groups": groups}


# -- tables and plots --------------------------------------------------------------------------

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
            row += [format_stat(shift["reference"][n].get(c)) if n in sims else "",
                    format_stat(shift["cost"][n].get(c), signed=True)]
        lines.append("| " + " | ".join(row) + " |")
    b = shift["zero_cost"]
    if b:
        parts = [f"{n} {format_stat(b[n], signed=True)}" for n in sims if n in b]
        lines += ["", "within − resize if the within model lost nothing to the camera change (within's no-change "
                  "score − resize's score; what these test sets allow at this network quality): " + ", ".join(parts)
                  + (f"; simulated mean **{format_stat(b['simulated'], signed=True)}**" if "simulated" in b else "")
                  + (f"; other cameras (KITTI as measured) **{format_stat(b['other cameras'], signed=True)}**"
                     if "other cameras" in b else "") + "."]
    v = shift.get("exact_vp") or {}
    if v:
        lines += ["", "within with each frame's EXACT camera pose (the simulation's, as a perfect per-frame "
                  "calibration gives) instead of its estimated road VP (same model, same virtual camera): "
                  + ", ".join(f"{n} {format_stat(v[n]['exact'])} (estimated − exact: "
                              f"{format_stat(v[n]['cost'], signed=True)})" for n in v) + "."]
    return lines + [""]


def seed_table(agg: dict, sets: list[str], conditions: list[str], items: dict[str, int]) -> str:
    """Markdown: a row per test set (its frames) and group, a column per condition and paired
    difference; cells mean ± std over seeds (IoU points)."""
    diff, adapt = bool(agg["within_minus_resize"]), list(agg["adapt_minus_within"])
    header = (["test set", "frames"] + conditions + (["within − resize"] if diff else [])
              + [f"{c} − within" for c in adapt])
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for s in sets + [g for g in agg["groups"] if agg["groups"][g]]:
        row = [s if s in sets else f"**{s}** (mean)", str(items.get(s, "")) if s in sets else ""]
        row += [format_stat(agg["cells"][s][c]) for c in conditions]
        if diff:
            row.append(format_stat(agg["within_minus_resize"].get(s), signed=True))
        for c in adapt:
            row.append(format_stat(agg["adapt_minus_within"][c].get(s), signed=True))
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines) + "\n"


def bar_plot(cell: dict[tuple[str, str], float], groups: list[str], conditions: list[str], title: str,
             spread: dict[tuple[str, str], float] | None = None) -> np.ndarray:
    """Grouped bars: road IoU in [0, 1] per group and condition (colours); ``spread``: error bars
    (+/- that much) where given."""
    colours = [(160, 160, 160), (200, 140, 60), (60, 170, 60), (40, 110, 30), (60, 60, 200), (170, 70, 170),
               (0, 150, 255)]
    W, H, top, bottom, left = 1000, 540, 80, 60, 60
    img = np.full((H, W, 3), 255, np.uint8)
    gw = (W - left - 20) / len(groups)
    bw = gw * 0.8 / len(conditions)
    y0 = H - bottom
    for t in range(0, 101, 20):
        y = int(y0 - t / 100 * (H - top - bottom))
        cv2.line(img, (left, y), (W - 20, y), (225, 225, 225), 1)
        cv2.putText(img, f"{t}", (18, y + 5), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (80, 80, 80), 1, cv2.LINE_AA)
    for g, name in enumerate(groups):
        x0 = left + g * gw + gw * 0.1
        for j, c in enumerate(conditions):
            if (name, c) not in cell:
                continue
            h = cell[name, c] * (H - top - bottom)
            x = int(x0 + j * bw)
            cv2.rectangle(img, (x, int(y0 - h)), (int(x + bw - 2), y0), colours[j % len(colours)], -1)
            e = (spread or {}).get((name, c)) or 0.0
            if e:
                e *= H - top - bottom
                xm = int(x + bw / 2 - 1)
                for a, b in (((xm, int(y0 - h - e)), (xm, int(y0 - h + e))), ((xm - 3, int(y0 - h - e)),
                             (xm + 3, int(y0 - h - e))), ((xm - 3, int(y0 - h + e)), (xm + 3, int(y0 - h + e)))):
                    cv2.line(img, a, b, (0, 0, 0), 1)
            cv2.putText(img, f"{100 * cell[name, c]:.0f}", (x, int(y0 - h - e) - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.35,
                        (40, 40, 40), 1, cv2.LINE_AA)
        cv2.putText(img, name, (int(x0), y0 + 22), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    for j, c in enumerate(conditions):
        x = left + j * 150
        cv2.rectangle(img, (x, 18), (x + 14, 32), colours[j % len(colours)], -1)
        cv2.putText(img, c, (x + 20, 31), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(img, title, (left, 52), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (80, 80, 80), 1, cv2.LINE_AA)
    return img


# -- the models of a study ---------------------------------------------------------------------

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


# -- the camera change alone -------------------------------------------------------------------

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
    from vctrain.study import CONDITIONS as MODES
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


def shift_costs(per_seed: dict[int, dict], no_shift: dict[int, dict], sets: list[str], conditions: list[str],
                others: list[str]) -> dict:
    """The camera change alone, per simulated set and condition (mean, std, per seed): ``reference``
    (:func:`no_shift_reference`: the same pixels seen by the model in the source camera), ``cost``
    = score on the simulated camera - reference (and per group), and ``zero_cost``: within -
    resize if the within model lost nothing to the camera change (within's reference - resize's
    score; what these test sets allow at this network quality), per simulated set, over the
    simulated sets, and over the other cameras ``others`` with the real ones (no reference) as measured."""
    seeds = [k for k in sorted(per_seed) if no_shift.get(k)]
    sims = [n for n in SIM if n in sets]
    trained = [c for c in conditions if c not in UNTRAINED]
    ref: dict[str, dict] = {n: {} for n in sims}
    cost: dict[str, dict] = {n: {} for n in sims}
    for n in sims:
        for c in trained:
            ks = [k for k in seeds if (n, c) in no_shift[k] and (n, c) in per_seed[k]]
            if ks:
                ref[n][c] = seed_stats([no_shift[k][n, c]["iou"] for k in ks])
                cost[n][c] = seed_stats([per_seed[k][n, c]["iou"] - no_shift[k][n, c]["iou"] for k in ks])
    if sims:
        cost["simulated"] = {c: seed_stats([float(np.mean([per_seed[k][n, c]["iou"] - no_shift[k][n, c]["iou"]
                                                       for n in sims])) for k in seeds])
                             for c in trained if all(c in cost[n] for n in sims)}
    zero: dict[str, dict] = {}
    if {"within", "resize"} <= set(trained) and sims and all("within" in ref[n] for n in sims):
        def gap(k: int, n: str) -> float:
            if n in sims:
                return no_shift[k][n, "within"]["iou"] - per_seed[k][n, "resize"]["iou"]
            return per_seed[k][n, "within"]["iou"] - per_seed[k][n, "resize"]["iou"]

        for n in sims:
            zero[n] = seed_stats([gap(k, n) for k in seeds])
        zero["simulated"] = seed_stats([float(np.mean([gap(k, n) for n in sims])) for k in seeds])
        if all((n, c) in per_seed[k] for k in seeds for n in others for c in ("within", "resize")):
            zero["other cameras"] = seed_stats([float(np.mean([gap(k, n) for n in others])) for k in seeds])
    return {"reference": ref, "cost": cost, "zero_cost": zero, "seeds": seeds}


def vp_costs(per_seed: dict[int, dict], exact: dict[int, dict]) -> dict:
    """Per simulated set (and their mean): within with each frame's exact pose (``exact``, mean,
    std, per seed) and ``cost`` = within with estimated road VPs - that."""
    seeds = [k for k in sorted(exact) if exact[k]]
    sims = [n for n in SIM if all(n in exact[k] and (n, "within") in per_seed[k] for k in seeds)] if seeds else []
    out = {n: {"exact": seed_stats([exact[k][n]["iou"] for k in seeds]),
               "cost": seed_stats([per_seed[k][n, "within"]["iou"] - exact[k][n]["iou"] for k in seeds])} for n in sims}
    if sims:
        out["simulated"] = {"exact": seed_stats([float(np.mean([exact[k][n]["iou"] for n in sims])) for k in seeds]),
                            "cost": seed_stats([float(np.mean([per_seed[k][n, "within"]["iou"] - exact[k][n]["iou"]
                                                          for n in sims])) for k in seeds])}
    return out


# -- road vanishing points ---------------------------------------------------------------------

def baseline_vp(image: np.ndarray, iters: int = 500, min_len_px: float = 15.0, lower: float = 0.6,
                min_deg: float = 15.0, max_deg: float = 75.0, band_px: float = 3.0,
                seed: int = 0) -> tuple[float, float]:
    """The plain baseline of issue 17: OpenCV's LSD (default settings) on the grey image; segments
    kept if 15-75 deg from horizontal, longer than 15 px and with their midpoint in the lower 60 %
    of the image; ``iters`` RANSAC pairs (seeded), each pair's intersection scored by the summed
    length of the kept segments whose line passes within ``band_px`` px of it; the best
    intersection, unrefined. No prior, no camera. (Image centre if fewer than 2 segments.)"""
    h, w = image.shape[:2]
    lines = cv2.createLineSegmentDetector().detect(to_gray(image))[0]
    seg = np.zeros((0, 4)) if lines is None else lines.reshape(-1, 4).astype(np.float64)
    d = seg[:, 2:4] - seg[:, 0:2]
    L = np.hypot(d[:, 0], d[:, 1])
    ang = np.degrees(np.arctan2(np.abs(d[:, 1]), np.abs(d[:, 0])))
    mid_y = 0.5 * (seg[:, 1] + seg[:, 3])
    keep = (L > min_len_px) & (ang >= min_deg) & (ang <= max_deg) & (mid_y >= (1 - lower) * h)
    seg, L = seg[keep], L[keep]
    if len(seg) < 2:
        return (w / 2 - 0.5, h / 2 - 0.5)
    hom = np.cross(np.c_[seg[:, :2], np.ones(len(seg))], np.c_[seg[:, 2:], np.ones(len(seg))])
    hom /= np.linalg.norm(hom[:, :2], axis=1, keepdims=True)          # a u + b v + c = 0, (a, b) unit
    rng = np.random.default_rng(seed)
    i = rng.integers(0, len(seg), iters)
    j = rng.integers(0, len(seg), iters)
    X = np.cross(hom[i], hom[j])
    ok = (i != j) & (np.abs(X[:, 2]) > 1e-12)
    if not ok.any():
        return (w / 2 - 0.5, h / 2 - 0.5)
    X = X[ok, :2] / X[ok, 2:3]
    dist = np.abs(X @ hom[:, :2].T + hom[None, :, 2])                  # (candidates, segments) px
    score = (dist < band_px).astype(np.float64) @ L
    best = X[int(np.argmax(score))]
    return float(best[0]), float(best[1])


def _fit_side(ys: np.ndarray, xs: np.ndarray, band: float = 2.0, gate: bool = True):
    """RANSAC + LSQ line x = a*y + b; returns (a, b) or None if the fit is not good (rule 3).
    ``band``: RANSAC inlier band in px (the rule uses 2); ``gate=False`` skips the goodness
    tests. Both only serve to measure the reference's own sensitivity (camvid_vp_set)."""
    n = len(ys)
    if n < 25:
        return None
    i, j = np.triu_indices(n, 1)
    if len(i) > 4000:
        sel = np.linspace(0, len(i) - 1, 4000).astype(int)
        i, j = i[sel], j[sel]
    dy = ys[j] - ys[i]
    ok = np.abs(dy) >= 10
    i, j, dy = i[ok], j[ok], dy[ok]
    if len(i) == 0:
        return None
    a = (xs[j] - xs[i]) / dy
    b = xs[i] - a * ys[i]
    res = np.abs(xs[None, :] - (a[:, None] * ys[None, :] + b[:, None]))
    cnt = (res < band).sum(1)
    k = int(np.argmax(cnt))
    inl = res[k] < band
    A = np.c_[ys[inl], np.ones(inl.sum())]
    a, b = np.linalg.lstsq(A, xs[inl], rcond=None)[0]
    r = xs[inl] - (a * ys[inl] + b)
    span = ys[inl].max() - ys[inl].min()
    if gate and (inl.sum() < 25 or inl.mean() < 0.6 or span < 40 or math.sqrt(np.mean(r ** 2)) > 1.2):
        return None
    return float(a), float(b), float(ys[inl].min())


def reference_vp(label: np.ndarray, cam, band: float = 2.0, gate: bool = True) -> tuple[float, float] | None:
    """Reference road VP of a CamVid label image (rule in the module docstring), or None.
    ``band`` (rule 3's inlier band, 2 px) and ``gate`` (rule 3's goodness tests) are changed
    only to measure the reference's spread on frames the rule accepted."""
    return reference_from_masks(label == 3, np.isin(label, STATIC), cam, band, gate)


def kitti_reference_vp(gt: np.ndarray, cam) -> tuple[float, float] | None:
    """The same rule on a KITTI road ground truth (BGR colours): road = magenta; a road edge
    counts where the pixel outside is red (evaluated not-road), never black (outside the
    evaluated area)."""
    b, g, r = (gt[..., k].astype(int) for k in range(3))
    road = (r > 127) & (b > 127) & (g < 128)
    not_road = (r > 127) & (b < 128) & (g < 128)
    return reference_from_masks(road, not_road, cam)


def reference_from_masks(road: np.ndarray, edge_ok: np.ndarray, cam, band: float = 2.0,
                         gate: bool = True) -> tuple[float, float] | None:
    """Rule steps 1-4 on a road mask; ``edge_ok`` marks the pixels whose border with the road is
    a real road edge (static classes), so occluders never give boundary points."""
    road = road.astype(np.uint8)
    n, comp, stats, _ = cv2.connectedComponentsWithStats(road, connectivity=8)
    if n < 2:
        return None
    big = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    road = comp == big
    h, w = road.shape
    rows = np.flatnonzero(road.any(1))
    top = rows.min() + 0.15 * (rows.max() - rows.min())
    pts = {"l": ([], []), "r": ([], [])}
    for y in rows:
        if y < top:
            continue
        xs = np.flatnonzero(road[y])
        xl, xr = xs[0], xs[-1]
        if xr - xl < 12:
            continue
        if xl >= 3 and edge_ok[y, xl - 1]:
            pts["l"][0].append(y), pts["l"][1].append(xl - 0.5)
        if xr <= w - 4 and edge_ok[y, xr + 1]:
            pts["r"][0].append(y), pts["r"][1].append(xr + 0.5)
    fits = [_fit_side(np.array(pts[s][0], float), np.array(pts[s][1], float), band, gate) for s in ("l", "r")]
    if fits[0] is None or fits[1] is None:
        return None
    (al, bl, yl), (ar, br, yr) = fits
    ang = abs(math.degrees(math.atan(al) - math.atan(ar)))
    if ang < 8 or abs(al - ar) < 1e-9:
        return None
    y = (br - bl) / (al - ar)
    x = al * y + bl
    u0, v0, u1, v1 = prior_window(cam)
    if y >= min(yl, yr) or not (u0 <= x <= u1 and v0 <= y <= v1):
        return None
    return float(x), float(y)


def synthetic_vp_set(n: int, cam, seed: int = 0):
    rng = np.random.default_rng(seed)
    out = []
    W, H = cam.size
    for k in range(n):
        pan, tilt = rng.uniform(-20, 20), rng.uniform(-15, 15)
        scene = RoadScene(offset=float(rng.uniform(-3, 3)), width=float(rng.uniform(6, 12)),
                          lanes=int(rng.integers(1, 4)), texture_seed=k)
        img, _ = render_road(cam, scene, pan=pan, tilt=tilt, supersample=2)
        img = img.astype(np.float64) + rng.normal(0, 5, img.shape)
        for c in range(10):
            p = rng.uniform([0, 0], [W, H])
            ang = rng.uniform(85, 95) if c < 3 else rng.uniform(0, 180)  # 3 "poles", 7 random
            ln = rng.uniform(20, 160) * W / 480
            q = p + ln * np.array([math.cos(math.radians(ang)), -math.sin(math.radians(ang))])
            cv2.line(img, tuple(int(v) for v in p), tuple(int(v) for v in q),
                     tuple(float(v) for v in rng.uniform(0, 255, 3)), int(rng.integers(1, 4)))
        img = np.clip(np.rint(img), 0, 255).astype(np.uint8)
        out.append((f"syn{k:03d}", img, vp_from_pose(cam, pan, tilt)))
    return out


def camvid_vp_set(split: str, cam):
    """(id, image, reference VP) of the frames the rule accepts, the number skipped, and the
    reference's own spread per kept frame: |VP(band 1.5 px) - VP(band 3 px)| in % of the width,
    both fitted to the same boundary points without rule 3's goodness tests (the frame already
    passed them; nan if either intersection is invalid) - how far the reference moves under an
    equally reasonable choice of its own parameter: a floor under any detector's measured error."""
    img_dir, lab_dir = DATA / split, DATA / f"{split}annot"
    out, skipped, spread = [], 0, []
    for p in sorted(img_dir.glob("*.png")):
        lab = cv2.imread(str(lab_dir / p.name), cv2.IMREAD_UNCHANGED)
        ref = reference_vp(lab, cam) if lab is not None else None
        if ref is None:
            skipped += 1
            continue
        out.append((p.stem, cv2.imread(str(p), cv2.IMREAD_COLOR), ref))
        a, b = reference_vp(lab, cam, 1.5, gate=False), reference_vp(lab, cam, 3.0, gate=False)
        spread.append(math.hypot(a[0] - b[0], a[1] - b[1]) / cam.size[0] * 100 if a and b else float("nan"))
    return out, skipped, spread


def simulated_vp_sets(split_items, workdir: Path, split: str = "val"):
    """CamVid frames of ``split`` that have a reference VP, through the simulated cameras of the
    cross-camera benchmarks (``vcprep simulate``: crop/zoom and rotation about the optical centre
    are exact), each frame's reference VP mapped exactly by the same homography (``--vps``).
    Returns [(name, camera, [(id, image, reference VP)])]; the camera is the simulated camera at
    its nominal pose (per-image pan/tilt jitter is what the detector must find); the source
    camera is CamVid's (the camvid preset at 480x360). ``split='train'`` builds the development
    sets of ``--dev`` (same cameras, same seeds, other frames)."""
    from vcprep.camera import load_camera

    src = workdir / f"{split}_with_reference"
    shutil.rmtree(src, ignore_errors=True)
    src.mkdir(parents=True)
    rows = ["id,u,v"]
    for iid, _, ref in split_items:
        (src / f"{iid}.png").symlink_to(DATA / split / f"{iid}.png")
        rows.append(f"{iid},{ref[0]:.9f},{ref[1]:.9f}")
    (workdir / f"{split}_reference_vps.csv").write_text("\n".join(rows) + "\n")
    native = native_camera(workdir)
    out = []
    for name, args in SIMULATED.items():
        dst = workdir / "sim" / (name if split == "val" else f"{split}-{name}")
        run(BIN / "vcprep", "simulate", "--camera", native, "--images", src, "--out", dst, "--name", name,
            "--vps", workdir / f"{split}_reference_vps.csv", "--quiet", *args)
        refs = {r[0]: (float(r[1]), float(r[2])) for r in
                (line.split(",") for line in (dst / "vps.csv").read_text().splitlines()[1:])}
        items = [(iid, cv2.imread(str(dst / "images" / f"{iid}.png"), cv2.IMREAD_COLOR), refs[iid])
                 for iid, _, _ in split_items]
        out.append((name, load_camera(str(dst / "camera.yaml")), items))
    return out


def kitti_vp_set():
    """The KITTI road frames shipped in ../shared/data whose ground truth the rule accepts, each
    with its own calibration file; (camera, items, skipped)."""
    from vcprep.camera import load_camera

    items, cams, skipped = [], [], 0
    for p in sorted((KITTI / "image_2").glob("*.png")) if (KITTI / "image_2").is_dir() else []:
        prefix, _, num = p.stem.partition("_")
        gt = cv2.imread(str(KITTI / "gt_image_2" / f"{prefix}_road_{num}.png"), cv2.IMREAD_COLOR)
        img = cv2.imread(str(p), cv2.IMREAD_COLOR)
        cam = load_camera(str(KITTI / "calib" / f"{p.stem}.txt")).for_image_size((img.shape[1], img.shape[0]))
        ref = kitti_reference_vp(gt, cam) if gt is not None else None
        if ref is None:
            skipped += 1
            continue
        items.append((p.stem, img, ref))
        cams.append(cam)
    return cams, items, skipped


def vp_errors(vps, items, cams) -> np.ndarray:
    """|VP - reference| of each item in % of its camera's width."""
    return np.array([math.hypot(v[0] - r[0], v[1] - r[1]) / c.size[0] * 100
                     for v, (_, _, r), c in zip(vps, items, cams)])


def error_summary(e: np.ndarray) -> dict:
    return {"n": int(len(e)), "median_pct_width": round(float(np.median(e)), 3) if len(e) else None,
            "p90_pct_width": round(float(np.percentile(e, 90)), 3) if len(e) else None,
            "mean_pct_width": round(float(np.mean(e)), 3) if len(e) else None}


_FRAME_RE = re.compile(r"^(.*?)(\d+)$")


def scenes(ids, gap: int = SCENE_GAP) -> list[int]:
    """Scene index of each frame id: frames of one sequence (:func:`sequence_key`) whose frame
    numbers (the id's trailing digits) are at most ``gap`` apart, chained, are one scene (CamVid
    is 30 fps: 30 = one second of driving); an id without a frame number is a scene of its own.
    Consecutive frames of one drive see the same road, so their errors are not independent."""
    keyed = []
    for k, iid in enumerate(ids):
        m = _FRAME_RE.match(iid.rsplit("_", 1)[-1]) if "_" in iid else None
        keyed.append((sequence_key(iid), int(m.group(2)) if m else None, k))
    out = [0] * len(ids)
    scene, last = -1, None
    for seq, num, k in sorted(keyed, key=lambda t: (t[0], -1 if t[1] is None else t[1], t[2])):
        if num is None or last is None or seq != last[0] or num - last[1] > gap:
            scene += 1
        out[k] = scene
        last = None if num is None else (seq, num)
    return out


def _scene_groups(scene: list[int]) -> list[np.ndarray]:
    """Frame indices of each scene, in scene order."""
    scene = np.asarray(scene)
    return [np.flatnonzero(scene == s) for s in np.unique(scene)]


def scene_bootstrap(ours: np.ndarray, base: np.ndarray, groups: list[np.ndarray], n_boot: int = 2000,
                    seed: int = 0) -> dict:
    """Paired scene-block bootstrap (whole scenes resampled with replacement, ``n_boot`` draws,
    seeded): 90 % intervals (5th-95th percentile) of the median and p90 error of ours, of the
    baseline, and of their differences (ours - baseline; negative = ours better), in % width.
    With few scenes the intervals are wide: that is what the set can say. ``groups``: the frame
    indices of each scene (:func:`_scene_groups`)."""
    rng = np.random.default_rng(seed)
    stats = {k: [] for k in ("median", "p90", "baseline_median", "baseline_p90", "median_minus_baseline",
                             "p90_minus_baseline")}
    for _ in range(n_boot):
        idx = np.concatenate([groups[g] for g in rng.integers(0, len(groups), len(groups))])
        mo, po = np.median(ours[idx]), np.percentile(ours[idx], 90)
        mb, pb = np.median(base[idx]), np.percentile(base[idx], 90)
        for k, v in (("median", mo), ("p90", po), ("baseline_median", mb), ("baseline_p90", pb),
                     ("median_minus_baseline", mo - mb), ("p90_minus_baseline", po - pb)):
            stats[k].append(v)
    ci = {k: [round(float(np.percentile(v, 5)), 3), round(float(np.percentile(v, 95)), 3)] for k, v in stats.items()}
    return {"scenes": len(groups), "n_boot": n_boot, "seed": seed, "ci90": ci,
            "frames_per_scene": [int(len(g)) for g in groups]}


def evaluate_vps(items, cams, cfg: VPConfig, repeats: int):
    """Errors (% width) and median ms/image for ours and the baseline, same images, same run;
    ``cams``: one camera per item (or one for all). For ours also the reliability rule's split:
    the error of the VPs it accepts, and of those it rejects (their detection, and the dataset
    mean of the accepted VPs that replaces them: what ``vcprep warp`` uses)."""
    cams = list(cams) if isinstance(cams, (list, tuple)) else [cams] * len(items)
    ids = [iid for iid, _, _ in items]
    res = {}
    for name, fn in (("ours", lambda im, c: estimate_vp(im, c, cfg)),
                     ("baseline", lambda im, c: baseline_vp(im))):
        per_pass, out = [], []
        for rep in range(repeats):
            t0 = time.perf_counter()
            got = [fn(im, c) for (_, im, _), c in zip(items, cams)]
            per_pass.append((time.perf_counter() - t0) * 1000 / max(1, len(items)))
            if rep == 0:
                out = got
        vps = [r.vp for r in out] if name == "ours" else out
        e = vp_errors(vps, items, cams)
        res[name] = {**error_summary(e), "ms_per_image": round(float(np.median(per_pass)), 2),
                     "ms_spread": [round(float(min(per_pass)), 2), round(float(max(per_pass)), 2)],
                     "errors": [round(float(x), 4) for x in e],
                     "vps": {iid: [round(float(v[0]), 4), round(float(v[1]), 4)] for (iid, _, _), v in zip(items, vps)}}
        if name == "ours":
            acc = np.array([r.status == "accepted" for r in out], bool)
            final = apply_reliability(out, cams, ids)
            det = [(r.detected or r.vp) for r in out]
            # the tail, split by the detector's own score (score_vps): a reference VP scoring higher
            # than the detection is a search miss; lower, the image's lines converge elsewhere
            tail = np.flatnonzero(e > TAIL_PCT)
            split = {"search_miss": [], "lines_elsewhere": []}
            for k in tail:
                (iid, im, ref), c = items[k], cams[k]
                s_det, s_ref = score_vps(im, c, [out[k].detected or out[k].vp, ref], cfg)
                split["search_miss" if s_ref > s_det else "lines_elsewhere"].append(
                    {"id": iid, "error_pct_width": round(float(e[k]), 3),
                     "score_reference_over_detection": round(float(s_ref / s_det), 3) if s_det > 0 else None})
            res[name]["tail"] = {"threshold_pct_width": TAIL_PCT, "n": int(len(tail)), **split}
            res[name]["reliability"] = {
                "accepted": error_summary(e[acc]),
                "rejected_detection": error_summary(vp_errors(det, items, cams)[~acc]),
                "rejected_fallback": error_summary(vp_errors([r.vp for r in final], items, cams)[~acc]),
                "reasons": sorted({r.reason for r in out if r.status != "accepted"}),
            }
    e_o, e_b = np.array(res["ours"]["errors"]), np.array(res["baseline"]["errors"])
    groups = _scene_groups(scenes(ids))
    res["scenes"] = scene_bootstrap(e_o, e_b, groups)
    res["scenes"]["per_scene"] = [
        {"first": ids[g[0]], "last": ids[g[-1]], "n": int(len(g)),
         "median_pct_width": round(float(np.median(e_o[g])), 3), "max_pct_width": round(float(e_o[g].max()), 3),
         "baseline_median_pct_width": round(float(np.median(e_b[g])), 3),
         "baseline_max_pct_width": round(float(e_b[g].max()), 3)}
        for g in groups]
    return res


def fallback_loo(split: str, cam, items, cfg: VPConfig) -> dict:
    """What the reliability rule's fallback is worth on real frames, leave-one-out: the detector
    runs on EVERY frame of the split (as ``vcprep warp --within estimate`` would), then each
    referenced frame in turn is marked rejected and ``apply_reliability`` replaces it - with its
    sequence's mean (ids given, the tool's rule) and with the whole split's mean (no ids, the
    rule before) - and the replacement is scored against the frame's reference (% width)."""
    paths = sorted((DATA / split).glob("*.png"))
    ids = [p.stem for p in paths]
    res = [estimate_vp(cv2.imread(str(p), cv2.IMREAD_COLOR), cam, cfg) for p in paths]
    cams = [cam] * len(res)
    where = {iid: k for k, iid in enumerate(ids)}
    out = {"sequence": [], "dataset": []}
    for iid, _, ref in items:
        k = where[iid]
        trial = list(res)
        trial[k] = replace(res[k], status="rejected")
        for name, fb in (("sequence", apply_reliability(trial, cams, ids)[k]),
                         ("dataset", apply_reliability(trial, cams)[k])):
            out[name].append(math.hypot(fb.vp[0] - ref[0], fb.vp[1] - ref[1]) / cam.size[0] * 100)
    return {"frames_detected": len(res), "rejected_in_split": sum(r.status != "accepted" for r in res),
            **{f"{k}_mean": error_summary(np.array(v)) for k, v in out.items()}}


def camera_consistency(source_vps: dict, sim_items, sim_vps: dict, sim_dir: Path, width: int) -> dict:
    """Reference-free camera independence of our detector on one simulated set: its VP on each
    simulated frame vs its VP on the SOURCE frame carried into the simulated camera by that
    frame's exact homography (``out_H_src`` recorded by the simulation), in % of the simulated
    width. A camera-independent detector finds the same road direction in both (0 up to
    resampling), whatever the reference says. ``inherited``: the source frame's own error
    carried over (its VP vs its reference, both through the same homography), i.e. the simulated
    set's error if the detector did exactly as well on every simulated frame as on its source;
    a crop/zoom makes it larger in % of the (narrower) width."""
    from vcprep.homography import apply_homography
    from vcprep.simulate import recorded_homographies

    H = recorded_homographies(sim_dir)
    cons, inh = [], []
    for iid, _, ref in sim_items:
        mapped = apply_homography(H[iid], np.array([source_vps[iid]], float))[0]
        cons.append(math.hypot(*(np.asarray(sim_vps[iid]) - mapped)) / width * 100)
        inh.append(math.hypot(mapped[0] - ref[0], mapped[1] - ref[1]) / width * 100)
    return {"consistency": error_summary(np.array(cons)), "inherited": error_summary(np.array(inh)),
            "consistency_errors": [round(x, 4) for x in cons]}
