"""Real cameras as they ship: will a model trained on CamVid work on other real cameras, with
nothing set by hand (issues 24 and 25)?

    .venv/bin/python benchmarks/other_cameras/as_shipped.py [--seeds 0,1,2] [--loo-seeds 0,1,2] [--conditions within,resize]
                                                            [--canvases shared,footprint] [--ablation-seeds 0,1] [--epochs N]
                                                            [--workdir benchmarks/out/as_shipped] [--threads 2] [--quick]

Two ``vctrain crossval`` studies, each run once per seed (``--seed k``; an interrupted run resumes),
both with crossval's defaults (the measured best design: 172800-px stores, the virtual camera kept
to 8 deg above the horizon, full-height 4/9 training windows; nothing set but ``--epochs`` when given,
and study 1's rectangle rule, below):

**1. Trained on CamVid** (WORKDIR/seed<k>/): per condition ONE model trained on CamVid train minus
sequence 0001TP (0016E5 + 0006R0, 305 frames, no own vehicle in view), scored in each test set's own
camera (back-projected; road IoU = sum TP / sum (TP+FP+FN) over the set, ignore excluded) on:

* real other cameras, each with the camera file it ships with (the headline):
  ``cityscapes`` (400 frames of ../shared/data/cityscapes_pix2pix, its scaled calibration; the bonnet
  found from the labels: ``ego: auto``, the study's default), ``idd`` (1,403 IDD-Lite frames, 309
  drives, label format idd, the dataset's ASSUMED camera.yaml), ``kitti`` (the KITTI road frame with
  its own calibration file), ``bdd`` (41 BDD100K frames of 27 dashcams, its ASSUMED camera.yaml) and
  ``lums`` (144 frames of a low campus vehicle, its assumed/estimated camera.yaml);
* the same with ``camera: estimate`` (horizon, tilt, pan from the frames' road VPs, the own vehicle
  from the labels; focal length and height ASSUMED and said): ``cityscapes-est``, ``idd-est``,
  ``bdd-est``, against the shipped camera of the same frames (in the default rectangle rule's study
  only: in ``shared`` an estimated camera would size the one rectangle every other row is seen in);
* known cameras hidden from the estimate: ``sim-tele``, ``sim-band``, ``sim-dashcam`` (CamVid val made
  exactly into measure.data.SIMULATED's cameras by ``vcprep simulate``, each with its exact camera file) and
  the same frames with ``camera: estimate`` (``sim-<name>-est``), in the default rectangle's study only;
* the own vehicle: ``cityscapes-noego`` and ``camvid-0001TP-noego`` (``ego: none``: the bonnet
  warped as road surface, what a user got before) against ``cityscapes`` and ``camvid-0001TP``
  (CamVid's unseen sequence 0001TP, 62 frames, bonnet up to 36 rows, found from the labels);
* in domain: ``camvid-val`` (101 frames, no own vehicle: the search must find none).

Study 1 runs once per rectangle rule of the virtual camera (crossval's ``canvas``, ``--canvases``):
``shared`` (one rectangle holding every camera of the study, the paper's rule; WORKDIR/seed<k>/, with
the resize baseline) and ``footprint`` (the rectangle holds the training camera, each test camera's
stores extend it; WORKDIR/footprint/seed<k>/, the virtual-camera conditions only). The headline rows
are crossval's default rule; the other is reported beside it, paired per seed.

**2. Leave one real dataset out** (the paper's Table 4 protocol over real cameras; WORKDIR/loo/seed<k>/):
CamVid (train 367 frames; tested on val), Cityscapes (400) and IDD-Lite (1,403), each ``role: both``:
held out in turn, trained on the other two, tested on it (Cityscapes and IDD: all their frames).
Every fold trains as many steps as the CamVid model of study 1 (``max_steps`` per epoch = that
model's steps per epoch: 305 frames less the 10 % validation share, batch 8), so a fold costs what
one model costs whatever the size of its training union.

**Ablation: no geometric augmentation** (``--ablation-seeds``, WORKDIR/noaug/seed<k>/, the default
rectangle's stores): study 1 again with the random scale about the VP and the random shift off
(``scale_aug: 0, shift_aug: 0``) for both conditions, tested on camvid-val, 0001TP and the five real
other cameras; compared paired per seed with the default recipe's models of the same seeds. The
paper's SegNet recipe trains without augmentation; a resize baseline that learns scale tolerance
from augmentation could be what holds within - resize far below the paper's +21.

The resize baseline reads the frames as they are (no geometry, so ``ego`` and ``camera`` do not touch
it); the rows of a frame set share its resize score. Reported, mean +/- sample std over seeds: road
IoU per test set and condition; within - resize paired per seed, per camera and over the real
other cameras (per seed the mean over them, then over seeds); the own-vehicle gain auto - none;
estimated - given camera (real and simulated); the held-out scores of the LOO study. Targets (issue 24, checked, not
asserted): real within - resize >= +10 on the mean, no real camera below resize - 2, LOO >= +10,
camvid-val and 0001TP (own vehicle found) >= 85, <= 15 minutes per model.

The last stdout line is one JSON object: ``real_within_minus_resize`` (and ``_std``),
``real_within_minus_resize_<camera>``, ``loo_within_minus_resize`` (and ``_std``, and
``loo_within_minus_resize_<dataset>``), ``in_domain_within``/``in_domain_resize`` (camvid-val),
``in_domain_0001TP_within``/``_resize``, ``ego_gain_<camera>``, ``ego_rows_found``,
``estimated_minus_given_<camera>`` (and ``_simulated``, the mean over the simulated cameras), ``within_estimated_minus_resize_<camera>``, ``minutes_per_model``,
``canvas_default``, ``real_within_minus_resize@<canvas>`` and ``real_footprint_minus_shared`` (and
``_std``, and ``footprint_minus_shared_<test set>``); with the ablation ``noaug_real_within_minus_resize``,
``aug_real_within_minus_resize`` (same seeds), ``noaug_minus_aug_real_within`` / ``_resize`` (each with
``_std``) and ``noaug_within_minus_resize_<camera>``. Outputs: benchmarks/other_cameras/results/as_shipped.{md,json,png} (``--quick``: a smoke run, a
few frames, 1 seed, 2 steps, into WORKDIR/results). Nothing is tuned on a test set: the own-vehicle
search and the camera estimate have no parameter fitted to these frames, the checkpoints are chosen
on the training frames' validation share.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import yaml

import cv2

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.as_shipped_figures import (ABLATION_TESTS, ESTIMATED, REAL_OTHER, Runs, headline_more,
                                                  headline_studies, stat, tables, targets_met)
from benchmarks.measure.data import (BDD, CITYSCAPES, CS_FORMAT, DATA, IDD, KITTI, KITTI_SEM,  # noqa: F401
                                    KITTI_SEM_FORMAT, LUMS, LUMS_FORMAT, ROOT, SHARED_DATA, SIM, native_camera,
                                    require_data, simulate)  # (the datasets: importable here too)
from benchmarks.measure.report import machine, results_dir, today
from benchmarks.measure.studies import (camvid_steps_per_epoch, link_stores, run_study, share_stores,  # noqa: F401
                                       subset_glob, subset_links, write_study)  # (importable here too)
from benchmarks.measure.tables import bar_plot
from vctrain.study import CANVASES, DEFAULT_CANVAS


def _folders(wd: Path, quick: bool) -> dict[str, dict]:
    """The frame sets as split mappings (a few frames each in a smoke run: >= 5, what the searches need)."""
    f = {"camvid-train": {"images": str(DATA / "train"), "labels": str(DATA / "trainannot")},
         "camvid-0001TP": {"images": str(DATA / "train"), "labels": str(DATA / "trainannot"), "include": "0001TP_*"},
         "camvid-val": {"images": str(DATA / "val"), "labels": str(DATA / "valannot")},
         "cityscapes": {"images": str(CITYSCAPES / "images"), "labels": str(CITYSCAPES / "labels")},
         "idd": {"images": str(IDD / "leftImg8bit" / "train"), "labels": str(IDD / "gtFine" / "train")},
         "kitti": {"images": str(KITTI / "image_2"), "labels": str(KITTI / "gt_image_2")},
         "bdd": {"images": str(BDD / "images"), "labels": str(BDD / "labels")},
         "lums": {"images": str(LUMS / "images"), "labels": str(LUMS / "labels")}}
    if quick:
        for name, src in (("cityscapes", CITYSCAPES), ("bdd", BDD), ("lums", LUMS)):
            f[name]["images"], f[name]["labels"] = subset_links(src, wd / "quick" / name, 6)
        f["camvid-val"]["include"] = "0016E5_079*"
        f["idd"]["include"] = "1[0-9]_*"
        f["camvid-train"]["exclude"] = ["0001TP_*", "0006R0_*", "0016E5_0[0-6]*"]
    return f


def _simulated(wd: Path, cam: Path, f: dict) -> dict[str, tuple[Path, dict]]:
    """CamVid val (the test frames of ``f``) through each simulated camera of measure.data.SIMULATED, into
    WORKDIR/sim/<name>/ (``vcprep simulate`` resumes: an earlier run's finished frames are kept as
    they are): {set name: (its exact camera file, its split)}."""
    out = {}
    images, labels = Path(f["camvid-val"]["images"]), Path(f["camvid-val"]["labels"])
    if "include" in f["camvid-val"]:  # (a smoke run: its few frames)
        images, labels = subset_glob(images, labels, f["camvid-val"]["include"], wd / "quick" / "sim-src")
    for n in SIM:
        dst = wd / "sim" / n
        simulate(cam, images, labels, dst, n)
        out["sim-" + n] = (dst / "camera.yaml", {"images": str(dst / "images"), "labels": str(dst / "labels")})
    return out


def study_file(wd: Path, quick: bool, epochs: int | None, canvas: str = "shared", model: str | None = None) -> Path:
    """Study 1: one model per condition trained on CamVid minus 0001TP, every other set a test, in
    the virtual camera's rectangle rule ``canvas`` (written out: the study is the same whatever
    crossval's default)."""
    cam, f = native_camera(wd), _folders(wd, quick)
    d = lambda name, camera, fmt, split, **kw: {"name": name, "role": "test", "camera": str(camera),
                                                 "label_format": fmt, "test": split, **kw}
    train = {**f["camvid-train"], "exclude": f["camvid-train"].get("exclude", "0001TP_*")}
    datasets = [
        {"name": "camvid", "role": "train", "camera": str(cam), "label_format": "camvid", "train": train},
        d("camvid-val", cam, "camvid", f["camvid-val"]),
        d("camvid-0001TP", cam, "camvid", f["camvid-0001TP"]),
        d("camvid-0001TP-noego", cam, "camvid", f["camvid-0001TP"], ego="none"),
        d("cityscapes", CITYSCAPES / "camera.yaml", CS_FORMAT, f["cityscapes"]),
        d("idd", IDD / "camera.yaml", "idd", f["idd"]),
        d("kitti", KITTI / "calib", "kitti", f["kitti"]),
        d("bdd", BDD / "camera.yaml", "bdd", f["bdd"]),
        d("lums", LUMS / "camera.yaml", LUMS_FORMAT, f["lums"]),
        d("cityscapes-noego", CITYSCAPES / "camera.yaml", CS_FORMAT, f["cityscapes"], ego="none"),
    ]
    if canvas == DEFAULT_CANVAS:  # (estimated cameras: the default rule only; in 'shared' they would size
        fmt = {x["name"]: x["label_format"] for x in datasets}  # the one rectangle, so shape what is compared)
        datasets += [d(c + "-est", "estimate", fmt[c], f[c]) for c in ESTIMATED]
        for name, (camera, split) in _simulated(wd, cam, f).items():
            datasets += [d(name, camera, "camvid", split), d(name + "-est", "estimate", "camvid", split)]
    train_cfg = {"epochs": 1, "max_steps": 2} if quick else ({"epochs": epochs} if epochs else {})
    train_cfg.update({"arch": model} if model else {})  # --model: every condition's network
    return write_study(wd, "study.yaml" if canvas == "shared" else f"study-{canvas}.yaml", datasets, train_cfg,
                  {"canvas": canvas})


