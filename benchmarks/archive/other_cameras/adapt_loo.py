"""Adapting to a held-out camera without its labels: does the geometric prior beat self-training? (issue 34)

    .venv/bin/python benchmarks/archive/other_cameras/adapt_loo.py [--folds idd,bdd] [--seeds 0,1] [--threads 2]
                                                           [--workdir benchmarks/out/multi_camera/adapt]

A user always has unlabelled frames of their own camera. In the virtual camera the project can adapt a
model to them with the training cameras' geometric prior p_g (``vctrain adapt``, paper §4.5); the resize
twin has no prior, but it can self-train on its own confident predictions. This benchmark puts the two
side by side on folds of the leave-one-camera-out benchmark (benchmarks/other_cameras/multi_camera.py: train on four
real cameras, test on ALL frames of the fifth, road IoU = sum TP / sum (TP+FP+FN) in its own camera).

**Conditions**, one ``vctrain crossval`` study (the LOO study file, WORKDIR/seed<k>/, ``--heldout`` the
folds): ``within`` (the virtual camera; the adapt conditions need one rectangle, so this within model
is trained afresh in it), ``adapt`` (surrogate labels: the prior's 0.25/0.75 tri-mask), ``adapt-fuse``
(the prior fused with the model's own P(road)), ``adapt-self`` (the model's own P(road) alone: what
self-training gives without the prior); ``resize`` (the twin: the LOO study's own model and score, which
no rectangle touches); and here ``resize-self``: the resize twin self-trained exactly as
``adapt-self`` (its P(road) on the held-out frames, tri-mask 0.25/0.75, the twin's own training settings
for 5 epochs of at most the study's steps at a tenth of its learning rate, no validation, the study's
seed); and ``resize-fuse``: the same, its P(road) first fused with the prior carried back from the virtual
camera into each frame (the frame's own VP pose; ``vctrain predict --prior``'s p_g): the prior's geometry
with the resize twin's network. **Every adaptation is transductive**: it adapts to the frames it is scored on, without their
labels (what a user with one folder of frames does).

**Read**: adapt-fuse - adapt-self is what the prior adds to self-training in the virtual camera;
adapt-fuse - resize-self is the user's question (each with its best unlabelled recipe); resize-fuse -
resize-self is what the prior adds to a network that never saw the virtual camera.
Outputs benchmarks/other_cameras/results/adapt_loo.{md,json}; the last stdout line is one JSON object.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import BIN, ROOT, run
from vcprep.labels import get_label_format
from benchmarks.measure.report import machine, results_dir, today, write_json

COMBINED = ["within", "adapt", "adapt-fuse", "adapt-self"]
LO, HI = 0.25, 0.75
PSEUDO_FORMAT = "values:road=1;ignore=255;max=255"


def flat_items(ds: dict, wd: Path) -> Path:
    """wd/<name>: images/ and labels/ of the dataset's test split as links named by item id (IDD-Lite's
    '<drive>_<frame>' ids collide as file stems), each in the dataset's own naming rule."""
    from vcprep.dataset import list_dataset

    fmt = get_label_format(ds["label_format"])
    split = ds["test"]
    jobs = list_dataset(split["images"], split["labels"], fmt)
    d = wd / ds["name"]
    if d.exists():
        shutil.rmtree(d)
    for sub in ("images", "labels"):
        (d / sub).mkdir(parents=True)
    for j in jobs:
        (d / "images" / f"{j.id}{fmt.image_suffix}{j.image.suffix}").symlink_to(j.image)
        (d / "labels" / f"{j.id}{fmt.label_suffix}{j.label.suffix}").symlink_to(j.label)
    return d


def score(model: Path, flat: Path, fmt: str, out: Path, threads: int) -> float:
    """Road IoU (%) of a resize model on the flat test frames (vctrain predict, vctrain eval)."""
    env = {"OMP_NUM_THREADS": str(threads)}
    run(BIN / "vctrain", "predict", model, flat / "images", "--out", out, "-q", env=env)
    res = json.loads(run(BIN / "vctrain", "eval", out, "--labels", flat / "labels", "--label-format", fmt,
                         "--json", "-q", env=env).strip().splitlines()[-1])
    return 100 * float(res["iou"])


def prior_in_frames(adapt_run: Path, image_suffix: str) -> dict[str, np.ndarray]:
    """{flat image stem: p_g in the frame's own pixels}: the training cameras' prior (the adapt run's
    prior.npy) carried back from the virtual camera into each frame of its target store (each frame's
    own VP pose, as ``vctrain predict --prior``; 0 where the virtual image does not reach)."""
    from vcprep.store import Store
    from vctrain.adapt import PriorPredictor

    prior, store = PriorPredictor(adapt_run / "prior.npy"), Store.open(adapt_run / "target.store")
    return {f"{rec['id']}{image_suffix}": prior.store_item(store, rec) for rec in store}


