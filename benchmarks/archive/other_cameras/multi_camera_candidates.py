"""Issue 44's candidates for a camera-aware model that wins when cameras are merged: one table of every measured one.

    .venv/bin/python benchmarks/archive/other_cameras/multi_camera_candidates.py [--workdir benchmarks/out/multi_camera/median] [--seeds 0,1]
                                                                         [--held-out idd,bdd]

Runs nothing: collects the finished leave-one-camera-out folds of ``benchmarks/other_cameras/multi_camera.py --extent
median`` (the recipe: balance: datasets, shading_aug 0.4, 35 steps x 20 epochs a model; cameras of
IDD-Lite, BDD100K and LUMS ASSUMED, in training and testing) from WORKDIR and its candidate studies:

* WORKDIR/seed<k>: crossval conditions ``within``, ``resize`` (the baseline: the same frames, steps and
  sampling, read as they are), ``average`` (within's and resize's probabilities averaged in the camera's
  pixels) and ``resize-vp`` (resize plus each frame's own road VP as a 4th input channel);
* WORKDIR/extra-<settings>/seed<k> (``multi_camera.py --train-extra``): ``within`` trained with extra
  settings. Two were measured and dropped again (the settings are gone; commits 76215da and 7b31c8a
  have them): ``blur_aug=1.5`` (half the items down- and up-sampled by up to 2.5x: IDD-Lite's frames
  are magnified 2.1-2.6x in the virtual camera) and ``seen_only=true`` (the loss ignores the labels
  completion filled in).
* WORKDIR/estimate-<names>/seed<k> (``multi_camera.py --camera-estimate``): ``within`` with those
  datasets' cameras estimated from their own frames and labels (``camera: estimate``) instead of their
  assumed camera files; run only on folds that hold out another dataset (its test geometry must not read
  its labels).

Road IoU (%) on every frame of the held-out camera in its own pixels; each candidate against ``resize``
of the same fold and seed (paired). Outputs benchmarks/other_cameras/results/multi_camera_candidates.{md,json}; the
JSON's ``headline`` has ``<candidate>_minus_resize_<fold>`` (mean over the seeds measured) and
``<candidate>_seeds_<fold>``. Which candidates and seeds are missing is listed, never filled in.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import ROOT
from benchmarks.measure.report import machine, results_dir, today, write_json

CONDITIONS = ["resize", "within", "average", "resize-vp"]  # crossval conditions of the median study


def studies(wd: Path) -> dict[str, tuple[Path, str]]:
    """candidate name -> (study folder, crossval condition in it)."""
    out = {c: (wd, c) for c in CONDITIONS}
    for extra in sorted(wd.glob("extra-*")):
        out["within + " + extra.name.removeprefix("extra-")] = (extra, "within")
    for est in sorted(wd.glob("estimate-*")):
        out["within, cameras estimated: " + est.name.removeprefix("estimate-")] = (est, "within")
    return out


def cells(wd: Path, seeds: list[int], held: list[str]) -> dict[str, dict[str, list]]:
    """{candidate: {fold: [IoU % per seed, None where not finished]}}."""
    out: dict[str, dict[str, list]] = {}
    for name, (sd, cond) in studies(wd).items():
        for t in held:
            row = []
            for s in seeds:
                f = sd / f"seed{s}" / "runs" / t / cond / "result.json"
                r = json.loads(f.read_text()) if f.is_file() else {}
                # (a row of a warping condition scored before test splits were warped as predict warps them
                # is not counted; resize and resize-vp read the frames as they are)
                ok = r.get("test_warp") or (r and cond in ("resize", "resize-vp"))
                row.append(100 * r["iou"] if ok else None)
            out.setdefault(name, {})[t] = row
    return out


def paired(cand: list, resize: list) -> list[float]:
    """candidate − resize per seed, over the seeds where both were measured."""
    return [a - b for a, b in zip(cand, resize) if a is not None and b is not None]


def fold_mean(folds: dict[str, list], resize: dict[str, list], held: list[str]) -> float | None:
    """The mean over the held-out folds of (candidate − resize, paired per seed, mean over the seeds);
    None unless every fold has at least one pair (a mean over some folds is not the target's)."""
    per = []
    for t in held:
        d = paired(folds[t], resize[t])
        if not d:
            return None
        per.append(float(np.mean(d)))
    return float(np.mean(per))


def headline(c: dict[str, dict[str, list]], held: list[str]) -> dict:
    head: dict = {}
    for name, folds in c.items():
        key = name.replace(" + ", "_").replace(", ", "_").replace(": ", "_").replace(" ", "_").replace("=", "-")
        if name != "resize" and len(held) > 1:
            over = fold_mean(folds, c["resize"], held)
            head[f"{key}_minus_resize_fold_mean"] = None if over is None else round(over, 2)
        for t in held:
            d = paired(folds[t], c["resize"][t])
            head[f"{key}_{t}"] = round(float(np.mean([v for v in folds[t] if v is not None])), 2) \
                if any(v is not None for v in folds[t]) else None
            if name != "resize":
                head[f"{key}_minus_resize_{t}"] = round(float(np.mean(d)), 2) if d else None
                head[f"{key}_seeds_{t}"] = len(d)
    return head


def render(c: dict[str, dict[str, list]], seeds: list[int], held: list[str]) -> str:
    """One row per candidate, one column per held-out fold: each seed's IoU (``-``: not measured) and,
    in brackets, the candidate − resize paired per seed and averaged over the seeds that have both."""
    f = lambda v: "-" if v is None else f"{v:.1f}"
    seeds_txt = " / ".join(f"s{s}" for s in seeds)
    lines = [f"# Issue 44: camera-aware candidates, leave one camera out (held out: {', '.join(held)})", "",
             "Recipe of benchmarks/other_cameras/multi_camera.py --extent median (balance: datasets, shading_aug 0.4, 35 steps x 20 "
             "epochs = 700 steps a model). Cameras: CamVid and Cityscapes calibrated; IDD-Lite, BDD100K and LUMS "
             "ASSUMED, in training and in testing (unless a candidate estimates them). Road IoU (%) on all frames "
             f"of the held-out camera in its own pixels, each fold trained on the other four; per cell seeds "
             f"{seeds_txt}, in brackets the mean difference to `resize` of the same fold and seeds (paired). Test "
             "splits warped as `vctrain predict` warps them. Written by benchmarks/archive/other_cameras/multi_camera_candidates.py.", "",
             "| candidate | " + " | ".join(held) + " | mean over the folds − resize |",
             "|---|" + "---|" * (len(held) + 1)]
    for name, folds in c.items():
        vals = []
        for t in held:
            d = paired(folds[t], c["resize"][t])
            vals.append(" / ".join(f(v) for v in folds[t])
                        + ("" if name == "resize" or not d else f" ({np.mean(d):+.1f})"))
        over = fold_mean(folds, c["resize"], held)
        vals.append("" if name == "resize" else ("-" if over is None else f"{over:+.1f}"))
        lines.append(f"| {name} | " + " | ".join(vals) + " |")
    missing = []
    for n, folds in c.items():
        gaps = [f"{t} s{s}" for t in held for i, s in enumerate(seeds) if folds[t][i] is None]
        if gaps:
            missing.append(f"{n}: {', '.join(gaps)}")
    if missing:
        lines += ["", "Not measured (a candidate is dropped as soon as its numbers say so): "
                  + "; ".join(missing) + "."]
    return "\n".join(lines) + "\n"


def fold_args(doc: str) -> tuple[argparse.Namespace, list[int], list[str]]:
    """The options of the scripts that read a finished median workdir: (args, seeds, held-out folds)."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--workdir", type=Path, default=ROOT / "benchmarks" / "out" / "multi_camera" / "median")
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--held-out", default="idd,bdd")
    a = ap.parse_args()
    return a, [int(s) for s in a.seeds.split(",")], a.held_out.split(",")


def main() -> None:
    a, seeds, held = fold_args(__doc__)
    c = cells(a.workdir, seeds, held)
    table = render(c, seeds, held)
    print(table)
    res = results_dir(__file__)
    (res / "multi_camera_candidates.md").write_text(table)
    head = headline(c, held)
    write_json(res / "multi_camera_candidates.json", {
        "headline": head, "cells": c, "seeds": seeds, "held_out": held, "workdir": str(a.workdir),
        "machine": machine(), "date": today(),
        "command": f"benchmarks/archive/other_cameras/multi_camera_candidates.py --seeds {a.seeds} --held-out {a.held_out}"})
    print(json.dumps(head))


if __name__ == "__main__":
    main()