NO_GEOMETRIC_AUG = {"scale_aug": 0.0, "shift_aug": 0.0}   # the ablation's training (the paper's SegNet recipe has none)
def ablation_study_file(wd: Path, quick: bool, epochs: int | None, model: str | None = None) -> Path:
    """Study 1 in the default rectangle, trained WITHOUT geometric augmentation (random scale about
    the VP and shift off, both conditions), on the in-domain and real test sets only: is the resize
    baseline's augmentation what holds within - resize down?"""
    full = yaml.safe_load(study_file(wd, quick, epochs, DEFAULT_CANVAS, model).read_text())
    datasets = [x for x in full["datasets"] if x["role"] == "train" or x["name"] in ABLATION_TESTS]
    return write_study(wd, "study-noaug.yaml", datasets, {**full.get("train", {}), **NO_GEOMETRIC_AUG},
                  {"canvas": DEFAULT_CANVAS})


def loo_study_file(wd: Path, quick: bool, epochs: int | None) -> Path:
    """Study 2: CamVid, Cityscapes and IDD-Lite held out in turn (the paper's Table 4 protocol)."""
    cam, f = native_camera(wd), _folders(wd, quick)
    datasets = [
        {"name": "camvid", "camera": str(cam), "label_format": "camvid",
         "train": {**f["camvid-train"], **({"exclude": "0001TP_*"} if quick else {})}, "test": f["camvid-val"]},
        {"name": "cityscapes", "camera": str(CITYSCAPES / "camera.yaml"), "label_format": CS_FORMAT,
         "train": f["cityscapes"], "test": f["cityscapes"]},
        {"name": "idd", "camera": str(IDD / "camera.yaml"), "label_format": "idd", "train": f["idd"], "test": f["idd"]},
    ]
    if quick:
        datasets[0]["train"]["exclude"] = f["camvid-train"]["exclude"]
    train_cfg = ({"epochs": 1, "max_steps": 2} if quick else
                 {"max_steps": camvid_steps_per_epoch(), **({"epochs": epochs} if epochs else {})})
    (wd / "loo").mkdir(parents=True, exist_ok=True)
    return write_study(wd / "loo", "study.yaml", datasets, train_cfg)


