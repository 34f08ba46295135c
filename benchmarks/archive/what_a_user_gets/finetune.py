"""Fine-tuning on a camera the model has not seen: 20 labelled frames of it (issue 34, item 4).

    .venv/bin/python benchmarks/archive/what_a_user_gets/finetune.py [--set lums] [--base-epochs 120 | --model M] [--seeds 0,1,2]
                                                             [--epochs 40[,120]] [--lr-factors 0.1[,0.3]] [--frames 20[,10,5]]
                                                             [--threads 2]
                                                             [--workdir benchmarks/out/finetune]

**Sets** (``--set``; ../shared/data, each with the camera it ships with; held out by capture range or city,
never by frame):

* ``lums`` (the verdict): the first 20 frames (capture order) of captures 400-466 to train on; scored on
  every frame of the other captures (1-79 and 160-319, 118 frames);
* ``cityscapes`` (the development camera the fine-tuning recipe is chosen on, so LUMS's test frames
  choose nothing): the first 20 frames in name order (cs_0001 ..., the release's first city); scored on
  cs_25xx .. cs_29xx (43 frames, the shipped model's held-out cities).

Scored in the set's own camera (back-projected; road IoU = sum TP / sum (TP+FP+FN), ignore excluded).

**Model**: ``--base-epochs N`` trains it first: the shipped recipe (benchmarks/what_a_user_gets/shipped_model.py's study,
``resize``, seed 0, N epochs) on every development set's training split but the set's own (WORKDIR/base/;
its scores on the shipped model's held-out splits are recorded as ``base_heldout``).
Otherwise ``--model``, by default the LOO benchmark's fold of the set, seed 0, of ``--condition``
(benchmarks/out/multi_camera/seed0/runs/<set>/<condition>/model.pt: a LOO fold's 20-epoch budget).
Every frame's road VP (a virtual-camera model only): ``--vps`` or the LOO study's estimates beside it.

**Conditions**, each seed and each ``--epochs`` E:

* ``as-is``: the model, no training on the set;
* ``fine-tuned``: ``vctrain fit --init MODEL`` on the 20 frames (a resize model: the frames as they are,
  ``--baseline resize``; a virtual-camera model: warped into its own virtual camera, ``vcprep warp
  --virtual`` with the checkpoint's store parameters), E epochs at each ``--lr-factors`` share of the
  recipe's learning rate (default a tenth, vctrain adapt's rule);
* ``scratch``: the same frames, epochs and steps from random weights at the recipe's learning rate.

``--frames 20,10,5`` also runs the recipe (first epochs and factor) and scratch on the first 10 and 5 of
the 20 frames. No validation share (20 frames): the last epoch is the model. **Target** (checked, not asserted), on the
first epochs and the first factor (the recipe): fine-tuned >= both others + 3 points, mean over seeds.
Outputs benchmarks/what_a_user_gets/results/finetune.{md,json} (``--set lums``) or finetune_<set>.{md,json}; the last
stdout line is one JSON object.
"""
from __future__ import annotations

import argparse
import json
import re
import shutil
import sys
from fnmatch import fnmatch
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import BIN, CITYSCAPES, CS_FORMAT, LUMS, LUMS_FORMAT, ROOT, run
from benchmarks.measure.report import machine, results_dir, today, write_json
from benchmarks.measure.stats import seed_stats
from benchmarks.what_a_user_gets.own_frames import shipped_without
from vctrain.training import load_checkpoint

N_TRAIN = 20


def capture(stem: str) -> int:
    """The capture number N of a LUMS stem 'color_N_png.rf.<hash>'."""
    return int(re.match(r"color_(\d+)_", stem).group(1))


def _lums(stems: list[str]) -> tuple[list[str], list[str]]:
    stems = sorted(stems, key=lambda s: (capture(s), s))
    return [s for s in stems if 400 <= capture(s) <= 466][:N_TRAIN], [s for s in stems if capture(s) < 400]


