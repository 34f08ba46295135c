"""Training benchmark on CamVid: virtual-camera model vs the plain-resize baseline, same budget.

    .venv/bin/python benchmarks/archive/what_a_user_gets/train.py [--epochs 6] [--workdir benchmarks/out/train]

Data: ../shared/data/camvid train (367) -> val (101), same camera (so this measures the pipeline
and the budget, not the cross-camera gain; that is benchmarks/archive/other_cameras/cross_camera.py). Model segnet-narrow on
the CPU, seed 0, SGD as `vctrain fit` documents, --epochs each (default 6: about 8 minutes per model
on this 2-core machine, inside the 20-minute budget). Working sizes with about the same pixel count:
virtual camera 344x176 (the 1/8 store halved), resize baseline 288x216 (CamVid's 4:3). Validation for
checkpoint selection uses the val store in the training domain; the reported IoU is measured in the
ORIGINAL val images after back-projection (`vctrain predict` + `vctrain eval`), ignore (id 11) excluded.
Never tuned on val. Last line: JSON with val_iou_vc, val_iou_resize, train_images_per_s.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import BIN, DATA, ROOT, run
from benchmarks.measure.report import results_dir, write_json


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--epochs", type=int, default=6)
    ap.add_argument("--workdir", type=Path, default=ROOT / "benchmarks" / "out" / "train")
    args = ap.parse_args()
    if not DATA.is_dir():
        sys.exit(f"{DATA} not found: this benchmark needs the CamVid train/val folders of ../shared/data")
    wd = args.workdir
    wd.mkdir(parents=True, exist_ok=True)
    stores = {}
    for split in ("train", "val"):
        stores[split] = wd / f"store_{split}"
        run(BIN / "vcprep", "warp", "--camera", "camvid", "--images", DATA / split, "--labels", DATA / f"{split}annot",
            "--label-format", "camvid", "--out", stores[split], "--quiet",
            "--virtual", "virtual", "--scale", "0.125", "--within", "none")  # (the 688x350 store it always timed)
    results = {}
    for name, extra in (("vc", ["--size", "344x176"]), ("resize", ["--baseline", "resize", "--size", "288x216"])):
        ck = wd / f"{name}.pt"
        t0 = time.perf_counter()
        summary = json.loads(run(BIN / "vctrain", "fit", stores["train"], "--val-store", stores["val"], "--epochs",
                                 args.epochs, "--seed", "0", "--out", ck, "--json", "--quiet", "--device", "cpu",
                                 *extra).strip().splitlines()[-1])
        fit_s = time.perf_counter() - t0
        pred = wd / f"pred_{name}"
        run(BIN / "vctrain", "predict", ck, "--store", stores["val"], "--out", pred, "--quiet")
        ev = json.loads(run(BIN / "vctrain", "eval", pred, "--labels", DATA / "valannot", "--label-format", "camvid",
                            "--json", "--quiet").strip().splitlines()[-1])
        results[name] = {"val_iou": ev["iou"], "val_f1": ev["f1"], "maxf": ev.get("maxf"), "fit_seconds": fit_s,
                         "train_images_per_s": summary.get("train_images_per_s"),
                         "best_val_iou_training_domain": summary.get("best_val_iou")}
        print(f"{name:<7} val IoU {ev['iou']:.3f}  F1 {ev['f1']:.3f}  MaxF {ev.get('maxf', float('nan')):.3f}  "
              f"fit {fit_s:.0f} s  {results[name]['train_images_per_s']:.2f} img/s", flush=True)
    headline = {"val_iou_vc": round(results["vc"]["val_iou"], 4), "val_iou_resize": round(results["resize"]["val_iou"], 4),
                "train_images_per_s": round(results["vc"]["train_images_per_s"], 3),
                "train_images_per_s_resize": round(results["resize"]["train_images_per_s"], 3),
                "epochs": args.epochs, "model": "segnet-narrow", "threads": "torch default (2 cores)",
                "data": "CamVid train 367 -> val 101"}
    write_json(results_dir(__file__) / "train.json", {"headline": headline, "detail": results}, indent=2)
    print(json.dumps(headline))


if __name__ == "__main__":
    main()
