"""The shipped model's recipe judged on cameras held out of training (issue 82): candidate data mixes,
each dataset held out in turn, trained on the rest of the candidate's datasets.

    .venv/bin/python benchmarks/other_cameras/ship_loo.py [--candidates today,four,six] [--seeds 0,1]
                                                          [--held-out kitti_semantics,camvid,cityscapes,idd]
                                                          [--epochs 10] [--threads 2] [--quick] [--collect]
                                                          [--workdir benchmarks/out/ship_loo]

**Candidates** (:data:`CANDIDATES`; every one the shipped recipe otherwise: ``lite0fpn`` from ImageNet,
``balance: datasets``, lens-shading 0.4, the LOO step budget of 35 steps an epoch, the frames read as
they are: condition ``resize``, the network the project ships):

| candidate | datasets |
|---|---|
| ``today`` | CamVid, Cityscapes, IDD-Lite, BDD100K, LUMS (the model shipped until issue 82) |
| ``four`` | CamVid, Cityscapes, ``kitti_semantics``, IDD-Lite (the issue's four-dataset run) |
| ``six`` | all six: ``today`` with ``kitti_semantics``, or ``four`` with BDD100K and LUMS |
| ``four-virtual`` | ``four``'s datasets, condition ``within``: ``four``'s virtual-camera twin (:data:`TWINS`) |
| ``six-two`` | ``six``'s datasets, two outputs (:data:`TWO_OUTPUTS`): road from CamVid, Cityscapes, ``kitti_semantics`` and LUMS, drivable from IDD-Lite and BDD100K |
| ``four-long``, ``today-long`` | ``four``'s and ``today``'s datasets with twice the epochs (:data:`LONGER`): the training budget |
| ``four-30``, ``today-30`` | the same with five times the epochs (30 at ``--epochs 6``: the shipped model's budget) |
| ``six-long``, ``six-30`` | ``six``'s datasets at twice and five times the epochs: does a longer budget close ``six``'s gap to ``four`` |
| ``today-items`` | ``today``'s datasets, ``balance: items`` (:data:`ITEMS`): each dataset's share of an epoch its share of the frames |
| ``four-aspect`` | ``four``'s datasets, ``keep_aspect`` (:data:`ASPECT`): every frame, trained and scored, at the working size's pixel count at its own aspect |

A virtual-camera twin trains on its candidate's datasets warped into one virtual camera designed from
their cameras (crossval's condition ``within``: each frame's VP corrects its pan and tilt, projective
completion fills the gaps) and is scored with the held-out camera given (its camera file: calibrated for
CamVid, Cityscapes and ``kitti_semantics``, IDD-Lite's assumed one), its masks back-projected; it shares its
candidate's study folder, stores and seeds, so ``<twin>_minus_<candidate>`` is paired per seed (issue 82:
the twin ships behind the candidate's name only if it wins on the held-out folds with the camera given).

A two-output candidate (``train: outputs: road,drivable``, docs/training.md) trains one network with a road
and a drivable output, each dataset supervising only the output its labels define (IDD-Lite's and
BDD100K's labels are drivable area); a held-out road dataset is scored on the road output, held-out
IDD-Lite on the drivable one (what its labels are). It trains in its own folder on the stores of the
candidate with its datasets (``six``'s: the same frames, so ``six-two`` against ``six`` isolates the
label definitions).

A longer-budget candidate (:data:`LONGER`) trains its ``BUDGET_FACTOR`` times the epochs (the same steps an epoch)
in its own folder on its candidate's stores: ``four-long`` − ``four`` is the budget's effect on the same
frames, ``four-long`` − ``today-long`` the data mix's at the longer budget.

An items-balanced candidate (:data:`ITEMS`) draws every epoch from all of its training frames at random, so
each dataset's share is its share of the frames (``today``'s, all five: IDD-Lite 57 %, CamVid 19 %, Cityscapes 16 %,
LUMS 6 %, BDD100K 2 %) instead of ``balance: datasets``' equal fifths (BDD100K's 41 frames and LUMS's 144 two
fifths of every epoch); it trains in its own folder on its candidate's stores: ``today-items`` − ``today``
is the shares' effect on the same frames and budget.

A pixel-budget candidate (:data:`ASPECT`, the issue's "pixel budget of wide frames") trains with ``keep_aspect``:
each frame at the working size's pixel count (480x360's 172,800 with CamVid first) at its own aspect,
``kitti_semantics``' 1242x375 at 757x228 instead of squashed to 4:3, a batch frames of one size (so of one
dataset here), and its models size every scored frame the same way; in its own folder on its candidate's
stores: ``four-aspect`` − ``four`` is the aspect's effect on the same frames, budget and pixel count.

``four`` against ``six`` isolates BDD100K and LUMS (27 dashcams' drivable areas and a low campus
camera, two fifths of every epoch of ``today``); ``today`` against ``six`` isolates ``kitti_semantics``.

**Folds** (``--held-out``): ``kitti_semantics``, CamVid (train + val, 468 frames), Cityscapes (400) and
IDD-Lite (1,403), each held out whole in turn. A held-out dataset that is one of the candidate's is
``role: both`` (crossval trains a model on the candidate's other datasets: ``runs/<fold>/resize``); one that
is not (``kitti_semantics`` for ``today``) is ``role: test``, scored by the model trained on all of the
candidate's datasets (``runs/_all/resize``): for every candidate each fold's model never saw the camera it
is scored on. BDD100K and LUMS, where a candidate has them, are trained on in every fold (``role:
train``): their cameras' held-out figures are in ``shipped_model.py``'s splits, not here.

One ``vctrain crossval`` study per candidate and seed (WORKDIR/<candidate>/seed<k>/, resumable; the stores of
a candidate are built once and shared by its seeds). The workdir is not committed: a fold whose result file
it lacks but whose scores the results file has from an earlier run at the same protocol (epochs, steps an epoch,
condition, budget) is not trained again and is reported from there (``carried``; delete its cells to retrain
it), so a new checkout adds seeds and folds to what earlier ones measured. Scores: road IoU, precision and recall over the
held-out dataset's frames in its own camera (sum over the set, ignore excluded).

**Baseline**: ``today`` (the recipe shipped until issue 82) in the same run, same folds, seeds and budget;
a longer-budget candidate's is ``today``'s mix at its budget (:data:`SAME_BUDGET`: ``four-long`` against
``today-long``, ``four-30`` against ``today-30``), never the 6-epoch ``today``.

**Targets** (issue 82, checked, not asserted): a candidate's mean road IoU over the folds >= ``today``'s + 3,
its precision up, no fold below ``today``'s by more than 1.

Outputs: benchmarks/other_cameras/results/ship_loo.{md,json} (rewritten after every study; ``--quick``: a
smoke run, a few frames, 2 steps, into WORKDIR/quick/results). ``--collect`` runs nothing and reports what
is finished. The last stdout line is one JSON object: ``<candidate>_<fold>`` (road IoU %, the mean over
seeds), ``<candidate>_precision_<fold>``, ``<candidate>_recall_<fold>``, ``<candidate>_mean`` (the folds'
mean, per seed then averaged; ``_std`` over seeds), ``<candidate>_minus_<its baseline>`` (paired per seed),
``minutes_per_model`` (over the models whose training time is known), ``seeds``, ``missing``; the results file
also lists the scores ``carried``.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import BDD, CITYSCAPES, DATA, IDD, KITTI_SEM, LUMS, ROOT, require_data
from benchmarks.measure.studies import camvid_steps_per_epoch, link_stores, run_study
from benchmarks.other_cameras.multi_camera import study_file
from benchmarks.measure.report import machine, results_dir, today, write_json
from benchmarks.measure.stats import seed_stats

CANDIDATES = {
    "today": ["camvid", "cityscapes", "idd", "bdd", "lums"],
    "four": ["camvid", "cityscapes", "kitti_semantics", "idd"],
    "six": ["camvid", "cityscapes", "kitti_semantics", "idd", "bdd", "lums"],
}
TWINS = {"four-virtual": "four"}  # virtual-camera twin -> the candidate whose datasets, folder and stores it shares
# two-output candidates -> the candidate whose datasets and stores they share (their own study folder)
TWO_OUTPUTS = {"six-two": "six"}
# twice the training budget (epochs) -> the candidate whose datasets and stores they share (their own study folder)
LONGER = {"four-long": "four", "today-long": "today", "four-30": "four", "today-30": "today", "six-long": "six",
          "six-30": "six"}
# each longer candidate's epochs, times --epochs (2x; 5x: 30 at the protocol's 6, the shipped model's budget)
BUDGET_FACTOR = {"four-long": 2, "today-long": 2, "four-30": 5, "today-30": 5, "six-long": 2, "six-30": 5}
# each dataset's share of an epoch its share of the frames (balance: items) -> the candidate whose datasets and stores they share
ITEMS = {"today-items": "today"}
# every frame at the working size's pixel count at its own aspect (train: keep_aspect) -> the candidate whose stores they share
ASPECT = {"four-aspect": "four"}
SHARES = {**TWO_OUTPUTS, **LONGER, **ITEMS, **ASPECT}
# paired differences reported (per seed): each twin and longer budget against its candidate, the longer budgets' recipes
PAIRS = [*TWINS.items(), *LONGER.items(), ("four-long", "today-long"), ("four-30", "today-30"), ("six-long", "today-long"),
         ("six-long", "four-long"), ("six-30", "today-30"), ("six-30", "four-30"), *ITEMS.items(), ("four", "today-items"),
         *ASPECT.items()]  # a candidate trained in its own folder on another's stores
CANDIDATES.update({t: CANDIDATES[c] for t, c in {**TWINS, **SHARES}.items()})
FOLDS = ["kitti_semantics", "camvid", "cityscapes", "idd"]
BASELINE = "today"
# a longer-budget candidate is judged against `today`'s mix at its own budget, trained in the same run
SAME_BUDGET = {"four-long": "today-long", "four-30": "today-30", "six-long": "today-long", "six-30": "today-30"}
BASELINES = {BASELINE, *SAME_BUDGET.values()}
COND, TWIN_COND = "resize", "within"
TARGET_GAIN, TARGET_WORST = 3.0, -1.0
# the documents that show the table (between these markers; tests/test_docs.py checks they match the results file)
DOCS = [ROOT / "docs" / "training.md", ROOT / "models" / "road-street" / "README.md"]
BEGIN, END = "<!-- ship_loo:", "<!-- end ship_loo -->"


def table_lines(table: str) -> str:
    """The Markdown tables of ``table`` (the results file's .md) without its prose: what the documents show."""
    keep = [ln for ln in table.splitlines() if ln.startswith("|") or not ln.strip()]
    return "\n".join(ln for i, ln in enumerate(keep) if ln or (i and keep[i - 1])).strip() + "\n"


def embed(table: str, docs: list[Path] = DOCS) -> None:
    """Each document's block between BEGIN's line and END replaced by the table's tables."""
    for doc in docs:
        text = doc.read_text()
        i, j = text.find(BEGIN), text.find(END)
        if 0 <= i < j:
            head = text.index("\n", i) + 1
            doc.write_text(text[:head] + table_lines(table) + text[j:])


def candidate_study(wd: Path, cand: str, quick: bool, epochs: int | None) -> Path:
    """WORKDIR/<cand>/study.yaml: the candidate's datasets (a fold ``both``, its others ``train``), the folds
    it does not train on ``test``; a two-output candidate names the source files of the candidate whose
    stores it shares and trains with ``outputs: road,drivable``."""
    sets = CANDIDATES[cand]
    names = sets + [f for f in FOLDS if f not in sets]
    shares = wd / SHARES[cand] if cand in SHARES else None
    (wd / cand).mkdir(parents=True, exist_ok=True)  # (a study sharing another's frames links none of its own)
    epochs = epochs * BUDGET_FACTOR[cand] if cand in LONGER and epochs else epochs
    path = study_file(wd / cand, quick, epochs, names=names, home=shares)
    study = yaml.safe_load(path.read_text())
    for d in study["datasets"]:
        if d["name"] not in sets:
            d["role"] = "test"
            del d["train"]
        elif d["name"] not in FOLDS:
            d["role"] = "train"
            del d["test"]
    study["train"]["arch"] = "lite0fpn"
    if cand in TWO_OUTPUTS:
        study["train"]["outputs"] = "road,drivable"
    if cand in ITEMS:
        study["train"]["balance"] = "items"
    if cand in ASPECT:
        study["train"]["keep_aspect"] = True
    path.write_text(yaml.safe_dump(study, sort_keys=False))
    return path


def home(cand: str) -> str:
    """The study folder a candidate trains in: its own, or a twin's candidate's."""
    return TWINS.get(cand, cand)


def condition(cand: str) -> str:
    """crossval's condition for ``cand``: ``within`` for a virtual-camera twin, else ``resize``."""
    return TWIN_COND if cand in TWINS else COND


def same_model(cand: str, fold: str) -> str:
    """The first candidate whose model for ``fold`` trains on the very same datasets as ``cand``'s in the same
    condition with the same outputs (same recipe, seed and stores: the same model; ``six`` without
    ``kitti_semantics`` is ``today``): ``cand`` itself if none."""
    trained = lambda c: (frozenset(CANDIDATES[c]) - {fold}, condition(c), c in TWO_OUTPUTS, BUDGET_FACTOR.get(c, 1), c in ITEMS,
                         c in ASPECT)
    return next(c for c in CANDIDATES if trained(c) == trained(cand))


def result_file(wd: Path, seed: int, cand: str, fold: str) -> Path:
    """Where crossval writes the fold's score in one seed's study of ``cand`` (or of the candidate that trains
    the same model: :func:`same_model`)."""
    cand = same_model(cand, fold)
    sd = wd / home(cand) / f"seed{seed}"
    if fold in CANDIDATES[cand]:
        return sd / "runs" / fold / condition(cand) / "result.json"
    return sd / "runs" / "_all" / condition(cand) / f"result-{fold}.json"


def kept(path: Path, epochs: int | None, steps: int) -> dict:
    """``'<cand>|<fold>|seed<k>'`` -> its ``iou``, ``precision``, ``recall`` (%) and ``minutes`` where known, from an
    earlier run's results file at the same protocol (epochs, steps an epoch, each candidate's condition and budget):
    the scores of models trained in a workdir this checkout does not have (benchmarks/out is not committed).
    {} when there is no such file or it ran another protocol."""
    if not path.is_file():
        return {}
    old = json.loads(path.read_text())
    if old.get("epochs") != epochs or old.get("steps_per_epoch") != steps:
        return {}
    same = lambda c: (old.get("condition", {}).get(c), old.get("budget_factor", {}).get(c, 1)) == (condition(c), BUDGET_FACTOR.get(c, 1))
    return {f"{c}|{f}|seed{s}": m for (c, f, s), m in cells_by_seed(old).items()
            if c in CANDIDATES and same(c) and m.get("iou") is not None}


def cells_by_seed(results: dict) -> dict[tuple[str, str, int], dict]:
    """A results file's measured cells (``'<cand>|<fold>|<metric>'``: one value a seed) by (candidate, fold, seed):
    {metric: value}."""
    out: dict[tuple[str, str, int], dict] = {}
    for key, vals in results.get("cells", {}).items():
        cand, fold, k = key.split("|")
        for seed, v in zip(results.get("seeds", []), vals):
            if v is not None:
                out.setdefault((cand, fold, seed), {})[k] = v
    return out


def model_minutes(result: Path, row: dict) -> float:
    """A model's training time (minutes): its study's ``train_seconds``, or its log's epochs (training steps and
    validation, ``model.log.jsonl`` beside ``result``) where they add up to more: a model a study resumed before it
    counted the interrupted invocation's epochs (``resumed_after``) recorded only the last invocation's."""
    from vctrain.study.conditions import epochs_seconds

    log = result.parent / "model.log.jsonl"
    rows = {r["epoch"]: r for r in (json.loads(x) for x in log.read_text().splitlines() if x.strip())} \
        if log.is_file() else {}
    return round(max(float(row["train_seconds"]), epochs_seconds(rows.values())) / 60, 2)


def collect(wd: Path, cands: list[str], folds: list[str], seeds: list[int],
            earlier: dict | None = None) -> tuple[dict, list[str], list[float], list[str]]:
    """(cells {'<cand>|<fold>|<iou|precision|recall|minutes>': per seed, None where missing}, missing, minutes a
    model, carried): a fold's result file in ``wd``, else its scores in ``earlier`` (:func:`kept`; listed in carried)."""
    cells: dict[str, list] = {}
    missing, minutes, carried = [], {}, []
    for cand in cands:
        for i, seed in enumerate(seeds):
            for fold in folds:
                f = result_file(wd, seed, cand, fold)
                keys = {k: cells.setdefault(f"{cand}|{fold}|{k}", [None] * len(seeds))
                        for k in ("iou", "precision", "recall", "minutes")}
                old = (earlier or {}).get(f"{cand}|{fold}|seed{seed}")
                if f.is_file():
                    row = json.loads(f.read_text())
                    old = {k: round(100 * row[k], 2) if row.get(k) is not None else None for k in ("iou", "precision", "recall")}
                    old["minutes"] = model_minutes(f, row)
                elif old:
                    carried.append(f"{cand}|{fold}|seed{seed}")
                else:
                    missing.append(f"{cand}|{fold}|seed{seed}")
                    continue
                for k, cell in keys.items():
                    cell[i] = old.get(k)
                if old.get("minutes") is not None:  # one model scored on several folds counts once
                    run = fold if fold in CANDIDATES[same_model(cand, fold)] else "_all"
                    minutes[(same_model(cand, fold), seed, run)] = old["minutes"]
    return cells, missing, list(minutes.values()), carried


def headline(cells: dict, cands: list[str], folds: list[str], seeds: list[int]) -> dict:
    """Per candidate and fold the mean over its seeds with every fold (over every seed it has, where none has
    every fold yet: a seed part-trained shows in no fold's cell, so the folds are read on the same seeds); the
    folds' mean per seed (seeds with every fold) and each candidate's gain over ``today`` paired per seed."""
    r2 = lambda x: None if x is None else round(float(x), 2)
    mean = lambda v: r2(np.mean([x for x in v if x is not None])) if any(x is not None for x in v) else None
    head: dict = {}
    per_seed: dict[str, list] = {}
    prec_seed: dict[str, list] = {}
    for cand in cands:
        per_seed[cand] = seed_means(cells, cand, "iou", folds, len(seeds))
        done = [i for i, x in enumerate(per_seed[cand]) if x is not None] or range(len(seeds))
        for fold in folds:
            for k, key in (("iou", f"{cand}_{fold}"), ("precision", f"{cand}_precision_{fold}"),
                           ("recall", f"{cand}_recall_{fold}")):
                head[key] = mean([cells[f"{cand}|{fold}|{k}"][i] for i in done])
        s = [x for x in per_seed[cand] if x is not None]
        head[f"{cand}_mean"] = r2(np.mean(s)) if s else None
        head[f"{cand}_mean_std"] = r2(seed_stats(s)["std"] or 0.0) if len(s) > 1 else None
        prec_seed[cand] = seed_means(cells, cand, "precision", folds, len(seeds))  # per seed with every fold, as the IoU's
        p = [x for x in prec_seed[cand] if x is not None]
        head[f"{cand}_precision_mean"] = r2(np.mean(p)) if p else None
    for cand, base in [(c, baseline_of(c)) for c in cands if baseline_of(c) in cands]:
        d = [a - b for a, b in zip(per_seed[cand], per_seed[base]) if a is not None and b is not None]
        head[f"{cand}_minus_{base}"] = r2(np.mean(d)) if d else None
        d = [a - b for a, b in zip(prec_seed[cand], prec_seed[base]) if a is not None and b is not None]
        head[f"{cand}_precision_minus_{base}"] = r2(np.mean(d)) if d else None  # paired per seed, as the IoU's gain
        head[f"{cand}_worst_fold_minus_{base}"] = worst_fold(cells, cand, base, folds, per_seed)
    for twin, cand in [(t, c) for t, c in PAIRS if t in cands and c in cands]:
        d = [a - b for a, b in zip(per_seed[twin], per_seed[cand]) if a is not None and b is not None]
        head[f"{twin}_minus_{cand}"] = r2(np.mean(d)) if d else None
    return head


def worst_fold(cells: dict, cand: str, base: str, folds: list[str], per_seed: dict[str, list]) -> float | None:
    """The fold where ``cand`` is furthest below ``base``, each fold's gap a mean over the seeds on which both
    have every fold (paired, as the gain: a candidate's two seeds against its baseline's one would compare seeds)."""
    both = [i for i, (a, b) in enumerate(zip(per_seed[cand], per_seed[base])) if a is not None and b is not None]
    if not both:
        return None
    gap = lambda f: np.mean([cells[f"{cand}|{f}|iou"][i] - cells[f"{base}|{f}|iou"][i] for i in both])
    return round(float(min(gap(f) for f in folds)), 2)


def seed_means(cells: dict, cand: str, metric: str, folds: list[str], n: int) -> list:
    """Per seed the mean of ``metric`` over the folds, None for a seed with a fold still to train."""
    col = [cells[f"{cand}|{f}|{metric}"] for f in folds]
    return [None if any(c[i] is None for c in col) else float(np.mean([c[i] for c in col])) for i in range(n)]


def baseline_of(cand: str) -> str:
    """The candidate a candidate is judged against: `today`'s mix at the same budget."""
    return SAME_BUDGET.get(cand, BASELINE)


def targets(head: dict, cands: list[str]) -> dict:
    """Issue 82's rule for every candidate but the baselines, each against its own budget's baseline."""
    out = {}
    for cand, base in [(c, baseline_of(c)) for c in cands if c not in BASELINES and baseline_of(c) in cands]:
        gain, worst = head[f"{cand}_minus_{base}"], head[f"{cand}_worst_fold_minus_{base}"]
        dp = head[f"{cand}_precision_minus_{base}"]
        out[f"{cand}: mean >= {base} + {TARGET_GAIN:g}"] = None if gain is None else gain >= TARGET_GAIN
        out[f"{cand}: precision up"] = None if dp is None else dp > 0
        out[f"{cand}: no fold below {base} - {-TARGET_WORST:g}"] = None if worst is None else worst >= TARGET_WORST
    for twin, cand in [(t, c) for t, c in TWINS.items() if t in cands and c in cands]:
        gain = head.get(f"{twin}_minus_{cand}")
        out[f"{twin}: mean above {cand} (ships behind its name)"] = None if gain is None else gain > 0
    return out


def gain_cell(head: dict, cand: str) -> str:
    """The table's last column: a candidate's paired gain over `today`'s mix at its budget ("baseline" for those)."""
    if cand in BASELINES:
        return "baseline"
    v = head.get(f"{cand}_minus_{baseline_of(cand)}")
    return "-" if v is None else f"{v:+.1f}"


def render(head: dict, tg: dict, cands: list[str], folds: list[str], seeds: list[int], epochs: int | None,
           missing: list[str]) -> str:
    """The markdown table: a row per candidate, a column per held-out dataset (IoU, P / R)."""
    f = lambda v, s="": "-" if v is None else f"{v:{s}.1f}"
    lines = [f"Issue 82: candidate data mixes for the shipped model, each dataset held out whole in turn and scored "
             f"by a model that never saw its camera (`resize` unless the row says virtual camera, lite0fpn, balance: datasets unless the row says items, {camvid_steps_per_epoch()} steps an epoch, "
             f"{epochs} epochs; seeds {seeds}; a model trained on the same datasets as another candidate's is that one). Road IoU % (precision / recall %): "
             f"a row's cells are means over the seeds on which it has every fold (± the seeds' spread where two or more); the last column and the targets pair the seeds both rows have.", "",
             "| candidate | trained on | " + " | ".join(f"held out {x}" for x in folds) + " | mean | − today at its budget |",
             "|---|---|" + "---|" * (len(folds) + 2)]
    for cand in cands:
        row = [f"{f(head[f'{cand}_{x}'])} ({f(head[f'{cand}_precision_{x}'])} / {f(head[f'{cand}_recall_{x}'])})"
               for x in folds]
        sd = head[f"{cand}_mean_std"]
        what = ", ".join(CANDIDATES[cand]) + (" (virtual camera, the held-out camera given)" if cand in TWINS else
                                              " (two outputs; IDD-Lite scored on drivable)" if cand in TWO_OUTPUTS else
                                              f" ({BUDGET_FACTOR[cand]}× the epochs)" if cand in LONGER else
                                              " (balance: items)" if cand in ITEMS else
                                              " (each frame at its own aspect)" if cand in ASPECT else "")
        lines.append(f"| `{cand}` | {what} | " + " | ".join(row) + f" | {f(head[f'{cand}_mean'])}"
                     + (f" ± {sd:.1f}" if sd is not None else "") + f" | {gain_cell(head, cand)} |")
    pairs = [f"`{t}` − `{c}` {f(head.get(f'{t}_minus_{c}'), '+')}" for t, c in PAIRS if t in cands and c in cands]
    lines += ["", f"Paired per seed: {'; '.join(pairs)}."] if pairs else []
    if missing:
        lines += ["", f"Missing (not finished): {', '.join(missing)}."]
    lines += ["", "| target (issue 82) | met |", "|---|---|"] + [
        f"| {k} | {'not measured' if v is None else 'yes' if v else 'no'} |" for k, v in tg.items()]
    return "\n".join(lines) + "\n"


def results_of(a: argparse.Namespace, wd: Path) -> Path:
    """The results folder: the committed one, or the workdir's for ``--quick``."""
    return wd / "results" if a.quick else results_dir(__file__)


def earlier_scores(a: argparse.Namespace, wd: Path) -> dict:
    """The results file's scores at this run's protocol (:func:`kept`)."""
    return kept(results_of(a, wd) / "ship_loo.json", a.epochs, 2 if a.quick else camvid_steps_per_epoch())


def report(a: argparse.Namespace, wd: Path, cands: list[str], folds: list[str], seeds: list[int]) -> dict:
    cells, missing, minutes, carried = collect(wd, cands, folds, seeds, earlier_scores(a, wd))
    head = headline(cells, cands, folds, seeds)
    tg = targets(head, cands)
    head.update({"minutes_per_model": round(float(np.mean(minutes)), 2) if minutes else None, "seeds": seeds,
                 "missing": missing})
    table = render(head, tg, cands, folds, seeds, a.epochs, missing)
    if carried:
        table += (f"\nCarried from the results file's earlier run (their models are not in this workdir): "
                  f"{len(carried)} of {sum(len(v) - v.count(None) for k, v in cells.items() if k.endswith('|iou'))} scores.\n")
    rd = results_of(a, wd)
    (rd / "ship_loo.md").parent.mkdir(parents=True, exist_ok=True)
    (rd / "ship_loo.md").write_text(table)
    if not a.quick:
        embed(table)
    write_json(rd / "ship_loo.json", {
        "headline": head, "targets": tg, "cells": cells, "carried": carried, "candidates": {c: CANDIDATES[c] for c in cands},
        "held_out": folds, "seeds": seeds, "epochs": a.epochs, "steps_per_epoch": 2 if a.quick else camvid_steps_per_epoch(),
        "condition": {c: condition(c) for c in cands}, "budget_factor": {c: BUDGET_FACTOR.get(c, 1) for c in cands}, "arch": "lite0fpn", "issue": 82, "threads": a.threads, "machine": machine(), "date": today(),
        "command": "benchmarks/other_cameras/ship_loo.py " + " ".join(sys.argv[1:])})
    print(table, flush=True)
    return head


def selection(a: argparse.Namespace) -> tuple[list[str], list[str]]:
    """(candidates, folds) of ``--candidates`` and ``--held-out`` (comma-separated); stops on an unknown one."""
    cands = [c for c in a.candidates.split(",") if c]
    folds = [f for f in a.held_out.split(",") if f]
    if set(cands) - set(CANDIDATES) or set(folds) - set(FOLDS) or not cands or not folds:
        raise SystemExit(f"candidates are {', '.join(CANDIDATES)}; folds {', '.join(FOLDS)}")
    return cands, folds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--candidates", default=",".join(CANDIDATES), help="comma-separated: " + ", ".join(CANDIDATES))
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--held-out", default=",".join(FOLDS))
    ap.add_argument("--epochs", type=int, default=10, help="epochs of 35 steps (default 10: 350 steps a model)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--workdir", type=Path, default=ROOT / "benchmarks" / "out" / "ship_loo")
    ap.add_argument("--quick", action="store_true", help="smoke run: a few frames, 2 steps, seed 0")
    ap.add_argument("--collect", action="store_true", help="run nothing: report what is finished")
    a = ap.parse_args()
    cands, folds = selection(a)
    seeds = [0] if a.quick else [int(s) for s in a.seeds.split(",") if s]
    require_data(DATA, CITYSCAPES, KITTI_SEM, IDD, BDD, LUMS)
    wd = a.workdir / "quick" if a.quick else a.workdir
    earlier = earlier_scores(a, wd)  # what an earlier checkout trained is not trained again
    # seed by seed, fold by fold, every candidate in turn: a cut-off run leaves folds that every candidate has
    for seed in seeds if not a.collect else []:
        for fold in folds:
            for cand in [c for c in cands if same_model(c, fold) == c]:  # (the others: an earlier candidate's model)
                study = candidate_study(wd, home(cand), a.quick, a.epochs)
                sd = wd / home(cand) / f"seed{seed}"
                if not result_file(wd, seed, cand, fold).is_file() and f"{cand}|{fold}|seed{seed}" in earlier:
                    print(f"{cand}, seed {seed}, held out {fold}: scored in the results file's earlier run", flush=True)
                    continue
                if seed != seeds[0] or cand in SHARES:
                    link_stores(sd, wd / SHARES.get(cand, home(cand)) / f"seed{seeds[0]}")
                run_study(study, sd, [condition(cand)], seed, a.threads, heldout=[fold])
            report(a, wd, cands, folds, seeds)
    print(json.dumps(report(a, wd, cands, folds, seeds)))


if __name__ == "__main__":
    main()
