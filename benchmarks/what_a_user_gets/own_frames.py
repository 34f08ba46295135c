"""A user's own labelled frames (issue 60, item 1): use the shipped model as it is, fine-tune it with
``vctrain fit --init`` as a user types it, or train on the frames from ImageNet -- for 20, 60 and 200
frames, on a camera the model never saw and on one it knows.

    .venv/bin/python benchmarks/what_a_user_gets/own_frames.py [--set idd] [--base-epochs 30 | --model M]
                                                               [--frames 20,60,200] [--seeds 0,1,2]
                                                               [--conditions fine-tuned,before,imagenet]
                                                               [--controls-up-to 60 --large-seeds 0,1] [--fit-args "..."]

**Sets** (``--set``; ../shared/data; the test frames are the shipped model's held-out split of the set,
never a training drive's):

* ``idd`` (IDD-Lite): a user's first drives -- the training drives (number % 7 != 3) in number order,
  their frames in name order, the first N of them (20 frames: 4 drives, 60: 10, 200: 32); scored on
  the 170 frames of the 45 held-out drives (% 7 == 3);
* ``camvid``: the 62 frames of sequence 0001TP (one drive, the issue's case; N at most 62); scored on
  CamVid val (sequence 0016E5, 101 frames).

**Model**: ``--base-epochs N``: the shipped recipe (benchmarks/what_a_user_gets/shipped_model.py's study,
lite0fpn, ``resize``, seed 0, N epochs) trained on every development set's training split but the
set's own (WORKDIR/base/; a camera the model never saw). Otherwise ``--model`` (default the shipped
model, models/road-multicamera/road.pt: a camera it knows).

**Conditions**, each N and seed (``--conditions``; ``zero-shot`` always):

* ``zero-shot``: the model as it is (the same number for every seed);
* ``fine-tuned``: ``vctrain fit --baseline resize --images ... --labels ... --label-format ... --init MODEL``
  and nothing else (plus ``--fit-args`` when screening a variant): the defaults a user gets;
  the checkpoint averages the trained weights with the start (``--average-init``), and ``fine-tuned, not
  averaged`` scores the trained weights themselves (its ``model.last.pt``: the same fit);
* ``before``: the command the model card gave before issue 60 (``--init MODEL --epochs 40 --val-fraction 0``)
  as it then ran: at the frames' own size (``--size`` of the first frame);
* ``imagenet``: the same frames from the ImageNet encoder (``--model lite0fpn --size 480x360``, the cpu
  recipe: 20 epochs, a tenth held out at random).

``before`` and ``imagenet`` run up to ``--controls-up-to`` frames (default 60; 200 frames cost about 8
minutes a fit on 2 cores), and more frames run the seeds of ``--large-seeds`` (default ``--seeds``).

Scored in the set's own frames: road IoU = sum TP / sum (TP+FP+FN), precision and recall beside it, and
the wall time of each fit. **Targets** (issue 60; checked, not asserted): on a camera the model never
saw, 60 frames fine-tuned >= zero-shot + 2 (mean over seeds) in at most 10 minutes; 20 frames never
below zero-shot (every seed); on a camera it knows, never below zero-shot (every seed, every N).
Outputs benchmarks/what_a_user_gets/results/own_frames_<set>_<tag>.{md,json} (tag: ``unseen`` with
--base-epochs, ``shipped`` for the shipped model, else ``--tag``); the last stdout line is one JSON object.
Time: a fit of 60 frames takes about 2-3 minutes on 2 cores; the default run of ``--set idd`` about
an hour plus the base model (about 30 min at 30 epochs).
"""
from __future__ import annotations

import argparse
import json
import shlex
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import BIN, DATA, IDD, ROOT, require_data, run
from benchmarks.measure.report import machine, results_dir, today, write_json
from benchmarks.measure.stats import seed_stats
from benchmarks.what_a_user_gets.shipped_model import IDD_HELD, IDD_MOD
from vctrain.training import load_checkpoint

SHIPPED = ROOT / "models" / "road-multicamera" / "road.pt"
CONDITIONS = ("fine-tuned", "before", "imagenet")
RAW = "fine-tuned, not averaged"  # the trained weights of a fine-tuned checkpoint averaged with its start


