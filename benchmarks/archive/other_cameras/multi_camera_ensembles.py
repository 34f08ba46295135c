"""Is condition ``average`` the geometry or just an ensemble? Its control, on the leave-one-camera-out folds (issue 44).

    .venv/bin/python benchmarks/archive/other_cameras/multi_camera_ensembles.py [--workdir benchmarks/out/multi_camera/median]
                                                                        [--seeds 0,1] [--held-out idd,bdd]

Condition ``average`` (vctrain crossval) averages two networks, the ``within`` and the ``resize`` model of a
fold, in the held-out camera's pixels; its baseline ``resize`` is one network. Two networks averaged beat one
on their own (variance), so the fair control is two networks of ONE kind averaged: the fold's resize models
of two seeds (``resize x2``), and its within models of two seeds (``within x2``). Read from a finished
``benchmarks/other_cameras/multi_camera.py --extent median --conditions within,resize,average --seeds 0,1`` workdir
(WORKDIR/seed<k>/runs/<held out>/{within,resize}/model.pt); nothing is trained.

Every model predicts every labelled frame of the held-out camera's within test store of the first seed
once (the resize models read each record's source frame); the averages are formed from those
probabilities and scored like crossval scores a condition (P(road) >= 0.5 in the camera's own pixels,
road IoU = sum TP / sum (TP + FP + FN) over the set).

Reported per held-out camera (road IoU %): each seed's within, resize and average (within + resize of
that seed), then ``resize x2``, ``within x2`` and all four averaged; ``average`` against ``resize x2`` is
the geometry's share of average's gain. Outputs benchmarks/other_cameras/results/multi_camera_ensembles.{md,json}.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.archive.other_cameras.multi_camera_candidates import fold_args
from benchmarks.measure.report import machine, results_dir, today, write_json


def combos(seeds: list[int]) -> dict[str, list[tuple[str, int]]]:
    """Name -> the (condition, seed) models it averages."""
    out: dict[str, list[tuple[str, int]]] = {}
    for s in seeds:
        out[f"within s{s}"] = [("within", s)]
        out[f"resize s{s}"] = [("resize", s)]
        out[f"average s{s}"] = [("within", s), ("resize", s)]
    out["resize x2"] = [("resize", s) for s in seeds]
    out["within x2"] = [("within", s) for s in seeds]
    out["all four"] = [(c, s) for c in ("within", "resize") for s in seeds]
    return out


def score_fold(wd: Path, seeds: list[int], held: str) -> dict[str, float]:
    """Road IoU (%) of every combination on the held-out camera ``held``."""
    from vcprep.io import read_image
    from vcprep.labels import decode_label, get_label_format
    from vcprep.store import Store
    from vctrain.metrics import RoadMetrics
    from vctrain.predict import Predictor

    models = {(c, s): Predictor(wd / f"seed{s}" / "runs" / held / c / "model.pt", device="cpu")
              for c in ("within", "resize") for s in seeds}
    store = Store.open(wd / f"seed{seeds[0]}" / "stores" / held / "test" / "within")
    todo = combos(seeds)
    metrics = {k: RoadMetrics() for k in todo}
    for rec in store:
        if not rec.get("label_source"):
            continue
        prob = {k: p.store_item(store, rec) for k, p in models.items()}
        label = decode_label(read_image(rec["label_source"], label=True).array, get_label_format(rec["label_format"]),
                             rec["label_source"])
        for name, parts in todo.items():
            metrics[name].add(sum(prob[k] for k in parts) / len(parts) >= 0.5, label)
    return {k: round(100 * m.result()["iou"], 2) for k, m in metrics.items()}


def render(cells: dict[str, dict[str, float]], seeds: list[int]) -> str:
    names = list(combos(seeds))
    lines = ["Condition average against two networks of one kind (issue 44): road IoU (%) on all frames of the "
             "held-out camera, each fold trained on the other four (benchmarks/other_cameras/multi_camera.py --extent median "
             f"recipe), seeds {seeds}. `average sK` = within + resize of seed K (two networks); `resize x2` / "
             "`within x2` = the two seeds' models of one kind (two networks); `all four` = every model.", "",
             "| held out | " + " | ".join(names) + " | mean average − resize x2 |",
             "|---|" + "---|" * (len(names) + 1)]
    for t, c in cells.items():
        gap = np.mean([c[f"average s{s}"] for s in seeds]) - c["resize x2"]
        lines.append(f"| {t} | " + " | ".join(f"{c[n]:.1f}" for n in names) + f" | {gap:+.1f} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    a, seeds, held = fold_args(__doc__)
    cells = {t: score_fold(a.workdir, seeds, t) for t in held}
    table = render(cells, seeds)
    print(table)
    res = results_dir(__file__)
    (res / "multi_camera_ensembles.md").write_text(table)
    write_json(res / "multi_camera_ensembles.json", {
        "cells": cells, "seeds": seeds, "workdir": str(a.workdir), "machine": machine(), "date": today(),
        "command": f"benchmarks/archive/other_cameras/multi_camera_ensembles.py --seeds {a.seeds} --held-out {a.held_out}"})
    print(json.dumps({f"{t}_{k.replace(' ', '_')}": v for t, c in cells.items() for k, v in c.items()}))


if __name__ == "__main__":
    main()
