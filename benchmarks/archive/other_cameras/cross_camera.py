"""Cross-camera study on CamVid (paper Tables 4/7): leave one camera out, five conditions.

    .venv/bin/python benchmarks/archive/other_cameras/cross_camera.py [--epochs 6] [--workdir benchmarks/out/cross_camera]

The paper's five datasets are not available here, so four cameras are made EXACTLY from real
CamVid frames with ``vcprep simulate`` (crop/scale = a new K; rotation about the optical centre =
the homography K' R K^-1, exact for any scene; only fully covered output pixels are kept):

* ``native``  CamVid as released (480x360, the camvid preset at 1/2: 58 deg horizontal FOV);
* ``tele``    a telephoto crop, 35 deg horizontal FOV, tilted down 3 deg, 320x240;
* ``band``    a wide short band with KITTI's aspect ratio (about 3.3:1), 480x146, widest covered FOV;
* ``dashcam`` a re-mounted 16:9 dashcam, 400x225, 40 deg horizontal FOV, per-image random pan +/-8 deg and tilt +/-4 deg.

Train and test frames come from disjoint splits: each camera's TRAINING frames are its own quarter
of CamVid ``train`` (367 frames dealt round-robin in name order, so the cameras see different
scenes), its TEST frames are all 101 frames of CamVid ``val`` through that camera. No test frame of
any camera is ever trained on; checkpoints are selected on 10 % of the training cameras' items.

``vctrain crossval`` then trains on three cameras and tests on the fourth, for every held-out
camera and every condition: ``resize`` (the baseline, run in the same study on the same frames),
``between``, ``within`` (estimated VPs), ``within-gt`` (given VPs) and ``zero`` (within with zero
padding). Given VPs: each simulated image's VP is its source frame's NOMINAL VP (camvid average
pose) moved exactly by the simulated rotation, so the per-image pose change is exact but the
source frame's own deviation from the nominal pose is not known; for ``native`` it is the nominal
VP for every frame (within-gt = between there). Also available with ``--conditions`` (not run by
default): ``prior`` (no training: the training cameras' geometric prior p_g >= 0.5, Table 5's
"Geo-Prior"), ``adapt`` (each run's within model adapted without labels to the held-out camera's
test images with that prior's tri-mask) and ``adapt-fuse`` (the same, the prior fused with the
within model's own prediction); they appear in the table, the plot and the JSON like the others.

Budget: segnet-narrow on the CPU, torch's default threads (2 on the reference machine), seed 0,
``--epochs`` each (default 6), working size = the virtual store's (default width 288; the resize baseline uses the same
size). The virtual camera is designed from the four cameras (pan +/-10, tilt +/-5 deg).
Outputs in benchmarks/other_cameras/results/: ``cross_camera.md`` (+ ``.csv``) the table, ``cross_camera.png`` a
bar plot, ``cross_camera_runs.jsonl`` every run; the last stdout line is one JSON object
{condition: mean road IoU over held-out cameras}, also saved as ``cross_camera.json``.
"""
from __future__ import annotations

import argparse
import json
import platform
import shutil
import sys
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import BIN, DATA, ROOT, SIMULATED, native_camera, run, simulate
from benchmarks.measure.report import results_dir
from benchmarks.measure.tables import bar_plot as _bars

CONDITIONS = ["resize", "between", "within", "within-gt", "zero"]  # the default; --conditions may add prior,
                                                                    # adapt, adapt-fuse
# name -> vcprep simulate arguments (None: the native CamVid frames)
CAMERAS: dict[str, list[str] | None] = {"native": None, **SIMULATED}


def deal(split: str, k: int, n: int, dest: Path) -> Path:
    """Frames i = k (mod n) of CamVid ``split`` (name order) linked into dest/images, dest/labels."""
    names = sorted(p.name for p in (DATA / split).glob("*.png"))
    for sub, src in (("images", DATA / split), ("labels", DATA / f"{split}annot")):
        d = dest / sub
        if d.exists():
            shutil.rmtree(d)
        d.mkdir(parents=True)
        for name in names[k::n]:
            (d / name).symlink_to(src / name)
    return dest


def make_cameras(wd: Path) -> dict[str, dict]:
    """The four cameras' train/test folders, camera files and given VPs."""
    from vcprep.camera import load_camera
    from vcprep.warp import vp_from_pose

    native = load_camera(str(native_camera(wd)))
    out: dict[str, dict] = {}
    for k, (name, sim) in enumerate(CAMERAS.items()):
        entry: dict = {"name": name, "label_format": "camvid"}
        for split, src in (("train", deal("train", k, len(CAMERAS), wd / "src" / name / "train")),
                           ("test", deal("val", 0, 1, wd / "src" / name / "test"))):
            if sim is None:
                ids = sorted(p.stem for p in (src / "images").iterdir())
                u, v = vp_from_pose(native)
                (src / "vps.csv").write_text("id,u,v\n" + "".join(f"{i},{u:.4f},{v:.4f}\n" for i in ids))
                entry[split] = {"images": str(src / "images"), "labels": str(src / "labels"),
                                "vps": str(src / "vps.csv")}
                entry["camera"] = str(wd / "native.yaml")
                continue
            entry[split] = simulate(wd / "native.yaml", src / "images", src / "labels", wd / "cams" / name / split, name)
            # one camera file per camera: the train and test simulations share every parameter
            entry["camera"] = str(wd / "cams" / name / "train" / "camera.yaml")
        out[name] = entry
    for name in out:
        if CAMERAS[name] is not None:
            a = (wd / "cams" / name / "train" / "camera.yaml").read_text()
            b = (wd / "cams" / name / "test" / "camera.yaml").read_text()
            if a != b:
                sys.exit(f"{name}: train and test simulations gave different cameras:\n{a}\n{b}")
    return out