def pseudo_labels(pred: Path, flat: Path, out: Path, prior: dict[str, np.ndarray] | None = None) -> dict[str, float]:
    """out/<image stem>.png: the 0.25/0.75 tri-mask (0 / 1 / 255) of each frame's P(road) (pred's
    <stem>_prob.png), with ``prior`` first fused with that frame's p_g (vctrain.adapt.fuse); returns the
    label shares."""
    from vcprep.io import read_image, write_png
    from vcprep.prior import surrogate_labels
    from vctrain.adapt import fuse

    out.mkdir(parents=True, exist_ok=True)
    counts = np.zeros(3, np.int64)
    for img in sorted((flat / "images").iterdir()):
        p = read_image(pred / f"{img.stem}_prob.png", label=True).array.astype(np.float32) / 255.0
        if prior is not None:
            p = fuse(prior[img.stem], p)
        lab = surrogate_labels(p, LO, HI)  # vctrain adapt's tri-mask
        write_png(out / f"{img.stem}.png", lab, kind="mask")
        counts += [np.count_nonzero(lab == 1), np.count_nonzero(lab == 0), np.count_nonzero(lab == 255)]
    return dict(zip(("road", "not_road", "ignore"), (counts / max(counts.sum(), 1)).round(4).tolist()))


def resize_adapted(model: Path, flat: Path, fmt: str, out: Path, seed: int, max_steps: int, threads: int,
                   prior: dict[str, np.ndarray] | None = None) -> dict:
    """The resize twin fine-tuned on the tri-mask of its own P(road) on the flat frames (``prior``: fused
    with the prior carried into each frame first), as ``vctrain adapt`` would (the model's own training
    settings, 5 epochs, a tenth of its learning rate, no validation)."""
    from vctrain.adapt import own_settings
    from vctrain.training import load_checkpoint
    from vctrain.training import ADAPT_EPOCHS, ADAPT_LR_FACTOR
    from vctrain.training import fit

    if (out / "result.json").is_file():
        return json.loads((out / "result.json").read_text())
    asis = score(model, flat, fmt, out / "pred-as-is", threads)
    shares = pseudo_labels(out / "pred-as-is", flat, out / "pseudo", prior)
    ck = load_checkpoint(model)
    cfg = own_settings(
        ck, stores=[], baseline="resize", images=str(flat / "images"), labels=str(out / "pseudo"),
        label_format=PSEUDO_FORMAT, out=str(out / "model.pt"), init=str(model), resume=None, log=None,
        val_fraction=0.0, val_stores=[], size=tuple(ck["data"]["input_size"]), epochs=ADAPT_EPOCHS,
        lr=ADAPT_LR_FACTOR * float(ck["config"]["lr"]), seed=seed, max_steps=max_steps, balance="items",
        progress=False, workers=0)
    t0 = time.perf_counter()
    fit(cfg)
    res = {"resize": round(asis, 2), "adapted": round(score(out / "model.pt", flat, fmt, out / "pred", threads), 2),
           "label_shares": shares, "adapt_seconds": round(time.perf_counter() - t0, 1)}
    write_json(out / "result.json", res)
    return res


