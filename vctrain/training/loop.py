"""Training: one readable loop (nanoGPT style), with two recipes.

``recipe`` chooses the defaults of every setting (:class:`vctrain.training.config.TrainConfig`) left unset
(``None``); an explicit value wins:

=========  ==============================================================================
paper      VCSeg's own (Table 2): segnet, SGD momentum 0.9, lr 0.005, weight decay 0.0005,
           batch 8, "poly" decay lr·(1 − it/total)^0.9, no augmentation, whole images. On request.
cpu        305 CamVid frames on a 2-core CPU in about 3 minutes at the default store's 638x271:
           resfpn (residual encoder + FPN decoder, see vctrain.networks.resnet), AdamW lr 0.002, weight decay
           0.01, batch 8, cosine decay after a linear warm-up over the first 3 % of the steps,
           augmentation: horizontal flip, random scale 1/1.25..1.25 about the VP (the image
           centre when the VP is unknown) with a shift of up to 5 % of the size, and photometric
           jitter (brightness, contrast, per-channel gain, gamma; 0.3); full-height windows of 4/9
           of the width (config.TRAIN_WINDOW, a crossval study's); 20 epochs. The default on
           every device.
=========  ==============================================================================

Loss: cross-entropy over {not road, road}, label 255 ignored, optionally weighted by
median-frequency balancing. With ``outputs: road,drivable`` the network has three classes and each dataset
supervises the output of its label format's definition through a set-valued cross entropy
(:mod:`vctrain.training.outputs`); validation scores each item on its own definition's output.

Validation: a seeded ``val_fraction`` of the training items, or separate ``val_stores``; the
metric is the road IoU in the training domain (virtual camera for store training, the resized
image for the baseline) — the honest number, in the original camera, comes from
``vctrain predict`` + ``vctrain eval``. The checkpoint at ``out`` is the epoch with the best
validation road IoU (the last epoch without validation); ``<out stem>.last.pt`` is the latest
epoch, for ``resume``. Every epoch appends one JSON line to the log.

Determinism: the item order and augmentations of epoch e depend only on (seed, e, rank), so a
resumed run continues exactly where the interrupted one would have gone (on the CPU).

Several stores (one virtual camera and scale, e.g. one per source camera): ``balance`` says how an
epoch draws from them (:func:`vctrain.training.trainset.epoch_order`): ``items`` every item once, ``datasets``
every store an equal share of the epoch. Fine-tuning: ``init`` starts from a checkpoint's network
and weights with a fresh optimiser; another architecture, width, input channels or mode (virtual
camera vs resize) is refused, and the new checkpoint records the one it started from (``init``).

Multi-process: launched with ``torchrun --nproc-per-node N vctrain fit ...`` the loop runs
DistributedDataParallel (gloo on CPU, NCCL on GPUs); ``batch_size`` is the global batch, split
across processes; rank 0 alone writes checkpoints and logs.
"""
from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
from torch import nn
from tqdm import tqdm

from vcprep.errors import InputError

from .checkpoint import last_path, load_checkpoint, model_from_checkpoint, save_checkpoint
from .checkpoint_data import CheckpointData
from .config import (BALANCES, FINETUNE_VAL_FRACTION, VAL_FRACTION, DEFAULT_RECIPE, OPTIMIZERS, RECIPES, SCHEDULES,
                     TrainConfig)
from .data import RoadDataset, class_frequencies, median_frequency_weights
from .outputs import ONE_OUTPUT, loss_of, num_classes, parse_outputs, scored
from .finetune import (anchor_weights, as_saved, averaged, check_init, freeze_encoder, init_record, l2sp_penalty,
                       train_mode, trainable, unset_from_checkpoints)
from . import guard
from .distributed import average_buffers, import_before_group, leave_group, ranks
from .rerun import log_path, request_of
from .parts import MixedViews, Parts, view_batches
from .trainset import check_labels, crop_size, epoch_order, prepare_data, training_sets
from ..metrics import RoadMetrics
from ..networks.args import ARCHITECTURES, model_args_for
from ..networks.build import build_model, resolve_pretrained

