"""How exact a camera file must be (issue 73 item 2): calibrated real frames predicted by the README route's
virtual-camera model with camera files wrong by known amounts, against its resize twin on the same frames.

    .venv/bin/python benchmarks/archive/other_cameras/camera_error.py [--seeds 0,1,2] [--sets kitti_semantics,cityscapes]
                                                              [--workdir benchmarks/out/user_route] [--quick]

The models are the README route's (benchmarks/what_a_user_gets/user_route.py: CamVid train minus 0001TP,
``vcprep warp --camera camvid`` + ``vctrain fit``, the virtual camera and ``--baseline resize``; trained there,
or here when missing, into WORKDIR/seed<k>/{vc,resize}.pt). The test frames are calibrated cameras the models
never saw: ``kitti_semantics`` (98 frames, the rectified KITTI camera, published height) and Cityscapes
(400 frames, scaled calibration). Each camera file is changed by one known error at a time: focal length
x0.6 .. x1.5 (fx and fy together), height x0.5 .. x2, tilt (pitch) and pan +-2 / +-5 deg; and roll 2 deg, which
a camera file cannot state: the frames and labels are rotated by 2 deg about the principal point (an exact
homography K R K^-1 for any scene; pixels rotated in from outside the frame are ignore), the file left level.
``vctrain predict MODEL --camera WRONG.yaml`` as a user types it (its default pose rule: each frame's own road
vanishing point), ``vctrain eval`` scores road IoU. The resize twin reads no camera: its IoU on the same frames
is the baseline every row is set against (for roll, on the same rotated frames).

Outputs: benchmarks/other_cameras/results/camera_error.{md,json}; the last stdout line is the JSON summary
(``within_minus_resize_<set>_<error>`` per set and error, mean over seeds; and whether the issue's target
holds: ``within`` above ``resize`` for focal +-20 %, height +-30 %, pitch +-2 deg).
"""
from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import BIN, CS_FORMAT, ROOT, SHARED_DATA, require_data, run
from benchmarks.measure.report import machine, results_dir, today, write_json

SETS = {  # name: (camera file, images, labels, label format)
    "kitti_semantics": (SHARED_DATA / "kitti_semantics" / "camera.yaml", SHARED_DATA / "kitti_semantics" / "images",
                        SHARED_DATA / "kitti_semantics" / "labels", "values:road=1;ignore=255;max=255"),
    "cityscapes": (SHARED_DATA / "cityscapes_pix2pix" / "camera.yaml", SHARED_DATA / "cityscapes_pix2pix" / "images",
                   SHARED_DATA / "cityscapes_pix2pix" / "labels", CS_FORMAT),
}
# error name -> (field, how): "scale" multiplies, "add" adds degrees
ERRORS = {"exact": (None, None, 0.0),
          **{f"focal x{s:g}": ("focal", "scale", s) for s in (0.6, 0.8, 0.9, 1.1, 1.2, 1.5)},
          **{f"height x{s:g}": ("height", "scale", s) for s in (0.5, 0.7, 1.3, 2.0)},
          **{f"tilt {d:+g}": ("tilt", "add", d) for d in (-5.0, -2.0, 2.0, 5.0)},
          **{f"pan {d:+g}": ("pan", "add", d) for d in (-5.0, 5.0)},
          "roll 2": ("roll", None, 2.0)}
# the target: within above resize for these errors
TARGET = ["focal x0.8", "focal x1.2", "height x0.7", "height x1.3", "tilt -2", "tilt +2"]


def wrong_camera(cam_file: Path, error: str, dst: Path) -> Path:
    """dst: ``cam_file`` with one known error (roll: the file as it is; the frames carry the roll)."""
    from vcprep.camera import camera_to_yaml, read_camera_yaml

    cam = read_camera_yaml(cam_file)
    field, how, v = ERRORS[error]
    if field == "focal":
        cam = replace(cam, fx=cam.fx * v, fy=cam.fy * v)
    elif field == "height":
        cam = replace(cam, height=cam.height * v)
    elif field in ("tilt", "pan"):
        cam = replace(cam, **{field: getattr(cam, field) + v})
    dst.parent.mkdir(parents=True, exist_ok=True)
    dst.write_text(camera_to_yaml(cam))
    return dst