def one_seed(seed: int, folds: list[str], loo: Path, wd: Path, threads: int) -> tuple[dict, dict]:
    """({fold: {condition: IoU %}}, {fold: extra figures}) of one seed (its crossval study resumes)."""
    study = loo / "study.yaml"
    spec = yaml.safe_load(study.read_text())
    sets = {d["name"]: d for d in spec["datasets"]}
    sd, loo_seed = wd / f"seed{seed}", loo / f"seed{seed}"
    missing = [f for f in folds if not (loo_seed / "runs" / f / "resize" / "model.pt").is_file()]
    if missing:
        raise SystemExit(f"needs the LOO study's resize models of {', '.join(missing)} in {loo_seed} "
                         f"(run benchmarks/other_cameras/multi_camera.py --seeds {seed} first)")
    run(BIN / "vctrain", "crossval", study, "--out", sd, "--conditions", ",".join(COMBINED),
        "--heldout", ",".join(folds), "--seed", seed, "--jobs", threads, stream=True)
    cells: dict[str, dict[str, float]] = {f: {} for f in folds}
    # the adapt conditions' study (one rectangle) and, for resize, the LOO study itself: no rectangle touches
    # the resize twin, and a study with adapt conditions would retrain it under another key for nothing
    for path, conds in ((sd / "results.jsonl", COMBINED), (loo_seed / "results.jsonl", ["resize"])):
        for r in (json.loads(x) for x in path.read_text().splitlines() if x.strip()):
            if r["heldout"] in cells and r["condition"] in conds:
                cells[r["heldout"]][r["condition"]] = round(100 * float(r["iou"]), 2)
    extra: dict[str, dict] = {}
    max_steps = int((spec.get("train") or {}).get("max_steps") or 0) or None
    for f in folds:
        flat = flat_items(sets[f], wd / "frames")
        model, fmt = loo_seed / "runs" / f / "resize" / "model.pt", sets[f]["label_format"]
        res = resize_adapted(model, flat, fmt, wd / "resize-self" / f"seed{seed}" / f, seed, max_steps, threads)
        pg = prior_in_frames(sd / "runs" / f / "adapt", get_label_format(fmt).image_suffix)
        fused = resize_adapted(model, flat, fmt, wd / "resize-fuse" / f"seed{seed}" / f, seed, max_steps, threads, pg)
        cells[f]["resize-self"], cells[f]["resize-fuse"] = res["adapted"], fused["adapted"]
        extra[f] = {"resize_by_predict_eval": res["resize"], "resize_self_label_shares": res["label_shares"],
                    "resize_fuse_label_shares": fused["label_shares"]}
    return cells, extra


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--folds", default="idd,bdd", help="held-out datasets of the LOO study")
    ap.add_argument("--seeds", default="0", help="comma-separated; each needs the LOO study's seed")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--loo", type=Path, default=ROOT / "benchmarks" / "out" / "multi_camera",
                    help="the LOO benchmark's workdir (its study.yaml; its finished resize models are reused)")
    ap.add_argument("--workdir", type=Path, default=None, help="default: LOO/adapt")
    a = ap.parse_args()
    loo = a.loo.resolve()
    if not (loo / "study.yaml").is_file():
        raise SystemExit(f"needs {loo / 'study.yaml'} (run benchmarks/other_cameras/multi_camera.py first)")
    wd = (a.workdir or loo / "adapt").resolve()
    folds = [f for f in a.folds.split(",") if f]
    seeds = [int(x) for x in a.seeds.split(",") if x]
    os.environ["OMP_NUM_THREADS"] = str(a.threads)
    per_seed, extra = {}, {}
    for seed in seeds:
        per_seed[seed], extra[seed] = one_seed(seed, folds, loo, wd, a.threads)
    conds = ["resize", "resize-self", "resize-fuse"] + COMBINED
    pairs = (("adapt-fuse", "adapt-self"), ("adapt", "within"), ("adapt-fuse", "resize-self"),
             ("adapt-self", "within"), ("resize-self", "resize"), ("resize-fuse", "resize-self"),
             ("resize-fuse", "resize"), ("within", "resize"))
    # cells: {fold: {condition: mean over seeds}}; per seed in per_seed
    cells = {f: {k: round(float(np.mean([per_seed[s][f][k] for s in seeds])), 2) for k in conds
                 if all(per_seed[s][f].get(k) is not None for s in seeds)} for f in folds}
    head: dict = {}
    for f in folds:
        for k in conds:
            head[f"{k}_{f}"] = cells[f].get(k)
        for x, y in pairs:
            d = [per_seed[s][f][x] - per_seed[s][f][y] for s in seeds if x in per_seed[s][f] and y in per_seed[s][f]]
            if len(d) == len(seeds):
                head[f"{x}_minus_{y}_{f}"] = round(float(np.mean(d)), 2)
                head[f"{x}_minus_{y}_{f}_std"] = round(float(np.std(d, ddof=1)), 2) if len(d) > 1 else None
    lines = [f"Adapting to a held-out camera without its labels (LOO folds {', '.join(folds)}, seeds {seeds}; "
             "every adaptation transductive: on the frames it is scored on); road IoU (%).", "",
             "| held out | seed | " + " | ".join(conds) + " |", "|---|---|" + "---|" * len(conds)]
    for f in folds:
        rows = [(str(s), per_seed[s][f]) for s in seeds] + ([("mean", cells[f])] if len(seeds) > 1 else [])
        lines += [f"| {f} | {name} | " + " | ".join("-" if c.get(k) is None else f"{c[k]:.1f}" for k in conds) + " |"
                  for name, c in rows]
    table = "\n".join(lines) + "\n"
    print(table)
    res_dir = results_dir(__file__)
    (res_dir / "adapt_loo.md").write_text(table)
    write_json(res_dir / "adapt_loo.json", {
        "headline": head, "cells": cells, "per_seed": {str(s): per_seed[s] for s in seeds},
        "extra": {str(s): extra[s] for s in seeds}, "folds": folds, "seeds": seeds, "lo": LO, "hi": HI,
        "machine": machine(), "date": today(),
        "command": f"benchmarks/archive/other_cameras/adapt_loo.py --folds {a.folds} --seeds {a.seeds} --threads {a.threads}"})
    print(json.dumps(head))
    sys.stdout.flush()


if __name__ == "__main__":
    main()
