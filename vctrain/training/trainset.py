"""A training run's data: its stores opened and checked, the samples of the view it trains on
(:data:`BASELINES`), the validation share or stores, the working size, the training window
(:func:`crop_size`), the datasets (:func:`training_sets`) and each epoch's batches
(:func:`epoch_order`, :func:`vctrain.training.parts.view_batches`). The items themselves, their decoding and augmentation:
:mod:`vctrain.training.data`.

Mixed views (``baseline: mixed``, issue 53's candidate): every frame twice, its virtual-camera store
item and its original image resized, each view at its own working size and window
(:class:`~vctrain.training.parts.MixedViews`); a batch holds one view. ``keep_aspect`` (a resize baseline):
every frame at the working size's pixel count at its own aspect (:class:`~vctrain.training.parts.AspectParts`);
a batch holds frames of one size.
"""
from __future__ import annotations

import json
import math
import re
from collections import Counter
from dataclasses import replace
from typing import Any, Sequence

import numpy as np
import torch

from vcprep.dataset import list_dataset
from vcprep.errors import InputError
from vcprep.io import image_size
from vcprep.labels import get_label_format
from vcprep.store import Store, record_magnification

from .config import BALANCES, VAL_SPLITS, TrainConfig
from .data import RoadDataset, Sample, resize_samples, store_samples
from .outputs import ONE_OUTPUT, parse_outputs
from .parts import AspectParts, MixedViews, resize_working_size

__all__ = ["BASELINES", "MIN_SIDE", "prepare_data",
           "training_magnification", "crop_size", "epoch_order", "training_sets", "label_shares", "check_labels",
           "sequence_of", "sequence_items"]

MIN_SIDE = 32  # the smallest working side: five 2x2 poolings
# what a model is trained on (TrainConfig.baseline): 'none' the virtual camera's store items, 'resize'
# the original images simply resized, 'mixed' both views of every frame (:class:`MixedViews`)
BASELINES = ("none", "resize", "mixed")
# the 'sequence' split holds out whole sequences only where the names show at least this many: with fewer
# (KITTI road's um_/umm_/uu_, one drive) a single one is a third of the frames or more, not a fifth (issue 80)
MIN_SEQUENCES = 5


def _open_stores(paths: list[str]) -> list[Store]:
    stores = [Store.open(p) for p in paths]
    for s in stores[1:]:
        for k in ("virtual", "scale", "store_size"):
            if s.params.get(k) != stores[0].params.get(k):
                raise InputError(f"store has another {k} than {stores[0].root}", s.root,
                                 "train on stores of one virtual camera at one scale")
    return stores


def _samples(stores: list[Store], baseline: str) -> list[Sample]:
    """The stores' samples in the view ``baseline`` trains on ('mixed': call once per view)."""
    out: list[Sample] = []
    for s in stores:
        got = resize_samples(s) if baseline == "resize" else store_samples(s)
        if not got:
            raise InputError("store has no labelled items", s.root, "build it with --labels")
        out += got
    return out


def _completion(stores: list[Store]) -> str:
    kinds = {rec.get("completion", "none") for s in stores for rec in s}
    if len(kinds) > 1:
        raise InputError(f"stores mix completion methods ({', '.join(sorted(kinds))})", stores[0].root,
                         "train on items built with one --complete method")
    return kinds.pop() if kinds else "none"


def val_split(cfg: TrainConfig) -> str:
    """The validation split a run uses: ``cfg.val_split``, 'auto' resolved (sequence when fine-tuning)."""
    if cfg.val_split not in VAL_SPLITS:
        raise InputError(f"unknown validation split '{cfg.val_split}'", None, f"use one of {', '.join(VAL_SPLITS)}")
    if cfg.val_split == "auto":
        return "sequence" if cfg.init else "random"
    return cfg.val_split


def sequence_of(item_id: str) -> str:
    """The sequence (drive, clip) a frame's name shows: the name less its trailing frame number
    (CamVid ``0001TP_006690`` -> ``0001TP``, IDD-Lite ``<drive>_<frame>`` -> ``<drive>``); frames of
    one sequence share it."""
    return re.sub(r"[_.-]?\d+$", "", item_id.rsplit("/", 1)[-1])


