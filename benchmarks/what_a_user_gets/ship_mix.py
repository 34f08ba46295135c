"""A candidate data mix for the shipped model trained at the shipped budget (issue 82, item 3): its own
held-out splits (what a user of its training cameras keeps) against today's shipped model, same run.

    .venv/bin/python benchmarks/what_a_user_gets/ship_mix.py [--candidate four] [--epochs 30] [--seeds 0]
                                                             [--threads 2] [--shipped models/road-multicamera/road.pt]
                                                             [--also models/road-street/road.pt]
                                                             [--workdir benchmarks/out/ship_mix] [--quick] [--collect]

**Study** (``shipped_model.study_file``: the splits never by frame): the candidate's datasets
(``ship_loo.CANDIDATES``) trained on their training splits (role ``train``), the held-out splits of all
six development sets and the KITTI road frame tested (role ``test``; the sets the candidate does not
train on are cameras new to it). The shipped recipe otherwise: ``resize`` (the frames read as they
are), ``lite0fpn`` from ImageNet, ``balance: datasets``, lens shading 0.4, ``--epochs`` of 35 steps (the
shipped model: 30), the checkpoint chosen on the training splits' validation share.

**Baseline in the same run**: the model ``--shipped`` names (``road-multicamera``, the one shipped before issue
82; its keys ``shipped_<set>``) and each ``--also`` model (``road-street``, shipped since; keys ``<its folder>_<set>``),
scored on the very same test stores by ``vctrain.study.evaluate_heldout``, the function that scores the study's own
models.

The held-out-camera verdict is ``benchmarks/other_cameras/ship_loo.py``'s; this script says what the
candidate keeps or loses on the cameras it trains on. Outputs:
benchmarks/what_a_user_gets/results/ship_mix_<candidate>.{md,json}; the model at
WORKDIR/<candidate>/epochs<N>/seed<k>/runs/_all/resize/model.pt (``--ship DIR``: DIR/road.pt, the first seed's,
less the optimizer state, and DIR/results.json). Last stdout line: one JSON object
(``<who>_<set>``, ``<who>_precision_<set>``, ``<who>_recall_<set>``, ``mean_<who>``).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import BDD, CITYSCAPES, DATA, IDD, KITTI, KITTI_SEM, LUMS, ROOT, require_data
from benchmarks.measure.keyed import scored_on_store
from benchmarks.measure.studies import run_study, share_stores
from benchmarks.other_cameras.ship_loo import CANDIDATES
from benchmarks.measure.report import machine, results_dir, today, write_json
from benchmarks.what_a_user_gets.shipped_model import SETS, collect, ship_checkpoint, study_file
from vctrain.training import RECIPES

SPLITS = [t for t in SETS if t != "kitti"] + ["kitti_semantics", "kitti"]
KEYS = ("iou", "precision", "recall")


def shipped_scores(model: Path, sd: Path, sets: list[str], who: str = "shipped") -> dict[str, dict]:
    """{set: {iou, precision, recall} %} of ``model`` on each resize test store of the study ``sd`` (cached
    in sd/<who>/ for the model's bytes and the store's items: :mod:`benchmarks.measure.keyed`)."""
    from vctrain.study import CONDITIONS, evaluate_heldout

    out = {}
    for t in sets:
        cache, store = sd / who / f"result-{t}.json", sd / "stores" / t / "test" / CONDITIONS["resize"][0]
        row = scored_on_store(cache, model, store, lambda: {**evaluate_heldout(model, store), "model": str(model)})
        if row is not None:
            out[t] = {k: round(100 * row[k], 2) for k in KEYS if row.get(k) is not None}
    return out


def render(head: dict, cand: str, a: argparse.Namespace, also: list[str] = ()) -> str:
    """The table: a row per held-out split, the candidate, today's shipped model (``--shipped``) and each
    ``--also`` model, the candidate's difference to each."""
    f = lambda v: "-" if v is None else f"{v:.1f}"
    cell = lambda who, t: (f"{f(head.get(f'{who}_{t}'))} ({f(head.get(f'{who}_precision_{t}'))} / "
                           f"{f(head.get(f'{who}_recall_{t}'))})")
    diff = lambda who, t: ("-" if head.get(f"{cand}_{t}") is None or head.get(f"{who}_{t}") is None
                           else f"{head[f'{cand}_{t}'] - head[f'{who}_{t}']:+.1f}")
    new = lambda t: "" if t == "kitti" or t in CANDIDATES[cand] else " (new to it)"
    whos = ["shipped", *also]
    names = [f"`{a.shipped.parent.name}`" if w == "shipped" else f"`{w}`" for w in whos]
    lines = [f"Issue 82: candidate `{cand}` ({', '.join(CANDIDATES[cand])}) trained at the shipped budget ({a.epochs} "
             f"epochs of 35 steps, seeds {a.seeds}, resize, lite0fpn) against {' and '.join(names)} on the same "
             "held-out splits. Road IoU % (precision / recall %).", "",
             f"| held-out split | `{cand}` | " + " | ".join(names) + " | " + " | ".join(
                 f"difference to {n}" if len(whos) > 1 else "difference" for n in names) + " |",
             "|---|---|" + "---|" * 2 * len(whos)]
    for t in SPLITS:
        lines.append(f"| {t}{new(t)} | {cell(cand, t)} | " + " | ".join(cell(w, t) for w in whos) + " | "
                     + " | ".join(diff(w, t) for w in whos) + " |")
    lines.append(f"| mean | {f(head.get(f'mean_{cand}'))} | " + " | ".join(f(head.get(f"mean_{w}")) for w in whos)
                 + " |" + " |" * len(whos))
    return "\n".join(lines) + "\n"


