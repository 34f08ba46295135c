"""Geometry-driven adaptation in the virtual camera (paper §4.5, after GeoSeg) and the prior as a
predictor (Table 5's "Geo-Prior").

:func:`adapt` fine-tunes a virtual-camera model on UNLABELLED target images:

1. the target images are warped into a store exactly as the model's training store was built
   (:func:`vctrain.predict.warp_like_training`: same virtual camera, scale, completion and
   within-camera mode; the store is kept, so a second run warps nothing);
2. each item gets surrogate labels (:func:`surrogate_for_item`), written as the item's store label:
   ``combine='prior'`` (default, the paper's §4.5): road where ``p_g > hi``, not road where
   ``p_g < lo``, ignore elsewhere — the same for every image; ``combine='fuse'``: the prior fused
   with the model's own prediction on that image before thresholding, ``p = p_g p_n / (p_g p_n +
   (1 - p_g)(1 - p_n))`` (the prior and the network as independent evidence, log-odds added), so a
   confident network decides where the prior is unsure, a confident prior where the network is,
   and a confident disagreement cancels to ignore — our reading of GeoSeg's combination of the
   geometric prior with the network's confident predictions, not a reproduction of its code.
   Pixels no source pixel reaches are ignored when the model was trained without completion
   (its training labels were ignore there too);
3. :func:`vctrain.training.fit` runs with ``init`` = the model (its network and weights, a fresh
   optimiser) and the model's own training settings, a short schedule (``epochs`` 5, ``lr`` a
   tenth of the model's), no validation (there are no target labels); the output checkpoint
   records ``adapted``: the source model, the prior (path, SHA-256 of its values, description),
   thresholds, combination, target images and camera, and the surrogate label shares.

:class:`PriorPredictor` stands in for a model in :mod:`vctrain.predict`: P(road) of a source
pixel is ``p_g`` back-projected (bilinear) from the virtual camera, so ``vctrain predict --prior``
writes ``p_g >= 0.5`` as the mask.
"""
from __future__ import annotations

import hashlib
from dataclasses import fields
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from vcprep.warp import backproject_array
from vcprep.camera import Camera, FrameCameras
from vcprep.dataset import Job
from vcprep.errors import InputError, one_of
from vcprep.io import read_image, write_png
from vcprep.labels import IGNORE, ROAD
from vcprep.prior import check_prior_fits, check_thresholds, meta_path, read_prior, surrogate_labels
from vcprep.progress import err
from vcprep.store import Store, store_lock

from .training.checkpoint import load_checkpoint, save_checkpoint
from .training.checkpoint_data import CheckpointData
from .training.config import ADAPT_EPOCHS, ADAPT_LR_FACTOR, AdaptSettings, TrainConfig

__all__ = ["COMBINE", "AdaptSettings", "own_settings", "ADAPT_EPOCHS", "ADAPT_LR_FACTOR", "PriorPredictor", "fuse", "surrogate_for_item", "write_surrogate_labels", "adapt",
           "adapt_store_path"]

COMBINE = ("prior", "fuse", "self")  # what a surrogate label is the tri-mask of: p_g, fused, the model's p_n