def sequence_items(ids: list[str], sources: list[str], fraction: float, seed: int) -> tuple[set[int], str]:
    """('sequence' split) the indices held out and how they were chosen (the words ``fit`` prints):
    whole sequences (a seeded draw of them, about ``fraction`` of the frames) where the names show
    :data:`MIN_SEQUENCES` or more; by frame where they show fewer (KITTI's um_/umm_/uu_, one drive): the
    last share of each sequence in name order (a stretch of each, not the neighbours of training frames),
    since whole ones would hold out a third of the frames or more; a seeded share where every name is
    its own (no sequence)."""
    groups: dict[tuple[str, str], list[int]] = {}
    for i, (name, src) in enumerate(zip(ids, sources)):
        groups.setdefault((src, sequence_of(name)), []).append(i)
    if all(len(m) == 1 for m in groups.values()):
        held = validation_items(ids, sources, fraction, "random", seed)
        return held, f"a seeded {fraction:.0%} (the frames' names show no sequence)"
    if len(groups) >= MIN_SEQUENCES:
        held, chosen = _whole_sequences(groups, len(ids), fraction, seed)
        if chosen:
            return held, f"whole sequences {', '.join(sorted(chosen))} of {len(groups)}"
    names = sorted({g[1] or "(unnamed)" for g in groups})
    held = _stretches(ids, list(groups.values()), fraction)
    few = f"fewer than {MIN_SEQUENCES}" if len(groups) < MIN_SEQUENCES else "too unequal"
    return held, (f"by frame: the last {fraction:.0%} in name order of each of the {len(groups)} sequences "
                  f"{', '.join(names[:6])}{', ...' if len(names) > 6 else ''} ({few} to hold out whole ones)")


def _whole_sequences(groups: dict[tuple[str, str], list[int]], n: int, fraction: float,
                     seed: int) -> tuple[set[int], list[str]]:
    """Whole sequences drawn in a seeded order until about ``fraction`` of the ``n`` frames are held out:
    one that would take the share past 1.5 times it is passed over, never every sequence; none chosen
    (an empty list) where they reach less than half of it."""
    target, held, chosen = max(1, int(round(fraction * n))), set(), []
    keys = sorted(groups)
    for k in np.random.default_rng(seed).permutation(len(keys)):
        if len(held) >= target or len(chosen) == len(keys) - 1:
            break
        if len(held) + len(groups[keys[k]]) <= max(1.5 * target, 1):
            held.update(groups[keys[k]])
            chosen.append(keys[k][1] or "(unnamed)")
    return (held, chosen) if len(held) >= target / 2 else (set(), [])


def _stretches(ids: list[str], groups: list[list[int]], fraction: float) -> set[int]:
    """Of each group (a sequence) the last ``fraction`` of its items in name order; at least one item
    in all (the last of the largest group), never every item."""
    held: set[int] = set()
    for members in groups:
        k = int(round(fraction * len(members)))
        held.update(sorted(members, key=lambda i: ids[i])[len(members) - k:] if k else [])
    if not held:
        held.add(max(max(groups, key=len), key=lambda i: ids[i]))
    if len(held) >= len(ids):
        raise InputError(f"{len(ids)} items are too few to hold out {fraction:g} of each sequence", None,
                         "add items, or use --val-split random / --val-fraction 0 / --val-store")
    return held


def validation_items(ids: list[str], sources: list[str], fraction: float, split: str, seed: int) -> set[int]:
    """The indices held out for validation: ``fraction`` of the items (at least one, never all).
    'random': a seeded draw; 'block': of each source (store or folder) the last share of its items in
    name order -- frames named by drive and time give whole drives or one stretch of a drive, not
    the neighbours of training frames, so the score says what another drive would see."""
    n = len(ids)
    n_val = max(1, int(round(fraction * n)))
    if n_val >= n:
        raise InputError(f"{n} items are too few to hold out {fraction:g}", None,
                         "add items, or use --val-fraction 0 / --val-store")
    if split == "random":
        return {int(i) for i in np.random.default_rng(seed).permutation(n)[:n_val]}
    groups: dict[str, list[int]] = {}
    for i, s in enumerate(sources):
        groups.setdefault(s, []).append(i)
    held: set[int] = set()
    for members in groups.values():
        k = int(round(fraction * len(members)))
        held.update(sorted(members, key=lambda i: ids[i])[len(members) - k:] if k else [])
    if not held:  # every source too small for its share: the last item in name order of the largest
        largest = max(groups.values(), key=len)
        held.add(max(largest, key=lambda i: ids[i]))
    if len(held) >= n:
        raise InputError(f"{n} items are too few to hold out {fraction:g} of each source", None,
                         "add items, or use --val-split random / --val-fraction 0 / --val-store")
    return held


