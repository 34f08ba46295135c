"""Training: one readable loop (nanoGPT style), with two recipes.

``recipe`` chooses the defaults of every setting left unset (``None``); an explicit value wins:

=========  ==============================================================================
paper      VCSeg's own (Table 2): segnet, SGD momentum 0.9, lr 0.005, weight decay 0.0005,
           batch 8, "poly" decay lr·(1 − it/total)^0.9, no augmentation. The default on a GPU.
cpu        CamVid train (367 images) on a 2-core CPU: 3.3 minutes at 344x176, 14.2 at 688x350:
           resfpn (residual encoder + FPN decoder, see model.py), AdamW lr 0.002, weight decay
           0.01, batch 8, cosine decay after a linear warm-up over the first 3 % of the steps,
           augmentation: horizontal flip, random scale 1/1.25..1.25 about the VP (the image
           centre when the VP is unknown) with a shift of up to 5 % of the size, and photometric
           jitter (brightness, contrast, per-channel gain, gamma; 0.3); 20 epochs. The default
           without a GPU.
=========  ==============================================================================

Loss: cross-entropy over {not road, road}, label 255 ignored, optionally weighted by
median-frequency balancing.

Validation: a seeded ``val_fraction`` of the training items, or separate ``val_stores``; the
metric is the road IoU in the training domain (virtual camera for store training, the resized
image for the baseline) — the honest number, in the original camera, comes from
``vctrain predict`` + ``vctrain eval``. The checkpoint at ``out`` is the epoch with the best
validation road IoU (the last epoch without validation); ``<out stem>.last.pt`` is the latest
epoch, for ``resume``. Every epoch appends one JSON line to the log.

Determinism: the item order and augmentations of epoch e depend only on (seed, e, rank), so a
resumed run continues exactly where the interrupted one would have gone (on the CPU).

Multi-process: launched with ``torchrun --nproc-per-node N vctrain fit ...`` the loop runs
DistributedDataParallel (gloo on CPU, NCCL on GPUs); ``batch_size`` is the global batch, split
across processes; rank 0 alone writes checkpoints and logs.
"""
from __future__ import annotations

import json
import math
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Optional

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F
from tqdm import tqdm

from vcprep.build import list_dataset
from vcprep.errors import InputError
from vcprep.labels import get_label_format
from vcprep.store import Store

from .checkpoint import load_checkpoint, model_from_checkpoint, save_checkpoint
from .data import RoadDataset, Sample, class_frequencies, median_frequency_weights, resize_samples, store_samples
from .metrics import RoadMetrics
from .model import ARCHITECTURES, build_model, model_args_for

__all__ = ["TrainConfig", "RECIPES", "fit", "evaluate", "get_lr", "resolve_device", "resolve_recipe", "last_path",
           "crop_size"]

MIN_SIDE = 32  # five 2x2 poolings

# recipe -> the defaults it gives every TrainConfig field left at None (module docstring)
RECIPES: dict[str, dict[str, Any]] = {
    "paper": {"arch": "segnet", "epochs": 30, "batch_size": 8, "optimizer": "sgd", "lr": 0.005, "momentum": 0.9,
              "weight_decay": 0.0005, "schedule": "poly", "hflip": False, "scale_aug": 0.0, "shift_aug": 0.0,
              "color_aug": 0.0},
    "cpu": {"arch": "resfpn", "epochs": 20, "batch_size": 8, "optimizer": "adamw", "lr": 0.002, "momentum": 0.9,
            "weight_decay": 0.01, "schedule": "cosine", "hflip": True, "scale_aug": 0.25, "shift_aug": 0.05,
            "color_aug": 0.3},
}
SCHEDULES = ("poly", "cosine", "constant")
OPTIMIZERS = ("sgd", "adamw")
WARMUP = 0.03  # share of the steps with a linear warm-up (cosine schedule)