def bar_plot(rows: list[dict], heldout: list[str], conditions: list[str]) -> np.ndarray:
    """Grouped bars: road IoU per held-out camera (groups) and condition (colours), plus the mean."""
    cell = {(r["heldout"], r["condition"]): r["iou"] for r in rows}
    for c in conditions:
        v = [cell[h, c] for h in heldout if (h, c) in cell]
        if v:
            cell["mean", c] = float(np.mean(v))
    return _bars(cell, heldout + ["mean"], conditions,
                 "road IoU (%) on the held-out camera's test frames, by held-out camera")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--epochs", type=int, default=6, help="training epochs per run (default 6)")
    ap.add_argument("--store-width", type=int, default=288, help="working width of the virtual stores (px)")
    from vctrain.study import CONDITIONS as AVAILABLE

    ap.add_argument("--conditions", default=",".join(CONDITIONS),
                    help=f"comma-separated, from {','.join(AVAILABLE)} (default: {','.join(CONDITIONS)})")
    ap.add_argument("--workdir", type=Path, default=ROOT / "benchmarks" / "out" / "cross_camera")
    ap.add_argument("--results", type=Path, default=results_dir(__file__))
    args = ap.parse_args()
    if not DATA.is_dir():
        sys.exit(f"{DATA} not found: this benchmark needs the CamVid train/val folders of ../shared/data")
    import yaml

    t0 = time.perf_counter()
    wd = args.workdir.resolve()
    wd.mkdir(parents=True, exist_ok=True)
    print(f"simulating {len(CAMERAS)} cameras from CamVid into {wd} ...", file=sys.stderr, flush=True)
    datasets = make_cameras(wd)
    t_sim = time.perf_counter() - t0
    conditions = [c for c in args.conditions.split(",") if c]
    if not conditions or any(c not in AVAILABLE for c in conditions):
        sys.exit(f"--conditions: choose from {', '.join(AVAILABLE)}")
    study = {"datasets": list(datasets.values()), "conditions": conditions, "virtual": "design",
             "pan_range": 10, "tilt_range": 5, "store_width": args.store_width,
             "train": {"epochs": args.epochs, "arch": "segnet-narrow", "batch_size": 8, "seed": 0,
                       "val_fraction": 0.1, "hflip": True, "device": "cpu"}}
    (wd / "study.yaml").write_text(yaml.safe_dump(study, sort_keys=False))
    summary = json.loads(run(BIN / "vctrain", "crossval", wd / "study.yaml", "--out", wd / "study", "--json",
                             "--jobs", "2", stream=True).strip().splitlines()[-1])
    total = time.perf_counter() - t0

    rows = [json.loads(line) for line in (wd / "study" / "results.jsonl").read_text().splitlines()]
    heldout = list(datasets)
    res = args.results
    res.mkdir(parents=True, exist_ok=True)
    table = (wd / "study" / "table.md").read_text()
    study_json = json.loads((wd / "study" / "study.json").read_text())
    virt = study_json["virtual"]
    cams = {n: yaml.safe_load(Path(d["camera"]).read_text()) for n, d in datasets.items()}
    lines = [
        "# Cross-camera study on CamVid (benchmarks/archive/other_cameras/cross_camera.py)", "",
        table.strip(), "",
        f"- Cameras (simulated exactly from CamVid; train = a disjoint quarter of CamVid train each, "
        f"test = CamVid val through that camera, {rows[0]['test_items'] if rows else '?'} frames):",
    ]
    for n, c in cams.items():
        hf = 2 * np.degrees(np.arctan(c["image_size"][0] / 2 / c["fx"]))
        lines.append(f"  - {n}: {c['image_size'][0]}x{c['image_size'][1]}, fx {c['fx']:.1f}, fy {c['fy']:.1f}, "
                     f"HFOV {hf:.1f} deg, tilt {c['tilt']:.2f}, pan {c['pan']:.2f}"
                     + (f" ({' '.join(CAMERAS[n])})" if CAMERAS[n] else " (as released)"))
    lines += [
        f"- Virtual camera (designed from the four, pan +/-10, tilt +/-5): {virt['image_size'][0]}x"
        f"{virt['image_size'][1]}, f {virt['fx']:.1f}, height {virt['height']:.2f} m; store scale "
        f"{study_json['scale']:.4f} -> working size {rows[0]['input_size'][0]}x{rows[0]['input_size'][1]}"
        if rows else "",
        f"- Training: segnet-narrow, {args.epochs} epochs, batch 8, SGD lr 0.005 poly, hflip, seed 0, CPU "
        f"({platform.processor() or platform.machine()}, torch default threads); checkpoint by val IoU on 10 % of "
        "the training cameras' items.",
        f"- Wall time: {total / 60:.1f} min in all ({t_sim:.0f} s simulating cameras); "
        f"{sum(r['total_seconds'] for r in rows) / 60:.1f} min in the {len(rows)} runs of this invocation and earlier "
        "ones (resumed runs keep their time).",
    ]
    (res / "cross_camera.md").write_text("\n".join(lines) + "\n")
    shutil.copyfile(wd / "study" / "table.csv", res / "cross_camera.csv")
    (res / "cross_camera_runs.jsonl").write_text((wd / "study" / "results.jsonl").read_text())
    cv2.imwrite(str(res / "cross_camera.png"), bar_plot(rows, heldout, conditions))
    headline = {c: round(v, 4) for c, v in summary.items()}
    (res / "cross_camera.json").write_text(json.dumps(headline) + "\n")
    print(table, file=sys.stderr)
    print(json.dumps(headline))


if __name__ == "__main__":
    main()