__all__ = ["fit", "evaluate", "get_lr", "resolve_device", "resolve_recipe"]

WARMUP = 0.03  # share of the steps with a linear warm-up (cosine schedule)


def resolve_recipe(cfg: TrainConfig, device: torch.device | None = None) -> TrainConfig:
    """``cfg`` with every unset (None) recipe field filled from its recipe (in place; returned); no
    recipe: :data:`DEFAULT_RECIPE` whatever the device (``device`` is no longer consulted)."""
    if cfg.recipe is None:  # every device: the recipe behind every measured number (DEFAULT_RECIPE)
        cfg.recipe = DEFAULT_RECIPE
    if cfg.val_fraction is None:
        cfg.val_fraction = FINETUNE_VAL_FRACTION if cfg.init else VAL_FRACTION
    if cfg.recipe not in RECIPES:
        raise InputError(f"unknown recipe '{cfg.recipe}'", None, f"use one of {', '.join(RECIPES)}")
    for k, v in RECIPES[cfg.recipe].items():
        if getattr(cfg, k) is None:
            setattr(cfg, k, v)
    if cfg.schedule not in SCHEDULES:
        raise InputError(f"unknown schedule '{cfg.schedule}'", None, f"use one of {', '.join(SCHEDULES)}")
    if cfg.optimizer not in OPTIMIZERS:
        raise InputError(f"unknown optimizer '{cfg.optimizer}'", None, f"use one of {', '.join(OPTIMIZERS)}")
    if cfg.balance not in BALANCES:
        raise InputError(f"unknown balance '{cfg.balance}'", None, f"use one of {', '.join(BALANCES)}")
    cfg.pretrained = resolve_pretrained(cfg.arch, cfg.pretrained)
    parse_outputs(cfg.outputs)  # (an unknown value: its error before any data is read)
    for k in ("epochs", "batch_size"):
        if int(getattr(cfg, k)) < 1:
            raise InputError(f"{k.replace('_', ' ')} must be at least 1, got {getattr(cfg, k)}", None, "use e.g. 8")
    for k in ("lr", "scale_aug", "shift_aug", "color_aug", "weight_decay", "shading_aug"):
        v = float(getattr(cfg, k))
        if not math.isfinite(v) or v < 0 or (k == "lr" and v == 0) :
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
            return cfg.lr * min(1.0, (it + 1) / max(WARMUP * total, 1))  # never above the peak
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


# -- evaluation ----------------------------------------------------------------------------------
@torch.no_grad()
def evaluate(model: nn.Module, loader, device: torch.device, weight: torch.Tensor | None = None) -> dict[str, float]:
    """Loss and road metrics (argmax; a two-output model each item on its own definition's output) of
    ``model`` over ``loader``."""
    model.eval()
    m = RoadMetrics()
    loss_sum, n = 0.0, 0
    for x, y in loader:
        x, y = x.to(device), y.to(device)
        logits = model(x)
        if (y != 255).any():
            loss_sum += float(loss_of(logits, y, weight)) * len(x)
            n += len(x)
        pred, labels = scored(logits, y)
        for p, g in zip(pred, labels):
            m.add(p, g)
    model.train()
    return {"loss": loss_sum / max(n, 1), **m.result()}


# -- the loop ------------------------------------------------------------------------------------
def _write_log(path: Path, row: dict[str, Any]) -> None:
    with open(path, "a") as f:
        f.write(json.dumps(row) + "\n")


