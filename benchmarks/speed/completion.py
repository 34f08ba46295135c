"""Speed of warp + projective completion (one remap) and of back-projection, against a bare
``cv2.warpPerspective`` of the same image to the same size, in the same process, one thread.

Run:

    .venv/bin/python benchmarks/speed/completion.py                # CamVid frames if ../shared/data exists
    .venv/bin/python benchmarks/speed/completion.py --repeats-full 5 --repeats-eighth 40

Data: the first ``--frames`` images of ``../shared/data/camvid/train`` (SegNet release, 480x360,
camvid camera scaled by 1/2) with their labels from ``trainannot`` (id 11 = ignore); when that
folder is absent, a synthetic ``render_road`` frame through the same camera (the script says so).

Timed, per frame, median over repeats (spread = 10th..90th percentile and min..max):

* ``bare``: ``cv2.warpPerspective(img, H, store_size, INTER_LINEAR, BORDER_CONSTANT)``;
* ``ours``: ``vcprep.warp.warp_image`` with the cached warp + projective-completion maps (what
  every image of a camera costs in between-camera mode, where H and the VP are shared): one
  pass, covered pixels remapped from the source, uncovered ones looked up in the per-image
  angle table (see ``vcprep.warp.completion.CompletionMaps``);
* ``ours_cold``: building those maps from scratch + the remap (one-off per camera; per image in
  within-camera mode, where H differs per image), reported, not a target;
* ``back``: ``vcprep.warp.backproject.backproject_array`` of a store-sized probability map to the
  source size (maps cached), vs ``bare_back``: ``cv2.warpPerspective`` of the same map with
  ``WARP_INVERSE_MAP`` to the same size.

Targets (issue 4): ours / bare <= 1.3 at full 5500x2800 and at 1/8 (688x350); back / bare_back
<= 1.1. Results: ``benchmarks/speed/results/completion.json``; the last stdout line is one JSON object
with ``ratio_full``, ``ratio_eighth`` and ``backproject_ratio`` (the latter at 1/8, the store
scale training uses; ``backproject_ratio_full`` is given too).
"""
from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import DATA as CAMVID
from benchmarks.measure.report import results_dir
from vcprep.warp import completion, remap as warp
from vcprep.warp import backproject_array
from vcprep.camera import PRESETS
from vcprep.warp import border_ignore, completion_maps, store_vp
from vcprep.warp import virt_H_src, virtual_at_scale, vp_from_pose
from vcprep.labels import LABEL_FORMATS, decode_label
from vcprep.synthetic import render_road
from vcprep.warp import warp_image, warp_label


def frames(n: int):
    """[(name, image, decoded label or None)] and a sentence about where they came from."""
    train, annot = CAMVID / "train", CAMVID / "trainannot"
    files = sorted(train.glob("*.png"))[:n] if train.is_dir() else []
    if files:
        out = []
        for f in files:
            lab = cv2.imread(str(annot / f.name), cv2.IMREAD_UNCHANGED) if (annot / f.name).is_file() else None
            out.append((f.name, cv2.imread(str(f), cv2.IMREAD_UNCHANGED),
                        None if lab is None else decode_label(lab, LABEL_FORMATS["camvid"])))
        return out, f"CamVid train frames from {CAMVID} (480x360)"
    cam = PRESETS["camvid"].for_image_size((480, 360))
    img, lab = render_road(cam, supersample=1)
    return [("synthetic", img, lab)], f"{CAMVID} absent: one synthetic render_road frame (480x360)"


def timeit(fn, repeats: int) -> dict:
    fn()  # warm-up (allocations, caches)
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        ts.append((time.perf_counter() - t) * 1000)
    a = np.array(ts)
    return {"median_ms": float(np.median(a)), "p10_ms": float(np.percentile(a, 10)),
            "p90_ms": float(np.percentile(a, 90)), "min_ms": float(a.min()), "max_ms": float(a.max()),
            "repeats": repeats}