@dataclass
class TrainConfig:
    """All settings of a training run (saved in the checkpoint)."""

    stores: list[str] = field(default_factory=list)  # training stores (one virtual camera and scale)
    out: str = "model.pt"              # best checkpoint; '<stem>.last.pt' beside it is the latest epoch
    baseline: str = "none"             # 'none': train on the stores; 'resize': original images resized
    images: Optional[str] = None       # baseline from folders instead of stores: image folder
    labels: Optional[str] = None       #   ... label folder
    label_format: Optional[str] = None  #  ... label format (camvid, kitti, values:road=..)
    recipe: Optional[str] = None       # 'cpu' | 'paper' (module docstring); None: paper on a GPU, cpu without
    arch: Optional[str] = None         # 'resfpn' | 'segnet' | 'segnet-narrow'; None: the recipe's
    base_width: Optional[int] = None   # override the architecture's first-block width
    size: Optional[tuple[int, int]] = None  # working size (w, h); None: the store size (first image for folders)
    crop: Optional[Any] = None         # training window: (w, h) pixels (ints), a share of each side (float) or
                                       # of width and height (two floats); None: the whole image (validation
                                       # and prediction always see it whole)
    epochs: Optional[int] = None       # None: the recipe's (the paper trains 600 on a GPU)
    batch_size: Optional[int] = None   # global batch (paper Table 2: 8)
    optimizer: Optional[str] = None    # 'sgd' (momentum) | 'adamw'
    lr: Optional[float] = None         # peak learning rate
    momentum: Optional[float] = None   # SGD momentum (AdamW: beta1)
    weight_decay: Optional[float] = None  # L2 (SGD) or decoupled (AdamW) weight decay
    schedule: Optional[str] = None     # 'poly' (power 0.9), 'cosine' (with warm-up) or 'constant'
    scale_aug: Optional[float] = None  # random scale in [1/(1+a), 1+a] about the VP (0: off)
    shift_aug: Optional[float] = None  # random shift up to this share of the width/height
    color_aug: Optional[float] = None  # photometric jitter strength (0: off)
    seed: int = 0                      # seeds init, split, order and augmentation
    device: str = "auto"               # 'auto' (cuda if present), 'cpu', 'cuda', 'cuda:1'
    val_fraction: float = 0.1          # held-out share of the training items (0: none)
    val_stores: list[str] = field(default_factory=list)  # validation stores (replace val_fraction)
    class_weights: str = "none"        # 'none' or 'median-freq' (median frequency balancing)
    hflip: Optional[bool] = None       # random horizontal flip, p = 0.5
    greyscale: float = 0.0             # probability of a greyscale image (1.0: greyscale model)
    vp_channel: bool = False           # 4th input channel: VP proximity map
    resume: Optional[str] = None       # continue from this checkpoint ('.last.pt') up to `epochs`
    init: Optional[str] = None         # start from this checkpoint's network and weights (fine-tuning, vctrain adapt)
    workers: int = 0                   # DataLoader worker processes
    log: Optional[str] = None          # JSON-lines log; None: '<out stem>.log.jsonl'
    progress: bool = True              # tqdm bar on stderr
    max_steps: Optional[int] = None    # stop each epoch after this many steps (smoke tests)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["size"] = list(self.size) if self.size else None
        return d


def last_path(out: str | Path) -> Path:
    out = Path(out)
    return out.with_name(out.stem + ".last.pt")


def resolve_recipe(cfg: TrainConfig, device: torch.device | None = None) -> TrainConfig:
    """``cfg`` with every unset (None) recipe field filled from its recipe (in place; returned)."""
    if cfg.recipe is None:
        dev = device if device is not None else resolve_device(cfg.device)
        cfg.recipe = "paper" if dev.type == "cuda" else "cpu"
    if cfg.recipe not in RECIPES:
        raise InputError(f"unknown recipe '{cfg.recipe}'", None, f"use one of {', '.join(RECIPES)}")
    for k, v in RECIPES[cfg.recipe].items():
        if getattr(cfg, k) is None:
            setattr(cfg, k, v)
    if cfg.schedule not in SCHEDULES:
        raise InputError(f"unknown schedule '{cfg.schedule}'", None, f"use one of {', '.join(SCHEDULES)}")
    if cfg.optimizer not in OPTIMIZERS:
        raise InputError(f"unknown optimizer '{cfg.optimizer}'", None, f"use one of {', '.join(OPTIMIZERS)}")
    for k in ("epochs", "batch_size"):
        if int(getattr(cfg, k)) < 1:
            raise InputError(f"{k.replace('_', ' ')} must be at least 1, got {getattr(cfg, k)}", None, "use e.g. 8")
    for k in ("lr", "scale_aug", "shift_aug", "color_aug", "weight_decay"):
        v = float(getattr(cfg, k))
        if not math.isfinite(v) or v < 0 or (k == "lr" and v == 0):
            raise InputError(f"{k.replace('_', '-')} must be a finite number >= 0 (lr > 0), got {v}", None,
                             "see vctrain fit --help")
    return cfg


