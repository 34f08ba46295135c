"""Video prediction speed: per-frame VP correction (``within``) against a fixed pose (``between``) (issue 35).

    .venv/bin/python benchmarks/speed/video.py [--seconds 60] [--stage-frames 300] [--workdir benchmarks/out/video]

Input: a 1-minute 1280x720 video at 30 fps made from real frames: 40 of BDD100K's 41 frames
(../shared/data/bdd100k_drivable, 40 different dashcams), each shown for 1.5 s (45 frames) while the
camera turns smoothly about its optical centre (pan 1.0 deg x sin(2 pi t / 3.1 s), tilt 0.6 deg x
sin(2 pi t / 2.3 s): the exact homography K R K^-1 of the folder's camera.yaml, borders reflected),
so the road VP moves in every frame as a car's yaw and pitch move it; written with OpenCV's mp4v.
Camera: the folder's camera.yaml (assumed K, no ego_rows: ``--ego auto`` looks for the own vehicle in
48 frames spread over the video, and its time is part of the command's).
Model: untrained (speed only): resfpn (1.3 M parameters, seed 0) at the cpu recipe's working size
344x176 on the default 688x350 canvas (scale 0.125), projective completion, as ``vctrain fit
--size 344x176`` writes it; its ``vp_status`` says per-image VPs, so ``--within auto`` is ``estimate``.

Measured, on the machine's 2 cores (torch and OpenCV at ``--threads``, default 2; the 1-minute load
average before and after is recorded, as other jobs on the machine slow both conditions):
  end to end   ``vctrain predict MODEL --camera CAM video.mp4 --out OUT --overlay --quiet`` timed as a
               subprocess (model load, own-vehicle search, decode, VPs, warp, network, back-projection,
               a mask and a probability PNG per frame, the overlay video), ``--within none`` (between:
               the camera's average pose) and ``--within estimate`` (within: each frame's own road VP,
               smoothed over 2 frames either side); frames per second = frames / wall seconds;
  per stage    :func:`vctrain.predict.video.predict_video` in this process on the video's first
               ``--stage-frames`` frames, between and within alternated twice after a warm-up on 20
               frames (median and range over the two): ms per frame of VP detection, warp (pose, homography, warp + completion
               maps, remap), network, back-projection, and the rest (decode, PNG and video writing).
The ratio within / between (time per frame) is the issue's figure (target <= 1.3): the baseline is
the same command on the same video with a fixed pose.
Writes benchmarks/speed/results/video.json; prints the table, then one JSON line last.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import BDD, BIN, ROOT
from benchmarks.measure.report import machine, results_dir, today, write_json
from vcprep.store import store_params
from vcprep.camera import PRESETS, load_camera
from vctrain.training import save_checkpoint
from vctrain.predict import StageTimes
from vctrain.networks import build_model, model_args_for
from vctrain.predict import Predictor
from vcprep.io import open_video
from vctrain.predict import ego_camera, predict_video

FPS, HOLD = 30.0, 45                      # video frame rate; frames each BDD100K frame is shown
PAN_DEG, PAN_S, TILT_DEG, TILT_S = 1.0, 3.1, 0.6, 2.3
THREADS = 2


def make_video(path: Path, seconds: float) -> int:
    """The drive described in the module docstring; returns its frame count."""
    cam = load_camera(BDD / "camera.yaml").for_image_size((1280, 720))
    K = np.array([[cam.fx, 0, cam.cx], [0, cam.fy, cam.cy], [0, 0, 1.0]])
    files = sorted((BDD / "images").glob("*.jpg"))[:40]
    n = int(round(seconds * FPS))
    tmp = path.with_name(".tmp-" + path.name)
    w = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), FPS, cam.size)
    img = None
    for i in range(n):
        if i % HOLD == 0:
            img = cv2.imread(str(files[(i // HOLD) % len(files)]))
        t = i / FPS
        a = math.radians(PAN_DEG * math.sin(2 * math.pi * t / PAN_S))
        b = math.radians(TILT_DEG * math.sin(2 * math.pi * t / TILT_S))
        R_pan = np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])
        R_tilt = np.array([[1, 0, 0], [0, math.cos(b), -math.sin(b)], [0, math.sin(b), math.cos(b)]])
        H = K @ R_tilt @ R_pan @ np.linalg.inv(K)
        w.write(cv2.warpPerspective(img, H, cam.size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT_101))
    w.release()
    tmp.replace(path)
    return n


def cut(video: Path, out: Path, frames: int) -> None:
    """The first ``frames`` frames of ``video`` as another mp4v video."""
    cap = cv2.VideoCapture(str(video))
    w = None
    for _ in range(frames):
        ok, f = cap.read()
        if not ok:
            break
        if w is None:
            w = cv2.VideoWriter(str(out), cv2.VideoWriter_fourcc(*"mp4v"), FPS, (f.shape[1], f.shape[0]))
        w.write(f)
    w.release()
    cap.release()


def untrained_model(path: Path) -> None:
    """A checkpoint 'vctrain fit --size 344x176' would write, with resfpn's initial weights (seed 0)."""
    torch.manual_seed(0)
    args = model_args_for("resfpn")
    model = build_model(args)
    sp = store_params(PRESETS["virtual"], 0.125)
    save_checkpoint(path, {"model": model.state_dict(), "model_args": args.to_dict(), "config": {},
                           "data": {"mode": "virtual", "input_size": [344, 176], "store_params": sp,
                                    "completion": "projective", "vp_channel": False, "greyscale": 0.0,
                                    "vp_status": ["accepted"], "train_items": 0, "val_items": 0},
                           "epoch": 0, "step": 0, "metrics": {}, "best_iou": 0.0, "best_epoch": 0, "history": []})