def shipped_without(name: str, wd: Path, epochs: int, threads: int, arch: str = "lite0fpn") -> Path:
    """The shipped recipe (benchmarks/what_a_user_gets/shipped_model.py: its study, ``resize``, seed 0,
    network ``arch``: the shipped model's) trained on every development set's training split but set
    ``name``'s: WORKDIR/base/seed0/runs/_all/resize/model.pt (resumed where it stopped)."""
    from benchmarks.measure.studies import run_study
    from benchmarks.what_a_user_gets.shipped_model import study_file

    base = (wd / "base").resolve()
    base.mkdir(parents=True, exist_ok=True)
    path = study_file(base, False, epochs, arch)
    study = yaml.safe_load(path.read_text())
    study["datasets"] = [d for d in study["datasets"] if d["name"] != f"{name}-train"]
    path.write_text(yaml.safe_dump(study, sort_keys=False))
    run_study(path, base / "seed0", ["resize"], 0, threads)
    return base / "seed0" / "runs" / "_all" / "resize" / "model.pt"


def _idd() -> tuple[list[tuple[Path, Path, str]], list[tuple[Path, Path, str]]]:
    """(training pool, test frames) of IDD-Lite: (image, label, flat name '<drive>_<frame>')."""
    drives = sorted((d for d in (IDD / "leftImg8bit" / "train").iterdir() if d.is_dir()), key=lambda d: int(d.name))
    pool, test = [], []
    for d in drives:
        for im in sorted(d.glob("*_image.jpg")):
            stem = im.name[: -len("_image.jpg")]
            item = (im, IDD / "gtFine" / "train" / d.name / f"{stem}_label.png", f"{d.name}_{stem}")
            (test if int(d.name) % IDD_MOD == IDD_HELD else pool).append(item)
    return pool, test


def _camvid() -> tuple[list[tuple[Path, Path, str]], list[tuple[Path, Path, str]]]:
    """(the 62 frames of 0001TP, CamVid val)."""
    def items(split: str, glob: str) -> list[tuple[Path, Path, str]]:
        return [(p, DATA / f"{split}annot" / p.name, p.stem) for p in sorted((DATA / split).glob(glob))]
    return items("train", "0001TP_*.png"), items("val", "*.png")


# set -> (label format, its frames, the (image, label) suffixes of its format, what the split is)
SETS = {
    "idd": ("idd", _idd, ("_image.jpg", "_label.png"),
            "IDD-Lite: the first N frames of the training drives in number order; scored on the 170 frames of the 45 held-out drives"),
    "camvid": ("camvid", _camvid, (".png", ".png"),
               "CamVid: N of the 62 frames of sequence 0001TP; scored on CamVid val (0016E5, 101 frames)"),
}


def link_frames(items: list[tuple[Path, Path, str]], folder: Path, suffixes: tuple[str, str]) -> Path:
    """folder/{images,labels}: links to ``items`` under their flat names (made afresh)."""
    if folder.exists():
        shutil.rmtree(folder)
    for sub in ("images", "labels"):
        (folder / sub).mkdir(parents=True)
    for im, lab, name in items:
        (folder / "images" / f"{name}{suffixes[0]}").symlink_to(im)
        (folder / "labels" / f"{name}{suffixes[1]}").symlink_to(lab)
    return folder


def score(model: Path, test: Path, fmt: str, out: Path, threads: int) -> dict[str, float]:
    """Road IoU, precision and recall (%) of ``model`` on the test frames."""
    env = {"OMP_NUM_THREADS": str(threads)}
    run(BIN / "vctrain", "predict", model, test / "images", "--out", out, "--engine", "torch", "-q", env=env)  # (the engine studies score)
    res = json.loads(run(BIN / "vctrain", "eval", out, "--labels", test / "labels", "--label-format", fmt,
                         "--json", "-q", env=env).strip().splitlines()[-1])
    return {k: round(100 * float(res[k]), 2) for k in ("iou", "precision", "recall")}


def fit_args(condition: str, model: Path, frames: Path, fmt: str, extra: list[str]) -> list:
    """``vctrain fit``'s arguments for a condition on the training frames."""
    data = ["--baseline", "resize", "--images", frames / "images", "--labels", frames / "labels", "--label-format", fmt]
    if condition == "fine-tuned":
        return [*data, "--init", model, *extra]
    if condition == "before":
        from vcprep.io import image_size

        w, h = image_size(next((frames / "images").iterdir()))
        return [*data, "--init", model, "--epochs", 40, "--val-fraction", 0, "--size", f"{w}x{h}"]
    return [*data, "--model", "lite0fpn", "--size", "480x360"]