class PriorPredictor:
    """The geometric prior as a predictor with the interface :mod:`vctrain.predict` uses
    (``mode``, ``data``, ``path``, ``store_item``). Its description (``<prior>.json``, written by
    ``vcprep prior``) gives the virtual camera, scale and VP mode that images are warped with."""

    beyond_rule = None  # p_g is an image of one rectangle: images are warped into it, 0 outside it

    mode = "virtual"
    vp_channel = ray_channels = takes_frames = False  # (vctrain.predict.kinds.RoadPredictor)
    camera = engine = None

    def check_frame_size(self, size: tuple[int, int], name: str | Path | None = None) -> None:
        """Frames of any size are taken (warped into the prior's rectangle)."""

    def __init__(self, prior: str | Path):
        self.path = Path(prior)
        self.prior, meta = read_prior(self.path)
        if meta is None:
            raise InputError(f"no description {meta_path(self.path).name} beside the prior (it says which virtual "
                             "camera and scale the prior is in)", self.path,
                             "write the prior with 'vcprep prior STORE... -o FILE'")
        sp = meta.get("store_params") or {}
        w, h = sp.get("store_size") or (0, 0)
        if (self.prior.shape[1], self.prior.shape[0]) != (w, h):
            raise InputError(f"prior is {self.prior.shape[1]}x{self.prior.shape[0]} but its description says {w}x{h}",
                             self.path, "write the prior and its description again with 'vcprep prior'")
        # the warp only places the prior: completion does not change the geometry
        self.data = CheckpointData(mode="virtual", store_params=sp, completion="none",
                                   vp_status=tuple(meta.get("vp_status", ["camera"])), input_size=(w, h),
                                   vp_rule=meta.get("vp_rule") or None)

    def store_item(self, store: Store, rec: dict[str, Any]) -> np.ndarray:
        """P(road) = p_g in the item's ORIGINAL camera (source size; 0 outside the virtual image)."""
        return np.clip(backproject_array(self.prior, rec, kind="prob"), 0.0, 1.0)


def fuse(prior: np.ndarray, prob: np.ndarray) -> np.ndarray:
    """``p_g p_n / (p_g p_n + (1 - p_g)(1 - p_n))`` (float32); 0.5 where both are certain and
    disagree (0/0)."""
    a = np.asarray(prior, np.float64) * np.asarray(prob, np.float64)
    b = (1.0 - np.asarray(prior, np.float64)) * (1.0 - np.asarray(prob, np.float64))
    return np.divide(a, a + b, out=np.full(a.shape, 0.5), where=(a + b) > 0).astype(np.float32)


def surrogate_for_item(prior: np.ndarray, lo: float, hi: float, valid: np.ndarray | None = None,
                       prob: np.ndarray | None = None, own_only: bool = False) -> np.ndarray:
    """Surrogate label (uint8 0/1/255, store size) of one item: the prior's tri-mask, or with
    ``prob`` (the model's P(road) at the store size) the tri-mask of :func:`fuse`, or with
    ``own_only`` the tri-mask of ``prob`` alone (self-training: the control without the prior);
    ``valid`` (1 where a source pixel landed) given: ignore where it is 0."""
    if own_only and prob is None:
        raise ValueError("own_only needs the model's prob")
    lab = surrogate_labels(prior if prob is None else prob if own_only else fuse(prior, prob), lo, hi)
    if valid is not None:
        lab[np.asarray(valid) == 0] = IGNORE
    return lab


def write_surrogate_labels(store: Store | str | Path, prior: np.ndarray, lo: float = 0.25, hi: float = 0.75,
                           combine: str = "prior", predictor=None, ids: Iterable[str] | None = None,
                           ignore_uncovered: bool = False) -> dict[str, float]:
    """Write each item's surrogate label as its store label (``labels/<id>.png``) and record it
    (``label_kind`` 'surrogate'), holding the store's writer lock. ``predictor`` (a
    :class:`vctrain.predict.Predictor`) is needed for ``combine`` 'fuse' and 'self'. Returns the label
    shares over all pixels (road, not_road, ignore)."""
    if combine not in COMBINE:
        raise InputError(f"unknown combination '{combine}'", None, one_of(combine, COMBINE))
    check_thresholds(lo, hi)
    root = store.root if isinstance(store, Store) else Path(store)
    with store_lock(root, on_wait=err):
        return _write_surrogates(Store.open(root), prior, lo, hi, combine, predictor, ids, ignore_uncovered)