def _val_frames(cfg: TrainConfig) -> list[Sample]:
    """The validation samples of ``--val-images``/``--val-labels`` (the resize baseline's frames, read
    with ``--label-format``): frames of the light or drive the model will see, which the training
    frames' own share cannot stand for."""
    if cfg.baseline != "resize" or cfg.images is None:
        raise InputError("--val-images is for the resize baseline trained on --images", cfg.val_images,
                         "add --baseline resize --images/--labels, or validate a store run on --val-store")
    if cfg.val_labels is None:
        raise InputError("--val-images needs --val-labels", cfg.val_images, "add the folder of their labels")
    if cfg.val_stores:
        raise InputError("give either --val-images or --val-store, not both", cfg.val_images, "drop one of them")
    return _folder_samples(cfg.val_images, cfg.val_labels, get_label_format(cfg.label_format))


def training_magnification(stores: Sequence[Store]) -> float | None:
    """The most the warp enlarged any training camera's frames: the largest store-pixels-per-source-pixel
    figure (:func:`vcprep.store.record_magnification`) over the cameras of ``stores``' items; None when
    no item records its camera. A predictor shrinks its working size only for frames enlarged more."""
    seen: dict[str, float | None] = {}
    for st in stores:
        virtual, vs = st.virtual, st.params.get("virtual_scaled")
        for rec in st:
            key = json.dumps([rec.get("camera_params"), rec.get("size"), vs], sort_keys=True)
            if key not in seen:
                seen[key] = record_magnification(rec, virtual)
    found = [m for m in seen.values() if m is not None]
    return round(max(found), 4) if found else None


def _folder_samples(images: str, labels: str, fmt) -> list[Sample]:
    """The samples of an image folder and its label folder (``--images``/``--labels``, ``--val-images``)."""
    return [Sample(j.id, j.image, j.label, fmt.name, source=str(images)) for j in list_dataset(images, labels, fmt)]