def end_to_end(model: Path, cam: Path, video: Path, out: Path, within: str) -> float:
    """Wall seconds of one 'vctrain predict' command (a fresh output folder)."""
    shutil.rmtree(out, ignore_errors=True)
    cmd = [BIN / "vctrain", "predict", model, "--camera", cam, video, "--out", out, "--overlay", "--within", within,
           "--quiet"]
    env = {**os.environ, "OMP_NUM_THREADS": str(THREADS)}
    t0 = time.perf_counter()
    proc = subprocess.run([str(c) for c in cmd], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        sys.exit(f"failed: {' '.join(map(str, cmd))}\n{proc.stderr[-3000:]}")
    return wall


def stages(pred: Predictor, cam, clip: Path, out: Path, within: str) -> dict:
    """ms per frame of each stage (and the rest) of predict_video on ``clip`` in this process."""
    shutil.rmtree(out, ignore_errors=True)
    t = StageTimes()
    t0 = time.perf_counter()
    predict_video(pred, clip, out, cam, within=within, overlay=True, progress=False, times=t, ego="none")
    wall = time.perf_counter() - t0
    ms = t.per_frame_ms()
    ms["rest"] = 1000 * wall / t.frames - sum(ms.values())
    ms["total"] = 1000 * wall / t.frames
    return ms


def _print_tables(video: Path, info, ego_rows: int, ego_s: float, stage: dict, keys: tuple, wall: dict,
                  fps: dict) -> float:
    """Print the stage and end-to-end tables; returns within / between (time per frame, end to end)."""
    frames = info.frames
    print(f"video: {video.name}, {info.size[0]}x{info.size[1]}, {frames} frames at {info.fps:g} fps "
          f"({frames / info.fps:.0f} s); {THREADS} threads; own vehicle: {ego_rows} rows ({ego_s:.1f} s)")
    print("\n| stage (ms per frame) | between | within |\n|---|---|---|")
    for k in keys:
        cell = lambda n: f"{stage[n][k]['median']:.1f} ({stage[n][k]['min']:.1f}-{stage[n][k]['max']:.1f})"
        print(f"| {k} | {cell('between')} | {cell('within')} |")
    print("\n| end to end (1 command) | wall s | frames/s | ms/frame |\n|---|---|---|---|")
    for n in ("between", "within"):
        print(f"| {n} | {wall[n]:.1f} | {fps[n]:.2f} | {1000 * wall[n] / frames:.1f} |")
    ratio = wall["within"] / wall["between"]
    print(f"\nwithin / between (time per frame): end to end {ratio:.3f}; stages "
          f"{stage['within']['total']['median'] / stage['between']['total']['median']:.3f}")
    return ratio


def main() -> None:
    global THREADS
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="length of the video (s)")
    ap.add_argument("--stage-frames", type=int, default=300, help="frames of the per-stage runs")
    ap.add_argument("--workdir", type=Path, default=ROOT / "benchmarks" / "out" / "video")
    ap.add_argument("--threads", type=int, default=THREADS, help="torch and OpenCV threads (the machine's 2 cores; "
                                                                 "1 when other jobs load them)")
    args = ap.parse_args()
    THREADS = args.threads
    load_before = os.getloadavg()[0]
    cv2.setNumThreads(THREADS)
    torch.set_num_threads(THREADS)
    wd = args.workdir
    wd.mkdir(parents=True, exist_ok=True)
    video = wd / f"bdd_{int(args.seconds)}s_720p.mp4"
    if not video.exists():
        print(f"making {video} ...", file=sys.stderr)
        make_video(video, args.seconds)
    clip = wd / f"clip_{args.stage_frames}.mp4"
    if not clip.exists():
        cut(video, clip, args.stage_frames)
    model = wd / "untrained_resfpn.pt"
    untrained_model(model)
    cam_file = BDD / "camera.yaml"
    cam = load_camera(cam_file)
    _, info = open_video(video)
    frames = info.frames

    # the own-vehicle search alone (part of every end-to-end run: the camera states no ego_rows)
    t0 = time.perf_counter()
    ego = ego_camera(cam, info, "auto")
    ego_s = time.perf_counter() - t0

    # per stage, in this process, alternated
    pred = Predictor(model, "cpu")
    warm = wd / "warm_20.mp4"
    if not warm.exists():
        cut(video, warm, 20)
    for within in ("none", "estimate"):  # first calls (torch's kernels for each canvas size) are not timed
        stages(pred, cam, warm, wd / "warm", within)
    runs = {"between": [], "within": []}
    for _ in range(2):
        for name, within in (("between", "none"), ("within", "estimate")):
            print(f"stages {name} ...", file=sys.stderr)
            runs[name].append(stages(pred, cam, clip, wd / f"stages_{name}", within))
    keys = ("vp", "warp", "network", "backproject", "rest", "total")
    stage = {n: {k: {"median": statistics.median(r[k] for r in rs), "min": min(r[k] for r in rs),
                     "max": max(r[k] for r in rs)} for k in keys} for n, rs in runs.items()}

    # end to end, the one command
    wall = {}
    for name, within in (("between", "none"), ("within", "estimate")):
        print(f"end to end {name} ({frames} frames) ...", file=sys.stderr)
        wall[name] = end_to_end(model, cam_file, video, wd / f"out_{name}", within)
    fps = {n: frames / s for n, s in wall.items()}

    ratio = _print_tables(video, info, ego.ego_rows, ego_s, stage, keys, wall, fps)
    headline = {"within_over_between": round(ratio, 3), "fps_between": round(fps["between"], 2),
                "fps_within": round(fps["within"], 2), "fps_one_minute_720p": round(fps["within"], 2)}
    out = {"headline": headline, "date": today(), "command": "benchmarks/speed/video.py",
           "machine": machine(), "cpu_threads": THREADS,
           "loadavg_1min": [round(load_before, 2), round(os.getloadavg()[0], 2)],  # before, after: other jobs
           "video": {"frames": frames, "size": list(info.size), "fps": info.fps, "source": "BDD100K frames (40 "
                     "dashcams), 1.5 s each, smooth pan/tilt about the optical centre; mp4v"},
           "model": "resfpn, untrained (seed 0), 344x176 on the 688x350 canvas, projective completion",
           "ego_search_s": round(ego_s, 2), "ego_rows": ego.ego_rows,
           "end_to_end": {n: {"wall_s": round(wall[n], 2), "fps": round(fps[n], 3),
                              "ms_per_frame": round(1000 * wall[n] / frames, 2)} for n in wall},
           "stage_frames": args.stage_frames,
           "stages_ms": {n: {k: {q: round(v, 2) for q, v in c.items()} for k, c in s.items()} for n, s in stage.items()},
           "stages_within_over_between": round(stage["within"]["total"]["median"] / stage["between"]["total"]["median"], 3)}
    write_json(results_dir(__file__) / "video.json", out)
    print(json.dumps(headline))


if __name__ == "__main__":
    main()