def rolled_frames(name: str, degrees: float, dst: Path, quick: bool) -> tuple[Path, Path]:
    """dst/{images,labels}: the set's frames and labels rotated by ``degrees`` about the principal point
    (the camera rolled; exact for any scene): bilinear images, nearest labels, 255 where nothing came in."""
    from vcprep.camera import read_camera_yaml

    cam_file, images, labels, _ = SETS[name]
    cam = read_camera_yaml(cam_file)
    out_i, out_l = dst / "images", dst / "labels"
    if (dst / "done").exists():
        return out_i, out_l
    out_i.mkdir(parents=True, exist_ok=True)
    out_l.mkdir(parents=True, exist_ok=True)
    a = np.deg2rad(degrees)
    R = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])  # about the optical axis
    H = cam.K @ R @ np.linalg.inv(cam.K)  # new pixel <- old pixel
    for img in frames(images, quick):
        lab = labels / (img.stem + ".png")
        im, lb = cv2.imread(str(img)), cv2.imread(str(lab), cv2.IMREAD_UNCHANGED)
        size = (im.shape[1], im.shape[0])
        cv2.imwrite(str(out_i / (img.stem + ".png")), cv2.warpPerspective(im, H, size, flags=cv2.INTER_LINEAR))
        cv2.imwrite(str(out_l / lab.name), cv2.warpPerspective(lb, H, size, flags=cv2.INTER_NEAREST,
                                                               borderValue=255))
    (dst / "done").touch()
    return out_i, out_l


def frames(images: Path, quick: bool) -> list[Path]:
    """The set's frames (a smoke run: the first 6)."""
    got = sorted(p for p in images.iterdir() if p.suffix.lower() in (".png", ".jpg", ".jpeg"))
    return got[:6] if quick else got


def quick_links(images: Path, dst: Path, quick: bool) -> Path:
    """The images to predict: the folder itself, or links to its first 6 frames (a smoke run)."""
    if not quick:
        return images
    dst.mkdir(parents=True, exist_ok=True)
    for f in frames(images, True):
        if not (dst / f.name).exists():
            (dst / f.name).symlink_to(f.resolve())
    return dst


def iou(model: Path, cam: Path, images: Path, labels: Path, fmt: str, out: Path) -> float:
    """``vctrain predict`` + ``vctrain eval``: road IoU % (cached in out/eval.json)."""
    if not (out / "eval.json").exists():
        run(BIN / "vctrain", "predict", model, "--camera", cam, images, "--out", out, "-q")
        (out / "eval.json").write_text(run(BIN / "vctrain", "eval", out, "--labels", labels, "--label-format", fmt,
                                           "--json", "-q"))
    return 100.0 * float(json.loads((out / "eval.json").read_text())["iou"])


def ensure_models(wd: Path, seed: int) -> Path:
    """WORKDIR/seed<k>/{vc,resize}.pt, trained by user_route.py's commands when missing."""
    sd = wd / f"seed{seed}"
    if not ((sd / "vc.pt").exists() and (sd / "resize.pt").exists()):
        from benchmarks.what_a_user_gets.user_route import my_frames

        images, labels = my_frames(wd, False)
        store = wd / "stores" / "mine"
        run(BIN / "vcprep", "warp", "--camera", "camvid", "--images", images, "--labels", labels, "--label-format",
            "camvid", "--out", store, "-q")
        for m in ("vc", "resize"):
            if not (sd / f"{m}.pt").exists():
                run(BIN / "vctrain", "fit", store, *(["--baseline", "resize"] if m == "resize" else []),
                    "--out", sd / f"{m}.pt", *(["--seed", seed] if seed else []), "-q")
    return sd