def _cityscapes(stems: list[str]) -> tuple[list[str], list[str]]:
    stems = sorted(stems)
    return stems[:N_TRAIN], [s for s in stems if fnmatch(s, "cs_2[5-9]*")]


# set -> (folder, label format, (train, test) stems from all stems, what the split is)
SETS = {
    "lums": (LUMS, LUMS_FORMAT, _lums, "LUMS: the first 20 frames of captures 400-466; scored on the 118 frames of captures 1-79 and 160-319"),
    "cityscapes": (CITYSCAPES, CS_FORMAT, _cityscapes, "Cityscapes: the first 20 frames (cs_0001 ...); scored on the 43 frames cs_25xx-cs_29xx"),
}


def split_frames(name: str, wd: Path, n: int = N_TRAIN) -> tuple[Path, Path]:
    """wd/frames/{train<n>,test}/{images,labels}: links to the first ``n`` of the set's 20 training
    frames and to its test frames."""
    root, _, pick, _ = SETS[name]
    images = {p.stem: p for p in (root / "images").iterdir() if p.suffix in (".jpg", ".png")}
    train, test = pick(list(images))
    out = []
    for sub_name, sel in ((f"train{n}", train[:n]), ("test", test)):
        d = wd / "frames" / sub_name
        if d.exists():
            shutil.rmtree(d)
        (d / "images").mkdir(parents=True)
        (d / "labels").mkdir(parents=True)
        for s in sel:
            (d / "images" / images[s].name).symlink_to(images[s])
            (d / "labels" / f"{s}.png").symlink_to(root / "labels" / f"{s}.png")
        out.append(d)
    return out[0], out[1]


def virtual_of(data: dict, wd: Path) -> tuple[Path, float]:
    """(wd/virtual.yaml, scale): the virtual camera and store scale a model was trained in (its
    checkpoint's ``data``)."""
    sp = data["store_params"]
    path = wd / "virtual.yaml"
    path.write_text(yaml.safe_dump(sp["virtual"], sort_keys=False))
    return path, float(sp["scale"])


def score(name: str, model: Path, test: Path, vps: Path, out: Path, threads: int, virtual: bool) -> float:
    """Road IoU (%) of ``model`` on the test frames of set ``name``."""
    root, fmt, _, _ = SETS[name]
    env = {"OMP_NUM_THREADS": str(threads)}
    geo = ["--camera", root / "camera.yaml", "--within", vps] if virtual else []
    run(BIN / "vctrain", "predict", model, test / "images", *geo, "--out", out, "-q", env=env)
    res = json.loads(run(BIN / "vctrain", "eval", out, "--labels", test / "labels", "--label-format", fmt,
                         "--json", "-q", env=env).strip().splitlines()[-1])
    return 100 * float(res["iou"])


def training_data(name: str, data: dict, train: Path, vps: Path, wd: Path, threads: int) -> tuple[list, bool]:
    """(``vctrain fit`` arguments for the training frames, whether the model is a virtual-camera one): a
    store warped into the model's virtual camera (``data``: its checkpoint's), or the folders for
    ``--baseline resize``."""
    root, fmt, _, _ = SETS[name]
    if data["mode"] == "resize":
        w, h = data["input_size"]  # the model's working size (a folder's default would be the frames' own)
        return ["--baseline", "resize", "--images", train / "images", "--labels", train / "labels",
                "--label-format", fmt, "--size", f"{w}x{h}"], False
    wd.mkdir(parents=True, exist_ok=True)
    virtual, scale = virtual_of(data, wd)
    store = wd / "store20"
    run(BIN / "vcprep", "warp", "--camera", root / "camera.yaml", "--virtual", virtual, "--scale", scale,
        "--images", train / "images", "--labels", train / "labels", "--label-format", fmt,
        "--within", vps, "--out", store, "-q", env={"OMP_NUM_THREADS": str(threads)})
    return [store], True


