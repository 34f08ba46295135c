"""benchmarks/other_cameras/ship_loo.py (issue 82): the headline and the issue's targets from per-seed cells.
A candidate with a fold still to train has no mean, so no target is judged on it: a mean of the folds it has
would compare it with its baseline on other cameras."""
from __future__ import annotations

import pytest

from benchmarks.other_cameras import ship_loo

FOLDS = ["kitti_semantics", "camvid", "cityscapes", "idd"]


def _cells(cand: str, iou: dict, precision: dict) -> dict:
    out = {}
    for f in FOLDS:
        out[f"{cand}|{f}|iou"] = list(iou[f])
        out[f"{cand}|{f}|precision"] = list(precision[f])
        out[f"{cand}|{f}|recall"] = [None if x is None else 90.0 for x in iou[f]]
    return out


def test_targets_of_a_complete_candidate_against_its_budgets_baseline():
    base = {f: [80.0, 80.0] for f in FOLDS}
    cand = {"kitti_semantics": [84.0, 84.0], "camvid": [84.0, 86.0], "cityscapes": [79.5, 79.5], "idd": [83.0, 83.0]}
    cells = {**_cells("today-30", base, {f: [90.0, 90.0] for f in FOLDS}),
             **_cells("four-30", cand, {f: [91.0, 92.0] for f in FOLDS})}
    head = ship_loo.headline(cells, ["today-30", "four-30"], FOLDS, [0, 1])
    assert head["four-30_mean"] == pytest.approx(82.88) and head["four-30_minus_today-30"] == pytest.approx(2.88)
    assert head["four-30_worst_fold_minus_today-30"] == -0.5 and head["four-30_precision_mean"] == 91.5
    tg = ship_loo.targets(head, ["today-30", "four-30"])
    assert tg == {"four-30: mean >= today-30 + 3": False, "four-30: precision up": True,
                  "four-30: no fold below today-30 - 1": True}


def test_a_candidate_with_a_fold_to_train_is_not_judged():
    base = {f: [80.0, 80.0] for f in FOLDS}
    cand = {**{f: [85.0, None] for f in FOLDS}, "idd": [None, None]}
    prec = {**{f: [95.0, None] for f in FOLDS}, "idd": [None, None]}  # above the baseline where measured
    cells = {**_cells("today-30", base, {f: [90.0, 90.0] for f in FOLDS}), **_cells("six-30", cand, prec)}
    head = ship_loo.headline(cells, ["today-30", "six-30"], FOLDS, [0, 1])
    assert head["six-30_camvid"] == 85.0 and head["six-30_idd"] is None
    assert head["six-30_mean"] is None and head["six-30_precision_mean"] is None
    assert set(ship_loo.targets(head, ["today-30", "six-30"]).values()) == {None}


def test_precision_is_judged_on_the_seeds_both_have_finished_paired():
    base = {f: [80.0, 80.0] for f in FOLDS}
    cand = {**{f: [84.0, 84.0] for f in FOLDS}, "camvid": [84.0, 90.0], "idd": [84.0, None]}  # seed 1 part-trained
    prec = {**{f: [91.0, 99.0] for f in FOLDS}, "idd": [91.0, None]}
    cells = {**_cells("today-30", base, {f: [92.0, 88.0] for f in FOLDS}), **_cells("six-30", cand, prec)}
    head = ship_loo.headline(cells, ["today-30", "six-30"], FOLDS, [0, 1])
    # seed 0 only: 91 against the baseline's 92 (a mean over whatever seeds each fold has would say 94 against 90)
    assert head["six-30_precision_mean"] == 91.0 and head["today-30_precision_mean"] == 90.0
    assert head["six-30_precision_minus_today-30"] == -1.0 and head["six-30_minus_today-30"] == 4.0
    assert ship_loo.targets(head, ["today-30", "six-30"])["six-30: precision up"] is False
    # a fold's cell is read on the seeds with every fold, as the mean: the part-trained seed 1 shows in none
    assert head["six-30_camvid"] == 84.0 and head["six-30_precision_camvid"] == 91.0