def measure(a: argparse.Namespace, model: Path, wd: Path) -> dict:
    """{condition: {N: [per-seed {iou, precision, recall, seconds}]}}."""
    fmt, frames_of, suffixes, _ = SETS[a.set]
    pool, test_items = frames_of()
    test = link_frames(test_items, wd / "frames" / "test", suffixes)
    env = {"OMP_NUM_THREADS": str(a.threads)}
    ns = [int(n) for n in a.frames.split(",")]
    zero = score(model, test, fmt, wd / "pred-zero-shot", a.threads)
    cells: dict[str, dict[str, list]] = {"zero-shot": {str(n): [] for n in ns}}
    for n in ns:
        frames = link_frames(pool[:n], wd / "frames" / f"train{n}", suffixes)
        for seed in (a.seeds if n <= a.controls_up_to or not a.large_seeds else a.large_seeds):
            cells["zero-shot"][str(n)].append({**zero, "seconds": 0.0})
            for cond in a.conditions:
                if cond != "fine-tuned" and n > a.controls_up_to:
                    continue
                out = wd / f"n{n}" / f"seed{seed}" / cond
                out.mkdir(parents=True, exist_ok=True)
                done = out / "cell.json"
                if not done.is_file():
                    t0 = time.perf_counter()
                    run(BIN / "vctrain", "fit", *fit_args(cond, model, frames, fmt, shlex.split(a.fit_args)),
                        "--seed", seed, "--out", out / "model.pt", "-q", env=env)
                    dt = time.perf_counter() - t0
                    done.write_text(json.dumps({**score(out / "model.pt", test, fmt, out / "pred", a.threads),
                                                "seconds": round(dt, 1)}))
                cell = json.loads(done.read_text())
                cells.setdefault(cond, {}).setdefault(str(n), []).append(cell)
                print(f"n={n} seed={seed} {cond}: {cell}", flush=True)
                raw = out / "raw.json"  # an averaged checkpoint: its trained weights (model.last.pt) too, no extra fit
                if cond == "fine-tuned" and not raw.is_file() and "average_init" in load_checkpoint(out / "model.pt"):
                    raw.write_text(json.dumps({**score(out / "model.last.pt", test, fmt, out / "pred-raw", a.threads),
                                               "seconds": cell["seconds"]}))
                if cond == "fine-tuned" and raw.is_file():
                    cells.setdefault(RAW, {}).setdefault(str(n), []).append(json.loads(raw.read_text()))
    return cells


def cell_means(cells: dict) -> dict:
    """'<condition>_n<N>_<iou|precision|recall|minutes>': the mean over seeds of each condition and N."""
    head: dict = {}
    for cond, by_n in cells.items():
        for n, rows in by_n.items():
            for k in ("iou", "precision", "recall"):
                head[f"{cond}_n{n}_{k}"] = round(float(np.mean([r[k] for r in rows])), 2)
            head[f"{cond}_n{n}_minutes"] = round(float(np.mean([r["seconds"] for r in rows])) / 60, 2)
    return head


def summarise(cells: dict, unseen: bool) -> tuple[dict, dict]:
    """(headline, targets): per condition and N the mean IoU, precision, recall and minutes; the
    fine-tuned gain over zero-shot paired per seed."""
    head = cell_means(cells)
    targets = {}
    for n, rows in cells.get("fine-tuned", {}).items():
        gain = seed_stats([r["iou"] - z["iou"] for r, z in zip(rows, cells["zero-shot"][n])])
        head[f"fine-tuned_minus_zero-shot_n{n}"] = round(gain["mean"], 2)
        head[f"fine-tuned_minus_zero-shot_n{n}_std"] = round(gain["std"], 2)
        head[f"fine-tuned_minus_zero-shot_n{n}_min"] = round(min(gain["per_seed"]), 2)
        if unseen and n == "60":
            targets["60 frames: fine-tuned >= zero-shot + 2"] = gain["mean"] >= 2
            targets["60 frames: fine-tuning <= 10 min"] = head["fine-tuned_n60_minutes"] <= 10
        if (unseen and n == "20") or not unseen:
            targets[f"{n} frames: fine-tuned never below zero-shot (every seed)"] = min(gain["per_seed"]) >= 0
    return head, targets