def _network(cfg: TrainConfig, resume: dict[str, Any] | None, init: dict[str, Any] | None,
             info: dict[str, Any]) -> tuple[nn.Module, dict]:
    """``(model, model_args)``: the network to train -- the checkpoint's when resuming (checked
    against the data), the ``init`` checkpoint's when fine-tuning, else a fresh ``cfg.arch`` seeded
    by ``cfg.seed``."""
    if resume is not None:
        model_args = resume["model_args"]
        if cfg.arch and cfg.arch != model_args["arch"]:
            raise InputError(f"checkpoint is '{model_args['arch']}' but --model {cfg.arch} was asked", cfg.resume,
                             "leave --model out when resuming")
        trained = CheckpointData.from_dict(resume["data"])
        if trained.mode != info["mode"] or list(trained.input_size or ()) != list(info["input_size"]):
            raise InputError("checkpoint was trained on other data (mode or working size)", cfg.resume,
                             "resume with the same stores, --baseline and --size")
        _same_outputs(cfg, resume, cfg.resume, "resume")
    else:
        arch = cfg.arch
        if arch not in ARCHITECTURES:
            raise InputError(f"unknown model '{arch}'", None, f"use one of {', '.join(ARCHITECTURES)}")
        model_args = model_args_for(arch, cfg.in_channels, cfg.base_width,
                                    num_classes(parse_outputs(cfg.outputs))).to_dict()

    torch.manual_seed(cfg.seed)
    if init is not None:  # fine-tuning: the checkpoint's network (weights loaded below), a fresh optimiser
        check_init(cfg, init, info)
        _same_outputs(cfg, init, cfg.init, "fine-tune")
        model_args = init["model_args"]
    model = build_model(model_args)
    if resume is None and init is None and cfg.pretrained:
        model.load_pretrained()  # the encoder's ImageNet weights (vctrain.networks.efficientnet)
    if resume is not None:
        model = model_from_checkpoint(resume, cfg.resume)
    elif init is not None:
        model = model_from_checkpoint(init, cfg.init)
    return model, model_args


def _same_outputs(cfg: TrainConfig, ck: dict[str, Any], path: str | None, what: str) -> None:
    """Refuse a checkpoint (``--resume``, ``--init``) whose outputs differ from the run's ``--outputs``."""
    theirs = CheckpointData.from_dict(ck.get("data")).outputs
    if theirs != parse_outputs(cfg.outputs):
        raise InputError(f"checkpoint has the outputs {','.join(theirs)} but --outputs {cfg.outputs} was asked", path,
                         f"{what} with --outputs {','.join(theirs)}")


def _validate(row: dict[str, Any], model: nn.Module, loader, device: torch.device, weight: torch.Tensor | None,
              best_iou: float) -> bool:
    """Add the validation metrics and their wall clock (``val_seconds``) to the epoch's ``row``; whether
    its road IoU beats ``best_iou``."""
    t0 = time.perf_counter()
    vm = evaluate(model, loader, device, weight)
    row.update({f"val_{k}": v for k, v in vm.items()}, val_seconds=time.perf_counter() - t0)
    return vm["iou"] > best_iou


def _class_weight(cfg: TrainConfig, train_ds: RoadDataset, info: dict[str, Any],
                  device: torch.device) -> torch.Tensor | None:
    """The loss's class weights (``median-freq``: recorded in ``info``), or None."""
    if cfg.class_weights == "median-freq":
        if parse_outputs(cfg.outputs) != ONE_OUTPUT:
            raise InputError("class weights median-freq are for one output (road); a set-valued loss over road and "
                             "drivable has no class frequencies", None, "drop --class-weights, or train --outputs road")
        w = median_frequency_weights(class_frequencies(train_ds))
        info["class_weights"] = [float(v) for v in w]
        return torch.tensor(w, dtype=torch.float32, device=device)
    if cfg.class_weights != "none":
        raise InputError(f"unknown class weighting '{cfg.class_weights}'", None, "use none or median-freq")
    return None