def prepare_data(cfg: TrainConfig) -> tuple[list[Sample], list[Sample], dict[str, Any]]:
    """Training and validation samples plus the checkpoint's ``data`` description."""
    if cfg.baseline not in BASELINES:
        raise InputError(f"unknown baseline '{cfg.baseline}'", None, "use --baseline resize or mixed (or leave it out)")
    if cfg.baseline == "mixed":
        return _prepare_mixed(cfg)
    stores = _open_stores(cfg.stores) if cfg.stores else []
    info: dict[str, Any] = {"mode": "resize" if cfg.baseline == "resize" else "virtual",
                            "store_params": stores[0].params if stores else None,
                            "completion": _completion(stores) if stores else "none",
                            "vp_channel": cfg.vp_channel, "greyscale": cfg.greyscale,
                            **({"ray_channels": True} if cfg.ray_channels else {})}
    if info["mode"] == "virtual" and stores:
        m = training_magnification(stores)
        if m is not None:  # the reference of the predictors' density_scale
            info["source_magnification"] = m
    if cfg.images is not None:
        if cfg.baseline != "resize":
            raise InputError("--images is for the resize baseline", cfg.images,
                             "add --baseline resize, or train on a store built with 'vcprep warp'")
        if cfg.labels is None or cfg.label_format is None:
            raise InputError("--images needs --labels and --label-format", cfg.images, "add them")
        train = _folder_samples(cfg.images, cfg.labels, get_label_format(cfg.label_format))
        if stores:
            train += _samples(stores, cfg.baseline)
    elif stores:
        train = _samples(stores, cfg.baseline)
    else:
        raise InputError("no training data", None, "give STORE... (or --baseline resize --images/--labels)")
    if cfg.val_images is not None:
        val = _val_frames(cfg)
        info["held_out"] = f"the frames of {cfg.val_images} (--val-images)"
    elif cfg.val_stores:
        vstores = _open_stores(cfg.val_stores)
        if cfg.baseline != "resize" and stores:
            for k in ("virtual", "scale"):
                if vstores[0].params.get(k) != stores[0].params.get(k):
                    raise InputError(f"validation store has another {k} than the training store", vstores[0].root,
                                     "validate on a store of the same virtual camera and scale")
        val = _samples(vstores, cfg.baseline)
    elif cfg.val_fraction > 0:
        if not 0 < cfg.val_fraction < 1:
            raise InputError(f"validation fraction {cfg.val_fraction} is not in [0, 1)", None, "use e.g. 0.1")
        ids, sources, split = [s.id for s in train], [s.source for s in train], val_split(cfg)
        if split == "sequence":
            held, info["held_out"] = sequence_items(ids, sources, cfg.val_fraction, cfg.seed)
        else:
            held = validation_items(ids, sources, cfg.val_fraction, split, cfg.seed)
            info["held_out"] = f"{'a seeded' if split == 'random' else 'the last'} {cfg.val_fraction:.0%}" + \
                ("" if split == "random" else " of each folder or store in name order")
        val = [s for i, s in enumerate(train) if i in held]
        train = [s for i, s in enumerate(train) if i not in held]
    else:
        val = []
    size = _working_size(cfg, stores, train)
    info["input_size"] = list(size)
    info["crop_size"] = list(crop_size(cfg.crop, size))
    if cfg.keep_aspect:  # (input_size: the pixel budget; each frame at its own aspect, parts.AspectParts)
        if cfg.baseline != "resize":
            raise InputError("--keep-aspect is for the resize baseline (a store's items have one size)", None,
                             "add --baseline resize, or leave --keep-aspect out")
        info["keep_aspect"] = True
    info["vp_status"] = sorted({rec.get("vp_status", "camera") for s in stores for rec in s})
    rules = Counter(json.dumps(rec["vp_rule"], sort_keys=True) for s in stores for rec in s if rec.get("vp_rule"))
    if rules:  # the rule the estimated VPs were found with (of most items): predict follows it
        info["vp_rule"] = json.loads(max(sorted(rules), key=rules.get))
    if parse_outputs(cfg.outputs) != ONE_OUTPUT:  # (a one-output model's data section as before)
        info["outputs"] = list(parse_outputs(cfg.outputs))
    info["train_items"] = len(train)
    info["train_items_per_source"] = dict(Counter(t.source for t in train))  # (in the stores' order)
    info["val_items"] = len(val)
    return train, val, info


def _working_size(cfg: TrainConfig, stores: list[Store], train: list[Sample]) -> tuple[int, int]:
    """A run's working size (w, h): ``--size``; a resize baseline on stores the store's pixels at the first
    frame's aspect; a store's size; the first frame's (folders). Refused below MIN_SIDE."""
    if cfg.size is not None:
        size = (int(cfg.size[0]), int(cfg.size[1]))
    elif stores and cfg.baseline == "resize":  # the store's pixels at the frames' own aspect (as a study's twin)
        size = resize_working_size(stores[0].store_size, image_size(train[0].image))
    elif stores:
        size = stores[0].store_size
    else:
        from vcprep.io import read_image

        size = read_image(train[0].image).size
    if min(size) < MIN_SIDE:
        raise InputError(f"working size {size[0]}x{size[1]} is below {MIN_SIDE} pixels", None,
                         "use a larger --size or store scale")
    return size


