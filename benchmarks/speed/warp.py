"""Warp throughput: our store warp vs bare cv2.warpPerspective, same frames, same run.

    .venv/bin/python benchmarks/speed/warp.py [--frames 40] [--repeats 5]

Data: ../shared/data/camvid/train (480x360 CamVid frames, camvid preset scaled by 1/2); falls back
to synthetic renders when that folder is absent (and says so). One OpenCV thread.

Measured per frame, I/O excluded unless stated:
  bare      cv2.warpPerspective(img, H, store size, INTER_LINEAR)
  ours      vcprep's warp: one cv2.remap with cached fixed-point maps (built once per H), restricted
            to the box the source covers (the rest of the virtual view is border value)
  ours_cold the same plus building the maps (first frame of a camera only)
  png_io    PNG decode of the source + PNG encode of the warped image (for scale)
Ratios: ours / bare at 1/8 (688x350) and at full resolution (5500x2800). Last line: JSON.
"""
from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import SHARED_DATA
from benchmarks.measure.report import results_dir, write_json
from vcprep.camera import PRESETS
from vcprep.warp import virt_H_src, virtual_at_scale
from vcprep.warp import build_maps, maps_for, warp_image

DATA = SHARED_DATA / "camvid" / "train"


def load_frames(n: int) -> tuple[list[bytes], str]:
    if DATA.is_dir():
        files = sorted(DATA.glob("*.png"))[:n]
        return [f.read_bytes() for f in files], f"{len(files)} CamVid frames from {DATA}"
    from vcprep.synthetic import render_road
    cam = PRESETS["camvid"].for_image_size((480, 360))
    out = []
    for i in range(n):
        img, _ = render_road(cam, pan=i % 7 - 3, supersample=1)
        out.append(cv2.imencode(".png", img)[1].tobytes())
    return out, f"{n} synthetic renders ({DATA} not found)"


def timed(fn, frames, repeats):
    """Median over repeats of the mean time per frame (ms), and the spread (min..max)."""
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for f in frames:
            fn(f)
        runs.append((time.perf_counter() - t0) * 1000 / len(frames))
    return statistics.median(runs), min(runs), max(runs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--full-frames", type=int, default=6, help="frames for the full-resolution run")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    raw, source = load_frames(args.frames)
    imgs = [cv2.imdecode(np.frombuffer(b, np.uint8), cv2.IMREAD_UNCHANGED) for b in raw]
    cam = PRESETS["camvid"].for_image_size((imgs[0].shape[1], imgs[0].shape[0]))
    results = {}
    print(f"data: {source}; source {cam.size[0]}x{cam.size[1]}; cv2 threads 1; "
          f"{platform.processor() or platform.machine()}")
    print(f"{'scale':>6} {'size':>10} {'bare ms':>9} {'ours ms':>9} {'ratio':>6} {'cold ms':>9} {'png io ms':>9}")
    for label, scale, n in (("eighth", 0.125, args.frames), ("full", 1.0, args.full_frames)):
        v = virtual_at_scale(PRESETS["virtual"], scale)
        H = virt_H_src(cam, v)
        frames = imgs[:n]
        bare = timed(lambda im: cv2.warpPerspective(im, H, v.size, flags=cv2.INTER_LINEAR), frames, args.repeats)
        maps = maps_for(H, cam.size, v.size)
        ours = timed(lambda im: warp_image(im, maps), frames, args.repeats)
        t0 = time.perf_counter()
        cold_maps = build_maps(H, cam.size, v.size)
        warp_image(frames[0], cold_maps)
        cold = (time.perf_counter() - t0) * 1000
        warped = warp_image(frames[0], maps)
        io = timed(lambda b: cv2.imencode(".png", warped, [cv2.IMWRITE_PNG_COMPRESSION, 1])
                   if cv2.imdecode(np.frombuffer(b, np.uint8), cv2.IMREAD_UNCHANGED) is not None else None,
                   raw[:n], args.repeats)
        ratio = ours[0] / bare[0]
        # same output: pixels away from the source border are identical to warpPerspective's
        a = cv2.warpPerspective(frames[0], H, v.size, flags=cv2.INTER_LINEAR)
        inner = cv2.erode(maps.valid, np.ones((3, 3), np.uint8)).astype(bool)
        same = float(np.mean(np.abs(a.astype(int) - warped.astype(int))[inner] <= 1))
        results[label] = {"store_size": list(v.size), "bare_ms": bare, "ours_ms": ours, "ratio": ratio,
                          "cold_ms": cold, "png_io_ms": io, "frames": n,
                          "identical_to_bare_within_1": same}
        print(f"{scale:>6g} {v.size[0]:>5}x{v.size[1]:<4} {bare[0]:>9.2f} {ours[0]:>9.2f} {ratio:>6.2f} {cold:>9.1f} "
              f"{io[0]:>9.2f}   (same output as bare on {100 * same:.2f}% of covered pixels; spread bare {bare[1]:.2f}..{bare[2]:.2f}, ours {ours[1]:.2f}..{ours[2]:.2f})")
    headline = {"ratio_eighth": round(results["eighth"]["ratio"], 3), "ratio_full": round(results["full"]["ratio"], 3),
                "bare_ms_eighth": round(results["eighth"]["bare_ms"][0], 3),
                "ours_ms_eighth": round(results["eighth"]["ours_ms"][0], 3),
                "bare_ms_full": round(results["full"]["bare_ms"][0], 2),
                "ours_ms_full": round(results["full"]["ours_ms"][0], 2),
                "cold_maps_ms_full": round(results["full"]["cold_ms"], 1), "threads": 1, "data": source}
    write_json(results_dir(__file__) / "warp.json", {"headline": headline, "detail": results}, indent=2)
    print(json.dumps(headline))


if __name__ == "__main__":
    main()