def _write_surrogates(store: Store, prior, lo, hi, combine, predictor, ids, ignore_uncovered) -> dict[str, float]:
    from .training.data import vp_in_store

    w, h = store.store_size
    if prior.shape != (h, w):
        raise InputError(f"prior is {prior.shape[1]}x{prior.shape[0]} but the store is {w}x{h}", store.root,
                         "compute the prior from stores of this virtual camera and scale")
    counts = np.zeros(3, np.int64)
    recs = list(store) if ids is None else [store.get(i) for i in ids]
    for rec in recs:
        valid = read_image(store.path(rec["valid"]), label=True).array if ignore_uncovered else None
        prob = None
        if combine in ("fuse", "self"):
            prob = predictor.road_probability(read_image(store.path(rec["image"])).array, vp_in_store(rec, store))
        lab = surrogate_for_item(prior, lo, hi, valid, prob, own_only=combine == "self")
        rel = f"labels/{rec['id']}.png"
        sha = write_png(store.path(rel), lab, kind="mask")
        new = {**rec, "label": rel, "label_kind": "surrogate",
               "files_sha256": {**(rec.get("files_sha256") or {}), "label": sha}}
        store.record(new)
        counts += [np.count_nonzero(lab == ROAD), np.count_nonzero(lab == 0), np.count_nonzero(lab == IGNORE)]
    store.save()
    total = max(int(counts.sum()), 1)
    return {"road": float(counts[0] / total), "not_road": float(counts[1] / total), "ignore": float(counts[2] / total)}


def adapt_store_path(out: str | Path) -> Path:
    """Default store of the warped target images: ``OUT-stem.store`` beside the checkpoint."""
    out = Path(out)
    return out.with_name(out.stem + ".store")


def _sha256(arr: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(arr, np.float32).tobytes()).hexdigest()


def _prior_for(prior: str | Path | np.ndarray, store_params: dict[str, Any],
               model: Path) -> tuple[np.ndarray, str | None, dict | None]:
    """(p_g, its path, its description) of ``prior`` (a file or an array), checked to be in the
    virtual camera and scale of ``model``'s store (``store_params``)."""
    size = tuple(store_params["store_size"])
    if isinstance(prior, (str, Path)):
        p, meta = read_prior(prior, size=size)
        check_prior_fits(prior, meta, store_params)
        return p, str(prior), meta
    p = np.asarray(prior, np.float32)
    if p.shape != (size[1], size[0]):
        raise InputError(f"prior is {p.shape[1]}x{p.shape[0]} but the model's store is {size[0]}x{size[1]}", model,
                         "compute the prior from stores of the model's virtual camera and scale")
    return p, None, None



def own_settings(ck: dict, **overrides) -> TrainConfig:
    """The training settings of a run that continues checkpoint ``ck``'s training: its own settings
    (whatever this vctrain's TrainConfig knows), its network (architecture, width), then ``overrides``."""
    known = {f.name for f in fields(TrainConfig)}
    base = {k: v for k, v in (ck.get("config") or {}).items() if k in known}
    return TrainConfig(**{**base, "arch": ck["model_args"]["arch"], "base_width": ck["model_args"]["base_width"],
                          **overrides})

