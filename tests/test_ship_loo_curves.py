"""benchmarks/other_cameras/ship_loo_curves.py (issue 82): the figures it derives from per-threshold counts, against
thresholding the probability maps directly; a model whose P(road) is a monotone rescaling of another's has the
other's precision at the other's recall (the same ranking of pixels: the same precision-recall curve)."""
from __future__ import annotations

import numpy as np

from benchmarks.other_cameras import ship_loo_curves as curves
from vctrain.metrics import KittiMetrics, RoadMetrics


def _scene(seed: int = 0, n: int = 20000) -> tuple[np.ndarray, np.ndarray]:
    """(P(road) float32, label 0/1/255): road pixels score higher on average; some pixels ignored."""
    rng = np.random.default_rng(seed)
    label = (rng.random(n) < 0.4).astype(np.uint8)
    prob = 1.0 / (1.0 + np.exp(-(rng.normal(0.0, 1.2, n) + 2.0 * label - 1.0)))
    label[rng.random(n) < 0.05] = 255
    return prob.astype(np.float32).reshape(100, -1), label.reshape(100, -1)


def _counts(prob: np.ndarray, label: np.ndarray) -> dict:
    road, km = RoadMetrics(), KittiMetrics()
    road.add(prob >= 0.5, label)
    km.add(np.clip(np.rint(prob * 255.0), 0, 255).astype(np.uint8), label)
    return {"at_half": road.result(), "pos_hist": km.pos_hist.tolist(), "neg_hist": km.neg_hist.tolist()}


def test_curve_is_the_thresholded_maps():
    prob, label = _scene()
    c = curves.curve(_counts(prob, label))
    q = np.clip(np.rint(prob * 255.0), 0, 255)
    valid, road = label != 255, label == 1
    for k in (0, 40, curves.HALF, 200, 255):
        m = q >= k
        tp, fp, fn = (m & road & valid).sum(), (m & ~road & valid).sum(), (~m & road & valid).sum()
        assert np.isclose(c["iou"][k], tp / (tp + fp + fn)) and np.isclose(c["recall"][k], tp / (tp + fn))
        assert np.isclose(c["precision"][k], tp / max(tp + fp, 1))
    assert np.all(np.diff(c["recall"]) <= 0)  # a higher threshold never finds more road


def test_precision_at_the_baselines_recall_is_the_curves_not_the_threshold():
    prob, label = _scene(1)
    base = _counts(prob, label)
    sharper = _counts(prob ** 3, label)  # the same ranking, far less road at 0.5
    assert sharper["at_half"]["recall"] < base["at_half"]["recall"] - 0.2
    m = curves.fold_metrics(sharper, base["at_half"]["recall"])
    assert abs(m["precision_at_baseline_recall"] - base["at_half"]["precision"]) < 0.01
    assert m["recall"] == sharper["at_half"]["recall"] and m["iou"] == sharper["at_half"]["iou"]
    assert abs(m["maxf"] - curves.fold_metrics(base, None)["maxf"]) < 0.01  # MaxF: the curve's, not the threshold's


def test_lofo_threshold_comes_from_the_other_folds():
    folds = {f: curves.curve(_counts(*_scene(s))) for f, s in (("a", 2), ("b", 3), ("c", 4))}
    cheat = dict(folds, c={k: v.copy() for k, v in folds["c"].items()})
    cheat["c"]["iou"][:] = 0.0
    cheat["c"]["iou"][250] = 1.0  # fold c's own best threshold: not what c is scored at
    for f, (t, iou) in curves.lofo(cheat).items():
        k = int(round(t * 255))
        assert k == int(np.argmax(np.mean([cheat[g]["iou"] for g in cheat if g != f], axis=0)))
        assert iou == cheat[f]["iou"][k]
    assert curves.lofo(cheat)["c"][1] == 0.0 and curves.lofo(cheat)["c"][0] != 250 / 255


def test_each_candidate_is_compared_with_todays_mix_at_its_own_budget():
    both = ["today", "four", "today-long", "four-long"]
    assert curves.compared_with("four", both) == "today"
    assert curves.compared_with("four-long", both) == "today-long"  # never the 6-epoch today
    assert curves.compared_with("today-long", both) is None  # a baseline is compared with nothing
    assert curves.compared_with("four-long", ["today", "four-long"]) is None  # its baseline not in this run


def test_a_run_without_the_models_would_lose_the_measured_cells_and_says_which():
    """A new checkout has no ship_loo models and no cached counts: scoring its candidates again would replace
    the committed curves with nothing. would_lose names each such cell; a candidate the run does not ask
    for, or a cell this run measures, is not one."""
    old = {"seeds": [0, 1], "cells": {"four|camvid|iou": [0.85, 0.86], "today|camvid|iou": [0.74, None]}}
    cells = {"four|camvid|iou": [0.85, None]}  # seed 1's model gone
    assert curves.would_lose(old, cells, ["four"], [0, 1]) == ["four|camvid|iou|seed1"]
    assert curves.would_lose(old, cells, ["four", "today"], [0, 1]) == ["four|camvid|iou|seed1", "today|camvid|iou|seed0"]
    assert curves.would_lose(old, {"four|camvid|iou": [0.85, 0.86]}, ["four"], [0, 1]) == []
    assert curves.would_lose(old, {"four|camvid|iou": [0.85]}, ["four"], [0]) == ["four|camvid|iou|seed1"]


