"""How each kind of condition comes by the predictor it is scored with (:data:`KINDS`):

* :class:`Fit` (resize, between, within, within-gt, zero, mixed): a model trained with
  :func:`vctrain.training.fit` on the run's training stores of the condition's geometry;
* :class:`Prior` (prior): no model, P(road) = the training datasets' geometric prior p_g;
* :class:`Adapt` (adapt, adapt-fuse, adapt-self): the within run's model (trained once, shared with
  condition within) adapted to each evaluated dataset's unlabelled images;
* :class:`Average` (average): no model of its own, the mean of the within and resize runs' models'
  probabilities in the evaluated camera's pixels.

Nothing is tuned on an evaluated camera: the checkpoint kept is the best on a validation share of
the TRAINING datasets. Training settings not given in the study are
:class:`vctrain.training.config.TrainConfig`'s defaults (the project's current recipe). A model is never
trained twice: one trained earlier with the settings it depends on is found by its key.
"""
from __future__ import annotations

import json
import shutil
import time
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any, Callable

from vcprep.camera import FrameCameras
from vcprep.errors import InputError
from vcprep.store import Store

from ..training.checkpoint_data import CheckpointData
from ..training.config import AdaptSettings, TrainConfig
from ..training.rerun import interrupted_after
from ..report import write_json
from .hashing import file_sha256, settings_sha
from .keys import TEST_WARP, Keys
from .resolve import Resolution
from .runs import Run, what
from .spec import ADAPT_COMBINE, CONDITION_TRAIN, CONDITIONS, DEFAULT_TRAIN, GEOMETRIES, RUN_KEYS, Dataset, Study
from .stores import Stores

__all__ = ["Context", "KINDS", "Fit", "Prior", "Adapt", "Average", "AveragePredictor", "train_config",
           "training_settings"]


def train_config(study: Study, stores: list[Path], out: Path, baseline: str, size: tuple[int, int] | None,
                 progress: bool, overrides: dict[str, Any]) -> TrainConfig:
    """The study's ``train:``, then ``overrides``, then for every setting left unset the recipe's
    default exactly as ``vctrain fit`` resolves it (so a study follows the project's recipe)."""
    from ..training.loop import resolve_recipe

    cfg = TrainConfig(stores=[str(s) for s in stores], out=str(out / "model.pt"), baseline=baseline, size=size,
                      progress=progress)
    names = {f.name for f in fields(TrainConfig)}
    for k, v in {**DEFAULT_TRAIN, **study.train, **overrides}.items():
        if k in names and v is not None:
            setattr(cfg, k, v)
    try:
        return resolve_recipe(cfg)
    except InputError as e:
        raise InputError(f"'train': {e.problem}", study.path, e.fix) from None


# settings added after studies were first keyed, and the value that leaves training as it was
SETTINGS_ADDED: dict[str, Any] = {"balance": "items", "shading_aug": 0.0, "pretrained": False,
                                  "ray_channels": False, "val_split": "auto", "freeze_bn": None, "average_init": None,
                                  "val_images": None, "val_labels": None,
                                  "freeze_encoder": None, "outputs": "road", "keep_aspect": False}


