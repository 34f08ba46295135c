"""Real cameras as they ship: the own vehicle found from the labels, cameras estimated from their
frames (issues 24.2 and 25).

    .venv/bin/python benchmarks/as_shipped.py [--seeds 0,1,2] [--conditions within,resize] [--epochs N]
                                              [--workdir benchmarks/out/as_shipped] [--threads 2] [--quick]

One ``vctrain crossval`` study per seed (``--seed k``, into WORKDIR/seed<k>/; an interrupted run
resumes). Per condition ONE model is trained on CamVid train minus sequence 0001TP (0016E5 + 0006R0,
no own vehicle in view) with crossval's defaults (nothing set but ``--epochs`` when given) and
scored, in each test set's own camera, on:

* ``cityscapes`` / ``cityscapes-noego``: the 400 Cityscapes frames of ../shared/data/cityscapes_pix2pix
  (its camera.yaml; the bonnet and the star at the bottom of every frame, labelled void), with
  ``ego: auto`` (the study's default: the own vehicle found from the labels' common ignore region,
  :mod:`vcprep.ego`) and with ``ego: none`` (what a user got before: the bonnet warped as road surface);
* ``camvid-0001TP`` / ``camvid-0001TP-noego``: CamVid's sequence 0001TP (62 frames, never trained on;
  its bonnet rises to 36 rows at the right), the same two ways;
* ``camvid-val`` (101 frames, no own vehicle): the search must find none, so nothing changes there;
* ``cityscapes-est``: the same Cityscapes frames with ``camera: estimate`` (horizon, tilt, pan from
  the frames' road VPs, the own vehicle from the labels; focal length and height ASSUMED, the pixel
  aspect square: nothing is given) -- against ``cityscapes`` (the scaled Cityscapes calibration);
* ``idd`` / ``idd-est``: the 1,403 IDD-Lite frames (309 drives, label format idd) with the dataset's
  own assumed camera.yaml (90 deg FOV, squashed pixels, tilt 0) and with ``camera: estimate``.

The resize baseline reads the frames as they are (it has no geometry, so ``ego`` does not touch
it); its rows of a pair are the same model on the same pixels and are reported once.
Reported: road IoU per test set and condition (mean +/- sample std over seeds), the paired gain
auto - none per camera and seed, within - resize with the vehicle found, and the rows found
(``study.json``'s ``ego_found``). The last stdout line is one JSON object: ``ego_gain_<camera>``
(within, mean over seeds), ``within_minus_resize_<camera>`` (with ego: auto), ``ego_rows_found``,
``estimated_minus_given_<camera>`` and ``within_estimated_minus_resize_<camera>`` (cityscapes, idd),
``in_domain_within`` (camvid-val) and ``minutes_per_model``.
Outputs: benchmarks/results/as_shipped.{md,json}. Nothing is tuned on a test set: the detection
has no parameter fitted to these frames (its constants are in vcprep/ego.py), the checkpoint is
chosen on the training frames' validation share.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np
import yaml

from measure import BIN, DATA, ROOT, SHARED_DATA, native_camera, run

CITYSCAPES = SHARED_DATA / "cityscapes_pix2pix"
CS_FORMAT = "values:road=1;ignore=255;max=255"
IDD = SHARED_DATA / "idd_lite"
CAMERAS = ["cityscapes", "camvid-0001TP"]     # real cameras that show their own vehicle
ESTIMATED = ["cityscapes", "idd"]             # real cameras also estimated from their frames
TESTS = [c + s for c in CAMERAS for s in ("", "-noego")] + ["camvid-val", "cityscapes-est", "idd", "idd-est"]


def study_file(wd: Path, quick: bool, epochs: int | None) -> Path:
    cam = native_camera(wd)
    d = lambda name, camera, fmt, split, **kw: {"name": name, "role": "test", "camera": str(camera),
                                                 "label_format": fmt, "test": split, **kw}
    tp = {"images": str(DATA / "train"), "labels": str(DATA / "trainannot"), "include": "0001TP_*"}
    cs = {"images": str(CITYSCAPES / "images"), "labels": str(CITYSCAPES / "labels")}
    val = {"images": str(DATA / "val"), "labels": str(DATA / "valannot")}
    idd = {"images": str(IDD / "leftImg8bit" / "train"), "labels": str(IDD / "gtFine" / "train")}
    if quick:  # a smoke run: a few frames of each (>= 5 labelled frames, what the search needs)
        cs["images"], cs["labels"] = _subset(wd / "cs", 6)
        val["include"] = "0016E5_079*"
        idd["include"] = "1[0-9]_*"
    datasets = [
        {"name": "camvid", "role": "train", "camera": str(cam), "label_format": "camvid",
         "train": {"images": str(DATA / "train"), "labels": str(DATA / "trainannot"),
                   "exclude": "0001TP_*" if not quick else ["0001TP_*", "0006R0_*", "0016E5_0[0-6]*"]}},
        d("cityscapes", CITYSCAPES / "camera.yaml", CS_FORMAT, cs),
        d("cityscapes-noego", CITYSCAPES / "camera.yaml", CS_FORMAT, cs, ego="none"),
        d("camvid-0001TP", cam, "camvid", tp),
        d("camvid-0001TP-noego", cam, "camvid", tp, ego="none"),
        d("camvid-val", cam, "camvid", val),
        d("cityscapes-est", "estimate", CS_FORMAT, cs),
        d("idd", IDD / "camera.yaml", "idd", idd),
        d("idd-est", "estimate", "idd", idd),
    ]
    train = {"epochs": 1, "max_steps": 2} if quick else ({"epochs": epochs} if epochs else {})
    study = {"datasets": datasets, **({"train": train} if train else {})}
    path = wd / "study.yaml"
    path.write_text(yaml.safe_dump(study, sort_keys=False))
    return path


def _subset(dst: Path, n: int) -> tuple[str, str]:
    for sub in ("images", "labels"):
        (dst / sub).mkdir(parents=True, exist_ok=True)
        for f in sorted((CITYSCAPES / sub).iterdir())[:n]:
            if not (dst / sub / f.name).exists():
                (dst / sub / f.name).symlink_to(f)
    return str(dst / "images"), str(dst / "labels")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--conditions", default="within,resize")
    ap.add_argument("--epochs", type=int, default=None)
    ap.add_argument("--workdir", type=Path, default=ROOT / "benchmarks" / "out" / "as_shipped")
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    if not CITYSCAPES.is_dir() or not DATA.is_dir() or not IDD.is_dir():
        raise SystemExit(f"needs {CITYSCAPES}, {IDD} and {DATA} (../shared/data); not found")
    seeds = [0] if a.quick else [int(s) for s in a.seeds.split(",")]
    conds = a.conditions.split(",")
    a.workdir.mkdir(parents=True, exist_ok=True)
    study = study_file(a.workdir, a.quick, a.epochs)
    env = {"OMP_NUM_THREADS": str(a.threads)}
    cell: dict[tuple[str, str], list[float]] = {}
    found: dict = {}
    minutes: list[float] = []
    for seed in seeds:
        out = a.workdir / f"seed{seed}"
        t0 = time.time()
        run(BIN / "vctrain", "crossval", study, "--out", out, "--conditions", ",".join(conds), "--seed", seed,
            "--jobs", a.threads, "--json", stream=True, env=env)
        trained: dict[str, float] = {}
        for line in (out / "results.jsonl").read_text().splitlines():
            r = json.loads(line)
            cell.setdefault((r["heldout"], r["condition"]), []).append(100 * r["iou"])
            trained[r["condition"]] = r["train_seconds"] / 60  # one model per condition: every row repeats it
        minutes += trained.values()
        found = json.loads((out / "study.json").read_text()).get("ego_found", {})
        print(f"seed {seed}: {time.time() - t0:.0f} s", flush=True)

    ms = lambda k: (float(np.mean(cell[k])), float(np.std(cell[k], ddof=1)) if len(cell[k]) > 1 else 0.0)
    lines = [f"Road IoU (%) of models trained on CamVid train minus 0001TP, {len(seeds)} seed(s) "
             f"(mean +/- std); own vehicle: ego auto (found from the labels) vs ego none.", "",
             "| test set | " + " | ".join(conds) + " |", "|---|" + "---|" * len(conds)]
    for t in TESTS:
        lines.append(f"| {t} | " + " | ".join("%.1f +/- %.1f" % ms((t, c)) if (t, c) in cell else "-"
                                            for c in conds) + " |")
    head: dict = {}
    lines += ["", "| camera | rows found | within: auto - none (per seed) | within - resize (auto) |", "|---|---|---|---|"]
    for cam in CAMERAS:
        gain = (list(np.subtract(cell[cam, "within"], cell[cam + "-noego", "within"]))
                if (cam, "within") in cell else [])
        wmr = (list(np.subtract(cell[cam, "within"], cell[cam, "resize"]))
               if (cam, "within") in cell and (cam, "resize") in cell else [])
        rows = found.get(cam, {}).get("ego_rows_at_camera_size")
        head[f"ego_gain_{cam}"] = round(float(np.mean(gain)), 2) if gain else None
        head[f"within_minus_resize_{cam}"] = round(float(np.mean(wmr)), 2) if wmr else None
        head.setdefault("ego_rows_found", {})[cam] = rows
        lines.append(f"| {cam} | {rows} | {', '.join(f'{g:+.1f}' for g in gain) or '-'} | "
                     f"{', '.join(f'{g:+.1f}' for g in wmr) or '-'} |")
    head["ego_rows_found"]["camvid-val"] = found.get("camvid-val", {}).get("ego_rows", None)
    lines += ["", "| camera | within: estimated - given camera (per seed) | resize | within (estimated) - resize |",
              "|---|---|---|---|"]
    for cam in ESTIMATED:
        est = cam + "-est"
        diff = (list(np.subtract(cell[est, "within"], cell[cam, "within"]))
                if (est, "within") in cell and (cam, "within") in cell else [])
        wmr = (list(np.subtract(cell[est, "within"], cell[cam, "resize"]))
               if (est, "within") in cell and (cam, "resize") in cell else [])
        head[f"estimated_minus_given_{cam}"] = round(float(np.mean(diff)), 2) if diff else None
        head[f"within_estimated_minus_resize_{cam}"] = round(float(np.mean(wmr)), 2) if wmr else None
        lines.append(f"| {cam} | {', '.join(f'{g:+.1f}' for g in diff) or '-'} | "
                     f"{'%.1f' % ms((cam, 'resize'))[0] if (cam, 'resize') in cell else '-'} | "
                     f"{', '.join(f'{g:+.1f}' for g in wmr) or '-'} |")
    head["in_domain_within"] = round(ms(("camvid-val", "within"))[0], 2) if ("camvid-val", "within") in cell else None
    head["minutes_per_model"] = round(float(np.nanmean(minutes)), 2) if minutes else None
    table = "\n".join(lines) + "\n"
    print(table)
    res_dir = (a.workdir / "results") if a.quick else (ROOT / "benchmarks" / "results")
    res_dir.mkdir(parents=True, exist_ok=True)
    estimated = json.loads((a.workdir / f"seed{seeds[-1]}" / "study.json").read_text()).get("cameras_estimated", {})
    (res_dir / "as_shipped.md").write_text(table)
    (res_dir / "as_shipped.json").write_text(json.dumps(
        {"headline": head, "cells": {f"{t}|{c}": v for (t, c), v in cell.items()}, "ego_found": found,
         "cameras_estimated": estimated,
         "seeds": seeds, "conditions": conds, "epochs": a.epochs, "threads": a.threads,
         "machine": f"{platform.machine()}, {os.cpu_count()} cores", "date": time.strftime("%Y-%m-%d"),
         "command": "benchmarks/as_shipped.py " + " ".join(f"--{k} {v}" for k, v in
                                                            (("seeds", a.seeds), ("conditions", a.conditions)))},
        indent=1))
    print(json.dumps(head))


if __name__ == "__main__":
    main()