def parse_args() -> argparse.Namespace:
    """The options."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0,1,2", help="seeds of study 1 (trained on CamVid)")
    ap.add_argument("--loo-seeds", default="0,1,2", help="seeds of study 2 (leave one real dataset out); '' skips it")
    ap.add_argument("--conditions", default="within,resize")
    ap.add_argument("--canvases", default="shared,footprint",
                    help="the virtual camera's rectangle rules compared (crossval's 'canvas'); the headline is "
                         f"crossval's default ({DEFAULT_CANVAS})")
    ap.add_argument("--ablation-seeds", default="",
                    help="seeds of the ablation: study 1 without geometric augmentation (WORKDIR/noaug); '' skips it")
    ap.add_argument("--epochs", type=int, default=None)
    ap.add_argument("--workdir", type=Path, default=ROOT / "benchmarks" / "out" / "as_shipped")
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--model", default=None, help="every condition's network (study train: arch), e.g. lite0fpn "
                    "(issue 53); WORKDIR/model-<name>, results in its results/ (the LOO study keeps the recipe's)")
    a = ap.parse_args()
    if a.model:
        a.workdir = a.workdir / f"model-{a.model}"
    return a


def plan(a: argparse.Namespace) -> Runs:
    """The seeds, conditions and canvases the options ask for (checked), nothing measured yet."""
    require_data(CITYSCAPES, IDD, DATA, KITTI, BDD, LUMS)
    seeds = [0] if a.quick else [int(s) for s in a.seeds.split(",") if s]
    loo_seeds = [0] if a.quick else [int(s) for s in a.loo_seeds.split(",") if s]
    abl_seeds = ([0] if a.ablation_seeds else []) if a.quick else [int(s) for s in a.ablation_seeds.split(",") if s]
    conds = a.conditions.split(",")
    canvases = a.canvases.split(",")
    if "shared" not in canvases or any(c not in CANVASES for c in canvases):
        raise SystemExit(f"--canvases: 'shared' (it holds the resize baseline) and any of {', '.join(CANVASES)}")
    return Runs(seeds, loo_seeds, abl_seeds, conds, canvases)


def run_study1(a: argparse.Namespace, r: Runs) -> None:
    """Study 1: trained on CamVid, in each rectangle rule ('canvas'). The shared rectangle's study
    (WORKDIR/seed<k>) runs every condition, resize included; another canvas's (WORKDIR/<canvas>/seed<k>)
    only the virtual-camera conditions (resize reads the frames as they are: no rectangle touches it)."""
    seeds, conds, canvases, cell, minutes = r.seeds, r.conds, r.canvases, r.cell, r.minutes
    found, estimated = {}, {}
    for canvas in canvases:
        study = study_file(a.workdir, a.quick, a.epochs, canvas, a.model)
        wd = a.workdir if canvas == "shared" else a.workdir / canvas
        cc = conds if canvas == "shared" else [k for k in conds if k != "resize"]
        for seed in seeds:
            share_stores(wd, seed, seeds[0])
            rows, info = run_study(study, wd / f"seed{seed}", cc, seed, a.threads)
            trained: dict[str, float] = {}
            for row in rows:
                k = row["condition"]
                cell.setdefault((row["heldout"], f"{k}@{canvas}"), []).append(100 * row["iou"])
                if canvas == DEFAULT_CANVAS or k == "resize":
                    cell.setdefault((row["heldout"], k), []).append(100 * row["iou"])
                trained[k] = row["train_seconds"] / 60  # one model per condition: every row repeats it
            minutes += trained.values()
            found, estimated = info.get("ego_found") or found, info.get("cameras_estimated") or estimated
    r.found, r.estimated = found, estimated


def run_loo(a: argparse.Namespace, r: Runs) -> None:
    """Study 2: leave one real dataset out."""
    loo_seeds, conds, loo, loo_minutes = r.loo_seeds, r.conds, r.loo, r.loo_minutes
    if loo_seeds:
        loo_study = loo_study_file(a.workdir, a.quick, a.epochs)
        for seed in loo_seeds:
            share_stores(a.workdir / "loo", seed, loo_seeds[0])
            rows, _ = run_study(loo_study, a.workdir / "loo" / f"seed{seed}", conds, seed, a.threads)
            for row in rows:
                loo.setdefault((row["heldout"], row["condition"]), []).append(100 * row["iou"])
                loo_minutes.append(row["train_seconds"] / 60)  # one model per fold and condition


def run_ablation(a: argparse.Namespace, r: Runs) -> None:
    """The ablation: study 1 without geometric augmentation (stores shared with the default rectangle's)."""
    seeds, abl_seeds, conds, abl = r.seeds, r.abl_seeds, r.conds, r.abl
    if abl_seeds:
        abl_study = ablation_study_file(a.workdir, a.quick, a.epochs, a.model)
        for seed in abl_seeds:
            out = a.workdir / "noaug" / f"seed{seed}"
            link_stores(out, a.workdir / DEFAULT_CANVAS / f"seed{seeds[0]}")  # the default rectangle's stores
            rows, _ = run_study(abl_study, out, conds, seed, a.threads)
            for row in rows:
                abl.setdefault((row["heldout"], row["condition"]), []).append(100 * row["iou"])


def write_results(a: argparse.Namespace, r: Runs, head: dict, targets: dict, table: str) -> None:
    """as_shipped.{md,png,json} in benchmarks/other_cameras/results (a smoke run: WORKDIR/results)."""
    seeds, loo_seeds, abl_seeds, conds, canvases = r.seeds, r.loo_seeds, r.abl_seeds, r.conds, r.canvases
    cell, loo, abl, c = r.cell, r.loo, r.abl, r.c
    found, estimated = r.found, r.estimated
    others = r.others()
    res_dir = (a.workdir / "results") if a.quick or a.model else results_dir(__file__)
    res_dir.mkdir(parents=True, exist_ok=True)
    (res_dir / "as_shipped.md").write_text(table)
    groups = ["camvid-val", "camvid-0001TP"] + REAL_OTHER
    bars = [k for k in conds if k != "resize"] + others + [k for k in conds if k == "resize"]
    label = {k: (f"{k} ({DEFAULT_CANVAS})" if k != "resize" else k) for k in conds}
    label.update({k: k.replace("@", " (") + ")" for k in others})
    have = {(g, label[k]): stat(c(g, k)) for g in groups for k in bars if c(g, k)}
    cv2.imwrite(str(res_dir / "as_shipped.png"), bar_plot(
        {gk: v["mean"] / 100 for gk, v in have.items()}, groups, [label[k] for k in bars],
        f"road IoU (%), trained on CamVid, tested in each camera (mean +/- std over {len(seeds)} seeds)",
        {gk: (v["std"] or 0.0) / 100 for gk, v in have.items()}))
    (res_dir / "as_shipped.json").write_text(json.dumps(
        {"headline": head, "targets": targets, "cells": {f"{t}|{k}": v for (t, k), v in cell.items()},
         "loo_cells": {f"{t}|{k}": v for (t, k), v in loo.items()}, "ego_found": found,
         "ablation_cells": {f"{t}|{k}": v for (t, k), v in abl.items()}, "ablation_seeds": abl_seeds,
         "cameras_estimated": estimated, "seeds": seeds, "loo_seeds": loo_seeds, "conditions": conds,
         "canvases": canvases, "model": a.model,
         "loo_steps_per_epoch": camvid_steps_per_epoch(), "epochs": a.epochs, "threads": a.threads,
         "machine": machine(), "date": today(),
         "command": "benchmarks/other_cameras/as_shipped.py " + " ".join(f"--{k} {v}" for k, v in
                                                            (("seeds", a.seeds), ("loo-seeds", a.loo_seeds),
                                                             *((("ablation-seeds", a.ablation_seeds),)
                                                               if a.ablation_seeds else ()),
                                                             ("conditions", a.conditions),
                                                             ("canvases", a.canvases),
                                                             *((("model", a.model),) if a.model else ())))},
        indent=1))


def main() -> None:
    a = parse_args()
    r = plan(a)
    a.workdir.mkdir(parents=True, exist_ok=True)
    run_study1(a, r)
    run_loo(a, r)
    run_ablation(a, r)
    head = headline_studies(r)
    headline_more(r, head)
    targets = targets_met(head)
    table = tables(r, head, targets)
    print(table)
    write_results(a, r, head, targets, table)
    print(json.dumps(head))


if __name__ == "__main__":
    main()
