"""A study's execution (:func:`run_study`): every run of the plan through one executor
(:func:`execute`) over the condition kinds of :mod:`vctrain.study.conditions`, and the scoring.

Everything runs through the real tools: stores are built with :func:`vcprep.store.build.warp_dataset`
(one per dataset, split and geometry, shared by all folds), models with :func:`vctrain.training.fit`,
and the held-out test images are predicted in the model's own domain (warped as ``vctrain predict``
warps them for the model: the same masks) and scored in their ORIGINAL camera (back-projected
probabilities, threshold 0.5) against their original labels: road IoU = ΣTP / Σ(TP+FP+FN) over the
held-out test images, ignore pixels excluded.

Layout under OUT: ``stores/<dataset>/<split>/<geometry>/`` (vcprep stores), ``vps/<dataset>-<split>.csv``
(the estimated VPs), ``runs/<heldout>/<condition>/`` (checkpoint, training log, ``train.json``,
``result.json``: the metrics, and ``test_warp``, what the test frames were warped with: VP statuses
and rule, own-vehicle rows, rectangle, as ``vctrain predict`` says for the same frames) and, with
test-role datasets, ``runs/_all/<condition>/`` (one model, ``result-<dataset>.json`` per test-role
dataset), ``results.jsonl`` (one row per evaluated dataset and condition), ``table.md``, ``table.csv``,
``summary.json`` (:mod:`vctrain.report`). A finished result is not redone, and a finished training is
not repeated for a missing evaluation, so an interrupted study resumes where it stopped; a run
finished with other settings (:mod:`vctrain.study.keys`) is redone.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Callable, Sequence

from vcprep.errors import InputError
from vcprep.io import read_image
from vcprep.labels import decode_label, get_label_format
from vcprep.store import Store

from ..report import write_json, write_tables
from .conditions import KINDS, Context, training_settings
from .keys import Keys
from .resolve import Resolution
from .runs import Run, pending, plan_runs, write_result
from .spec import CONDITIONS, Study, check_conditions, evaluated_datasets
from .stores import Stores

__all__ = ["run_study", "execute", "evaluate_heldout", "score_store", "scored_items"]


def evaluate_heldout(checkpoint: Path, store_dir: Path, progress: bool = False) -> dict[str, Any]:
    """Road metrics of ``checkpoint`` on every labelled item of a held-out test store, scored in the
    item's ORIGINAL camera against its original label (P(road) >= 0.5)."""
    from ..predict.predictor import Predictor
    from ..predict.settings import STUDY_ENGINE

    return score_store(Predictor(checkpoint, device="cpu", engine=STUDY_ENGINE), store_dir, progress)


def score_store(predictor, store_dir: Path, progress: bool = False) -> dict[str, Any]:
    """Road metrics of ``predictor`` (a :class:`vctrain.predict.Predictor` or
    :class:`vctrain.adapt.PriorPredictor`: anything with ``store_item``) on every labelled item of
    a test store, each scored in its ORIGINAL camera against its original label (P(road) >= 0.5).
    A model with two outputs (road, drivable) scores each item on the output of its label format's
    definition (IDD-Lite's drivable area on drivable), and the result says which (``output``)."""
    from ..metrics import RoadMetrics

    m = RoadMetrics()
    n, used = 0, set()
    for prob, label in scored_items(predictor, store_dir, progress, used):
        m.add(prob >= 0.5, label)
        n += 1
    two = len(getattr(predictor, "outputs", ())) > 1
    return {**m.result(), "test_items": n, **({"output": ",".join(sorted(used))} if two else {})}


def scored_items(predictor, store_dir: Path, progress: bool = False, used: set | None = None):
    """(P(road) float32, label 0/1/255) of every labelled item of a test store, in the item's ORIGINAL
    camera, as :func:`score_store` scores them; a two-output model on each label format's own output
    (added to ``used``)."""
    from tqdm import tqdm

    store = Store.open(store_dir)
    two = len(getattr(predictor, "outputs", ())) > 1
    for rec in tqdm(list(store), desc="test", unit="img", disable=None if progress else True, leave=False):
        if not rec.get("label_source"):
            continue
        fmt = get_label_format(rec["label_format"])
        if two:  # (the label's own definition: every format's is an output of such a model)
            chosen = predictor.use_output(fmt.definition)
            if used is not None:
                used.add(chosen)
        prob = predictor.store_item(store, rec)
        raw = read_image(rec["label_source"], label=True).array
        yield prob, decode_label(raw, fmt, rec["label_source"])


