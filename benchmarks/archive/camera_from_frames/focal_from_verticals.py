"""Can the frames fix the focal length? The classical self-calibration from the road VP and the
vertical VP, measured on cameras whose calibration we know (issue 25's fx target).

    .venv/bin/python benchmarks/archive/camera_from_frames/focal_from_verticals.py [--frames 60] [--quick]

`vcprep camera estimate` does not estimate the focal length: it takes --fx, --hfov or EXIF, else it
ASSUMES a 60-degree lens and says so. This benchmark is the measurement behind that choice.

The method (Caprile & Torre 1990; any single-view calibration text): the road direction and the
world vertical are orthogonal, so their vanishing points r and v satisfy r^T w v = 0 with
w = K^-T K^-1. For a camera of zero roll, principal point (cx, cy) and tilt t (pitched down > 0)
the road VP lies at row cy - fy tan t and the vertical VP (the nadir) at (cx, cy + fy / tan t), so

    fy^2 = (v_vertical - cy) * (cy - v_road)

It fixes fy, the VERTICAL focal length: fx = fy / pixel aspect, and the aspect is a second unknown
(CamVid's calibration has fy / fx = 1.32). The information is in how much the building edges,
poles and door frames converge: a segment at column offset x leans by about x tan(t) / fy radians,
nothing for a level camera. Estimator (pooled, robust): every frame's near-vertical LSD segments
(within 20 deg of the image vertical, at least 8 % of the height long; below the horizon, none whose
line passes within a tenth of the width of the road VP: lane marks and road edges) and that frame's road VP row give, for each candidate fy on a
log grid of 0.3-12 image heights, the frame's tilt atan((cy - v_road) / fy), hence its nadir; the
cost is the sum over segments of length x min(angle to the line through the nadir, 1 deg)^2, and
the estimate its minimiser over all frames together. 68 % interval: 40 bootstrap resamples of the
frames. ``information``: (max - min) / max of the pooled cost curve (0 = flat: the frames say
nothing about fy).

Sets (truth -> compared):

* ``camvid-sim``: CamVid val (101 frames, 480x360) through ``vcprep simulate`` (exact K' R K^-1:
  every vertical stays a true vertical) at 400x300, hfov 20 and 30 deg x tilt -8, -4, 0, +4, +8 deg
  relative to the CamVid rig (the issue's tilt range; the truth inherits the rig's own unknown
  mounting offset, which CamVid val's VPs put within 0.1 deg of the preset's 0).
* ``camvid-val`` against the camvid preset at 480x360 (tilt 0), ``cityscapes`` (400 frames,
  256x256 squashed from 2048x1024) against its camera.yaml (tilt 2.4, typical extrinsics).

Each set twice: with the road VP row of the true camera (the horizon known exactly: the best case)
and with each frame's detected road VP (``vcprep.vp.estimate_vp`` with the true
camera's search window; frames without an accepted VP are left out): what a tool would have.
Beside it, the error of the 60-degree assumption the tool makes, in fx and in fy (square pixels
assumed). Nothing here is fitted to these frames. Threads: cv2.setNumThreads(1).
Outputs: benchmarks/camera_from_frames/results/focal_from_verticals.{md,json}; the last stdout line is one JSON object:
``fy_err_pct_median_abs`` (over sets, detected VPs), ``within_10pct`` (how many sets), per set
errors and intervals, ``fx_err_pct_median_abs_assumed`` and ``fy_err_pct_median_abs_assumed`` (the
60-degree assumption's errors over the same sets).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import BIN, CITYSCAPES, DATA, ROOT, native_camera, run
from benchmarks.measure.report import machine, results_dir, today, write_json
from vcprep.camera import PRESETS, Camera, load_camera
from vcprep.camera import ASSUMED_HFOV, whole_frame_vp_config
from vcprep.warp import vp_from_pose
from vcprep.io import read_image
from vcprep.vp import estimate_vp

SIM = [(hf, t) for hf in (20, 30) for t in (-8, -4, 0, 4, 8)]
MAX_DEV_DEG = 20.0        # a near-vertical segment: within this of the image vertical
MIN_LEN_SHARE = 0.08      # ... and at least this share of the image height long
TAU = math.radians(1.0)   # residuals truncated here (robust to non-vertical structure)
GRID = np.exp(np.linspace(math.log(0.3), math.log(12.0), 240))   # fy / image height
BOOT = 40


def line_segments(gray: np.ndarray) -> np.ndarray:
    """All LSD segments (x1, y1, x2, y2) of a grey image."""
    lines = cv2.createLineSegmentDetector().detect(gray)[0]
    return np.zeros((0, 4), np.float32) if lines is None else lines.reshape(-1, 4)


def vertical_segments(s: np.ndarray, size: tuple[int, int], road_vp: tuple[float, float]) -> np.ndarray:
    """The near-vertical ones of segments ``s`` in an image of ``size`` (w, h), less those below the
    horizon whose line passes within a tenth of the width of the road VP (lane marks and road edges
    run to it)."""
    w, h = size
    d = s[:, 2:] - s[:, :2]
    length = np.hypot(d[:, 0], d[:, 1])
    dev = np.degrees(np.arctan2(np.abs(d[:, 0]), np.abs(d[:, 1])))
    mid_v = (s[:, 1] + s[:, 3]) / 2
    to_vp = np.abs(d[:, 0] * (road_vp[1] - s[:, 1]) - d[:, 1] * (road_vp[0] - s[:, 0])) / np.maximum(length, 1e-9)
    road_line = (mid_v > road_vp[1]) & (to_vp < 0.1 * w)
    return s[(length >= MIN_LEN_SHARE * h) & (dev <= MAX_DEV_DEG) & ~road_line]


def frame_costs(seg: np.ndarray, cx: float, cy: float, v_road: float, fys: np.ndarray) -> np.ndarray:
    """For each candidate fy: the frame's robust cost of its segments against the nadir that fy
    and the frame's road VP row imply (homogeneous, so a level camera's nadir at infinity is fine)."""
    if len(seg) == 0:
        return np.zeros(len(fys))
    m = (seg[:, :2] + seg[:, 2:]) / 2
    d = seg[:, 2:] - seg[:, :2]
    length = np.hypot(d[:, 0], d[:, 1])
    t = np.arctan2(cy - v_road, fys)[:, None]                   # tilt per candidate
    s, c = np.sin(t), np.cos(t)
    nx = s * (cx - m[None, :, 0])                                # direction midpoint -> nadir
    ny = s * (cy - m[None, :, 1]) + fys[:, None] * c
    cross = np.abs(d[None, :, 0] * ny - d[None, :, 1] * nx) / (length[None] * np.hypot(nx, ny))
    err = np.arcsin(np.clip(cross, 0.0, 1.0))
    return (length[None] * np.minimum(err, TAU) ** 2).sum(axis=1)


def estimate_fy(costs: np.ndarray, fys: np.ndarray, rng: np.random.Generator) -> dict:
    """Pooled minimiser, its bootstrap 68 % interval and the cost curve's relative depth."""
    total = costs.sum(axis=0)
    best = float(fys[total.argmin()])
    boots = [float(fys[costs[rng.integers(0, len(costs), len(costs))].sum(axis=0).argmin()]) for _ in range(BOOT)]
    lo, hi = np.percentile(boots, [16, 84])
    info = float((total.max() - total.min()) / total.max()) if total.max() > 0 else 0.0
    return {"fy": best, "lo": float(lo), "hi": float(hi), "information": info}


