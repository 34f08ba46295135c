"""Where the virtual camera loses a held-out camera: one fold of benchmarks/other_cameras/multi_camera.py, looked at
pixel by pixel (issue 34).

    .venv/bin/python benchmarks/archive/other_cameras/loo_diagnose.py [--heldout idd] [--seed 0] [--every 4]
                                                              [--workdir benchmarks/out/multi_camera] [--threads 2]
    .venv/bin/python benchmarks/archive/other_cameras/loo_diagnose.py --calibrated-fold kitti_semantics --heldout idd
                     --workdir 'benchmarks/out/calibrated_loo/idd-1(0-4)(0-9)_x'      # a calibrated_loo.py fold

Reads the fold's finished models (``within`` of the ``extent: median`` study in WORKDIR/median/seed<k>,
``resize`` of WORKDIR/seed<k>) and the held-out camera's test store; trains nothing. On every
``--every``-th test frame, scored in the frame's own camera against its own label (road IoU = sum TP /
sum (TP + FP + FN), ignore excluded):

- **coverage**: the share of the label's road pixels that no store pixel reaches (the rectangle cut
  them off: a geometric loss) and the share ``within`` misses inside the covered part (the network's);
- **rows**: ``within``'s and ``resize``'s missed road (FN) and false road (FP) per eighth of the frame's
  height, top to bottom, as shares of the road / not-road pixels of that band;
- **scale**: ``within`` run at 0.5, 0.7, 1 and 1.4 times its working size (1 = the training's pixels
  per degree): whether the held-out camera's content is at the wrong scale for the network.

Baseline: ``resize`` on the same frames. Outputs benchmarks/other_cameras/results/loo_diagnose_<heldout>.{md,json};
the last stdout line is the JSON headline.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import ROOT
from benchmarks.measure.report import machine, results_dir, today, write_json

BANDS = 8
SCALES = (0.5, 0.7, 1.0, 1.4)


def _calibrated_fold(workdir: Path, fold: str, model: str, heldout: str, seed: int) -> tuple[Path, Path, Path]:
    """(within model, resize model, ``heldout``'s test store) of a fold of calibrated_loo.py (WORKDIR: its
    workdir for the IDD-Lite frames it ran, e.g. benchmarks/out/calibrated_loo/idd-1(0-4)(0-9)_x)."""
    base = workdir / model / fold / f"seed{seed}"
    within, resize = (base / "runs" / "_all" / c / "model.pt" for c in ("within", "resize"))
    store = base / "stores" / heldout / "test" / "within"
    for p in (within, resize, store / "store.json"):
        if not p.exists():
            sys.exit(f"{p}: not found (run benchmarks/other_cameras/calibrated_loo.py --model {model} --seeds {seed} "
                     f"--held-out {fold} first)")
    return within, resize, store


def _fold(workdir: Path, heldout: str, seed: int) -> tuple[Path, Path, Path]:
    """(within model, resize model, the held-out camera's test store) of one fold."""
    within = workdir / "median" / f"seed{seed}" / "runs" / heldout / "within" / "model.pt"
    resize = workdir / f"seed{seed}" / "runs" / heldout / "resize" / "model.pt"
    store = workdir / "median" / f"seed{seed}" / "stores" / heldout / "test" / "within"
    for p in (within, resize, store / "store.json"):
        if not p.exists():
            sys.exit(f"{p}: not found (run benchmarks/other_cameras/multi_camera.py --seeds {seed} and --extent median first)")
    return within, resize, store


def diagnose(within_ckpt: Path, resize_ckpt: Path, store_dir: Path, every: int) -> dict:
    from vcprep.warp import backproject_array
    from vcprep.io import read_image
    from vcprep.labels import decode_label, get_label_format
    from vcprep.store import Store
    from vctrain.metrics import RoadMetrics
    from vctrain.predict import Predictor

    pw, pr = Predictor(within_ckpt, device="cpu"), Predictor(resize_ckpt, device="cpu")
    st = Store.open(store_dir)
    recs = [r for r in st if r.get("label_source")][::every]
    scale_m = {s: RoadMetrics() for s in SCALES}
    m = {"within": RoadMetrics(), "resize": RoadMetrics()}
    band = {k: np.zeros((4, BANDS)) for k in m}  # FN, road, FP, not road per band
    road_total = uncovered = missed_covered = 0
    for rec in recs:
        lab = decode_label(read_image(rec["label_source"], label=True).array, get_label_format(rec["label_format"]),
                           rec["label_source"])
        road, notroad = lab == 1, lab == 0
        store_img = read_image(st.path(rec["image"])).array
        covered = backproject_array(np.ones(store_img.shape[:2], np.float32), rec, kind="prob") > 0.5
        preds = {}
        work = pw.working_size((store_img.shape[1], store_img.shape[0]))
        for s in SCALES:
            size = tuple(max(8, int(round(v * s))) for v in work)
            prob = np.clip(backproject_array(pw.road_probability(store_img, None, size), rec, kind="prob"), 0, 1)
            scale_m[s].add(prob >= 0.5, lab)
            if s == 1.0:
                preds["within"] = prob >= 0.5
        preds["resize"] = pr.road_probability(read_image(rec["source"]).array) >= 0.5
        h = lab.shape[0]
        for k, pred in preds.items():
            m[k].add(pred, lab)
            for b in range(BANDS):
                sl = slice(b * h // BANDS, (b + 1) * h // BANDS)
                band[k][:, b] += [(road[sl] & ~pred[sl]).sum(), road[sl].sum(), (notroad[sl] & pred[sl]).sum(),
                                  notroad[sl].sum()]
        road_total += int(road.sum())
        uncovered += int((road & ~covered).sum())
        missed_covered += int((road & covered & ~preds["within"]).sum())
    r4 = lambda x: round(float(x), 4)
    share = lambda a, b: [r4(x) for x in a / np.maximum(b, 1)]
    return {
        "frames": len(recs),
        "iou": {k: r4(v.result()["iou"]) for k, v in m.items()},
        "precision": {k: r4(v.result()["precision"]) for k, v in m.items()},
        "recall": {k: r4(v.result()["recall"]) for k, v in m.items()},
        "road_uncovered_share": r4(uncovered / max(road_total, 1)),
        "road_missed_inside_coverage_share": r4(missed_covered / max(road_total, 1)),
        "fn_share_by_band": {k: share(v[0], v[1]) for k, v in band.items()},
        "fp_share_by_band": {k: share(v[2], v[3]) for k, v in band.items()},
        "within_iou_by_scale": {f"{s:g}": r4(scale_m[s].result()["iou"]) for s in SCALES},
    }


def render(d: dict, heldout: str, seed: int) -> str:
    pct = lambda v: f"{100 * v:.1f}"
    lines = [f"Held out {heldout}, seed {seed}, {d['frames']} frames: road IoU within {pct(d['iou']['within'])} "
             f"(precision {pct(d['precision']['within'])}, recall {pct(d['recall']['within'])}), resize "
             f"{pct(d['iou']['resize'])} ({pct(d['precision']['resize'])}, {pct(d['recall']['resize'])}).", "",
             f"Road pixels no store pixel reaches: {pct(d['road_uncovered_share'])} %; road pixels within misses inside "
             f"the covered part: {pct(d['road_missed_inside_coverage_share'])} %.", "",
             "| band (top to bottom) | " + " | ".join(str(b + 1) for b in range(BANDS)) + " |",
             "|---|" + "---|" * BANDS]
    for k in ("within", "resize"):
        lines.append(f"| missed road, {k} (%) | " + " | ".join(pct(v) for v in d["fn_share_by_band"][k]) + " |")
    for k in ("within", "resize"):
        lines.append(f"| false road, {k} (%) | " + " | ".join(pct(v) for v in d["fp_share_by_band"][k]) + " |")
    lines += ["", "within at a multiple of its working size: " + ", ".join(
        f"{s}x {pct(v)}" for s, v in d["within_iou_by_scale"].items()) + "."]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--heldout", default="idd", choices=("lums", "bdd", "camvid", "cityscapes", "idd", "kitti_semantics",
                                                         "idd-est", "bdd-est", "lums-est"))
    ap.add_argument("--calibrated-fold", default=None, help="a fold of calibrated_loo.py (its held-out calibrated "
                    "camera); --heldout is then one of its test cameras and --workdir its workdir")
    ap.add_argument("--model", default="lite0fpn", help="with --calibrated-fold: the network of that run")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--every", type=int, default=4, help="every N-th test frame (1: all)")
    ap.add_argument("--workdir", type=Path, default=ROOT / "benchmarks" / "out" / "multi_camera")
    ap.add_argument("--threads", type=int, default=2)
    a = ap.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", str(a.threads))
    import torch

    torch.set_num_threads(a.threads)
    if a.calibrated_fold:
        within, resize, store = _calibrated_fold(a.workdir, a.calibrated_fold, a.model, a.heldout, a.seed)
        stem = f"loo_diagnose_{a.heldout}_calibrated_{a.calibrated_fold}"
        extra = f" --calibrated-fold {a.calibrated_fold} --model {a.model} --workdir '{a.workdir.resolve().relative_to(ROOT)}'"
    else:
        within, resize, store = _fold(a.workdir, a.heldout, a.seed)
        stem, extra = f"loo_diagnose_{a.heldout}", ""
    d = diagnose(within, resize, store, max(1, a.every))
    table = render(d, a.heldout, a.seed)
    if a.calibrated_fold:
        table = (f"A test-only camera of calibrated_loo.py's fold `{a.calibrated_fold}` ({a.model}, trained on the other "
                 "two calibrated cameras).\n\n" + table)
    print(table)
    res = results_dir(__file__)
    (res / f"{stem}.md").write_text(table)
    write_json(res / f"{stem}.json", {
        "headline": d, "heldout": a.heldout, "seed": a.seed, "every": a.every, "machine": machine(), "date": today(),
        "command": f"benchmarks/archive/other_cameras/loo_diagnose.py --heldout {a.heldout} --seed {a.seed} --every {a.every}"
                   + extra})
    print(json.dumps(d))


if __name__ == "__main__":
    main()