def execute(run: Run, ctx: Context, tag: str) -> list[dict[str, Any]]:
    """The result rows of ``run``: those finished earlier with the same settings, and the missing
    ones scored now with the predictor the condition's kind comes by (trained or found)."""
    kind = KINDS[CONDITIONS[run.condition][1]](run, ctx, tag)
    rows, todo = pending(run, ctx.out, kind.key, tag, ctx.say, kind.legacy)
    todo = kind.runnable(todo) if todo else todo
    if not todo:
        return rows
    info = kind.prepare(todo)
    for ds in todo:
        predictor, store, before, extra = kind.scored(ds)
        t0 = time.perf_counter()
        metrics = score_store(predictor, store, ctx.progress)
        from ..predict.frames import reads_road_vps

        if reads_road_vps(predictor):
            # what its frames were warped with (resize-vp: whose VPs it read): what vctrain predict says it uses
            from ..predict.predictor import warp_geometry

            extra = {**extra, "test_warp": warp_geometry(Store.open(store))}
        rows.append(write_result(run, ctx.out, ds, metrics, info, before + time.perf_counter() - t0, kind.key(ds),
                                 tag, ctx.say, **extra))
    return rows


def _check_adapt_targets(res: Resolution, evaluated: Sequence[str]) -> None:
    """Condition adapt needs, for every evaluated dataset, at least one image to adapt to."""
    for name in evaluated:
        ds = res.study.dataset(name)
        res.items(ds, res.adapt_split(ds))


def _write_study_json(out: Path, res: Resolution, conditions: list[str], training: dict[str, Any]) -> None:
    """``OUT/study.json``: what the study resolved to (the training stores' virtual camera, scale, each
    dataset's rule of estimated VPs, own vehicles, estimates); each test split's rectangle, VPs and own vehicle
    are in its results (``test_warp``)."""
    study = res.study
    write_json(out / "study.json", {"study": str(study.path), "virtual": res.training_virtual().to_dict(),
                                    "scale": res.scale(), "conditions": conditions,
                                    "datasets": [d.name for d in study.datasets],
                                    "roles": {d.name: d.role for d in study.datasets}, "train": training,
                                    "canvas": res.canvas, **({"extent": study.extent} if study.extent != "max" else {}),
                                    "vp_rules": {d.name: res.vp_rule(d).to_dict() for d in study.datasets},
                                    **({"ego_found": res.ego_found} if res.ego_found else {}),
                                    **({"cameras_estimated": {k: v["camera"] for k, v in res.estimated.items()}}
                                       if res.estimated else {})})


def run_study(study: Study, out: str | Path, conditions: Sequence[str] | None = None,
              heldout: Sequence[str] | None = None, progress: bool = True, jobs: int = 1,
              train_overrides: dict[str, Any] | None = None,
              say: Callable[[str], None] = lambda s: None) -> list[dict[str, Any]]:
    """Run (or resume) every (evaluated dataset, condition) of ``study`` into ``out`` (``heldout``:
    only these evaluated datasets); returns all result rows (finished earlier or now), in table
    order. Writes the tables (:func:`write_tables`)."""
    out = Path(out)
    conditions = check_conditions(conditions or study.conditions)
    evaluated = evaluated_datasets(study, heldout)
    overrides = dict(train_overrides or {})
    training = training_settings(study, overrides)  # checks the training settings before anything is written
    res = Resolution(study, out, say)
    if any(CONDITIONS[c][1] == "adapt" for c in conditions):
        _check_adapt_targets(res, evaluated)  # also before anything is written
    if any(CONDITIONS[c][1] in ("prior", "adapt") for c in conditions):
        # the prior is an image of the training rectangle: every store must share it
        if study.canvas == "footprint":
            raise InputError("conditions prior, adapt, adapt-fuse and adapt-self need every store in one rectangle", study.path,
                             "drop 'canvas: footprint' from the study, or those conditions")
        res.canvas = "shared"
    out.mkdir(parents=True, exist_ok=True)
    virt = res.training_virtual()  # (canvas: shared -- the one virtual camera of every store)
    for d in study.datasets:
        res.camera(d)  # every camera before anything is written: the own vehicle is searched for now
    res.say_ego()
    res.write_estimates()
    _write_study_json(out, res, conditions, training)
    ctx = Context(res, Stores(res, progress, jobs), Keys(res, virt, training), overrides, progress)
    runs = plan_runs(study, conditions, evaluated)
    rows: list[dict[str, Any]] = []
    for k, run in enumerate(runs, 1):
        rows += execute(run, ctx, f"[{k}/{len(runs)}]")
    order = {(h, c): i for i, (h, c) in enumerate((h, c) for h in evaluated for c in conditions)}
    rows.sort(key=lambda r: order[r["heldout"], r["condition"]])
    notes = [f"Camera of {k} ESTIMATED from its frames (cameras/{k}.yaml: what was estimated, given and assumed)."
             for k in res.estimated]
    write_tables(out, rows, evaluated, conditions, notes)
    return rows