def measure_set(files: list[Path], cam: Camera, rng: np.random.Generator) -> dict:
    w, h = cam.size
    fys = GRID * h
    vp_true = vp_from_pose(cam)
    cfg = whole_frame_vp_config(cam)
    exact, detected, nseg, accepted = [], [], 0, 0
    for f in files:
        img = read_image(f).array
        lines = line_segments(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img)
        seg = vertical_segments(lines, cam.size, vp_true)
        nseg += len(seg)
        exact.append(frame_costs(seg, cam.cx, cam.cy, vp_true[1], fys))
        r = estimate_vp(img, cam, cfg)
        if r.status == "accepted":
            accepted += 1
            seg_d = vertical_segments(lines, cam.size, r.vp)
            detected.append(frame_costs(seg_d, cam.cx, cam.cy, r.vp[1], fys))
    out = {"frames": len(files), "segments": nseg, "vps_accepted": accepted, "true_fy": cam.fy,
           "true_fx": cam.fx, "tilt": cam.tilt}
    for key, costs in (("exact_horizon", exact), ("detected_vp", detected)):
        if not costs:
            out[key] = None
            continue
        e = estimate_fy(np.array(costs), fys, rng)
        e["err_pct"] = 100 * (e["fy"] / cam.fy - 1)
        e["interval_pct"] = [100 * (e["lo"] / cam.fy - 1), 100 * (e["hi"] / cam.fy - 1)]
        out[key] = e
    f_assumed = (w / 2) / math.tan(math.radians(ASSUMED_HFOV) / 2)
    out["assumed_fx_err_pct"] = 100 * (f_assumed / cam.fx - 1)
    out["assumed_fy_err_pct"] = 100 * (f_assumed / cam.fy - 1)
    return out