def _prepare_mixed(cfg: TrainConfig) -> tuple[list[Sample], list[Sample], dict[str, Any]]:
    """:func:`prepare_data` for ``baseline: mixed`` (:class:`MixedViews`): the virtual-camera run's
    data, its resize twin's (the same frames, the same validation share: one seeded split of the
    frames), and ``resize_size`` / ``resize_crop_size`` (the twin's working size and window). The
    samples are the virtual view's then the resize view's; ``info['views']`` their counts."""
    if cfg.images is not None or not cfg.stores:
        raise InputError("--baseline mixed trains on stores (both views of their frames)", cfg.images,
                         "give STORE... built with 'vcprep warp' --labels")
    parts = {}
    for view in ("none", "resize"):
        sub = replace(cfg, baseline=view, size=cfg.size if view == "none" else None)
        parts[view] = prepare_data(sub)
    (tv, vv, info), (tr, vr, rinfo) = parts["none"], parts["resize"]
    if [s.id for s in tv] != [s.id for s in tr] or [s.id for s in vv] != [s.id for s in vr]:
        raise InputError("the store's labelled items and their sources differ", cfg.stores[0],
                         "rebuild the store with 'vcprep warp --labels'")
    info = {**info, "mode": "mixed", "resize_size": rinfo["input_size"], "resize_crop_size": rinfo["crop_size"],
            "views": [len(tv), len(tr)], "train_items": len(tv) + len(tr), "val_items": len(vv) + len(vr),
            "train_items_per_source": dict(Counter(t.source for t in tv + tr))}
    return tv + tr, vv + vr, info


def crop_size(crop: Any, size: tuple[int, int]) -> tuple[int, int]:
    """The training window (w, h) of ``crop`` at working size ``size``: None -> ``size``; a number
    in (0, 1] -> that share of each side; a pair of floats in (0, 1] -> the shares of the width
    and the height (e.g. (0.44, 1.0): full-height windows); a pair of ints -> pixels. Shares are
    rounded, and never below MIN_SIDE (so the recipe's share works on small stores too). The window
    must fit ``size`` and be at least MIN_SIDE on each side."""
    if crop is None:
        return tuple(size)

    def share(v: Any, side: int) -> int:
        if not 0 < float(v) <= 1:
            raise InputError(f"crop share {v} is not in (0, 1]", None, "use e.g. --crop 0.67, 0.44x1 or 320x240")
        return max(int(round(side * float(v))), min(MIN_SIDE, side))  # a share never below MIN_SIDE

    if isinstance(crop, (int, float)) and not isinstance(crop, bool):
        out = (share(crop, size[0]), share(crop, size[1]))
    elif all(isinstance(v, float) for v in crop):
        out = (share(crop[0], size[0]), share(crop[1], size[1]))
    else:
        out = (int(crop[0]), int(crop[1]))
    if out[0] > size[0] or out[1] > size[1] or min(out) < MIN_SIDE:
        raise InputError(f"crop {out[0]}x{out[1]} does not fit the working size {size[0]}x{size[1]} (or is below "
                         f"{MIN_SIDE} px)", None, "use a smaller --crop, a larger --size, or leave --crop out")
    return out


