"""Data, tools and study datasets of the benchmarks: the shared data folders (``SHARED_DATA``: CamVid
as ``DATA``, ``KITTI``; the other cameras' datasets: ``CITYSCAPES``, ``IDD``, ``BDD``, ``LUMS``,
``KITTI_SEM``), :func:`run` (a tool as a subprocess), cameras made EXACTLY from real CamVid
frames with ``vcprep simulate`` (crop/scale = a new K; rotation about the optical centre = the
homography K' R K^-1, exact for any scene; only fully covered output pixels are kept):
:data:`SIMULATED`, :func:`native_camera`, :func:`ego_camera`, :func:`simulate`; and study datasets
(:func:`link_files`, :func:`kitti_datasets`).
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]          # the repository
BIN = Path(sys.executable).parent                   # the tools (vcprep, vctrain) beside this Python
SHARED_DATA = ROOT.parent / "shared" / "data"
DATA = SHARED_DATA / "camvid"                       # CamVid, SegNet release (480x360)
KITTI = SHARED_DATA / "kitti_road" / "training"     # KITTI road: image_2, gt_image_2, calib
CS_FORMAT = "values:road=1;ignore=255;max=255"  # ../shared/data/cityscapes_pix2pix (its README)
LUMS_FORMAT = "values:road=2;max=4"              # ../shared/data/lums_road (its README)
CITYSCAPES = SHARED_DATA / "cityscapes_pix2pix"  # Cityscapes frames as pix2pix's release (256x256)
IDD = SHARED_DATA / "idd_lite"                   # IDD-Lite (India Driving Dataset, 320x227)
BDD = SHARED_DATA / "bdd100k_drivable"           # BDD100K drivable area (1280x720)
LUMS = SHARED_DATA / "lums_road"                 # LUMS road captures (640x640)
KITTI_SEM = SHARED_DATA / "kitti_semantics"      # 98 KITTI frames, road masks, the calibrated KITTI camera
KITTI_SEM_FORMAT = CS_FORMAT                     # 0 not road, 1 road, 255 void (its README)

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
SIM = list(SIMULATED)


# -- data and tools ----------------------------------------------------------------------------

def run(*args, stream: bool = False, env: dict[str, str] | None = None) -> str:
    """Run a command; its stdout, or exit with its stderr tail on failure (stream: stderr passes through)."""
    proc = subprocess.run([str(a) for a in args], stdout=subprocess.PIPE, stderr=None if stream else subprocess.PIPE,
                          text=True, env=None if env is None else {**os.environ, **env})
    if proc.returncode != 0:
        sys.exit(f"failed: {' '.join(map(str, args))}\n{(proc.stderr or '')[-3000:]}")
    return proc.stdout


# -- cameras and study datasets ----------------------------------------------------------------

def require_data(*folders: Path) -> None:
    """Exit with one line naming the first of ``folders`` (../shared/data) that is missing."""
    for need in folders:
        if not need.is_dir():
            raise SystemExit(f"needs {need} (../shared/data); not found")


def native_camera(wd: Path) -> Path:
    """wd/native.yaml: the camvid preset at the 480x360 size of the SegNet release."""
    from vcprep.camera import PRESETS, camera_to_yaml

    path = wd / "native.yaml"
    path.write_text(camera_to_yaml(PRESETS["camvid"].for_image_size((480, 360))))
    return path


def ego_camera(wd: Path, rows: int) -> Path:
    """wd/native-ego.yaml: the native camera with its bottom ``rows`` rows marked as the rig's own
    vehicle (``ego_rows``: every tool reads the frames as their exact bottom crop)."""
    from vcprep.camera import PRESETS, camera_to_yaml

    path = wd / "native-ego.yaml"
    path.write_text(camera_to_yaml(replace(PRESETS["camvid"].for_image_size((480, 360)), ego_rows=rows)))
    return path


def simulate(camera: Path, images: Path, labels: Path, dst: Path, name: str) -> dict[str, str]:
    """CamVid frames (``images``, ``labels``) through the simulated camera ``name``: a study split
    ({images, labels, vps}) under ``dst``; the camera file is ``dst/camera.yaml``."""
    run(BIN / "vcprep", "simulate", "--camera", camera, "--images", images, "--labels", labels, "--label-format",
        "camvid", "--out", dst, "--name", name, "--quiet", *SIMULATED[name])
    return {"images": str(dst / "images"), "labels": str(dst / "labels"), "vps": str(dst / "vps.csv")}


def link_files(names: list[str], src: Path, dest: Path) -> Path:
    """``dest`` afresh, holding a symbolic link to ``src/<name>`` for each of ``names``."""
    if dest.exists():
        shutil.rmtree(dest)
    dest.mkdir(parents=True)
    for n in names:
        (dest / n).symlink_to(src / n)
    return dest


def kitti_datasets() -> list[dict]:
    """The KITTI road frames with road ground truth, twice: ``kitti`` with every frame's own
    calibration (calib/: P2 and that frame's Tr_cam_to_road, the exact pose; what a user with
    KITTI's files gets), and ``kitti-vp`` with one camera (the first frame's file) and poses from
    estimated road VPs (the method without calibration; a row of its own, not in the headline)."""
    images = sorted((KITTI / "image_2").glob("*.png")) if (KITTI / "image_2").is_dir() else []
    if not images:
        return []
    test = {"images": str(KITTI / "image_2"), "labels": str(KITTI / "gt_image_2")}
    return [{"name": "kitti", "role": "test", "camera": str(KITTI / "calib"), "label_format": "kitti", "test": test},
            {"name": "kitti-vp", "role": "test", "camera": str(KITTI / "calib" / f"{images[0].stem}.txt"),
             "label_format": "kitti", "test": test}]