def test_an_earlier_runs_figures_are_carried_only_where_ship_loo_scores_the_same_model_alike():
    """A new checkout has ship_loo's committed scores but not the models: a fold's earlier curve figures are kept
    where ship_loo's results file scores that candidate, fold and seed alike at 0.5 (the same model), and not where
    it scores it otherwise (a model trained again), not at all, or on a seed it does not have."""
    fig = {"iou": 0.8490, "precision": 0.9936, "recall": 0.8537, "ap": 0.9367}
    old = {"seeds": [0, 1], "cells": {f"today-30|camvid|{k}": [v, None] for k, v in fig.items()}
           | {f"four-30|camvid|{k}": [v, v] for k, v in fig.items()}}
    loo_result = {"seeds": [0], "cells": {"today-30|camvid|iou": [84.9], "today-30|camvid|precision": [99.36],
                                          "today-30|camvid|recall": [85.37], "four-30|camvid|iou": [90.81],
                                          "four-30|camvid|precision": [95.9], "four-30|camvid|recall": [94.49]}}
    kept = curves.carried(old, loo_result)
    assert kept == {"today-30|camvid|seed0": fig}  # four-30's seed 0 scored otherwise; seed 1 not in ship_loo's file
    loo_result["cells"]["today-30|camvid|recall"] = [85.40]  # a model trained again: 0.03 point off
    assert curves.carried(old, loo_result) == {}


def test_a_run_adds_its_scored_folds_to_the_carried_ones_and_compares_them_with_a_carried_baseline(tmp_path):
    """The folds this workdir has counts for are scored from them (the threshold chosen on the other folds
    included); the baseline's folds carried from an earlier run still give the candidate its precision at the
    baseline's recall; a fold neither has is missing."""
    import json

    from benchmarks.other_cameras import ship_loo as loo

    folds, counts = ["camvid", "cityscapes"], {}
    for fold, s in zip(folds, (5, 6)):
        counts[fold] = c = _counts(*_scene(s))
        result = loo.result_file(tmp_path, 1, "four-30", fold)
        result.parent.mkdir(parents=True)
        result.write_text(json.dumps({k: c["at_half"][k] for k in ("iou", "precision", "recall")}))
        cache = tmp_path / "curves" / f"{loo.same_model('four-30', fold)}_seed1_{fold}.json"
        cache.parent.mkdir(exist_ok=True)
        cache.write_text(json.dumps(c))
    base = {"iou": 0.6, "precision": 0.9, "recall": 0.55}
    earlier = {"today-30|camvid|seed1": base}
    cells, missing, kept = curves.collect(tmp_path, ["today-30", "four-30"], folds, [1], 1, False, earlier)
    assert kept == ["today-30|camvid|seed1"] and missing == ["today-30|cityscapes|seed1"]
    assert cells["today-30|camvid|recall"] == [0.55] and cells["today-30|camvid|iou"] == [0.6]
    want = curves.fold_metrics(counts["camvid"], 0.55)["precision_at_baseline_recall"]
    assert cells["four-30|camvid|precision_at_baseline_recall"] == [want]
    assert want != counts["camvid"]["at_half"]["precision"]  # read on the curve at the baseline's recall, not at 0.5
    assert cells.get("four-30|cityscapes|precision_at_baseline_recall", [None]) == [None]  # no baseline for that fold
    assert cells["four-30|cityscapes|iou_lofo"][0] == curves.lofo({f: curves.curve(c) for f, c in counts.items()})["cityscapes"][1]


def test_a_threshold_choice_on_fewer_seeds_than_the_rest_is_said():
    """A seed carried without its threshold choice leaves that candidate's IoU at the chosen threshold on fewer
    seeds than its IoU at 0.5: the page says which, and says nothing where both stand on the same seeds."""
    folds = ["camvid", "idd"]
    cells = {"six-30|camvid|iou": [0.89, 0.88], "six-30|idd|iou": [0.84, 0.85],
             "six-30|camvid|iou_lofo": [None, 0.90], "six-30|idd|iou_lofo": [0.86, 0.87],
             "today-30|camvid|iou": [0.85, 0.89], "today-30|idd|iou": [0.84, 0.84],
             "today-30|camvid|iou_lofo": [0.87, 0.90], "today-30|idd|iou_lofo": [0.85, 0.85]}
    notes = curves.fewer_seeds(cells, ["today-30", "six-30"], folds, [0, 1])
    assert notes == ["`six-30`'s IoU at a threshold chosen on the other folds is seed 1's only (its other figures: seeds 0, 1)."]
    head = curves.headline(cells, ["today-30", "six-30"], folds)
    assert notes[0] in curves.render(head, ["today-30", "six-30"], folds, [0, 1], [], notes)
