"""The VP sets: (id, image, reference VP) of synthetic renders (:func:`synthetic_vp_set`), CamVid
(:func:`camvid_vp_set`), CamVid through the simulated cameras (:func:`simulated_vp_sets`) and KITTI
(:func:`kitti_vp_set`).
"""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import cv2
import numpy as np

from .data import BIN, DATA, KITTI, SIMULATED, native_camera, run
from .vp_reference import kitti_reference_vp, reference_vp
from vcprep.warp import vp_from_pose
from vcprep.synthetic import RoadScene, render_road


def synthetic_vp_set(n: int, cam, seed: int = 0):
    rng = np.random.default_rng(seed)
    out = []
    W, H = cam.size
    for k in range(n):
        pan, tilt = rng.uniform(-20, 20), rng.uniform(-15, 15)
        scene = RoadScene(offset=float(rng.uniform(-3, 3)), width=float(rng.uniform(6, 12)),
                          lanes=int(rng.integers(1, 4)), texture_seed=k)
        img, _ = render_road(cam, scene, pan=pan, tilt=tilt, supersample=2)
        img = img.astype(np.float64) + rng.normal(0, 5, img.shape)
        for c in range(10):
            p = rng.uniform([0, 0], [W, H])
            ang = rng.uniform(85, 95) if c < 3 else rng.uniform(0, 180)  # 3 "poles", 7 random
            ln = rng.uniform(20, 160) * W / 480
            q = p + ln * np.array([math.cos(math.radians(ang)), -math.sin(math.radians(ang))])
            cv2.line(img, tuple(int(v) for v in p), tuple(int(v) for v in q),
                     tuple(float(v) for v in rng.uniform(0, 255, 3)), int(rng.integers(1, 4)))
        img = np.clip(np.rint(img), 0, 255).astype(np.uint8)
        out.append((f"syn{k:03d}", img, vp_from_pose(cam, pan, tilt)))
    return out


def camvid_vp_set(split: str, cam):
    """(id, image, reference VP) of the frames the rule accepts, the number skipped, and the
    reference's own spread per kept frame: |VP(band 1.5 px) - VP(band 3 px)| in % of the width,
    both fitted to the same boundary points without rule 3's goodness tests (the frame already
    passed them; nan if either intersection is invalid) - how far the reference moves under an
    equally reasonable choice of its own parameter: a floor under any detector's measured error."""
    img_dir, lab_dir = DATA / split, DATA / f"{split}annot"
    out, skipped, spread = [], 0, []
    for p in sorted(img_dir.glob("*.png")):
        lab = cv2.imread(str(lab_dir / p.name), cv2.IMREAD_UNCHANGED)
        ref = reference_vp(lab, cam) if lab is not None else None
        if ref is None:
            skipped += 1
            continue
        out.append((p.stem, cv2.imread(str(p), cv2.IMREAD_COLOR), ref))
        a, b = reference_vp(lab, cam, 1.5, gate=False), reference_vp(lab, cam, 3.0, gate=False)
        spread.append(math.hypot(a[0] - b[0], a[1] - b[1]) / cam.size[0] * 100 if a and b else float("nan"))
    return out, skipped, spread


def simulated_vp_sets(split_items, workdir: Path, split: str = "val"):
    """CamVid frames of ``split`` that have a reference VP, through the simulated cameras of the
    cross-camera benchmarks (``vcprep simulate``: crop/zoom and rotation about the optical centre
    are exact), each frame's reference VP mapped exactly by the same homography (``--vps``).
    Returns [(name, camera, [(id, image, reference VP)])]; the camera is the simulated camera at
    its nominal pose (per-image pan/tilt jitter is what the detector must find); the source
    camera is CamVid's (the camvid preset at 480x360). ``split='train'`` builds the development
    sets of ``--dev`` (same cameras, same seeds, other frames)."""
    from vcprep.camera import load_camera

    src = workdir / f"{split}_with_reference"
    shutil.rmtree(src, ignore_errors=True)
    src.mkdir(parents=True)
    rows = ["id,u,v"]
    for iid, _, ref in split_items:
        (src / f"{iid}.png").symlink_to(DATA / split / f"{iid}.png")
        rows.append(f"{iid},{ref[0]:.9f},{ref[1]:.9f}")
    (workdir / f"{split}_reference_vps.csv").write_text("\n".join(rows) + "\n")
    native = native_camera(workdir)
    out = []
    for name, args in SIMULATED.items():
        dst = workdir / "sim" / (name if split == "val" else f"{split}-{name}")
        run(BIN / "vcprep", "simulate", "--camera", native, "--images", src, "--out", dst, "--name", name,
            "--vps", workdir / f"{split}_reference_vps.csv", "--quiet", *args)
        refs = {r[0]: (float(r[1]), float(r[2])) for r in
                (line.split(",") for line in (dst / "vps.csv").read_text().splitlines()[1:])}
        items = [(iid, cv2.imread(str(dst / "images" / f"{iid}.png"), cv2.IMREAD_COLOR), refs[iid])
                 for iid, _, _ in split_items]
        out.append((name, load_camera(str(dst / "camera.yaml")), items))
    return out


def kitti_vp_set():
    """The KITTI road frames shipped in ../shared/data whose ground truth the rule accepts, each
    with its own calibration file; (camera, items, skipped)."""
    from vcprep.camera import load_camera

    items, cams, skipped = [], [], 0
    for p in sorted((KITTI / "image_2").glob("*.png")) if (KITTI / "image_2").is_dir() else []:
        prefix, _, num = p.stem.partition("_")
        gt = cv2.imread(str(KITTI / "gt_image_2" / f"{prefix}_road_{num}.png"), cv2.IMREAD_COLOR)
        img = cv2.imread(str(p), cv2.IMREAD_COLOR)
        cam = load_camera(str(KITTI / "calib" / f"{p.stem}.txt")).for_image_size((img.shape[1], img.shape[0]))
        ref = kitti_reference_vp(gt, cam) if gt is not None else None
        if ref is None:
            skipped += 1
            continue
        items.append((p.stem, img, ref))
        cams.append(cam)
    return cams, items, skipped