def _optimizer(cfg: TrainConfig, model: nn.Module) -> torch.optim.Optimizer:
    if cfg.optimizer == "adamw":
        return torch.optim.AdamW(trainable(model), lr=cfg.lr, betas=(cfg.momentum, 0.999),
                                 weight_decay=cfg.weight_decay)
    return torch.optim.SGD(trainable(model), lr=cfg.lr, momentum=cfg.momentum, weight_decay=cfg.weight_decay)


def _epoch_loader(train_ds: RoadDataset, cfg: TrainConfig, epoch: int, rank: int, world: int, batch: int):
    """This rank's batches of ``epoch``: item order (:func:`vctrain.training.trainset.epoch_order`, ``cfg.balance``)
    and augmentation depend on (seed, epoch, rank) only -> exact resume."""
    gen = torch.Generator().manual_seed(cfg.seed * 1000003 + epoch)
    order = epoch_order([x.source for x in train_ds.samples], cfg.balance, gen)
    if world > 1:  # equal shares (DistributedSampler's padding) so no rank waits for another
        order += order[: (-len(order)) % world]
        order = order[rank::world]
    torch.manual_seed(cfg.seed * 1000003 + epoch * 101 + rank + 1)
    if isinstance(train_ds, Parts):  # batches of one part each (its own working size)
        return torch.utils.data.DataLoader(train_ds, batch_sampler=view_batches(train_ds, order, batch),
                                           num_workers=cfg.workers)
    return torch.utils.data.DataLoader(torch.utils.data.Subset(train_ds, order), batch_size=batch, shuffle=False,
                                       num_workers=cfg.workers, drop_last=False)


@dataclass
class _Loop:
    """What every epoch of :func:`fit` trains with."""

    net: nn.Module                   # the model (DDP-wrapped when distributed)
    opt: torch.optim.Optimizer
    cfg: TrainConfig
    device: torch.device
    fmt: torch.memory_format         # channels-last or contiguous
    weight: torch.Tensor | None      # class weights of the loss
    world: int
    steps_per_epoch: int
    total_steps: int
    show: bool                       # progress bar
    penalty: Any = None              # L2-SP: a callable giving the pull toward the starting weights


def _train_epoch(loop: _Loop, loader, epoch: int, step: int, t0: float) -> tuple[float, int, int]:
    """One epoch's steps from global step ``step``; returns (loss sum, items seen, next step)."""
    cfg, opt = loop.cfg, loop.opt
    train_mode(loop.net, cfg)  # (frozen BatchNorm statistics stay the ones the weights were learnt with)
    loss_sum, n_seen = 0.0, 0
    bar = tqdm(loader, total=loop.steps_per_epoch, desc=f"epoch {epoch + 1}/{cfg.epochs}", unit="batch",
               disable=None if loop.show else True, leave=False, dynamic_ncols=True)
    for i, (x, y) in enumerate(bar):
        if i >= loop.steps_per_epoch:
            break
        lr = get_lr(step, loop.total_steps, cfg)
        for g in opt.param_groups:
            g["lr"] = lr
        x = x.to(loop.device, non_blocking=True).contiguous(memory_format=loop.fmt)
        y = y.to(loop.device, non_blocking=True)
        loss = _step(loop.net, opt, x, y, loop.weight, epoch, loop.penalty)
        step += 1
        loss_sum += loss.item() * len(x)
        n_seen += len(x)
        dt = time.perf_counter() - t0
        bar.set_postfix(loss=f"{loss_sum / n_seen:.4f}", img_s=f"{n_seen * loop.world / max(dt, 1e-9):.1f}")
    bar.close()
    return loss_sum, n_seen, step


def _resumed(resume: dict[str, Any] | None, opt: torch.optim.Optimizer) -> tuple[int, int, float, int, list]:
    """(start epoch, step, best val IoU, best epoch, history): the resumed run's, or a fresh run's."""
    if resume is None:
        return 0, 0, -1.0, -1, []
    opt.load_state_dict(resume["optimizer"])
    return (int(resume["epoch"]), int(resume["step"]), float(resume.get("best_iou", -1.0)),
            int(resume.get("best_epoch", -1)), list(resume.get("history", [])))