def measure(wd: Path, seeds: list[int], sets: list[str], quick: bool) -> dict:
    """{set: {error: {"within": [per seed], "resize": [per seed]}}}."""
    cells: dict = {n: {e: {"within": [], "resize": []} for e in ERRORS} for n in sets}
    for seed in seeds:
        sd = ensure_models(wd, seed)
        for n in sets:
            cam_file, images, labels, fmt = SETS[n]
            ev = wd / "camera_error" / ("quick" if quick else "full") / n
            plain = quick_links(images, ev / "frames", quick)
            base = iou(sd / "resize.pt", cam_file, plain, labels, fmt, ev / f"seed{seed}" / "resize")
            for e, (field, _, v) in ERRORS.items():
                imgs, labs = (rolled_frames(n, v, ev / "rolled", quick) if field == "roll" else (plain, labels))
                cam = wrong_camera(cam_file, e, ev / "cameras" / f"{e.replace(' ', '_')}.yaml")
                within = iou(sd / "vc.pt", cam, imgs, labs, fmt, ev / f"seed{seed}" / "vc" / e.replace(" ", "_"))
                resize = base if field != "roll" else iou(sd / "resize.pt", cam, imgs, labs, fmt,
                                                          ev / f"seed{seed}" / "resize-roll")
                cells[n][e]["within"].append(within)
                cells[n][e]["resize"].append(resize)
                print(f"seed {seed} {n} {e}: within {within:.1f} resize {resize:.1f}", flush=True)
    return cells


def report(a: argparse.Namespace, cells: dict, seeds: list[int]) -> dict:
    """The table (rows: errors; per set within, resize, within - resize as mean +- std over seeds) and
    the JSON summary."""
    sets = list(cells)
    rows = ["| camera file error | " + " | ".join(f"{n}: within | resize | within − resize" for n in sets) + " |",
            "|---|" + "---|---|---|" * len(sets)]
    head: dict = {}
    for e in ERRORS:
        cols = []
        for n in sets:
            w, r = np.array(cells[n][e]["within"]), np.array(cells[n][e]["resize"])
            d = w - r
            sd = f" ± {d.std(ddof=1):.1f}" if len(d) > 1 else ""
            cols.append(f"{w.mean():.1f} | {r.mean():.1f} | {d.mean():+.1f}{sd}")
            head[f"within_minus_resize_{n}_{e.replace(' ', '_')}"] = round(float(d.mean()), 2)
        rows.append(f"| {e} | " + " | ".join(cols) + " |")
    held = {n: all(head[f"within_minus_resize_{n}_{e.replace(' ', '_')}"] > 0 for e in TARGET) for n in sets}
    head["target_within_above_resize_focal20_height30_pitch2"] = held
    table = "\n".join(rows)
    cmd = f"benchmarks/archive/other_cameras/camera_error.py --seeds {a.seeds} --sets {','.join(sets)}" + (" --quick" if a.quick else "")
    out = results_dir(__file__) if not a.quick else a.workdir / "camera_error" / "results"
    write_json(out / "camera_error.json", {"headline": head, "cells": cells, "seeds": seeds, "errors": list(ERRORS),
                                           "target_errors": TARGET, "machine": machine(), "date": today(),
                                           "command": cmd})
    (out / "camera_error.md").write_text(
        f"# How exact a camera file must be (benchmarks/archive/other_cameras/camera_error.py)\n\n{today()}, {machine()}; "
        f"`{cmd}`\n\nRoad IoU %, mean over seeds {a.seeds} (± std of the difference). Models: the README route "
        f"(CamVid train minus 0001TP), the virtual camera (`within`) and its resize twin.\n\n{table}\n")
    print(table)
    return head


def run_main(doc: str, sets_table: dict, measure_fn, report_fn) -> None:
    """The command line both route benchmarks share (this one and bev_worth.py): --seeds, --sets, --workdir,
    --quick; ``measure_fn(workdir, seeds, sets, quick)`` -> cells, ``report_fn(args, cells, seeds)`` -> the
    JSON summary, printed as the last line."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--sets", default=",".join(sets_table))
    ap.add_argument("--workdir", type=Path, default=ROOT / "benchmarks" / "out" / "user_route")
    ap.add_argument("--quick", action="store_true", help="6 frames a set (the models must exist)")
    a = ap.parse_args()
    sets = [s for s in a.sets.split(",") if s]
    require_data(*(sets_table[s][1] for s in sets))
    seeds = [int(s) for s in a.seeds.split(",") if s.strip()]
    cells = measure_fn(a.workdir, seeds, sets, a.quick)
    print(json.dumps(report_fn(a, cells, seeds)))


def main() -> None:
    run_main(__doc__, SETS, measure, report)


if __name__ == "__main__":
    main()