def get_lr(it: int, total: int, cfg: TrainConfig) -> float:
    """Learning rate at iteration ``it`` of ``total``."""
    if cfg.schedule == "constant":
        return cfg.lr
    t = min(it, total) / max(total, 1)
    if cfg.schedule == "cosine":
        if t < WARMUP:
            return cfg.lr * (it + 1) / max(WARMUP * total, 1)
        return cfg.lr * 0.5 * (1.0 + math.cos(math.pi * (t - WARMUP) / (1.0 - WARMUP)))
    return cfg.lr * (1.0 - t) ** 0.9


def resolve_device(spec: str, local_rank: int = 0) -> torch.device:
    if spec == "auto":
        spec = "cuda" if torch.cuda.is_available() else "cpu"
    if spec.startswith("cuda"):
        if not torch.cuda.is_available():
            raise InputError(f"device '{spec}' asked but no CUDA GPU is available", None, "use --device cpu")
        if spec == "cuda":
            spec = f"cuda:{local_rank}"
    elif spec != "cpu":
        raise InputError(f"unknown device '{spec}'", None, "use auto, cpu, cuda or cuda:N")
    return torch.device(spec)


# -- data ----------------------------------------------------------------------------------------
def _open_stores(paths: list[str]) -> list[Store]:
    stores = [Store.open(p) for p in paths]
    for s in stores[1:]:
        for k in ("virtual", "scale", "store_size"):
            if s.params.get(k) != stores[0].params.get(k):
                raise InputError(f"store has another {k} than {stores[0].root}", s.root,
                                 "train on stores of one virtual camera at one scale")
    return stores


def _samples(stores: list[Store], baseline: str) -> list[Sample]:
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


def prepare_data(cfg: TrainConfig) -> tuple[list[Sample], list[Sample], dict[str, Any]]:
    """Training and validation samples plus the checkpoint's ``data`` description."""
    if cfg.baseline not in ("none", "resize"):
        raise InputError(f"unknown baseline '{cfg.baseline}'", None, "use --baseline resize (or leave it out)")
    stores = _open_stores(cfg.stores) if cfg.stores else []
    info: dict[str, Any] = {"mode": "resize" if cfg.baseline == "resize" else "virtual",
                            "store_params": stores[0].params if stores else None,
                            "completion": _completion(stores) if stores else "none",
                            "vp_channel": cfg.vp_channel, "greyscale": cfg.greyscale}
    if cfg.images is not None:
        if cfg.baseline != "resize":
            raise InputError("--images is for the resize baseline", cfg.images,
                             "add --baseline resize, or train on a store built with 'vcprep warp'")
        if cfg.labels is None or cfg.label_format is None:
            raise InputError("--images needs --labels and --label-format", cfg.images, "add them")
        fmt = get_label_format(cfg.label_format)
        train = [Sample(j.id, j.image, j.label, fmt.name) for j in list_dataset(cfg.images, cfg.labels, fmt)]
        if stores:
            train += _samples(stores, cfg.baseline)
    elif stores:
        train = _samples(stores, cfg.baseline)
    else:
        raise InputError("no training data", None, "give STORE... (or --baseline resize --images/--labels)")
    if cfg.val_stores:
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
        perm = np.random.default_rng(cfg.seed).permutation(len(train))
        n_val = max(1, int(round(cfg.val_fraction * len(train))))
        if n_val >= len(train):
            raise InputError(f"{len(train)} items are too few to hold out {cfg.val_fraction:g}", None,
                             "add items, or use --val-fraction 0 / --val-store")
        val = [train[i] for i in sorted(perm[:n_val])]
        train = [train[i] for i in sorted(perm[n_val:])]
    else:
        val = []
    if cfg.size is not None:
        size = (int(cfg.size[0]), int(cfg.size[1]))
    elif stores:
        size = stores[0].store_size
    else:
        from vcprep.imageio import read_image

        size = read_image(train[0].image).size
    if min(size) < MIN_SIDE:
        raise InputError(f"working size {size[0]}x{size[1]} is below {MIN_SIDE} pixels", None,
                         "use a larger --size or store scale")
    info["input_size"] = list(size)
    info["crop_size"] = list(crop_size(cfg.crop, size))
    info["vp_status"] = sorted({rec.get("vp_status", "camera") for s in stores for rec in s})
    info["train_items"] = len(train)
    info["val_items"] = len(val)
    return train, val, info