def epoch_order(sources: Sequence[str], balance: str, generator: torch.Generator) -> list[int]:
    """The training items (indices into ``sources``, each item's store or folder) one epoch visits,
    in order: as many as there are items, drawn with ``generator`` (seeded per run and epoch, so a
    resumed run and the resize twin of a virtual-camera run draw the same).

    ``items``: a random permutation (every item once; a store weighs as many items as it holds).
    ``datasets``: every source gets an equal share of the epoch (the remainder to sources chosen at
    random), filled with fresh random permutations of its own items -- a small store is repeated,
    a large one sampled without replacement -- then the whole epoch shuffled. With one source it is
    ``items``' permutation."""
    n = len(sources)
    groups: dict[str, list[int]] = {}
    for i, s in enumerate(sources):
        groups.setdefault(s, []).append(i)
    if balance == "items" or len(groups) < 2:
        return torch.randperm(n, generator=generator).tolist()
    if balance != "datasets":
        raise InputError(f"unknown balance '{balance}'", None, f"use one of {', '.join(BALANCES)}")
    members = list(groups.values())
    quota = [n // len(members)] * len(members)
    for g in torch.randperm(len(members), generator=generator)[: n % len(members)].tolist():
        quota[g] += 1
    drawn: list[int] = []
    for idx, q in zip(members, quota):
        while q > 0:
            take = torch.randperm(len(idx), generator=generator)[:q].tolist()
            drawn += [idx[k] for k in take]
            q -= len(take)
    return [drawn[k] for k in torch.randperm(len(drawn), generator=generator).tolist()]


def training_sets(cfg: TrainConfig, train_s: list, val_s: list, info: dict[str, Any]) -> tuple[Any, Any]:
    """(training set with the augmentations and crop, validation set) at the working size; for
    ``mixed`` each view at its own working size and window (:class:`MixedViews`)."""
    def pair(train: list, val: list, size: list[int], crop: list[int]) -> tuple[RoadDataset, RoadDataset]:
        return (RoadDataset(train, tuple(size), hflip=cfg.hflip, greyscale=cfg.greyscale, vp_channel=cfg.vp_channel,
                            scale_aug=cfg.scale_aug, shift_aug=cfg.shift_aug, color_aug=cfg.color_aug,
                            crop=tuple(crop), shading_aug=cfg.shading_aug, ray_channels=cfg.ray_channels,
                            outputs=outputs),
                RoadDataset(val, tuple(size), greyscale=1.0 if cfg.greyscale >= 1 else 0.0, vp_channel=cfg.vp_channel,
                            ray_channels=cfg.ray_channels, outputs=outputs))

    outputs = parse_outputs(cfg.outputs)

    if info.get("keep_aspect"):  # every frame at the budget's pixels at its own aspect, a part per size
        budget = info["input_size"]
        return (AspectParts(train_s, budget, lambda g, size: pair(g, [], size, crop_size(cfg.crop, size))[0]),
                AspectParts(val_s, budget, lambda g, size: pair([], g, size, size)[1]))
    if info["mode"] != "mixed":
        return pair(train_s, val_s, info["input_size"], info["crop_size"])
    nt, nv = len(train_s) // 2, len(val_s) // 2  # (the virtual view's samples, then the resize view's)
    tv, vv = pair(train_s[:nt], val_s[:nv], info["input_size"], info["crop_size"])
    tr, vr = pair(train_s[nt:], val_s[nv:], info["resize_size"], info["resize_crop_size"])
    return MixedViews(tv, tr), MixedViews(vv, vr)


def label_shares(train_ds: Any, samples: int = 48) -> list[tuple[str, str, bool, Any]]:
    """Where road lies in the labels of every source of ``train_ds`` (a label folder, a store):
    ``(source, label format, whether a store's labels, RoadShare)`` of up to ``samples`` items spread
    over it, each at the working size, un-augmented. A store's labels (decoded when it was warped)
    count under the format they were warped with, their horizon the row of each item's road vanishing
    point (in the virtual camera it lies near the top of the image, not in the middle); frames
    without a known VP take their middle row (:class:`vcprep.labels.RoadShare`)."""
    from vcprep.labels import RoadShare

    out = []
    for (source, spec, warped), members in _label_sources(train_ds.samples).items():
        share = RoadShare()
        for k in sorted({int(round(k)) for k in np.linspace(0, len(members) - 1, min(samples, len(members)))}):
            _, label, vp = train_ds.item(members[k])
            share.add(label, vp[1] if vp is not None else None)
        out.append((source, spec, warped, share))
    return out


def check_labels(cfg: TrainConfig, train_ds: Any, samples: int = 48) -> None:
    """Refuse labels read with a format that does not fit them before training (:func:`label_shares`:
    no road, nearly all road, or most of it above the horizon), naming the source and the format;
    ``cfg.force_labels`` trains on them anyway."""
    if cfg.force_labels:
        return
    for source, spec, warped, share in label_shares(train_ds, samples):
        if warped:
            share.refuse(get_label_format(spec), source, "add --force-labels",
                         f", then warp the store again with it (vcprep warp ... --out {source})")
            continue
        folder = cfg.labels if cfg.labels and source == cfg.images else \
            next(s.label.parent for s in train_ds.samples if s.source == source and s.label is not None)
        share.refuse(get_label_format(spec), folder, "add --force-labels")


def _label_sources(samples: Sequence[Any]) -> dict[tuple[str, str, bool], list[int]]:
    """The items of each label source: (source, label format, whether a store's decoded labels) ->
    indices in ``samples``; items with no known format (a store of an older version) are left out."""
    groups: dict[tuple[str, str, bool], list[int]] = {}
    for i, s in enumerate(samples):
        spec = s.label_format or s.warped_from
        if spec is not None and s.label is not None:
            groups.setdefault((s.source, spec, s.label_format is None), []).append(i)
    return groups