def _step(net: nn.Module, opt: torch.optim.Optimizer, x: torch.Tensor, y: torch.Tensor,
          weight: torch.Tensor | None, epoch: int, penalty=None) -> torch.Tensor:
    """One optimiser step on the batch (x, y), plus ``penalty()`` (L2-SP) when given; returns its loss."""
    logits = net(x)
    loss = loss_of(logits, y, weight)
    if penalty is not None:
        loss = loss + penalty()
    if not torch.isfinite(loss):
        if (y != 255).any():
            raise InputError(f"training diverged (loss {float(loss)}) at epoch {epoch + 1}", None, "lower --lr")
        loss = logits.sum() * 0.0  # batch without a single labelled pixel
    opt.zero_grad(set_to_none=True)
    loss.backward()
    opt.step()
    return loss


def _say_epoch(row: dict[str, Any], epochs: int, improved: bool) -> None:
    from vcprep.progress import err

    val = f", val IoU {row['val_iou']:.4f}" if "val_iou" in row else ""
    took = f", validation {row['val_seconds']:.1f} s" if "val_seconds" in row else ""
    err(f"epoch {row['epoch']}/{epochs}: loss {row['train_loss']:.4f}{val}, training {row['seconds']:.1f} s "
        f"({row['images_per_s']:.1f} img/s){took}{' *' if improved and val else ''}")


def _steps_per_epoch(cfg: TrainConfig, train_ds: Any, world: int) -> tuple[int, int]:
    """(batch per rank, optimiser steps per epoch): every training item once per epoch over all
    ranks, capped at ``cfg.max_steps``; mixed views take the steps of one view's run (each frame
    once an epoch, in one view or the other)."""
    n_train = len(train_ds) // 2 if isinstance(train_ds, MixedViews) else len(train_ds)
    per_rank_batch = max(1, math.ceil(cfg.batch_size / world))
    steps = math.ceil(n_train / (per_rank_batch * world))
    return per_rank_batch, (min(steps, cfg.max_steps) if cfg.max_steps else steps)


def _start(cfg: TrainConfig) -> tuple[int, int, torch.device, Path, Path]:
    """(rank, world size, device, checkpoint path, log path) of a run; the process group joined
    when launched by torchrun; a missing output folder refused."""
    rank, world, local_rank = ranks()
    device = resolve_device(cfg.device, local_rank)
    if world > 1 and not torch.distributed.is_initialized():
        import_before_group()
        torch.distributed.init_process_group("nccl" if device.type == "cuda" else "gloo")
    out = Path(cfg.out)
    if rank == 0 and not out.parent.is_dir():
        raise InputError("output folder does not exist", out.parent, "create it first")
    return rank, world, device, out, log_path(cfg)


def _open_log(log_path: Path, history: list[dict[str, Any]] | None) -> None:
    """Start the log afresh with the rows of the run so far (a resumed run's history): a rerun never
    duplicates a row, and a new run never continues another's (None: another rank's, nothing)."""
    if history is not None:
        log_path.write_text("".join(json.dumps(row) + "\n" for row in history))


def _placed(model: nn.Module, model_args: dict[str, Any], device: torch.device, distributed: bool):
    """(memory format, the network the steps run: DDP-wrapped when distributed) with ``model`` on ``device``."""
    # channels-last runs resfpn's convolutions ~20 % faster on the CPU; SegNet's unpooling wants NCHW
    fmt = torch.channels_last if model_args["arch"] == "resfpn" else torch.contiguous_format
    model.to(device, memory_format=fmt)
    net = nn.parallel.DistributedDataParallel(model, device_ids=[device.index] if device.type == "cuda" else None) \
        if distributed else model
    return fmt, net