def crop_size(crop: Any, size: tuple[int, int]) -> tuple[int, int]:
    """The training window (w, h) of ``crop`` at working size ``size``: None -> ``size``; a number
    in (0, 1] -> that share of each side; a pair of floats in (0, 1] -> the shares of the width
    and the height (e.g. (0.44, 1.0): full-height windows); a pair of ints -> pixels. Shares are
    rounded. The window must fit ``size`` and be at least MIN_SIDE on each side."""
    if crop is None:
        return tuple(size)

    def share(v: Any, side: int) -> int:
        if not 0 < float(v) <= 1:
            raise InputError(f"crop share {v} is not in (0, 1]", None, "use e.g. --crop 0.67, 0.44x1 or 320x240")
        return int(round(side * float(v)))

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


# -- evaluation ----------------------------------------------------------------------------------
@torch.no_grad()
def evaluate(model: nn.Module, loader, device: torch.device, weight: torch.Tensor | None = None) -> dict[str, float]:
    """Loss and road metrics (argmax) of ``model`` over ``loader``."""
    model.eval()
    m = RoadMetrics()
    loss_sum, n = 0.0, 0
    for x, y in loader:
        x, y = x.to(device), y.to(device)
        logits = model(x)
        if (y != 255).any():
            loss_sum += float(F.cross_entropy(logits, y, weight=weight, ignore_index=255)) * len(x)
            n += len(x)
        pred = logits.argmax(1).cpu().numpy()
        for p, g in zip(pred, y.cpu().numpy().astype(np.uint8)):
            m.add(p, g)
    model.train()
    return {"loss": loss_sum / max(n, 1), **m.result()}


# -- the loop ------------------------------------------------------------------------------------
def _dist() -> tuple[int, int, int]:
    """(rank, world size, local rank) from torchrun's environment."""
    return int(os.environ.get("RANK", 0)), int(os.environ.get("WORLD_SIZE", 1)), int(os.environ.get("LOCAL_RANK", 0))


def _average_buffers(model: nn.Module, world: int) -> None:
    """Average BatchNorm running statistics over processes (DDP syncs gradients, not these;
    SyncBatchNorm needs GPUs), so every replica evaluates and saves the same model."""
    for b in model.buffers():
        if b.is_floating_point():
            torch.distributed.all_reduce(b, op=torch.distributed.ReduceOp.SUM)
            b.div_(world)


def _write_log(path: Path, row: dict[str, Any]) -> None:
    with open(path, "a") as f:
        f.write(json.dumps(row) + "\n")