def adapt(model: str | Path, images: str | Path | Iterable[str | Path] | Sequence[Job], camera: Camera | FrameCameras,
          prior: str | Path | np.ndarray, out: str | Path, settings: AdaptSettings = AdaptSettings()) -> dict[str, Any]:
    """Fine-tune the virtual-camera ``model`` on unlabelled ``images`` (a folder, image files, or
    :class:`vcprep.dataset.Job` items whose ids are kept) of ``camera`` with surrogate
    labels from ``prior`` (a ``.npy``/``.png`` written by ``vcprep prior``, or the array of
    :func:`vcprep.prior.compute_prior`); ``camera`` may be per-frame calibration (every frame
    its exact pose, no VP estimated); writes ``out`` (and ``OUT-stem.last.pt``, the log).
    Returns :func:`vctrain.training.fit`'s summary plus ``adapted`` (what the checkpoint records).
    See the module docstring for the steps and :class:`vctrain.training.config.AdaptSettings` for the settings."""
    from .predict.predictor import Predictor, warp_like_training
    from vcprep.dataset import collect_images
    from .training.loop import fit, last_path

    model = Path(model)
    ck = load_checkpoint(model)
    data = CheckpointData.from_dict(ck["data"])
    if not data.virtual:
        raise InputError("model has no virtual camera (a resize baseline); adaptation works in the virtual camera",
                         model, "adapt a model trained on a store built by 'vcprep warp'")
    lo, hi, combine = settings.lo, settings.hi, settings.combine
    check_thresholds(lo, hi)
    if combine not in COMBINE:
        raise InputError(f"unknown combination '{combine}'", None, one_of(combine, COMBINE))
    epochs = int(settings.epochs)
    lr = (float(settings.lr) if settings.lr is not None
          else ADAPT_LR_FACTOR * float((ck.get("config") or {}).get("lr") or 0.005))
    if epochs < 1 or not lr > 0:
        raise InputError(f"epochs {epochs} and lr {lr:g} must be positive", None, "use e.g. --epochs 5 --lr 0.001")
    size = data.store_size
    p, prior_path, meta = _prior_for(prior, data.store_params, model)
    out = Path(out)
    if not out.parent.is_dir():
        raise InputError("output folder does not exist", out.parent, "create it first")
    if out.resolve() == model.resolve():
        raise InputError("--out is the model being adapted", out, "write the adapted model to another file")
    images = [images] if isinstance(images, (str, Path)) else list(images)
    # Jobs keep their ids (a study's: IDD-Lite's '<drive>_<frame>', as its VP files name them), never their
    # labels (adaptation sees none); paths get their stems
    jobs = ([Job(j.id, j.image) for j in images] if images and all(isinstance(j, Job) for j in images)
            else collect_images(images))
    root = Path(settings.store) if settings.store is not None else adapt_store_path(out)
    # the surrogate labels come from the prior, an image of the training rectangle: no extension
    target = warp_like_training(data, model, jobs, camera, root, settings.within, settings.progress, extend=False)
    ids = [j.id for j in jobs]
    predictor = Predictor(model, settings.device) if combine in ("fuse", "self") else None
    shares = write_surrogate_labels(target, p, lo, hi, combine, predictor, ids,
                                    ignore_uncovered=data.completion == "none")
    if shares["road"] == 0 or shares["not_road"] == 0:
        what = f"surrogate labels hold no {'road' if shares['road'] == 0 else 'not-road'} pixel (thresholds {lo:g}/{hi:g})"
        if combine == "self":  # the labels are the model's own: it is that sure of nothing (or of one class)
            raise InputError(f"{what}: the model's own P(road) never crosses them on these images", model,
                             "widen --lo/--hi, or use --combine fuse or prior")
        raise InputError(what, prior_path or model, "check the prior, or widen --lo/--hi")

    overrides = dict(stores=[str(target.root)], out=str(out), init=str(model), resume=None, baseline="none",
                     images=None, labels=None, label_format=None, val_fraction=0.0, val_stores=[], log=None,
                     size=data.input_size or size,
                     epochs=epochs, lr=lr, device=settings.device, progress=settings.progress,
                     max_steps=settings.max_steps, workers=0,
                     average_init=0.0, freeze_bn=False, freeze_encoder=False,  # adapt's measured recipe
                     vp_channel=data.vp_channel, greyscale=data.greyscale)
    if settings.seed is not None:
        overrides["seed"] = int(settings.seed)
    if settings.batch_size is not None:
        overrides["batch_size"] = int(settings.batch_size)
    cfg = own_settings(ck, **overrides)
    summary = fit(cfg)

    adapted = {"from": str(model), "from_sha256": hashlib.sha256(model.read_bytes()).hexdigest(),
               "prior": prior_path, "prior_sha256": _sha256(p), "prior_meta": meta, "lo": float(lo), "hi": float(hi),
               "combine": combine, "images": [str(j.image) for j in jobs],
               "camera": camera.to_dict() if isinstance(camera, Camera) else {"calibration_folder": str(camera.folder)},
               "store": str(target.root), "label_shares": shares, "epochs": cfg.epochs, "lr": cfg.lr}
    for path in (out, last_path(out)):
        if path.is_file():
            ck_out = load_checkpoint(path)
            ck_out["adapted"] = adapted
            save_checkpoint(path, ck_out)
    return {**summary, "adapted": adapted}