def sim_sets(wd: Path, quick: bool) -> dict[str, tuple[list[Path], Camera]]:
    native = native_camera(wd)
    sets = {}
    for hf, t in SIM[::3] if quick else SIM:
        dst = wd / f"sim_hfov{hf}_tilt{t:+d}"
        if not (dst / "camera.yaml").exists():
            run(BIN / "vcprep", "simulate", "--camera", native, "--images", DATA / "val", "--out", dst,
                "--size", "400x300", "--hfov", hf, "--tilt", t, "--quiet")
        sets[f"camvid-sim hfov{hf}_tilt{t:+d}"] = (sorted((dst / "images").iterdir()), load_camera(dst / "camera.yaml"))
    return sets


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=60, help="frames per set (evenly spaced)")
    ap.add_argument("--workdir", type=Path, default=ROOT / "benchmarks" / "out" / "focal_from_verticals")
    ap.add_argument("--quick", action="store_true", help="4 simulated sets and CamVid val, 8 frames each (a smoke run)")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    args.workdir.mkdir(parents=True, exist_ok=True)
    frames = 8 if args.quick else args.frames
    sets = sim_sets(args.workdir, args.quick)
    sets["camvid-val"] = (sorted((DATA / "val").glob("*.png")), PRESETS["camvid"].for_image_size((480, 360)))
    if CITYSCAPES.is_dir() and not args.quick:
        sets["cityscapes"] = (sorted((CITYSCAPES / "images").glob("*.jpg")), load_camera(CITYSCAPES / "camera.yaml"))
    rng = np.random.default_rng(0)
    rows, t0 = {}, time.perf_counter()
    for name, (files, cam) in sets.items():
        pick = np.linspace(0, len(files) - 1, min(frames, len(files))).round().astype(int)
        rows[name] = measure_set([files[i] for i in sorted(set(pick))], cam, rng)
        d, x = rows[name]["detected_vp"], rows[name]["exact_horizon"]
        print(f"{name}: true fy {cam.fy:.0f}, tilt {cam.tilt:+.1f}: exact horizon {x['err_pct']:+.1f} % "
              f"[{x['interval_pct'][0]:+.0f}, {x['interval_pct'][1]:+.0f}] info {x['information']:.2f}; detected VP "
              + (f"{d['err_pct']:+.1f} % [{d['interval_pct'][0]:+.0f}, {d['interval_pct'][1]:+.0f}] info {d['information']:.2f}"
                 if d else "-"),
              file=sys.stderr)
    det = [abs(r["detected_vp"]["err_pct"]) for r in rows.values() if r["detected_vp"]]
    exa = [abs(r["exact_horizon"]["err_pct"]) for r in rows.values()]
    head = {"fy_err_pct_median_abs": float(np.median(det)),
            "fy_err_pct_median_abs_exact_horizon": float(np.median(exa)),
            "within_10pct": int(sum(e <= 10 for e in det)), "sets": len(rows),
            "within_10pct_exact_horizon": int(sum(e <= 10 for e in exa)),
            "fx_err_pct_median_abs_assumed": float(np.median([abs(r["assumed_fx_err_pct"]) for r in rows.values()])),
            "fy_err_pct_median_abs_assumed": float(np.median([abs(r["assumed_fy_err_pct"]) for r in rows.values()])),
            "seconds": round(time.perf_counter() - t0, 1)}
    md = ["| set | tilt (deg) | true fy | fy from verticals, horizon exact: err % [68 %] | information | "
          "fy from verticals, detected VPs: err % [68 %] | VPs | segments | 60 deg assumed: fx err % | fy err % |",
          "|---|---|---|---|---|---|---|---|---|---|"]
    for name, r in rows.items():
        x, d = r["exact_horizon"], r["detected_vp"]
        cell = lambda e: "-" if not e else f"{e['err_pct']:+.1f} [{e['interval_pct'][0]:+.0f}, {e['interval_pct'][1]:+.0f}]"
        md.append(f"| {name} | {r['tilt']:+.1f} | {r['true_fy']:.0f} | {cell(x)} | {x['information']:.3f} | {cell(d)} | "
                  f"{r['vps_accepted']}/{r['frames']} | {r['segments']} | {r['assumed_fx_err_pct']:+.1f} | "
                  f"{r['assumed_fy_err_pct']:+.1f} |")
    res = args.workdir if args.quick else results_dir(__file__)   # a smoke run never replaces the record
    stem = "focal_from_verticals"
    (res / f"{stem}.md").write_text("\n".join(md) + "\n")
    write_json(res / f"{stem}.json",
               {"headline": head, "sets": rows, "command": " ".join(["benchmarks/archive/camera_from_frames/focal_from_verticals.py", *sys.argv[1:]]),
         "settings": {"frames": frames, "max_dev_deg": MAX_DEV_DEG, "min_len_share": MIN_LEN_SHARE,
                      "tau_deg": math.degrees(TAU), "grid_fy_over_h": [float(GRID[0]), float(GRID[-1])], "boot": BOOT},
         "machine": machine(), "date": today()})
    print("\n".join(md))
    print(json.dumps(head))


if __name__ == "__main__":
    main()
