"""Fine-tuning on a camera the model has not seen: 20 labelled LUMS frames (issue 34, item 4).

    .venv/bin/python benchmarks/finetune.py [--condition resize] [--model M] [--seeds 0,1,2] [--epochs 40]
                                           [--threads 2] [--workdir benchmarks/out/finetune]

**Model**: ``--model`` (default: the LOO benchmark's LUMS fold, seed 0, of ``--condition``: resize, the
shipped model's (benchmarks/shipped_model.py ships the better of the two): benchmarks/out/multi_camera/
seed0/runs/lums/<condition>/model.pt, the shipped recipe trained on every development set but LUMS). **Frames**: LUMS (../shared/data/lums_road, its camera.yaml), the first 20
frames (capture order) of captures 400-466 to train on; scored on every frame of the other captures
(1-79 and 160-319, 118 frames), in LUMS's own camera (back-projected; road IoU = sum TP / sum (TP+FP+FN)).
Every frame's road VP: the LOO study's estimates (its vps/lums-test.csv), so the three conditions see
the same poses.

**Conditions**, each seed:

* ``as-is``: the model, no training on LUMS;
* ``fine-tuned``: ``vctrain fit --init MODEL`` on the 20 frames (a resize model: the frames as they are,
  ``--baseline resize``; a virtual-camera model: warped into its own virtual camera, ``vcprep warp
  --virtual`` with the checkpoint's store parameters), ``--epochs`` at a tenth of the recipe's learning
  rate (vctrain adapt's rule);
* ``scratch``: the same frames, epochs and steps from random weights at the recipe's learning rate.

No validation share (20 frames): the last epoch is the model. **Target** (checked, not asserted):
fine-tuned >= both others + 3 points, mean over seeds. Outputs benchmarks/results/finetune.{md,json};
the last stdout line is one JSON object.
"""
from __future__ import annotations

import argparse
import json
import re
import shutil
import sys
from pathlib import Path

import numpy as np
import yaml

from as_shipped import LUMS
from measure.data import BIN, LUMS_FORMAT, ROOT, run
from measure.report import machine, today, write_json
from measure.stats import seed_stats

N_TRAIN = 20
CONDS = ["as-is", "fine-tuned", "scratch"]


def capture(stem: str) -> int:
    """The capture number N of a LUMS stem 'color_N_png.rf.<hash>'."""
    return int(re.match(r"color_(\d+)_", stem).group(1))


def split_frames(wd: Path) -> tuple[Path, Path]:
    """wd/frames/{train20,test}/{images,labels}: links to the 20 training and the test frames."""
    stems = sorted((p.stem for p in (LUMS / "images").glob("*.jpg")), key=lambda s: (capture(s), s))
    train = [s for s in stems if 400 <= capture(s) <= 466][:N_TRAIN]
    test = [s for s in stems if capture(s) < 400]
    out = []
    for name, sel in (("train20", train), ("test", test)):
        d = wd / "frames" / name
        if d.exists():
            shutil.rmtree(d)
        for sub, ext in (("images", ".jpg"), ("labels", ".png")):
            (d / sub).mkdir(parents=True)
            for s in sel:
                (d / sub / f"{s}{ext}").symlink_to(LUMS / sub / f"{s}{ext}")
        out.append(d)
    return out[0], out[1]


def virtual_of(model: Path, wd: Path) -> tuple[Path, float]:
    """(wd/virtual.yaml, scale): the virtual camera and store scale the model was trained in."""
    import torch

    ck = torch.load(model, map_location="cpu", weights_only=False)
    sp = ck["data"]["store_params"]
    path = wd / "virtual.yaml"
    path.write_text(yaml.safe_dump(sp["virtual"], sort_keys=False))
    return path, float(sp["scale"])


def score(model: Path, test: Path, vps: Path, out: Path, threads: int, virtual: bool) -> float:
    """Road IoU (%) of ``model`` on the test frames."""
    env = {"OMP_NUM_THREADS": str(threads)}
    geo = ["--camera", LUMS / "camera.yaml", "--within", vps] if virtual else []
    run(BIN / "vctrain", "predict", model, test / "images", *geo, "--out", out, "-q", env=env)
    res = json.loads(run(BIN / "vctrain", "eval", out, "--labels", test / "labels", "--label-format", LUMS_FORMAT,
                         "--json", "-q", env=env).strip().splitlines()[-1])
    return 100 * float(res["iou"])