def table(cells: dict, a: argparse.Namespace, head: dict, model: str) -> str:
    lines = [f"{SETS[a.set][3]}; model {model}; seeds {a.seeds}; road IoU % (precision / recall), mean over seeds; "
             f"minutes a fit on {a.threads} cores." + (f" Fine-tuned with `{a.fit_args}`." if a.fit_args else ""), "",
             "| condition | " + " | ".join(f"{n} frames" for n in a.frames.split(",")) + " |",
             "|---|" + "---|" * len(a.frames.split(","))]
    for cond, by_n in cells.items():
        row = []
        for n in a.frames.split(","):
            if n not in by_n:
                row.append("-")
                continue
            per = " / ".join(f"{r['iou']:.1f}" for r in by_n[n])
            row.append(f"**{head[f'{cond}_n{n}_iou']:.1f}** ({head[f'{cond}_n{n}_precision']:.0f} / "
                       f"{head[f'{cond}_n{n}_recall']:.0f}; seeds {per}; {head[f'{cond}_n{n}_minutes']:.1f} min)")
        lines.append(f"| {cond} | " + " | ".join(row) + " |")
    gains = [f"{n} frames {head[f'fine-tuned_minus_zero-shot_n{n}']:+.1f} ± {head[f'fine-tuned_minus_zero-shot_n{n}_std']:.1f}"
             f" (worst seed {head[f'fine-tuned_minus_zero-shot_n{n}_min']:+.1f})"
             for n in a.frames.split(",") if f"fine-tuned_minus_zero-shot_n{n}" in head]
    return "\n".join(lines + (["", "Fine-tuned − zero-shot, paired per seed: " + "; ".join(gains) + "."] if gains else [])) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--set", default="idd", choices=list(SETS))
    ap.add_argument("--model", type=Path, default=SHIPPED)
    ap.add_argument("--base-epochs", type=int, default=0,
                    help="train the model first: the shipped recipe without the set, this many epochs (0: --model)")
    ap.add_argument("--frames", default="20,60,200", help="labelled frames to train on, comma list")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--conditions", default=",".join(CONDITIONS), help=f"of {', '.join(CONDITIONS)}")
    ap.add_argument("--controls-up-to", type=int, default=60,
                    help="run 'before' and 'imagenet' only for at most this many frames (their cost grows with N)")
    ap.add_argument("--large-seeds", default="", help="seeds above --controls-up-to frames (default: --seeds)")
    ap.add_argument("--fit-args", default="", help="more vctrain fit options for 'fine-tuned' (a variant)")
    ap.add_argument("--tag", default=None, help="results file tag (default: unseen / shipped / the model's stem)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--workdir", type=Path, default=None, help="default: benchmarks/out/own_frames/<set>_<tag>")
    a = ap.parse_args()
    require_data(IDD if a.set == "idd" else DATA)
    a.seeds = [int(s) for s in a.seeds.split(",") if s]
    a.large_seeds = [int(s) for s in a.large_seeds.split(",") if s]
    a.conditions = [c for c in a.conditions.split(",") if c]
    if set(a.conditions) - set(CONDITIONS):
        raise SystemExit(f"--conditions: use {', '.join(CONDITIONS)}")
    base_wd = ROOT / "benchmarks" / "out" / f"finetune_{a.set}"
    if a.base_epochs:
        a.model = shipped_without(a.set, base_wd, a.base_epochs, a.threads)
    tag = a.tag or ("unseen" if a.base_epochs else "shipped" if a.model == SHIPPED else a.model.stem)
    wd = a.workdir or ROOT / "benchmarks" / "out" / "own_frames" / f"{a.set}_{tag}"
    wd.mkdir(parents=True, exist_ok=True)
    cells = measure(a, a.model, wd)
    head, targets = summarise(cells, bool(a.base_epochs))
    model = a.model.relative_to(ROOT) if a.model.is_relative_to(ROOT) else a.model
    text = table(cells, a, head, str(model))
    text += "\n| target | met |\n|---|---|\n" + "".join(f"| {k} | {'yes' if v else 'no'} |\n" for k, v in targets.items())
    print(text)
    res = results_dir(__file__)
    (res / f"own_frames_{a.set}_{tag}.md").write_text(text)
    command = (f"benchmarks/what_a_user_gets/own_frames.py --set {a.set} "
               + (f"--base-epochs {a.base_epochs} " if a.base_epochs else f"--model {model} ")
               + f"--frames {a.frames} --seeds {','.join(map(str, a.seeds))} --conditions {','.join(a.conditions)} "
               + f"--controls-up-to {a.controls_up_to}"
               + (f" --large-seeds {','.join(map(str, a.large_seeds))}" if a.large_seeds else "")
               + (f" --fit-args {shlex.quote(a.fit_args)}" if a.fit_args else "") + (f" --tag {a.tag}" if a.tag else ""))
    write_json(res / f"own_frames_{a.set}_{tag}.json",
               {"headline": head, "targets": targets, "cells": cells, "seeds": a.seeds, "large_seeds": a.large_seeds or a.seeds, "frames": a.frames,
                "set": a.set, "split": SETS[a.set][3], "model": str(model), "unseen": bool(a.base_epochs),
                "fit_args": a.fit_args, "machine": machine(), "date": today(), "command": command})
    print(json.dumps(head))


if __name__ == "__main__":
    main()
