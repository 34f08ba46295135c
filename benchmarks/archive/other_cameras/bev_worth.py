"""The geometry's worth per square metre (issue 71 item 4): the README route's virtual-camera model, its resize
twin and the shipped model, scored in the bird's-eye view of the road (BEV) on every calibrated real camera,
beside the perspective scores of the same masks.

    .venv/bin/python benchmarks/archive/other_cameras/bev_worth.py [--seeds 0,1,2] [--sets camvid_val,cityscapes,...]
                                                           [--workdir benchmarks/out/user_route] [--quick]

Models: the README route's (benchmarks/what_a_user_gets/user_route.py: CamVid train minus 0001TP, ``vcprep warp
--camera camvid`` + ``vctrain fit``, the virtual camera ``vc`` and ``--baseline resize``; WORKDIR/seed<k>/, trained
when missing) and the shipped model (models/road-multicamera, a resize model trained on five datasets, CamVid
train and Cityscapes among them: on those two its frames are held-out splits, not other cameras). Sets, every
calibrated camera of ../shared/data: CamVid val (101, the camvid preset), Cityscapes (400, scaled calibration),
kitti_semantics (98, the rectified KITTI camera) and the KITTI road frame (its own calibration file with
``Tr_cam_to_road``: the devkit's transform). Each model predicts each set as a user types it (``vctrain predict
MODEL --camera CAM``), and ``vctrain eval --bev --camera CAM`` scores the same probability maps and masks twice:
in the frame's pixels and on the KITTI benchmark's grid (x -10..10 m, z 6..46 m ahead, 0.05 m cells; cells the
camera does not see left out; the camera's calibrated/nominal pose for labels and predictions alike). Reported:
road IoU and MaxF in both spaces, and ``vc - resize`` per seed, mean +- std.

Outputs: benchmarks/other_cameras/results/bev_worth.{md,json}; the last stdout line is the JSON summary.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import BIN, DATA, KITTI, ROOT, run
from benchmarks.measure.report import machine, results_dir, today, write_json
from benchmarks.archive.other_cameras.camera_error import SETS as CALIBRATED, ensure_models, quick_links, run_main

SETS = {  # name: (camera, images, labels, label format)
    "camvid_val": ("camvid", DATA / "val", DATA / "valannot", "camvid"),
    **CALIBRATED,
    "kitti_frame": (KITTI / "calib", KITTI / "image_2", KITTI / "gt_image_2", "kitti"),
}
SHIPPED = ROOT / "models" / "road-multicamera" / "road.pt"
METRICS = ("iou", "maxf")


def scores(model: Path, cam, images: Path, labels: Path, fmt: str, out: Path) -> dict:
    """``vctrain predict`` then ``vctrain eval --bev``: {"px": {iou, maxf}, "bev": {iou, maxf}} in % (cached)."""
    done = out / "eval_bev.json"
    if not done.exists():
        run(BIN / "vctrain", "predict", model, "--camera", cam, images, "--out", out, "-q")
        done.write_text(run(BIN / "vctrain", "eval", out, "--labels", labels, "--label-format", fmt, "--bev",
                            "--camera", cam, "--json", "-q"))
    d = json.loads(done.read_text())
    return {"px": {m: 100.0 * d[m] for m in METRICS}, "bev": {m: 100.0 * d["bev"][m] for m in METRICS}}


def measure(wd: Path, seeds: list[int], sets: list[str], quick: bool) -> dict:
    """{set: {model: [per seed {"px": .., "bev": ..}]}}; the shipped model once (it has no seeds here)."""
    ev = wd / "bev_worth" / ("quick" if quick else "full")
    cells: dict = {n: {"vc": [], "resize": [], "shipped": []} for n in sets}
    for n in sets:
        cam, images, labels, fmt = SETS[n]
        imgs = quick_links(images, ev / "frames" / n, quick and n != "kitti_frame")
        cells[n]["shipped"].append(scores(SHIPPED, cam, imgs, labels, fmt, ev / "shipped" / n))
        for seed in seeds:
            sd = ensure_models(wd, seed)
            for m in ("vc", "resize"):
                cells[n][m].append(scores(sd / f"{m}.pt", cam, imgs, labels, fmt, ev / f"seed{seed}" / m / n))
                print(f"seed {seed} {n} {m}: {cells[n][m][-1]}", flush=True)
    return cells


def _ms(v: list[float], signed: bool = False) -> str:
    a = np.array(v)
    s = f"{a.mean():+.1f}" if signed else f"{a.mean():.1f}"
    return s + (f" ± {a.std(ddof=1):.1f}" if len(a) > 1 else "")


def report(a: argparse.Namespace, cells: dict, seeds: list[int]) -> dict:
    """Rows: sets; per space (pixels, BEV) and metric: vc, resize, shipped, vc - resize (mean +- std)."""
    head: dict = {}
    rows = ["| set | space | metric | README route: virtual camera | its resize twin | vc − resize | shipped model |",
            "|---|---|---|---|---|---|---|"]
    for n, c in cells.items():
        for space in ("px", "bev"):
            for m in METRICS:
                vc, rs = [x[space][m] for x in c["vc"]], [x[space][m] for x in c["resize"]]
                diff = [v - r for v, r in zip(vc, rs)]
                sh = c["shipped"][0][space][m]
                rows.append(f"| {n} | {'pixels' if space == 'px' else 'BEV (m²)'} | {m} | {_ms(vc)} | {_ms(rs)} | "
                            f"**{_ms(diff, True)}** | {sh:.1f} |")
                key = f"{n}_{space}_{m}"
                head.update({f"vc_{key}": round(float(np.mean(vc)), 2), f"resize_{key}": round(float(np.mean(rs)), 2),
                             f"vc_minus_resize_{key}": round(float(np.mean(diff)), 2), f"shipped_{key}": round(sh, 2)})
    for space in ("px", "bev"):
        d = [head[f"vc_minus_resize_{n}_{space}_iou"] for n in cells]
        head[f"vc_minus_resize_mean_{space}_iou"] = round(float(np.mean(d)), 2)
    table = "\n".join(rows)
    cmd = f"benchmarks/archive/other_cameras/bev_worth.py --seeds {a.seeds} --sets {','.join(cells)}" + (" --quick" if a.quick else "")
    out = results_dir(__file__) if not a.quick else a.workdir / "bev_worth" / "results"
    write_json(out / "bev_worth.json", {"headline": head, "cells": cells, "seeds": seeds, "sets": list(cells),
                                        "machine": machine(), "date": today(), "command": cmd})
    (out / "bev_worth.md").write_text(
        f"# The geometry's worth per square metre (benchmarks/archive/other_cameras/bev_worth.py)\n\n{today()}, {machine()}; "
        f"`{cmd}`\n\nRoad IoU and MaxF %, in the frame's pixels and on the KITTI road benchmark's BEV grid "
        f"(x -10..10 m, z 6..46 m, 0.05 m cells), mean ± std over seeds {a.seeds}; the shipped model once.\n\n"
        f"{table}\n")
    print(table)
    return head


def main() -> None:
    run_main(__doc__, SETS, measure, report)


if __name__ == "__main__":
    main()
