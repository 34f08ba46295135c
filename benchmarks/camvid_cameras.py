"""Shared pieces of the cross-camera benchmarks (cross_camera.py, real_cameras.py).

Cameras made EXACTLY from real CamVid frames with ``vcprep simulate`` (crop/scale = a new K;
rotation about the optical centre = the homography K' R K^-1, exact for any scene; only fully
covered output pixels are kept), the subprocess runner and the bar plot (OpenCV, no matplotlib).
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
BIN = Path(sys.executable).parent
SHARED_DATA = ROOT.parent / "shared" / "data"
DATA = SHARED_DATA / "camvid"
# simulated camera -> `vcprep simulate` arguments, applied to CamVid frames through the native camera
SIMULATED: dict[str, list[str]] = {
    "tele": ["--size", "320x240", "--hfov", "35", "--tilt", "3"],
    "band": ["--size", "480x146"],
    "dashcam": ["--size", "400x225", "--hfov", "40", "--pan-jitter", "8", "--tilt-jitter", "4", "--seed", "1"],
}
DESCRIPTION = {
    "native": "CamVid as released (480x360, the camvid preset at 1/2: 58 deg HFOV)",
    "tele": "telephoto crop, 35 deg HFOV, tilted down 3 deg, 320x240",
    "band": "wide short band with KITTI's aspect ratio, 480x146, widest covered FOV",
    "dashcam": "re-mounted 16:9 dashcam, 400x225, 40 deg HFOV, per-image pan +/-8, tilt +/-4 deg",
}


def run(*args, stream: bool = False, env: dict[str, str] | None = None) -> str:
    """Run a command; its stdout, or exit with its stderr tail on failure (stream: stderr passes through)."""
    proc = subprocess.run([str(a) for a in args], stdout=subprocess.PIPE, stderr=None if stream else subprocess.PIPE,
                          text=True, env=None if env is None else {**os.environ, **env})
    if proc.returncode != 0:
        sys.exit(f"failed: {' '.join(map(str, args))}\n{(proc.stderr or '')[-3000:]}")
    return proc.stdout


def native_camera(wd: Path) -> Path:
    """wd/native.yaml: the camvid preset at the 480x360 size of the SegNet release."""
    from vcprep.camera import PRESETS, camera_to_yaml

    path = wd / "native.yaml"
    path.write_text(camera_to_yaml(PRESETS["camvid"].for_image_size((480, 360))))
    return path


def simulate(camera: Path, images: Path, labels: Path, dst: Path, name: str) -> dict[str, str]:
    """CamVid frames (``images``, ``labels``) through the simulated camera ``name``: a study split
    ({images, labels, vps}) under ``dst``; the camera file is ``dst/camera.yaml``."""
    run(BIN / "vcprep", "simulate", "--camera", camera, "--images", images, "--labels", labels, "--label-format",
        "camvid", "--out", dst, "--name", name, "--quiet", *SIMULATED[name])
    return {"images": str(dst / "images"), "labels": str(dst / "labels"), "vps": str(dst / "vps.csv")}


def bar_plot(cell: dict[tuple[str, str], float], groups: list[str], conditions: list[str], title: str,
             spread: dict[tuple[str, str], float] | None = None) -> np.ndarray:
    """Grouped bars: road IoU in [0, 1] per group and condition (colours); ``spread``: error bars
    (+/- that much) where given."""
    colours = [(160, 160, 160), (200, 140, 60), (60, 170, 60), (40, 110, 30), (60, 60, 200), (170, 70, 170),
               (0, 150, 255)]
    W, H, top, bottom, left = 1000, 540, 80, 60, 60
    img = np.full((H, W, 3), 255, np.uint8)
    gw = (W - left - 20) / len(groups)
    bw = gw * 0.8 / len(conditions)
    y0 = H - bottom
    for t in range(0, 101, 20):
        y = int(y0 - t / 100 * (H - top - bottom))
        cv2.line(img, (left, y), (W - 20, y), (225, 225, 225), 1)
        cv2.putText(img, f"{t}", (18, y + 5), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (80, 80, 80), 1, cv2.LINE_AA)
    for g, name in enumerate(groups):
        x0 = left + g * gw + gw * 0.1
        for j, c in enumerate(conditions):
            if (name, c) not in cell:
                continue
            h = cell[name, c] * (H - top - bottom)
            x = int(x0 + j * bw)
            cv2.rectangle(img, (x, int(y0 - h)), (int(x + bw - 2), y0), colours[j % len(colours)], -1)
            e = (spread or {}).get((name, c)) or 0.0
            if e:
                e *= H - top - bottom
                xm = int(x + bw / 2 - 1)
                for a, b in (((xm, int(y0 - h - e)), (xm, int(y0 - h + e))), ((xm - 3, int(y0 - h - e)),
                             (xm + 3, int(y0 - h - e))), ((xm - 3, int(y0 - h + e)), (xm + 3, int(y0 - h + e)))):
                    cv2.line(img, a, b, (0, 0, 0), 1)
            cv2.putText(img, f"{100 * cell[name, c]:.0f}", (x, int(y0 - h - e) - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.35,
                        (40, 40, 40), 1, cv2.LINE_AA)
        cv2.putText(img, name, (int(x0), y0 + 22), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    for j, c in enumerate(conditions):
        x = left + j * 150
        cv2.rectangle(img, (x, 18), (x + 14, 32), colours[j % len(colours)], -1)
        cv2.putText(img, c, (x + 20, 31), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(img, title, (left, 52), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (80, 80, 80), 1, cv2.LINE_AA)
    return img