def bench_scale(scale: float, data, repeats: int, cold_repeats: int) -> dict:
    cam = PRESETS["camvid"].for_image_size((480, 360))
    v = virtual_at_scale(PRESETS["virtual"], scale)
    H = virt_H_src(cam, v)
    vp = store_vp(H, vp_from_pose(cam))
    size = v.size
    rows = []
    for name, img, lab in data:
        ign = border_ignore(lab)
        maps = completion_maps(H, cam.size, size, "projective", vp, ign)
        bare = timeit(lambda: cv2.warpPerspective(img, H, size, flags=cv2.INTER_LINEAR,
                                                  borderMode=cv2.BORDER_CONSTANT, borderValue=0), repeats)
        ours = timeit(lambda: warp_image(img, maps), repeats)
        ours_label = timeit(lambda: warp_label(lab, maps, maps.label_border), repeats) if lab is not None else None

        def cold():
            completion.clear_cache()
            warp.clear_cache()
            warp_image(img, completion_maps(H, cam.size, size, "projective", vp, ign))

        ours_cold = timeit(cold, cold_repeats)
        # back-projection of a store-sized probability map to the source camera
        prob = cv2.GaussianBlur(warp_image(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), maps), (5, 5), 0)
        rec = {"H": H.ravel().tolist(), "store_size": list(size), "size": list(cam.size), "id": name}
        backproject_array(prob, rec, "prob")  # warm-up
        back = timeit(lambda: backproject_array(prob, rec, "prob"), repeats)
        bare_back = timeit(lambda: cv2.warpPerspective(prob, H, cam.size, flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                                       borderMode=cv2.BORDER_CONSTANT, borderValue=0), repeats)
        rows.append({"frame": name, "bare": bare, "ours": ours, "ours_label": ours_label, "ours_cold": ours_cold,
                     "back": back, "bare_back": bare_back, "ignore_cut": ign is not None,
                     "ratio": ours["median_ms"] / bare["median_ms"],
                     "cold_ratio": ours_cold["median_ms"] / bare["median_ms"],
                     "back_ratio": back["median_ms"] / bare_back["median_ms"]})
    med = lambda k: float(np.median([r[k] for r in rows]))  # noqa: E731
    return {"scale": scale, "store_size": list(size), "source_size": list(cam.size), "frames": rows,
            "ratio": med("ratio"), "cold_ratio": med("cold_ratio"), "back_ratio": med("back_ratio"),
            "ratio_spread": [float(min(r["ratio"] for r in rows)), float(max(r["ratio"] for r in rows))]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=3, help="CamVid frames to time")
    ap.add_argument("--repeats-full", type=int, default=7)
    ap.add_argument("--repeats-eighth", type=int, default=60)
    ap.add_argument("--out", type=Path, default=results_dir(__file__) / "completion.json")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    data, source = frames(args.frames)
    print(f"data: {source}; threads: cv2.setNumThreads(1)", file=sys.stderr)
    eighth = bench_scale(0.125, data, args.repeats_eighth, max(3, args.repeats_eighth // 10))
    full = bench_scale(1.0, data, args.repeats_full, 2)
    print(f"{'scale':>6} {'store':>10} {'bare ms':>9} {'ours ms':>9} {'ratio':>6} {'cold ms':>9} {'cold x':>7} "
          f"{'back ms':>8} {'bare_back':>9} {'back x':>6}")
    for res in (eighth, full):
        for r in res["frames"]:
            print(f"{res['scale']:>6g} {res['store_size'][0]:>5}x{res['store_size'][1]:<4} "
                  f"{r['bare']['median_ms']:>9.2f} {r['ours']['median_ms']:>9.2f} {r['ratio']:>6.2f} "
                  f"{r['ours_cold']['median_ms']:>9.1f} {r['cold_ratio']:>7.2f} {r['back']['median_ms']:>8.2f} "
                  f"{r['bare_back']['median_ms']:>9.2f} {r['back_ratio']:>6.2f}   {r['frame']}")
    result = {"benchmark": "completion", "data": source, "threads": 1, "cv2": cv2.__version__,
              "machine": platform.platform(), "eighth": eighth, "full": full}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {args.out}", file=sys.stderr)
    print(json.dumps({"ratio_full": round(full["ratio"], 3), "ratio_eighth": round(eighth["ratio"], 3),
                      "backproject_ratio": round(eighth["back_ratio"], 3),
                      "backproject_ratio_full": round(full["back_ratio"], 3),
                      "cold_ratio_full": round(full["cold_ratio"], 3), "cold_ratio_eighth": round(eighth["cold_ratio"], 3),
                      "targets": {"ratio": 1.3, "backproject_ratio": 1.1}, "data": source.split(" (")[0]}))


if __name__ == "__main__":
    main()