def fit(cfg: TrainConfig) -> dict[str, Any]:
    """Train according to ``cfg``; returns a summary (best val IoU, timings, paths)."""
    rank, world, local_rank = _dist()
    distributed = world > 1
    device = resolve_device(cfg.device, local_rank)
    if distributed and not torch.distributed.is_initialized():
        torch.distributed.init_process_group("nccl" if device.type == "cuda" else "gloo")
    master = rank == 0
    out = Path(cfg.out)
    if master and not out.parent.is_dir():
        raise InputError("output folder does not exist", out.parent, "create it first")
    log_path = Path(cfg.log) if cfg.log else out.with_name(out.stem + ".log.jsonl")

    resume = load_checkpoint(cfg.resume) if cfg.resume else None
    init = load_checkpoint(cfg.init) if cfg.init and resume is None else None
    resolve_recipe(cfg, device)
    train_s, val_s, info = prepare_data(cfg)
    if resume is not None:
        model_args = resume["model_args"]
        if cfg.arch and cfg.arch != model_args["arch"]:
            raise InputError(f"checkpoint is '{model_args['arch']}' but --model {cfg.arch} was asked", cfg.resume,
                             "leave --model out when resuming")
        if resume["data"]["mode"] != info["mode"] or resume["data"]["input_size"] != info["input_size"]:
            raise InputError("checkpoint was trained on other data (mode or working size)", cfg.resume,
                             "resume with the same stores, --baseline and --size")
    else:
        arch = cfg.arch
        if arch not in ARCHITECTURES:
            raise InputError(f"unknown model '{arch}'", None, f"use one of {', '.join(ARCHITECTURES)}")
        model_args = model_args_for(arch, 4 if cfg.vp_channel else 3, cfg.base_width).to_dict()

    torch.manual_seed(cfg.seed)
    if init is not None:  # fine-tuning: the checkpoint's network (weights loaded below), a fresh optimiser
        model_args = init["model_args"]
        if model_args["in_channels"] != (4 if cfg.vp_channel else 3):
            raise InputError(f"checkpoint takes {model_args['in_channels']} input channels, the data "
                             f"{4 if cfg.vp_channel else 3}", cfg.init,
                             "fine-tune with the model's own --vp-channel setting")
    model = build_model(model_args)
    if resume is not None:
        model = model_from_checkpoint(resume, cfg.resume)
    elif init is not None:
        model = model_from_checkpoint(init, cfg.init)
    # channels-last runs resfpn's convolutions ~20 % faster on the CPU; SegNet's unpooling wants NCHW
    fmt = torch.channels_last if model_args["arch"] == "resfpn" else torch.contiguous_format
    model.to(device, memory_format=fmt)
    net = model
    if distributed:
        net = nn.parallel.DistributedDataParallel(model, device_ids=[device.index] if device.type == "cuda" else None)

    size = tuple(info["input_size"])
    train_ds = RoadDataset(train_s, size, hflip=cfg.hflip, greyscale=cfg.greyscale, vp_channel=cfg.vp_channel,
                           scale_aug=cfg.scale_aug, shift_aug=cfg.shift_aug, color_aug=cfg.color_aug,
                           crop=tuple(info["crop_size"]))
    val_ds = RoadDataset(val_s, size, greyscale=1.0 if cfg.greyscale >= 1 else 0.0, vp_channel=cfg.vp_channel)
    weight = None
    if cfg.class_weights == "median-freq":
        w = median_frequency_weights(class_frequencies(train_ds))
        info["class_weights"] = [float(v) for v in w]
        weight = torch.tensor(w, dtype=torch.float32, device=device)
    elif cfg.class_weights != "none":
        raise InputError(f"unknown class weighting '{cfg.class_weights}'", None, "use none or median-freq")

    per_rank_batch = max(1, math.ceil(cfg.batch_size / world))
    steps_per_epoch = math.ceil(len(train_ds) / (per_rank_batch * world))
    if cfg.max_steps:
        steps_per_epoch = min(steps_per_epoch, cfg.max_steps)
    total_steps = steps_per_epoch * cfg.epochs
    if cfg.optimizer == "adamw":
        opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, betas=(cfg.momentum, 0.999),
                                weight_decay=cfg.weight_decay)
    else:
        opt = torch.optim.SGD(model.parameters(), lr=cfg.lr, momentum=cfg.momentum, weight_decay=cfg.weight_decay)
    val_loader = torch.utils.data.DataLoader(val_ds, batch_size=per_rank_batch, shuffle=False,
                                             num_workers=cfg.workers)

    start_epoch, step, best_iou, best_epoch, history = 0, 0, -1.0, -1, []
    if resume is not None:
        opt.load_state_dict(resume["optimizer"])
        start_epoch, step = int(resume["epoch"]), int(resume["step"])
        best_iou, best_epoch = float(resume.get("best_iou", -1.0)), int(resume.get("best_epoch", -1))
        history = list(resume.get("history", []))

    def checkpoint(epoch: int, metrics: dict[str, Any]) -> dict[str, Any]:
        return {"model": model.state_dict(), "model_args": model_args, "config": cfg.to_dict(), "data": info,
                "epoch": epoch, "step": step, "metrics": metrics, "best_iou": best_iou, "best_epoch": best_epoch,
                "history": history, "optimizer": opt.state_dict()}

    seconds, images = 0.0, 0
    for epoch in range(start_epoch, cfg.epochs):
        # item order and augmentation depend on (seed, epoch, rank) only -> exact resume
        gen = torch.Generator().manual_seed(cfg.seed * 1000003 + epoch)
        order = torch.randperm(len(train_ds), generator=gen).tolist()
        if world > 1:  # equal shares (DistributedSampler's padding) so no rank waits for another
            order += order[: (-len(order)) % world]
            order = order[rank::world]
        torch.manual_seed(cfg.seed * 1000003 + epoch * 101 + rank + 1)
        loader = torch.utils.data.DataLoader(torch.utils.data.Subset(train_ds, order), batch_size=per_rank_batch,
                                             shuffle=False, num_workers=cfg.workers, drop_last=False)
        net.train()
        t0 = time.perf_counter()
        loss_sum, n_seen = 0.0, 0
        bar = tqdm(loader, total=steps_per_epoch, desc=f"epoch {epoch + 1}/{cfg.epochs}", unit="batch",
                   disable=None if (cfg.progress and master) else True, leave=False, dynamic_ncols=True)
        for i, (x, y) in enumerate(bar):
            if i >= steps_per_epoch:
                break
            lr = get_lr(step, total_steps, cfg)
            for g in opt.param_groups:
                g["lr"] = lr
            x, y = x.to(device, non_blocking=True).contiguous(memory_format=fmt), y.to(device, non_blocking=True)
            logits = net(x)
            loss = F.cross_entropy(logits, y, weight=weight, ignore_index=255)
            if not torch.isfinite(loss):
                if (y != 255).any():
                    raise InputError(f"training diverged (loss {float(loss)}) at epoch {epoch + 1}", None,
                                     "lower --lr")
                loss = logits.sum() * 0.0  # batch without a single labelled pixel
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            step += 1
            loss_sum += loss.item() * len(x)
            n_seen += len(x)
            dt = time.perf_counter() - t0
            bar.set_postfix(loss=f"{loss_sum / n_seen:.4f}", img_s=f"{n_seen * world / max(dt, 1e-9):.1f}")
        bar.close()
        if distributed:
            _average_buffers(model, world)
        dt = time.perf_counter() - t0
        seconds += dt
        images += n_seen * world
        row: dict[str, Any] = {"epoch": epoch + 1, "step": step, "lr": get_lr(step, total_steps, cfg),
                               "train_loss": loss_sum / max(n_seen, 1), "seconds": dt,
                               "images_per_s": n_seen * world / max(dt, 1e-9)}
        if len(val_ds):
            vm = evaluate(model, val_loader, device, weight)
            row.update({f"val_{k}": v for k, v in vm.items()})
            improved = vm["iou"] > best_iou
        else:
            improved = True
        if improved:
            best_iou, best_epoch = row.get("val_iou", -1.0), epoch + 1
        history.append(row)
        if master:
            _write_log(log_path, row)
            ck = checkpoint(epoch + 1, row)
            save_checkpoint(last_path(out), ck)
            if improved:
                save_checkpoint(out, ck)
            if cfg.progress:
                from vcprep.cliutil import err

                val = f", val IoU {row['val_iou']:.4f}" if "val_iou" in row else ""
                err(f"epoch {epoch + 1}/{cfg.epochs}: loss {row['train_loss']:.4f}{val}, {dt:.1f} s "
                    f"({row['images_per_s']:.1f} img/s){' *' if improved and val else ''}")
    replicas_identical = None
    if distributed:  # every process must end with the same weights (DDP keeps them in lockstep)
        flat = torch.cat([t.detach().float().reshape(-1) for t in model.state_dict().values()])
        copies = [torch.empty_like(flat) for _ in range(world)]
        torch.distributed.all_gather(copies, flat)
        replicas_identical = all(torch.equal(copies[0], c) for c in copies[1:])
        torch.distributed.barrier()
        # tear the process group down here, not at interpreter exit, where gloo's threads can
        # abort the process ("terminate called without an active exception")
        torch.distributed.destroy_process_group()
    return {"replicas_identical": replicas_identical, "world_size": world,
            "out": str(out), "last": str(last_path(out)), "log": str(log_path), "epochs": cfg.epochs,
            "best_val_iou": best_iou if best_iou >= 0 else None, "best_epoch": best_epoch,
            "seconds_per_epoch": seconds / max(cfg.epochs - start_epoch, 1),
            "train_images_per_s": images / max(seconds, 1e-9), "model_args": model_args,
            "data": {k: v for k, v in info.items() if k != "store_params"}}
