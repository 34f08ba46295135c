"""Per-image runtime of each stage, shaped like the paper's Table 3, with the paper's figures beside.

    .venv/bin/python benchmarks/archive/speed/stages.py [--frames 20] [--scale 0.125]

Data: ../shared/data/camvid/val (480x360, camvid preset) when present, else synthetic renders (and
says so). One thread for OpenCV and PyTorch; CPU. Stages (ms per image, median over frames):
  line detection     LSD segments (vcprep.vp.detect_segments)
  VP                 vanishing point from those segments (estimate_vp with segments given)
  projection         warp into the virtual camera (one remap, cached maps, per-image pose)
  completion         warp + projective completion minus projection, maps built for each distinct
                     per-image pose (cached when a pose repeats, e.g. fallback VPs); the cached
                     between-camera case (one H for all frames) is reported as completion_cached
  inference          segnet-narrow (untrained weights: timing only) on the store image
  back-projection    store probability map -> source image (bilinear)
The paper's figures (i7 + GTX 1080 Ti, MATLAB for VP/completion) are printed beside ours; they are
not comparable hardware, so no ratio is claimed. Last line: JSON.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import SHARED_DATA
from benchmarks.measure.report import results_dir, write_json
from vcprep.warp import backproject_array
from vcprep.camera import PRESETS
from vcprep.warp import completion_maps
from vcprep.warp import apply_homography, pose_from_vp, virt_H_src, virtual_at_scale
from vcprep.vp import detect_segments, estimate_vp, to_gray
from vcprep.warp import build_maps, warp_image
from vctrain.networks import build_model, model_args_for

DATA = SHARED_DATA / "camvid" / "val"
PAPER_MS = {"line_detection": 6200, "vp": 25, "projection": 182, "completion": 85, "inference": 43,
            "back_projection": 43}


def frames(n):
    if DATA.is_dir():
        files = sorted(DATA.glob("*.png"))[:n]
        return [cv2.imread(str(f)) for f in files], f"{len(files)} CamVid val frames"
    from vcprep.synthetic import render_road
    cam = PRESETS["camvid"].for_image_size((480, 360))
    return [render_road(cam, pan=i % 9 - 4, supersample=1)[0] for i in range(n)], f"{n} synthetic renders ({DATA} absent)"


def ms(fn):
    t0 = time.perf_counter()
    out = fn()
    return (time.perf_counter() - t0) * 1000, out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--scale", type=float, default=0.125)
    args = ap.parse_args()
    cv2.setNumThreads(1)
    torch.set_num_threads(1)
    imgs, source = frames(args.frames)
    cam = PRESETS["camvid"].for_image_size((imgs[0].shape[1], imgs[0].shape[0]))
    v = virtual_at_scale(PRESETS["virtual"], args.scale)
    model = build_model(model_args_for("segnet-narrow")).eval()
    t = {k: [] for k in list(PAPER_MS) + ["completion_cached"]}
    with torch.no_grad():
        model(torch.zeros(1, 3, v.size[1], v.size[0]))  # warm-up
        for img in imgs:
            d, seg = ms(lambda: detect_segments(to_gray(img)))
            t["line_detection"].append(d)
            d, res = ms(lambda: estimate_vp(img, cam, segments=seg))
            t["vp"].append(d)
            pan, tilt = pose_from_vp(cam, res.vp)
            H = virt_H_src(cam, v, pan, tilt)
            d_maps, maps = ms(lambda: build_maps(H, cam.size, v.size))
            d, warped = ms(lambda: warp_image(img, maps))
            t["projection"].append(d + d_maps)
            vp_store = tuple(apply_homography(H, [res.vp])[0])
            d_all, cmaps = ms(lambda: completion_maps(H, cam.size, v.size, "projective", vp_store))
            d2, done = ms(lambda: warp_image(img, cmaps))
            t["completion"].append(max(0.0, d_all + d2 - (d + d_maps)))
            Hc = virt_H_src(cam, v)
            cm = completion_maps(Hc, cam.size, v.size, "projective", (v.cx, v.cy))
            d3, _ = ms(lambda: warp_image(img, cm))
            t["completion_cached"].append(d3)
            x = torch.from_numpy(done).permute(2, 0, 1)[None].float() / 255.0
            d, logits = ms(lambda: model(x))
            t["inference"].append(d)
            prob = torch.softmax(logits, 1)[0, 1].numpy().astype(np.float32)
            rec = {"H": H.ravel().tolist(), "size": list(cam.size), "store_size": list(v.size)}
            d, _ = ms(lambda: backproject_array(prob, rec, kind="prob"))
            t["back_projection"].append(d)
    med = {k: statistics.median(vs) for k, vs in t.items()}
    print(f"data: {source}; source {cam.size[0]}x{cam.size[1]} -> store {v.size[0]}x{v.size[1]}; 1 thread CPU")
    print(f"{'stage':<18} {'ours ms':>9} {'p90':>8} {'paper ms':>9}")
    for k in t:
        p90 = float(np.percentile(t[k], 90))
        print(f"{k:<18} {med[k]:>9.2f} {p90:>8.2f} {PAPER_MS.get(k, ''):>9}")
    total = sum(med[k] for k in PAPER_MS)
    print(f"{'total':<18} {total:>9.2f} {'':>8} {sum(PAPER_MS.values()):>9}")
    headline = {f"{k}_ms": round(med[k], 2) for k in t} | {"total_ms": round(total, 2), "store_size": list(v.size),
                                                          "threads": 1, "data": source}
    write_json(results_dir(__file__) / "stages.json", {"headline": headline, "paper_ms": PAPER_MS}, indent=2)
    print(json.dumps(headline))


if __name__ == "__main__":
    main()
