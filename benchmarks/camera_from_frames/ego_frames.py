"""The own vehicle from frames alone against the label method, on the real sets (issue 35).

    .venv/bin/python benchmarks/camera_from_frames/ego_frames.py

Per set, in the same run: ``ego_rows`` from the labels (:func:`vcprep.camera.ego.ego_rows_from_label_files`)
and from the frames without their labels (:func:`vcprep.camera.ego.ego_rows_from_frame_files`), both at the
frames' own size, and the difference. Also the frame method on windows of consecutive frames
(a few dozen each), to show it does not need the whole drive. Threads: cv2.setNumThreads(1).

Sets: CamVid 0001TP (train; an own vehicle, labels 36 of 360), CamVid val 0016E5 and train
0006R0 / 0016E5 (no vehicle), Cityscapes pix2pix (400 frames, one rig: a mirror-like bonnet and the
star), IDD-Lite (every 20th frame of the train split, many drives pooled: no vehicle), LUMS (no
vehicle; its labels have no ignore class), BDD100K's one dashcam with 8 frames (0a0c3694; a bonnet
labelled background, so the labels cannot say; run with ``min_distinct=8``, below the method's
minimum of 20, and hand-read as about 40 of 270 working rows = 107 of 720).
Writes benchmarks/camera_from_frames/results/ego_frames.json; prints the table, then one JSON line last.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import cv2

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import SHARED_DATA
from benchmarks.measure.report import machine, results_dir, today, write_json
from vcprep.camera import MIN_DISTINCT, ego_rows_from_frame_files, ego_rows_from_label_files
from vcprep.errors import InputError
from vcprep.labels import get_label_format, label_stem_for

DATA = SHARED_DATA
WINDOW = 30   # consecutive frames per window


def _camvid(split, seq):
    imgs = sorted((DATA / "camvid" / split).glob(f"{seq}_*.png"))
    return imgs, [DATA / "camvid" / f"{split}annot" / p.name for p in imgs], "camvid"


def _paired(img_dir, lab_dir, fmt_name, pattern="*.jpg", step=1):
    fmt = get_label_format(fmt_name)
    imgs = sorted(Path(img_dir).rglob(pattern))[::step]
    labs = []
    for p in imgs:
        rel = p.relative_to(img_dir).parent
        labs.append(next((Path(lab_dir) / rel).glob(label_stem_for(p, fmt) + ".*")))
    return imgs, labs, fmt_name


SETS = {   # name: (images, labels, label format); min_distinct
    "camvid_0001TP": (lambda: _camvid("train", "0001TP"), MIN_DISTINCT),
    "camvid_val_0016E5": (lambda: _camvid("val", "0016E5"), MIN_DISTINCT),
    "camvid_0006R0": (lambda: _camvid("train", "0006R0"), MIN_DISTINCT),
    "camvid_0016E5": (lambda: _camvid("train", "0016E5"), MIN_DISTINCT),
    "cityscapes": (lambda: _paired(DATA / "cityscapes_pix2pix/images", DATA / "cityscapes_pix2pix/labels",
                                   "values:road=1;ignore=255;max=255"), MIN_DISTINCT),
    "idd_lite": (lambda: _paired(DATA / "idd_lite/leftImg8bit/train", DATA / "idd_lite/gtFine/train", "idd",
                                 step=20), MIN_DISTINCT),
    "lums": (lambda: _paired(DATA / "lums_road/images", DATA / "lums_road/labels", "values:road=2;max=4"),
             MIN_DISTINCT),
    "bdd100k_0a0c3694": (lambda: _paired(DATA / "bdd100k_drivable/images", DATA / "bdd100k_drivable/labels", "bdd",
                                         pattern="0a0c3694*.jpg"), 8),
}


def _frames(files, min_distinct):
    try:
        return ego_rows_from_frame_files(files, min_distinct=min_distinct).rows
    except InputError:
        return None   # too few distinct frames: refused


def main() -> None:
    argparse.ArgumentParser(description=__doc__.split("\n")[0]).parse_args()  # no options; --help
    cv2.setNumThreads(1)
    rows, t0 = [], time.time()
    for name, (get, min_distinct) in SETS.items():
        imgs, labs, fmt = get()
        t = time.time()
        est = ego_rows_from_frame_files(imgs, min_distinct=min_distinct)
        sec = time.time() - t
        try:
            label_rows = ego_rows_from_label_files(labs, get_label_format(fmt)).rows
        except InputError as e:
            label_rows, _ = None, e
        windows = [_frames(imgs[i:i + WINDOW], min_distinct) for i in range(0, len(imgs) - WINDOW + 1, WINDOW)]
        rows.append({"set": name, "frames": len(imgs), "distinct": est.frames, "size": list(est.size),
                     "label_rows": label_rows, "frame_rows": est.rows, "span": round(est.bottom_share, 3),
                     "error": None if label_rows is None else est.rows - label_rows,
                     "windows": windows, "seconds": round(sec, 2)})
        print(f"{name}: {est.rows}", file=sys.stderr)
    head = "| set | frames (distinct) | size | label rows | frame rows | error | frame rows per 30-frame window |"
    print(head + "\n|---|---|---|---|---|---|---|")
    for r in rows:
        win = ", ".join("refused" if w is None else str(w) for w in r["windows"]) or "-"
        print(f"| {r['set']} | {r['frames']} ({r['distinct']}) | {r['size'][0]}x{r['size'][1]} | {r['label_rows']} | "
              f"{r['frame_rows']} | {r['error'] if r['error'] is not None else '-'} | {win} |")
    by = {r["set"]: r for r in rows}
    headline = {"camvid_0001TP_rows": by["camvid_0001TP"]["frame_rows"],
                "camvid_0001TP_label_rows": by["camvid_0001TP"]["label_rows"],
                "camvid_val_rows": by["camvid_val_0016E5"]["frame_rows"],
                "camvid_0006R0_rows": by["camvid_0006R0"]["frame_rows"],
                "cityscapes_rows": by["cityscapes"]["frame_rows"],
                "cityscapes_label_rows": by["cityscapes"]["label_rows"],
                "idd_lite_rows": by["idd_lite"]["frame_rows"], "lums_rows": by["lums"]["frame_rows"],
                "bdd100k_0a0c3694_rows": by["bdd100k_0a0c3694"]["frame_rows"]}
    out = {"headline": headline, "date": today(), "command": "benchmarks/camera_from_frames/ego_frames.py",
           "machine": machine(), "cpu_threads": 1,
           "seconds": round(time.time() - t0, 1), "sets": rows}
    write_json(results_dir(__file__) / "ego_frames.json", out)
    print(json.dumps(headline))


if __name__ == "__main__":
    main()