def training_settings(study: Study, overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """The training settings every run of ``study`` shares (the effective config, defaults included)."""
    cfg = train_config(study, [], Path("."), "none", None, False, dict(overrides or {}))
    out = {k: v for k, v in cfg.to_dict().items() if k not in RUN_KEYS and k != "workers"}
    for k, off in SETTINGS_ADDED.items():  # at their default the keys of studies from before them are as before
        if out.get(k) == off:
            del out[k]
    return out


@dataclass
class Context:
    """What every run of a study shares: its resolved files, stores, keys and training overrides."""

    res: Resolution
    stores: Stores
    keys: Keys
    overrides: dict[str, Any]
    progress: bool

    @property
    def out(self) -> Path:
        return self.res.out

    @property
    def say(self) -> Callable[[str], None]:
        return self.res.say


def _model_predictor(checkpoint: Path):
    from ..predict.predictor import Predictor
    from ..predict.settings import STUDY_ENGINE

    return Predictor(checkpoint, device="cpu", engine=STUDY_ENGINE)  # (on every install: settings.py says why)


ASPECT_NOTE = "'s pixels, each frame at its own aspect"  # (a keep_aspect model's size is its pixel budget)


def trained(run: Run, ctx: Context, tag: str) -> tuple[TrainConfig, dict[str, Any]]:
    """``(config, train.json)`` of ``run``'s model: trained now, or found trained earlier with
    the settings it depends on (``keys.model(run)``; ``runs/<run>/<condition>/train.json``), so a
    model is never trained twice."""
    from ..training.loop import fit

    say, c, keys = ctx.say, run.condition, ctx.keys
    run_dir = run.folder(ctx.out)
    geometry, baseline = CONDITIONS[c]
    stores = [ctx.stores.store(d, "train", geometry) for d in run.train]
    size = Store.open(stores[0]).store_size
    if baseline == "resize":
        size = ctx.stores.resize_size(run.train, size)
    run_dir.mkdir(parents=True, exist_ok=True)
    cfg = train_config(ctx.res.study, stores, run_dir, baseline, size, ctx.progress,
                       {**CONDITION_TRAIN.get(c, {}), **ctx.overrides})
    record = run_dir / "train.json"
    info = json.loads(record.read_text()) if record.exists() else None
    model_sha = keys.model(run)
    if (info is not None and model_sha in (info.get("model_sha"), info.get("settings_sha") == keys.full and model_sha)
            and Path(cfg.out).exists()):
        say(f"{tag} {run.name}, {c}: model trained earlier")
        if info.get("model_sha") != model_sha:  # (keyed by every setting of the study before Keys)
            info["model_sha"] = model_sha
            write_json(record, info)
        return cfg, info
    # a training of other settings: start afresh; one interrupted (no record, its last epoch's checkpoint of
    # these very settings and data): resumed after that epoch (the same model: the draws depend on seed and epoch)
    stopped = None if info is not None else interrupted_after(cfg)
    if stopped is None:
        for old in (record, Path(cfg.out), run_dir / "model.last.pt", run_dir / "model.log.jsonl"):
            old.unlink(missing_ok=True)
    else:
        cfg.resume = str(run_dir / "model.last.pt")
    say(f"{tag} {run.name}, {c}: training on {', '.join(d.name for d in run.train)} "
        f"({cfg.epochs} epochs at {size[0]}x{size[1]}{ASPECT_NOTE if cfg.keep_aspect else ''}"
        f"{'' if stopped is None else f'; resumed after epoch {stopped}'})")
    t0 = time.perf_counter() - (0.0 if stopped is None else earlier_seconds(Path(cfg.resume)))
    summary = fit(cfg)
    data = CheckpointData.from_dict(summary["data"])
    info = {"train_datasets": [d.name for d in run.train], "train_items": data.train_items,
            "val_items": data.val_items, "best_epoch": summary["best_epoch"],
            "best_val_iou": summary["best_val_iou"], "epochs": cfg.epochs, "input_size": list(size),
            "train_seconds": round(time.perf_counter() - t0, 1),
            "train_images_per_s": summary["train_images_per_s"], "model_args": summary["model_args"],
            "settings_sha": keys.full, "model_sha": model_sha, **({} if stopped is None else {"resumed_after": stopped})}
    write_json(record, info)
    return cfg, info


def epochs_seconds(rows) -> float:
    """The wall clock of a training's epochs (each one's training steps and validation) from its rows (the
    ``.last.pt`` history or ``model.log.jsonl``; one row an epoch)."""
    return sum(float(h.get("seconds") or 0.0) + float(h.get("val_seconds") or 0.0) for h in rows)


def earlier_seconds(last: Path) -> float:
    """The wall clock an interrupted training already spent (:func:`epochs_seconds` of its ``.last.pt``'s
    history): a resumed model's ``train_seconds`` is its whole training's, not the last invocation's (the
    setup of the earlier invocations is not recorded, so left out)."""
    from ..training.checkpoint import load_checkpoint

    return epochs_seconds(load_checkpoint(last).get("history", []))


def write_run_prior(run: Run, ctx: Context) -> tuple[Path, dict[str, Any], float]:
    """The geometric prior p_g of ``run``'s training datasets (their ``within`` training stores,
    :func:`vcprep.prior.compute_prior`), written as ``runs/<run>/<condition>/prior.npy`` with its
    description (usable by ``vctrain predict --prior``); returns (path, description, seconds)."""
    from vcprep.prior import compute_prior, prior_meta, write_prior

    stores = [ctx.stores.store(d, "train", CONDITIONS["prior"][0]) for d in run.train]
    t0 = time.perf_counter()
    prior, n_unlabelled = compute_prior(stores)
    meta = prior_meta(stores, n_unlabelled)
    run_dir = run.folder(ctx.out)
    run_dir.mkdir(parents=True, exist_ok=True)
    path = write_prior(run_dir / "prior.npy", prior, meta)
    return path, meta, time.perf_counter() - t0


# A condition kind, for one run: ``key(ds)`` (and ``legacy``) -- the settings its results are
# keyed by; ``runnable(todo)`` -- the pending datasets it can score; ``prepare(todo)`` -- its model
# (trained, found, or none), returning what each result row repeats of it; ``scored(ds)`` --
# (predictor, test store, seconds spent before scoring, extra result fields) for ``ds``.
class Fit:
    """Conditions resize, between, within, within-gt, zero: a model trained with ``vctrain fit``."""

    def __init__(self, run: Run, ctx: Context, tag: str):
        self.run, self.ctx, self.tag = run, ctx, tag
        self.geometry = CONDITIONS[run.condition][0]
        self.legacy: str | None = ctx.keys.full  # (rows keyed by every setting of the study, before Keys)

    def key(self, ds: Dataset) -> str:
        return self.ctx.keys.result(self.run, ds)

    def runnable(self, todo: list[Dataset]) -> list[Dataset]:
        """Without the datasets whose given VPs a ``within-gt`` run lacks (said)."""
        if GEOMETRIES[self.geometry][0] != "given":
            return todo
        has = self.ctx.stores.has_given_vps
        no_train = [d.name for d in self.run.train if not has(d, "train")]
        kept = []
        for ds in todo:
            missing = no_train + ([ds.name] if not has(ds, "test") else [])
            if missing:
                self.ctx.say(f"{what(self.run, ds, self.tag)}: skipped (no given VPs for {', '.join(missing)})")
            else:
                kept.append(ds)
        return kept

    def prepare(self, todo: list[Dataset]) -> dict[str, Any]:
        self.ctx.say(f"{self.tag} {self.run.name}, {self.run.condition}: stores")
        self.test_stores = {ds.name: self.ctx.stores.store(ds, "test", self.geometry) for ds in todo}
        self.cfg, self.info = trained(self.run, self.ctx, self.tag)
        return self.info

    def scored(self, ds: Dataset) -> tuple[Any, Path, float, dict[str, Any]]:
        return _model_predictor(Path(self.cfg.out)), self.test_stores[ds.name], self.info["train_seconds"], {}


class Prior:
    """Condition prior: no model; P(road) = the training datasets' p_g back-projected to each test
    image (:class:`vctrain.adapt.PriorPredictor`), scored like every other condition."""

    legacy: str | None = None

    def __init__(self, run: Run, ctx: Context, tag: str):
        self.run, self.ctx, self.tag = run, ctx, tag

    def key(self, ds: Dataset) -> str:
        return self.ctx.keys.full

    def runnable(self, todo: list[Dataset]) -> list[Dataset]:
        return todo

    def prepare(self, todo: list[Dataset]) -> dict[str, Any]:
        from ..adapt import PriorPredictor

        run = self.run
        self.ctx.say(f"{self.tag} {run.name}, prior: stores and the prior of {', '.join(d.name for d in run.train)}")
        path, self.meta, self.seconds = write_run_prior(run, self.ctx)
        self.predictor = PriorPredictor(path)
        return {"train_datasets": [d.name for d in run.train], "train_items": self.meta["items"], "val_items": 0,
                "best_epoch": None, "best_val_iou": None, "epochs": 0,
                "input_size": list(self.predictor.prior.shape[::-1]), "train_seconds": round(self.seconds, 1),
                "train_images_per_s": None}

    def scored(self, ds: Dataset) -> tuple[Any, Path, float, dict[str, Any]]:
        store = self.ctx.stores.store(ds, "test", CONDITIONS["prior"][0], fixed=True)  # as predict --prior warps
        return self.predictor, store, self.seconds, {"prior_unlabelled_pixels": self.meta["unlabelled_pixels"]}


class Adapt:
    """Conditions adapt, adapt-fuse, adapt-self: the within run's model (trained once, shared with condition
    within) adapted to each evaluated dataset's unlabelled images with the training datasets' prior
    (:func:`vctrain.adapt.adapt`), then scored on its test images like every other condition; a
    result depends on the study's settings, the adaptation's and the images adapted to."""

    legacy: str | None = None

    def __init__(self, run: Run, ctx: Context, tag: str):
        self.run, self.ctx, self.tag = run, ctx, tag

    def key(self, ds: Dataset) -> str:
        """The result's key: the adapted model's (:meth:`Keys.adapted`) and how its test split is warped."""
        return settings_sha({"adapted": self.ctx.keys.adapted(self.run, ds), "test_warp": TEST_WARP})

    def runnable(self, todo: list[Dataset]) -> list[Dataset]:
        return todo

    def prepare(self, todo: list[Dataset]) -> dict[str, Any]:
        within = replace(self.run, condition="within")
        self.cfg, self.info = trained(within, self.ctx, self.tag)
        self.source = Path(self.cfg.out)
        self.source_sha = file_sha256(self.source)
        self.prior_path, _, _ = write_run_prior(self.run, self.ctx)
        return self.info

    def scored(self, ds: Dataset) -> tuple[Any, Path, float, dict[str, Any]]:
        run_dir = self.run.folder(self.ctx.out)
        adir = run_dir if ds.name == self.run.name else run_dir / ds.name
        adir.mkdir(parents=True, exist_ok=True)
        model, record = adir / "model.pt", adir / "adapt.json"
        done = json.loads(record.read_text()) if record.exists() else None
        if (done is not None and done.get("settings_sha") == self.ctx.keys.adapted(self.run, ds)
                and done.get("from_sha256") == self.source_sha and model.exists()):
            self.ctx.say(f"{what(self.run, ds, self.tag)}: adapted earlier")
        else:  # adapted with other settings or from another model, or interrupted: afresh
            done = self._adapt(ds, adir, model, record)
        store = self.ctx.stores.store(ds, "test", CONDITIONS["adapt"][0])
        extra = {"adapt_target": done["target"], "adapt_items": done["target_items"],
                 "adapt_seconds": done["adapt_seconds"], "adapt_label_shares": done["label_shares"]}
        return _model_predictor(model), store, self.info["train_seconds"] + done["adapt_seconds"], extra

    def _adapt(self, ds: Dataset, adir: Path, model: Path, record: Path) -> dict[str, Any]:
        """Adapt the within model to ``ds``'s unlabelled images into ``adir`` (its images only:
        adapt never sees a label of the evaluated dataset; its labels are surrogates from the prior)."""
        from ..adapt import adapt

        res, stores = self.ctx.res, self.ctx.stores
        for old in (record, model, adir / "model.last.pt", adir / "model.log.jsonl"):
            old.unlink(missing_ok=True)
        shutil.rmtree(adir / "target.store", ignore_errors=True)  # never train on another run's items
        split = res.adapt_split(ds)
        jobs = res.items(ds, split)
        if isinstance(res.camera(ds), FrameCameras):
            poses = "none"  # per-frame calibration: every frame's exact pose, as in the test store
        else:
            stores.poses(ds, split, "estimate")  # the study's VP estimates (its pose range), as the test store's
            poses = str(self.ctx.out / "vps" / f"{ds.name}-{split}.csv")
        self.ctx.say(f"{what(self.run, ds, self.tag)}: adapting the within model to {len(jobs)} unlabelled {split} "
                     "images")
        t0 = time.perf_counter()
        settings = AdaptSettings(store=adir / "target.store", within=poses, combine=ADAPT_COMBINE[self.run.condition],
                                 device=self.cfg.device, seed=self.cfg.seed, max_steps=self.cfg.max_steps,
                                 progress=self.ctx.progress)
        summary = adapt(self.source, jobs, res.camera(ds), self.prior_path, model, settings)
        done = {"settings_sha": self.ctx.keys.adapted(self.run, ds), "from": str(self.source),
                "from_sha256": self.source_sha, "target": split, "target_items": len(jobs),
                "adapt_seconds": round(time.perf_counter() - t0, 1), "label_shares": summary["adapted"]["label_shares"],
                "epochs": summary["adapted"]["epochs"], "lr": summary["adapted"]["lr"]}
        write_json(record, done)
        return done


class AveragePredictor:
    """P(road) of a store item = the mean of several predictors' (each in the item's ORIGINAL camera)."""

    def __init__(self, predictors: list[Any]):
        self.predictors = predictors
        # scored on a virtual-camera test store when one of them warps: what its frames were warped with
        self.mode = "virtual" if any(p.mode == "virtual" for p in predictors) else "resize"
        # what the road's rules read of a predictor (vctrain.predict.kinds.RoadPredictor): it scores store items,
        # with no input channel of its own (as before the protocol, when these were read with getattr's default)
        self.takes_frames, self.vp_channel, self.ray_channels = False, False, False

    def store_item(self, store: Store, rec: dict[str, Any]):
        return sum(p.store_item(store, rec) for p in self.predictors) / len(self.predictors)


AVERAGED = ("within", "resize")  # condition average: the mean of these runs' models


class Average:
    """Condition average: the ``within`` and ``resize`` runs' models (trained once, shared with those
    conditions, trained here if not yet), their probabilities averaged in the evaluated camera's own
    pixels (back-projected from the virtual camera / resized back), scored like every other condition.
    Scored on the within test stores: the resize model reads each record's source image."""

    legacy: str | None = None

    def __init__(self, run: Run, ctx: Context, tag: str):
        self.run, self.ctx, self.tag = run, ctx, tag

    def key(self, ds: Dataset) -> str:
        return settings_sha({"average": list(AVERAGED), "result": self.ctx.keys.result(self.run, ds)})

    def runnable(self, todo: list[Dataset]) -> list[Dataset]:
        return todo

    def prepare(self, todo: list[Dataset]) -> dict[str, Any]:
        self.parts = [trained(replace(self.run, condition=c), self.ctx, self.tag) for c in AVERAGED]
        self.run.folder(self.ctx.out).mkdir(parents=True, exist_ok=True)
        self.test_stores = {ds.name: self.ctx.stores.store(ds, "test", CONDITIONS["average"][0]) for ds in todo}
        info = dict(self.parts[0][1])
        info["train_seconds"] = round(sum(i["train_seconds"] for _, i in self.parts), 1)
        return info

    def scored(self, ds: Dataset) -> tuple[Any, Path, float, dict[str, Any]]:
        predictor = AveragePredictor([_model_predictor(Path(cfg.out)) for cfg, _ in self.parts])
        return predictor, self.test_stores[ds.name], sum(i["train_seconds"] for _, i in self.parts), {
            "averaged": list(AVERAGED)}


# how a condition's predictor comes about (CONDITIONS[c][1]) -> its kind
KINDS: dict[str, type] = {"none": Fit, "resize": Fit, "mixed": Fit, "prior": Prior, "adapt": Adapt, "average": Average}
