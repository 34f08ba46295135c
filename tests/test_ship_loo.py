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