def grid(epochs: list[int], factors: list[float]) -> list[tuple[str, int, float | None]]:
    """The trained conditions (label, epochs, share of the recipe's lr or None from scratch); the first
    epochs and factor are the recipe the targets read ('fine-tuned', 'scratch')."""
    rows = []
    for k, e in enumerate(epochs):
        for j, f in enumerate(factors):
            rows.append(("fine-tuned" if k == j == 0 else f"fine-tuned lr x{f:g}, {e} epochs", e, f))
        rows.append(("scratch" if k == 0 else f"scratch, {e} epochs", e, None))
    return rows


def measure(a: argparse.Namespace, wd: Path, seeds: list[int]) -> tuple[dict[str, list[float]], bool]:
    """({condition: road IoU % per seed}, whether the model is a virtual-camera one)."""
    ns = [int(n) for n in a.frames.split(",")]
    _, test = split_frames(a.set, wd, ns[0])
    vps = a.vps or a.model.parents[3] / "vps" / f"{a.set}-test.csv"
    env = {"OMP_NUM_THREADS": str(a.threads)}
    model_ck = load_checkpoint(a.model)
    ck = model_ck["config"]
    epochs, factors = [int(e) for e in a.epochs.split(",")], [float(f) for f in a.lr_factors.split(",")]
    # (frames, label, epochs, lr share): the grid on the recipe's frames, then the recipe on fewer frames
    rows = [(ns[0], *r) for r in grid(epochs, factors)]
    rows += [(n, f"{what}, {n} frames", epochs[0], f) for n in ns[1:] for what, f in (("fine-tuned", factors[0]), ("scratch", None))]
    data = {}
    for n in ns:
        train, _ = split_frames(a.set, wd, n)
        data[n] = training_data(a.set, model_ck["data"], train, vps, wd / (f"n{n}" if n != N_TRAIN else ""), a.threads)
    is_virtual = data[ns[0]][1]
    cells: dict[str, list[float]] = {"as-is": []}
    asis = score(a.set, a.model, test, vps, wd / "pred-as-is", a.threads, is_virtual)
    for seed in seeds:
        cells["as-is"].append(asis)  # no training: the same number for every seed
        for n, label, e, f in rows:
            data_args = data[n][0]
            tag = "scratch" if f is None else "fine-tuned" if f == 0.1 else f"fine-tuned-x{f:g}"
            tag += f"-n{n}" if n != N_TRAIN else ""
            out = wd / f"seed{seed}" / (tag if e == 40 else f"{tag}-e{e}")  # the first runs' folder names kept
            # --average-init 0: the recipe as recorded (before issue 60 made WiSE-FT averaging --init's default)
            extra = ["--lr", ck["lr"]] if f is None else ["--init", a.model, "--lr", ck["lr"] * f, "--average-init", 0]
            if not (out / "model.pt").is_file():
                run(BIN / "vctrain", "fit", *data_args, "--out", out / "model.pt", "--epochs", e,
                    "--val-fraction", 0, "--seed", seed, "--balance", "items", *extra, "-q", env=env)
            cells.setdefault(label, []).append(score(a.set, out / "model.pt", test, vps, out / "pred", a.threads, is_virtual))
    return cells, is_virtual


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--set", default="lums", choices=list(SETS), help="the camera fine-tuned on (lums: the verdict)")
    ap.add_argument("--condition", default="resize", help="the LOO fold model's condition (default: the shipped one's)")
    ap.add_argument("--model", type=Path, default=None)
    ap.add_argument("--base-epochs", type=int, default=0,
                    help="train the model first: the shipped recipe without the set, this many epochs (0: --model)")
    ap.add_argument("--vps", type=Path, default=None, help="CSV id,u,v (default: beside the model's study)")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--epochs", default="40", help="comma list; the first is the recipe's")
    ap.add_argument("--lr-factors", default="0.1", help="fine-tuning lr as shares of the recipe's; the first is the recipe's")
    ap.add_argument("--frames", default="20", help="labelled frames to train on, comma list (at most 20; the first is the recipe's)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--workdir", type=Path, default=ROOT / "benchmarks" / "out" / "finetune")
    a = ap.parse_args()
    root = SETS[a.set][0]
    if a.base_epochs:
        a.model = shipped_without(a.set, a.workdir, a.base_epochs, a.threads)
    a.model = a.model or ROOT / "benchmarks" / "out" / "multi_camera" / "seed0" / "runs" / a.set / a.condition / "model.pt"
    if not a.model.is_file() or not root.is_dir():
        raise SystemExit(f"needs {a.model} (run benchmarks/other_cameras/multi_camera.py first) and {root}")
    if not all(1 <= int(n) <= N_TRAIN for n in a.frames.split(",")):
        raise SystemExit(f"--frames {a.frames}: each count must be 1..{N_TRAIN}")
    wd = a.workdir
    wd.mkdir(parents=True, exist_ok=True)
    seeds = [int(s) for s in a.seeds.split(",") if s]
    cells, is_virtual = measure(a, wd, seeds)
    head = {c: round(float(np.mean(v)), 2) for c, v in cells.items()}
    gain = {f"fine-tuned_minus_{c}": seed_stats([f - o for f, o in zip(cells["fine-tuned"], cells[c])]) for c in ("as-is", "scratch")}
    for k, s in gain.items():
        head[k], head[k + "_std"] = round(s["mean"], 2), round(s["std"] or 0.0, 2)
    targets = {f"fine-tuned >= {c} + 3": head[f"fine-tuned_minus_{c}"] >= 3 for c in ("as-is", "scratch")}
    e0, f0 = a.epochs.split(",")[0], a.lr_factors.split(",")[0]
    model = a.model.relative_to(ROOT) if a.model.is_relative_to(ROOT) else a.model
    lines = [f"Fine-tuning on {a.frames.split(',')[0]} labelled frames, {SETS[a.set][3]}; model {model}; recipe: {e0} epochs, "
             f"fine-tuned at lr x{f0} (scratch at the recipe's lr); seeds {seeds}; road IoU (%).", "",
             "| condition | " + " | ".join(f"seed {s}" for s in seeds) + " | mean |", "|---|" + "---|" * (len(seeds) + 1)]
    lines += [f"| {c} | " + " | ".join(f"{v:.1f}" for v in cells[c]) + f" | {np.mean(cells[c]):.1f} |" for c in cells]
    lines += ["", f"fine-tuned − as-is {head['fine-tuned_minus_as-is']:+.1f} ± {head['fine-tuned_minus_as-is_std']:.1f}; "
              f"fine-tuned − scratch {head['fine-tuned_minus_scratch']:+.1f} ± {head['fine-tuned_minus_scratch_std']:.1f}."]
    lines += ["", "| target | met |", "|---|---|"] + [f"| {k} | {'yes' if v else 'no'} |" for k, v in targets.items()]
    table = "\n".join(lines) + "\n"
    print(table)
    res = results_dir(__file__)
    stem = "finetune" if a.set == "lums" else f"finetune_{a.set}"
    (res / f"{stem}.md").write_text(table)
    command = (f"benchmarks/archive/what_a_user_gets/finetune.py --set {a.set} " + (f"--base-epochs {a.base_epochs} " if a.base_epochs else "")
               + f"--seeds {a.seeds} --epochs {a.epochs} --lr-factors {a.lr_factors} --frames {a.frames}")
    base_scores = {f.stem[len("result-"):]: round(100 * json.loads(f.read_text())["iou"], 2)
                   for f in sorted(a.model.parent.glob("result-*.json"))} if a.base_epochs else {}
    write_json(res / f"{stem}.json", {"headline": head, "base_heldout": base_scores, "targets": targets, "cells": cells, "seeds": seeds,
                                      "epochs": a.epochs, "lr_factors": a.lr_factors, "n_train": int(a.frames.split(",")[0]), "frames": a.frames,
                                      "set": a.set, "split": SETS[a.set][3], "model": str(model),
                                      "condition": "virtual camera" if is_virtual else "resize",
                                      "machine": machine(), "date": today(), "command": command})
    print(json.dumps(head))
    sys.stdout.flush()


if __name__ == "__main__":
    main()