def training_data(model: Path, train: Path, vps: Path, wd: Path, threads: int) -> tuple[list, bool]:
    """(``vctrain fit`` arguments for the 20 frames, whether the model is a virtual-camera one): a
    store warped into the model's virtual camera, or the folders for ``--baseline resize``."""
    import torch

    data = torch.load(model, map_location="cpu", weights_only=False)["data"]
    if data["mode"] == "resize":
        w, h = data["input_size"]  # the model's working size (a folder's default would be the frames' own)
        return ["--baseline", "resize", "--images", train / "images", "--labels", train / "labels",
                "--label-format", LUMS_FORMAT, "--size", f"{w}x{h}"], False
    virtual, scale = virtual_of(model, wd)
    store = wd / "store20"
    run(BIN / "vcprep", "warp", "--camera", LUMS / "camera.yaml", "--virtual", virtual, "--scale", scale,
        "--images", train / "images", "--labels", train / "labels", "--label-format", LUMS_FORMAT,
        "--within", vps, "--out", store, "-q", env={"OMP_NUM_THREADS": str(threads)})
    return [store], True


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--condition", default="resize", help="the LOO fold model's condition (default: the shipped one's)")
    ap.add_argument("--model", type=Path, default=None)
    ap.add_argument("--vps", type=Path, default=None, help="CSV id,u,v (default: beside the model's study)")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--epochs", type=int, default=40)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--workdir", type=Path, default=ROOT / "benchmarks" / "out" / "finetune")
    a = ap.parse_args()
    a.model = a.model or ROOT / "benchmarks" / "out" / "multi_camera" / "seed0" / "runs" / "lums" / a.condition / "model.pt"
    if not a.model.is_file() or not LUMS.is_dir():
        raise SystemExit(f"needs {a.model} (run benchmarks/multi_camera.py first) and {LUMS}")
    vps = a.vps or a.model.parents[3] / "vps" / "lums-test.csv"
    wd = a.workdir
    wd.mkdir(parents=True, exist_ok=True)
    train, test = split_frames(wd)
    data_args, is_virtual = training_data(a.model, train, vps, wd, a.threads)
    env = {"OMP_NUM_THREADS": str(a.threads)}
    ck = json.loads(run(BIN / "python", "-c", "import json,torch;c=torch.load(r'%s',map_location='cpu',"
                        "weights_only=False);print(json.dumps(c['config']))" % a.model).strip().splitlines()[-1])
    seeds = [int(s) for s in a.seeds.split(",") if s]
    cells: dict[str, list[float]] = {c: [] for c in CONDS}
    asis = score(a.model, test, vps, wd / "pred-as-is", a.threads, is_virtual)
    for seed in seeds:
        cells["as-is"].append(asis)  # no training: the same number for every seed
        for cond in ("fine-tuned", "scratch"):
            out = wd / f"seed{seed}" / cond
            extra = ["--init", a.model, "--lr", ck["lr"] / 10] if cond == "fine-tuned" else ["--lr", ck["lr"]]
            if not (out / "model.pt").is_file():
                run(BIN / "vctrain", "fit", *data_args, "--out", out / "model.pt", "--epochs", a.epochs,
                    "--val-fraction", 0, "--seed", seed, "--balance", "items", *extra, "-q", env=env)
            cells[cond].append(score(out / "model.pt", test, vps, out / "pred", a.threads, is_virtual))
    head = {c: round(float(np.mean(v)), 2) for c, v in cells.items()}
    gain = {f"fine-tuned_minus_{c}": seed_stats([f - o for f, o in zip(cells["fine-tuned"], cells[c])]) for c in ("as-is", "scratch")}
    for k, s in gain.items():
        head[k], head[k + "_std"] = round(s["mean"], 2), round(s["std"] or 0.0, 2)
    targets = {f"fine-tuned >= {c} + 3": head[f"fine-tuned_minus_{c}"] >= 3 for c in ("as-is", "scratch")}
    lines = [f"Fine-tuning on {N_TRAIN} labelled LUMS frames (captures 400-466), scored on the 118 frames of the other "
             f"captures; model {a.model.relative_to(ROOT) if a.model.is_relative_to(ROOT) else a.model}; "
             f"{a.epochs} epochs, seeds {seeds}; road IoU (%).", "",
             "| condition | " + " | ".join(f"seed {s}" for s in seeds) + " | mean |", "|---|" + "---|" * (len(seeds) + 1)]
    lines += [f"| {c} | " + " | ".join(f"{v:.1f}" for v in cells[c]) + f" | {np.mean(cells[c]):.1f} |" for c in CONDS]
    lines += ["", f"fine-tuned − as-is {head['fine-tuned_minus_as-is']:+.1f} ± {head['fine-tuned_minus_as-is_std']:.1f}; "
              f"fine-tuned − scratch {head['fine-tuned_minus_scratch']:+.1f} ± {head['fine-tuned_minus_scratch_std']:.1f}."]
    lines += ["", "| target | met |", "|---|---|"] + [f"| {k} | {'yes' if v else 'no'} |" for k, v in targets.items()]
    table = "\n".join(lines) + "\n"
    print(table)
    res = ROOT / "benchmarks" / "results"
    (res / "finetune.md").write_text(table)
    write_json(res / "finetune.json", {"headline": head, "targets": targets, "cells": cells, "seeds": seeds,
                                       "epochs": a.epochs, "n_train": N_TRAIN, "model": str(a.model),
                                       "condition": "virtual camera" if is_virtual else "resize",
                                       "machine": machine(), "date": today(),
                                       "command": f"benchmarks/finetune.py --condition {a.condition} --seeds {a.seeds} "
                                                  f"--epochs {a.epochs}"})
    print(json.dumps(head))
    sys.stdout.flush()


if __name__ == "__main__":
    main()
