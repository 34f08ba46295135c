"""ship_loo's held-out-dataset models scored at every threshold of P(road) (issue 82): is a candidate's lower
precision at P >= 0.5 a worse model, or the same model at another operating point?

    .venv/bin/python benchmarks/other_cameras/ship_loo_curves.py [--candidates today,four] [--seeds 0,1]
                                                                 [--held-out kitti_semantics,camvid,cityscapes,idd]
                                                                 [--workdir benchmarks/out/ship_loo] [--threads 2] [--collect]

For every candidate, seed and fold whose ship_loo model is finished (``ship_loo.py`` trains them; this script
trains nothing): the fold's held-out frames scored as crossval scores them (``vctrain.study.score_store``: each
item in its own camera against its own label, the study's torch engine), keeping P(road) quantised to 8 bits
as per-threshold counts (``vctrain.metrics.KittiMetrics``' histograms, the KITTI devkit's). Each fold's counts
are cached in WORKDIR/curves/ (resumable). From them, per candidate and fold (mean over seeds):

- ``iou``, ``precision``, ``recall`` at P >= 0.5 (the masks): ship_loo's figures, **checked**: the run stops if
  one differs from the model's own result file by more than 0.01 point, so the curves are those of the very models
  ship_loo scored;
- ``ap`` and ``maxf`` (KITTI devkit definitions: 11-point average precision, max F1 over thresholds):
  figures of the whole precision-recall curve, no threshold chosen;
- ``precision_at_baseline_recall``: the candidate's precision at the highest threshold where its recall still
  reaches its baseline's recall at 0.5 (same seed and fold): precision compared at equal recall;
- ``iou_lofo``: the IoU at one threshold chosen leave-one-fold-out (the threshold that maximises the mean IoU
  of the other folds, per seed), against ``iou`` at 0.5: what shipping another threshold than 0.5 would give on
  a camera it was not chosen on (``lofo_thresholds``: the thresholds chosen).

**Baseline**: ``today``'s mix at the candidate's own budget (``ship_loo.baseline_of``: ``today`` for the 6-epoch
candidates, ``today-long`` for ``four-long``, ``today-30`` for ``four-30``), in the same run (the same folds, seeds
and frames). A baseline has no comparison of its own.

Outputs: benchmarks/other_cameras/results/ship_loo_curves.{md,json}. ``--collect`` scores nothing and reports
the cached folds. A run that would replace a measured cell of one of its candidates with nothing (a new checkout
has no models and no cached counts: benchmarks/out is not committed) keeps the earlier run's figures of a fold where
ship_loo's results file scores the same model alike at 0.5 (``carried``); one that would still lose a measured cell
stops and writes nothing, unless ``--replace``. The last stdout line is one JSON object: ``<candidate>_<metric>_<fold>`` and
``<candidate>_<metric>_mean`` (% ; thresholds in [0, 1]), ``<candidate>_minus_<baseline>_<iou|maxf|ap|precision_at_baseline_recall>``
and ``<candidate>_iou_minus_<baseline>_iou_lofo`` (the folds' means; points), ``missing``.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.report import machine, results_dir, today, write_json
from benchmarks.other_cameras import ship_loo as loo

HALF = 128  # the 8-bit threshold k (road iff round(255 P) >= k) nearest P >= 0.5
METRICS = ("iou", "precision", "recall", "ap", "maxf", "precision_at_baseline_recall", "iou_lofo")


def test_store(wd: Path, cand: str, seed: int, fold: str) -> Path:
    """The fold's test store in the candidate's study (a resize model reads each item's source frame, so
    any geometry's store of the fold has its items; a virtual-camera twin needs its condition's)."""
    base = wd / loo.home(loo.same_model(cand, fold)) / f"seed{seed}" / "stores" / fold / "test"
    kinds = [loo.condition(cand)] if loo.condition(cand) != loo.COND else ["between", "within"]
    return next((base / k for k in kinds if (base / k).is_dir()), base / kinds[0])


def score_fold(model: Path, store_dir: Path, threads: int) -> dict:
    """Per-threshold counts and the P >= 0.5 metrics of ``model`` on every labelled item of ``store_dir``, as
    ``vctrain.study.score_store`` scores them (its items, :func:`vctrain.study.scored_items`, keeping the probability maps' histograms)."""
    import torch
    from vctrain.metrics import KittiMetrics, RoadMetrics
    from vctrain.predict import STUDY_ENGINE, Predictor
    from vctrain.study import scored_items

    torch.set_num_threads(threads)
    predictor = Predictor(model, device="cpu", engine=STUDY_ENGINE)
    road, curve, n = RoadMetrics(), KittiMetrics(), 0
    for prob, label in scored_items(predictor, store_dir, progress=True):
        road.add(prob >= 0.5, label)
        curve.add(np.clip(np.rint(prob * 255.0), 0, 255).astype(np.uint8), label)
        n += 1
    return {"model": str(model), "items": n, "at_half": road.result(),
            "pos_hist": curve.pos_hist.tolist(), "neg_hist": curve.neg_hist.tolist()}


def fold_counts(wd: Path, cand: str, seed: int, fold: str, threads: int, run: bool) -> dict | None:
    """The cached counts of ``cand``'s model for ``fold`` (scored now if missing and ``run``); None where the
    model is not finished. Stops when the P >= 0.5 figures differ from the model's result file."""
    result = loo.result_file(wd, seed, cand, fold)
    if not result.is_file():
        return None
    cache = wd / "curves" / f"{loo.same_model(cand, fold)}_seed{seed}_{fold}.json"
    if cache.is_file():
        counts = json.loads(cache.read_text())
    elif run:
        counts = score_fold(result.parent / "model.pt", test_store(wd, cand, seed, fold), threads)
        cache.parent.mkdir(parents=True, exist_ok=True)
        cache.write_text(json.dumps(counts))
    else:
        return None
    want = json.loads(result.read_text())
    for k in ("iou", "precision", "recall"):
        if abs(counts["at_half"][k] - want[k]) > 1e-4:
            raise SystemExit(f"{cache}: {k} at 0.5 is {counts['at_half'][k]:.6f}, {result} says {want[k]:.6f}: not "
                             "the model ship_loo scored (delete the cache file to score it again)")
    return counts


def curve(counts: dict) -> dict[str, np.ndarray]:
    """Precision, recall and IoU at every 8-bit threshold k = 0..255 (road iff round(255 P) >= k)."""
    pos, neg = np.asarray(counts["pos_hist"], float), np.asarray(counts["neg_hist"], float)
    tp, fp = np.cumsum(pos[::-1])[::-1], np.cumsum(neg[::-1])[::-1]
    fn = pos.sum() - tp
    return {"precision": tp / np.maximum(tp + fp, 1e-300), "recall": tp / max(pos.sum(), 1e-300),
            "iou": tp / np.maximum(tp + fp + fn, 1e-300)}


def fold_metrics(counts: dict, baseline_recall: float | None) -> dict:
    """One model's figures on one fold (fractions): at 0.5, of the whole curve, at the baseline's recall."""
    from vctrain.metrics import KittiMetrics

    km = KittiMetrics(np.asarray(counts["pos_hist"], np.int64), np.asarray(counts["neg_hist"], np.int64)).result()
    c = curve(counts)
    out = {**{k: counts["at_half"][k] for k in ("iou", "precision", "recall")}, "ap": km["ap"], "maxf": km["maxf"]}
    if baseline_recall is not None:
        reach = np.flatnonzero(c["recall"] >= baseline_recall - 1e-12)
        out["precision_at_baseline_recall"] = float(c["precision"][reach.max()]) if reach.size else None
    return out


def compared_with(cand: str, cands: list[str]) -> str | None:
    """The baseline ``cand`` is judged against (``today``'s mix at its budget) when it is in this run; None for a
    baseline itself or when its baseline was not selected."""
    base = loo.baseline_of(cand)
    return base if cand not in loo.BASELINES and base in cands else None


def lofo(curves: dict[str, dict[str, np.ndarray]]) -> dict[str, tuple[float, float]]:
    """Per fold (one seed): (the threshold maximising the other folds' mean IoU, this fold's IoU there)."""
    out = {}
    for fold in curves:
        others = np.mean([c["iou"] for f, c in curves.items() if f != fold], axis=0)
        k = int(np.argmax(others))
        out[fold] = (k / 255.0, float(curves[fold]["iou"][k]))
    return out


def carried(old: dict, loo_result: dict) -> dict[str, dict]:
    """``'<cand>|<fold>|seed<k>'`` -> its figures (fractions) in an earlier run's results file ``old``, where ship_loo's
    results file ``loo_result`` scores the same candidate, fold and seed at P >= 0.5 alike (IoU, precision and
    recall within 0.01 point: the same model): the curves of models whose counts this checkout does not have
    (benchmarks/out is not committed). A cell ship_loo scores otherwise (a model trained again) or not at all
    is not carried."""
    scored = loo.cells_by_seed(loo_result)

    def alike(key: tuple[str, str, int], m: dict) -> bool:
        want = scored.get(key, {})
        return all(m.get(k) is not None and want.get(k) is not None and abs(100 * m[k] - want[k]) <= 0.01 + 1e-9
                   for k in ("iou", "precision", "recall"))
    return {f"{c}|{f}|seed{s}": m for (c, f, s), m in loo.cells_by_seed(old).items() if alike((c, f, s), m)}


def collect(wd: Path, cands: list[str], folds: list[str], seeds: list[int], threads: int, run: bool,
            earlier: dict | None = None) -> tuple[dict, list, list]:
    """(cells {'<cand>|<fold>|<metric>': per seed, None where missing}, missing, carried): a fold's cached or scored
    counts, else its figures in ``earlier`` (:func:`carried`; listed in carried). The threshold chosen on the other
    folds needs every fold's curve of a seed: a seed part carried keeps the carried folds' choices (made on the same
    models' curves) and has none for the others."""
    cells: dict[str, list] = {}
    missing, kept = [], []
    earlier = earlier or {}
    for i, seed in enumerate(seeds):
        counts = {(c, f): fold_counts(wd, c, seed, f, threads, run) for f in folds for c in cands}
        for cand in cands:
            ok = {f: counts[(cand, f)] for f in folds if counts[(cand, f)] is not None}
            carry = {f: earlier[k] for f in folds if f not in ok and (k := f"{cand}|{f}|seed{seed}") in earlier}
            missing += [f"{cand}|{f}|seed{seed}" for f in folds if f not in ok and f not in carry]
            kept += [f"{cand}|{f}|seed{seed}" for f in carry]
            chosen = lofo({f: curve(c) for f, c in ok.items()}) if len(ok) == len(folds) > 1 else {}
            # a baseline's own "precision at the baseline's recall" is its precision at 0.5: what candidates are compared with
            ref = compared_with(cand, cands) or (cand if cand in loo.BASELINES else None)
            figures = dict(carry)
            for f, c in ok.items():
                b = counts.get((ref, f)) if ref else None
                recall = b["at_half"]["recall"] if b else earlier.get(f"{ref}|{f}|seed{seed}", {}).get("recall")
                figures[f] = fold_metrics(c, recall)
                if f in chosen:
                    figures[f]["lofo_threshold"], figures[f]["iou_lofo"] = chosen[f]
            for f, m in figures.items():
                for k, v in m.items():
                    cells.setdefault(f"{cand}|{f}|{k}", [None] * len(seeds))[i] = v
    return cells, missing, kept


def headline(cells: dict, cands: list[str], folds: list[str]) -> dict:
    """Per candidate and fold the mean over seeds (%), and the folds' mean; the thresholds chosen."""
    def mean(v):
        v = [x for x in v if x is not None]
        return float(np.mean(v)) if v else None
    head: dict = {}
    for cand in cands:
        for k in METRICS:
            per = [mean(cells.get(f"{cand}|{f}|{k}", [])) for f in folds]
            for f, v in zip(folds, per):
                head[f"{cand}_{k}_{f}"] = None if v is None else round(100 * v, 2)
            head[f"{cand}_{k}_mean"] = None if None in per else round(100 * float(np.mean(per)), 2)
        ths = [t for f in folds for t in cells.get(f"{cand}|{f}|lofo_threshold", []) if t is not None]
        head[f"{cand}_lofo_thresholds"] = sorted({round(t, 3) for t in ths})
    for cand, b in [(c, compared_with(c, cands)) for c in cands if compared_with(c, cands)]:  # against the baseline's
        d = lambda x, y: None if x is None or y is None else round(x - y, 2)
        for k in ("iou", "maxf", "ap", "precision_at_baseline_recall"):
            head[f"{cand}_minus_{b}_{k}"] = d(head[f"{cand}_{k}_mean"], head[f"{b}_{k}_mean"])
        head[f"{cand}_iou_minus_{b}_iou_lofo"] = d(head[f"{cand}_iou_mean"], head[f"{b}_iou_lofo_mean"])
    return head


def fewer_seeds(cells: dict, cands: list[str], folds: list[str], seeds: list[int]) -> list[str]:
    """A sentence per candidate whose IoU at the threshold chosen on the other folds stands on fewer seeds than its
    IoU at 0.5 (a seed part carried from a run that lacked one of its folds has no threshold chosen)."""
    def on(cand: str, metric: str) -> list[int]:
        return [s for i, s in enumerate(seeds)
                if all((cells.get(f"{cand}|{f}|{metric}") or [None] * len(seeds))[i] is not None for f in folds)]
    return [f"`{c}`'s IoU at a threshold chosen on the other folds is seed {', '.join(map(str, on(c, 'iou_lofo')))}'s "
            f"only (its other figures: seeds {', '.join(map(str, on(c, 'iou')))})."
            for c in cands if on(c, "iou_lofo") and on(c, "iou_lofo") != on(c, "iou")]


def render(head: dict, cands: list[str], folds: list[str], seeds: list[int], missing: list[str],
           notes: list[str] = ()) -> str:
    f = lambda v: "-" if v is None else f"{v:.1f}"
    lines = [f"Issue 82: ship_loo's models (each dataset held out whole, scored by a model that never saw its camera; seeds "
             f"{seeds}) at every threshold of P(road). Per held-out dataset: road IoU at P >= 0.5 · AP (11-point) · "
             f"precision at the baseline's recall at 0.5 (`today`'s mix at the same budget) · IoU at a threshold "
             f"chosen on the other folds; %.", "",
             "| candidate | " + " | ".join(f"held out {x}" for x in folds) + " | mean | thresholds chosen |",
             "|---|" + "---|" * (len(folds) + 2)]
    for cand in cands:
        cell = lambda x: " · ".join(f(head[f"{cand}_{k}_{x}"]) for k in ("iou", "ap", "precision_at_baseline_recall", "iou_lofo"))
        lines.append(f"| `{cand}` | " + " | ".join(cell(x) for x in folds) + f" | {cell('mean')} | "
                     + (", ".join(f"{t:.2f}" for t in head[f"{cand}_lofo_thresholds"]) or "-") + " |")
    for cand, b in [(c, compared_with(c, cands)) for c in cands if compared_with(c, cands)]:
        g = lambda k: f(head[f"{cand}_minus_{b}_{k}"]) if head[f"{cand}_minus_{b}_{k}"] is None else f"{head[f'{cand}_minus_{b}_{k}']:+.1f}"
        lofo = head[f"{cand}_iou_minus_{b}_iou_lofo"]
        lines += ["", f"`{cand}` − `{b}` (means of the folds): IoU at 0.5 {g('iou')}; precision at `{b}`'s recall "
                  f"{g('precision_at_baseline_recall')}; MaxF {g('maxf')}; AP {g('ap')}; `{cand}` at 0.5 against `{b}` at "
                  f"its threshold chosen on the other folds {'-' if lofo is None else f'{lofo:+.1f}'}."]
    lines += ["", *notes] if notes else []
    if missing:
        lines += ["", f"Missing (no model or not scored): {', '.join(missing)}."]
    return "\n".join(lines) + "\n"


def would_lose(old: dict, cells: dict, cands: list[str], seeds: list[int]) -> list[str]:
    """'<cand>|<fold>|<metric>|seed<k>' of the results file ``old`` that this run's ``cells`` would replace with
    nothing: a measured candidate of this run whose models (or cached counts) this checkout does not have."""
    lost = []
    for key, vals in old.get("cells", {}).items():
        for seed, v in zip(old.get("seeds", []), vals):
            new = cells.get(key, [])[seeds.index(seed)] if seed in seeds and cells.get(key) else None
            if key.split("|")[0] in cands and v is not None and new is None:
                lost.append(f"{key}|seed{seed}")
    return lost


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--candidates", default="today,four", help="comma-separated: " + ", ".join(loo.CANDIDATES))
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--held-out", default=",".join(loo.FOLDS))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--workdir", type=Path, default=loo.ROOT / "benchmarks" / "out" / "ship_loo")
    ap.add_argument("--collect", action="store_true", help="score nothing: report the cached folds")
    ap.add_argument("--replace", action="store_true", help="write the results file even where it loses measured cells")
    a = ap.parse_args()
    cands, folds = loo.selection(a)
    seeds = [int(s) for s in a.seeds.split(",") if s]
    rd = results_dir(__file__)
    read = lambda name: json.loads((rd / name).read_text()) if (rd / name).is_file() else {}
    old = read("ship_loo_curves.json")
    cells, missing, kept = collect(a.workdir, cands, folds, seeds, a.threads, not a.collect,
                                   carried(old, read("ship_loo.json")))
    head = {**headline(cells, cands, folds), "missing": missing}
    table = render(head, cands, folds, seeds, missing, fewer_seeds(cells, cands, folds, seeds))
    if kept:
        table += f"\nCarried from the results file's earlier run (no model or counts in this workdir): {len(kept)} folds.\n"
    if (lost := would_lose(old, cells, cands, seeds)) and not a.replace:
        raise SystemExit(f"Error: {rd / 'ship_loo_curves.json'}: this run would drop {len(lost)} measured cells "
                         f"(e.g. {lost[0]}; their models are not in {a.workdir}) (train them with ship_loo.py, "
                         "or --replace to write it anyway)")
    (rd / "ship_loo_curves.md").write_text(table)
    write_json(rd / "ship_loo_curves.json", {
        "headline": head, "cells": cells, "carried": kept, "candidates": {c: loo.CANDIDATES[c] for c in cands}, "held_out": folds,
        "seeds": seeds, "baselines": {c: compared_with(c, cands) for c in cands}, "issue": 82, "threads": a.threads, "machine": machine(),
        "date": today(), "command": "benchmarks/other_cameras/ship_loo_curves.py " + " ".join(sys.argv[1:])})
    print(table, flush=True)
    print(json.dumps(head))


if __name__ == "__main__":
    main()