def test_scores_of_an_earlier_checkout_are_carried_and_a_new_result_file_wins(tmp_path):
    import json
    old = {"epochs": 6, "steps_per_epoch": 35, "seeds": [0, 1], "condition": {"four-30": "resize"},
           "budget_factor": {"four-30": 5},
           "cells": {"four-30|camvid|iou": [90.0, None], "four-30|camvid|precision": [95.0, None],
                     "four-30|camvid|recall": [94.0, None], "four-30|idd|iou": [85.0, 84.0],
                     "four-30|idd|precision": [96.0, 97.0], "four-30|idd|recall": [88.0, 86.0]}}
    (tmp_path / "ship_loo.json").write_text(json.dumps(old))
    earlier = ship_loo.kept(tmp_path / "ship_loo.json", 6, 35)
    assert set(earlier) == {"four-30|camvid|seed0", "four-30|idd|seed0", "four-30|idd|seed1"}
    assert ship_loo.kept(tmp_path / "ship_loo.json", 10, 35) == {}  # another protocol carries nothing
    wd = tmp_path / "wd"
    f = ship_loo.result_file(wd, 1, "four-30", "idd")  # seed 1's idd retrained in this workdir
    f.parent.mkdir(parents=True)
    f.write_text(json.dumps({"iou": 0.8, "precision": 0.9, "recall": 0.85, "train_seconds": 1800}))
    cells, missing, minutes, carried = ship_loo.collect(wd, ["four-30"], ["camvid", "idd"], [0, 1], earlier)
    assert cells["four-30|idd|iou"] == [85.0, 80.0] and cells["four-30|camvid|precision"] == [95.0, None]
    assert carried == ["four-30|camvid|seed0", "four-30|idd|seed0"] and missing == ["four-30|camvid|seed1"]
    assert minutes == [30.0]  # the carried scores have no training time on record


def test_a_models_minutes_count_every_epoch_it_trained_when_a_resume_recorded_only_the_last_invocation(tmp_path):
    import json
    f = ship_loo.result_file(tmp_path, 1, "four-30", "camvid")
    f.parent.mkdir(parents=True)
    f.write_text(json.dumps({"iou": 0.91, "precision": 0.96, "recall": 0.95, "train_seconds": 1800}))
    log = f.parent / "model.log.jsonl"
    # 4 epochs of 90 s before the interruption, 26 of 80 s after it: 2,440 s, where train.json says 1,800
    log.write_text("".join(json.dumps({"epoch": e, "seconds": 60.0, "val_seconds": 30.0 if e <= 4 else 20.0}) + "\n"
                           for e in range(1, 31)))
    assert ship_loo.model_minutes(f, json.loads(f.read_text())) == pytest.approx(2440 / 60, abs=0.01)
    log.write_text(json.dumps({"epoch": 1, "seconds": 60.0, "val_seconds": 30.0}) + "\n")  # less than train_seconds
    assert ship_loo.model_minutes(f, json.loads(f.read_text())) == 30.0  # (setup and saving are in train_seconds)
    log.unlink()
    assert ship_loo.model_minutes(f, json.loads(f.read_text())) == 30.0


def test_the_worst_fold_is_judged_on_the_seeds_both_have_finished_paired():
    base = {**{f: [80.0, None] for f in FOLDS}, "cityscapes": [84.85, None]}  # the baseline has seed 0 only
    cand = {**{f: [85.0, 85.0] for f in FOLDS}, "cityscapes": [84.35, 83.02]}
    cells = {**_cells("today-30", base, {f: [90.0, None] for f in FOLDS}),
             **_cells("four-30", cand, {f: [90.0, 90.0] for f in FOLDS})}
    head = ship_loo.headline(cells, ["today-30", "four-30"], FOLDS, [0, 1])
    # seed 0: 84.35 - 84.85; the candidate's two-seed cell (83.69) against the baseline's one would say -1.16
    assert head["four-30_cityscapes"] == pytest.approx(83.69) and head["today-30_cityscapes"] == 84.85
    assert head["four-30_worst_fold_minus_today-30"] == pytest.approx(-0.5)
    assert ship_loo.targets(head, ["today-30", "four-30"])["four-30: no fold below today-30 - 1"] is True