def _start_of_fine_tuning(cfg: TrainConfig, info: dict[str, Any], init: dict[str, Any], model: nn.Module, val_loader,
                          device: torch.device, weight: torch.Tensor | None, master: bool) -> dict[str, Any] | None:
    """A fine-tuning run's epoch 0: the starting weights scored on the held-out frames (None: none held
    out), and the plan said before the first epoch (guard.py)."""
    t0 = time.perf_counter()
    row0 = guard.score_start(model, val_loader, device, weight, evaluate) if len(val_loader.dataset) else None
    if row0 is not None:
        row0["val_seconds"] = time.perf_counter() - t0
    if master and cfg.progress:
        guard.say_plan(cfg, info, init, row0)
    return row0


def _record_start(row0: dict, history: list, master: bool, log_path: Path, out: Path, checkpoint) -> None:
    """A fine-tuning's start as epoch 0: in the history and the log, and what --out and OUT.last.pt hold
    (a rerun resumes from here) until trained weights beat it; ``checkpoint(epoch, row)`` builds the dict."""
    history.append(row0)
    if master:
        _write_log(log_path, row0)
        for path in (out, last_path(out)):
            save_checkpoint(path, checkpoint(0, row0))


def fit(cfg: TrainConfig) -> dict[str, Any]:
    """Train according to ``cfg``; returns a summary (best val IoU, timings, paths: :func:`_summary`)."""
    started = time.perf_counter()
    request = request_of(cfg)  # the run as asked, before the defaults fill it (rerun.py)
    rank, world, device, out, log_path = _start(cfg)
    distributed, master = world > 1, rank == 0

    resume = load_checkpoint(cfg.resume) if cfg.resume else None
    init = load_checkpoint(cfg.init) if cfg.init and resume is None else None
    unset_from_checkpoints(cfg, resume, init)
    resolve_recipe(cfg, device)
    train_s, val_s, info = prepare_data(cfg)
    model, model_args = _network(cfg, resume, init, info)
    freeze_encoder(model, cfg)  # (before DDP wraps it: only the parameters that take gradients are reduced)
    fmt, net = _placed(model, model_args, device, distributed)
    train_ds, val_ds = training_sets(cfg, train_s, val_s, info)
    check_labels(cfg, train_ds)  # labels read with a format that does not fit them: refused before training
    weight = _class_weight(cfg, train_ds, info, device)
    per_rank_batch, steps_per_epoch = _steps_per_epoch(cfg, train_ds, world)
    total_steps = steps_per_epoch * cfg.epochs
    opt = _optimizer(cfg, model)
    val_loader = torch.utils.data.DataLoader(val_ds, batch_sampler=view_batches(val_ds, range(len(val_ds)), per_rank_batch),
                                             num_workers=cfg.workers)
    start_epoch, step, best_iou, best_epoch, history = _resumed(resume, opt)
    # the weights a fine-tuning run started from (a resumed one keeps its first run's record)
    init_from = (resume or {}).get("init") or (init_record(cfg.init, init) if init is not None else None)
    anchor, share = anchor_weights(cfg, model, resume, init), float(cfg.average_init or 0.0)
    loop = _Loop(net, opt, cfg, device, fmt, weight, world, steps_per_epoch, total_steps, cfg.progress and master,
                 l2sp_penalty(model, cfg, resume, init))
    del net  # the loop holds it (and leave_group drops it)
    guarded = init_from is not None and len(val_ds) > 0  # fine-tuning, never worse than its start (guard.py)

    def checkpoint(epoch: int, metrics: dict[str, Any]) -> dict[str, Any]:
        fine = guard.finetune_record(history, best_epoch, cfg.epochs) if guarded else None
        return {"model": model.state_dict(), "model_args": model_args, "config": cfg.to_dict(), "data": info,
                "request": request, "epoch": epoch, "step": step, "metrics": metrics, "best_iou": best_iou,
                "best_epoch": best_epoch, "history": history, "optimizer": opt.state_dict(),
                **({"init": init_from} if init_from else {}), **({"finetune": fine} if fine else {})}

    _open_log(log_path, history if master else None)
    row0 = _start_of_fine_tuning(cfg, info, init, model, val_loader, device, weight, master) \
        if init is not None and start_epoch == 0 else None
    if row0 is not None:  # the starting weights are what --out holds unless the trained ones beat them
        best_iou, best_epoch = row0["val_iou"], 0
        _record_start(row0, history, master, log_path, out, checkpoint)
    seconds, val_seconds, images = 0.0, 0.0, 0
    for epoch in range(start_epoch, cfg.epochs):
        loader = _epoch_loader(train_ds, cfg, epoch, rank, world, per_rank_batch)
        t0 = time.perf_counter()
        loss_sum, n_seen, step = _train_epoch(loop, loader, epoch, step, t0)
        if distributed:
            average_buffers(model, world)
        dt = time.perf_counter() - t0
        seconds, images = seconds + dt, images + n_seen * world
        row: dict[str, Any] = {"epoch": epoch + 1, "step": step, "lr": get_lr(step, total_steps, cfg),
                               "train_loss": loss_sum / max(n_seen, 1), "seconds": dt, "images_per_s": n_seen * world / max(dt, 1e-9)}
        saved = averaged(model, anchor, share)  # what --out holds: the trained weights, or their average with the start
        improved = _validate(row, as_saved(model, saved, anchor), val_loader, device, weight, best_iou) \
            if len(val_ds) else True
        improved = guard.keeps(cfg, epoch + 1, improved) if guarded else improved  # (guarded: the last epoch or none)
        val_seconds += row.get("val_seconds", 0.0)
        if improved:
            best_iou, best_epoch = row.get("val_iou", -1.0), epoch + 1
        history.append(row)
        if master:
            ck = checkpoint(epoch + 1, row)
            save_checkpoint(last_path(out), ck)  # the trained weights themselves: --resume goes on from them
            _write_log(log_path, row)  # (after the checkpoint: a row logged is a row a rerun resumes after)
            if improved:
                save_checkpoint(out, ck if anchor is None else {**ck, "model": saved, "average_init": share})
            if cfg.progress:
                _say_epoch(row, cfg.epochs, improved)
    replicas_identical = leave_group(loop, model, world) if distributed else None
    fine = guard.settle(out, history, best_epoch, cfg.epochs) if guarded and master else None
    return {"replicas_identical": replicas_identical, "world_size": world, "finetune": fine,
            "out": str(out), "last": str(last_path(out)), "log": str(log_path), "epochs": cfg.epochs,
            "best_val_iou": best_iou if best_iou >= 0 else None, "best_epoch": best_epoch, "model_args": model_args,
            **_times(seconds, val_seconds, images, cfg.epochs - start_epoch, row0, started),
            "data": {k: v for k, v in info.items() if k != "store_params"}}


def _times(seconds: float, val_seconds: float, images: int, epochs: int, row0: dict[str, Any] | None,
           started: float) -> dict[str, float | None]:
    """A run's times, each the wall clock of what it names: ``seconds`` the training steps of this
    invocation's ``epochs`` (``seconds_per_epoch``, ``train_images_per_s``), ``val_seconds`` their
    validation (``val_seconds_per_epoch``), ``start_seconds`` the starting model's score (``row0``, epoch 0 of
    a fine-tuning run scored in this invocation; else None),
    ``fit_seconds`` all of :func:`fit` from its first line (data, checkpoints and the final save too;
    the command's own total, its imports included, is ``vctrain fit``'s to say)."""
    return {"seconds": seconds, "seconds_per_epoch": seconds / max(epochs, 1),
            "train_images_per_s": images / max(seconds, 1e-9), "val_seconds": val_seconds,
            "val_seconds_per_epoch": val_seconds / max(epochs, 1),
            "start_seconds": row0.get("val_seconds") if row0 else None,
            "fit_seconds": time.perf_counter() - started}