def rel(p: Path) -> str:
    """``p`` relative to the repository where it is inside it."""
    return str(p.resolve().relative_to(ROOT)) if p.resolve().is_relative_to(ROOT) else str(p)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--candidate", default="four", choices=sorted(CANDIDATES))
    ap.add_argument("--epochs", type=int, default=RECIPES["multicamera"]["epochs"], help="default: the shipped recipe's")
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--shipped", type=Path, default=ROOT / "models" / "road-multicamera" / "road.pt")
    ap.add_argument("--also", type=Path, action="append", default=[], help="another model scored beside it on the "
                    "same stores (repeatable), named by its folder: e.g. --also models/road-street/road.pt")
    ap.add_argument("--workdir", type=Path, default=ROOT / "benchmarks" / "out" / "ship_mix")
    ap.add_argument("--quick", action="store_true", help="smoke run: a few frames, 2 steps")
    ap.add_argument("--collect", action="store_true", help="train nothing: report what is finished")
    ap.add_argument("--ship", type=Path, default=None, help="copy the first seed's model here (road.pt, less the "
                    "optimizer state) with results.json")
    a = ap.parse_args()
    seeds, cand = [int(s) for s in a.seeds.split(",")], a.candidate
    require_data(DATA, CITYSCAPES, IDD, BDD, LUMS, KITTI, KITTI_SEM)
    wd = (a.workdir / cand / f"epochs{a.epochs}" / ("quick" if a.quick else "")).resolve()
    wd.mkdir(parents=True, exist_ok=True)
    cells: dict[str, list] = {}
    for seed in seeds:
        sd = wd / f"seed{seed}"
        if not a.collect:
            share_stores(wd, seed, seeds[0])
            study = study_file(wd, a.quick, a.epochs, "lite0fpn", kitti_semantics=True, train_on=CANDIDATES[cand])
            run_study(study, sd, ["resize"], seed, a.threads)
        iou, _, _, pr = collect(sd, ["resize"], SPLITS)
        for t in SPLITS:
            cells.setdefault(f"{cand}_{t}", []).append(iou["resize"][t])
            for k in ("precision", "recall"):
                cells.setdefault(f"{cand}_{k}_{t}", []).append(pr.get(f"{k}_resize_{t}"))
    also = [m.parent.name for m in a.also]
    for who, model in [("shipped", a.shipped), *zip(also, a.also)]:
        for t, row in shipped_scores(model, wd / f"seed{seeds[0]}", SPLITS, who).items():
            for k, v in row.items():
                cells[f"{who}_{t}" if k == "iou" else f"{who}_{k}_{t}"] = [v]
    head = {k: round(float(np.mean([x for x in v if x is not None])), 2) if any(x is not None for x in v) else None
            for k, v in cells.items()}
    for who in (cand, "shipped", *also):
        v = [head.get(f"{who}_{t}") for t in SPLITS]
        head[f"mean_{who}"] = None if None in v else round(float(np.mean(v)), 2)
    table = render(head, cand, a, also)
    print(table)
    res = (wd / "results") if a.quick else results_dir(__file__)
    (res / f"ship_mix_{cand}.md").parent.mkdir(parents=True, exist_ok=True)
    (res / f"ship_mix_{cand}.md").write_text(table)
    write_json(res / f"ship_mix_{cand}.json", {
        "headline": head, "cells": cells, "candidate": cand, "datasets": CANDIDATES[cand], "splits": SPLITS,
        "epochs": a.epochs, "seeds": seeds, "shipped": rel(a.shipped), "also": {w: rel(m) for w, m in zip(also, a.also)}, "threads": a.threads, "machine": machine(),
        "date": today(), "issue": 82, "command": "benchmarks/what_a_user_gets/ship_mix.py " + " ".join(sys.argv[1:])})
    model = wd / f"seed{seeds[0]}" / "runs" / "_all" / "resize" / "model.pt"
    if a.ship and model.is_file():
        a.ship.mkdir(parents=True, exist_ok=True)
        ship_checkpoint(model, a.ship / "road.pt")
        write_json(a.ship / "results.json", json.loads((res / f"ship_mix_{cand}.json").read_text()))
    print(json.dumps(head))


if __name__ == "__main__":
    main()
