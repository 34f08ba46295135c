"""Fine-tuning that is never worse than where it started (``fit --init``, issue 72).

Part of the user's frames is held out (:func:`vctrain.training.trainset.sequence_items`: whole
sequences where the names show five or more, else by frame, the last stretch of each (KITTI road's
um_/umm_/uu_, one drive), else a seeded share); the
starting model is scored on them before the first epoch (:func:`score_start`, the log's first row,
``"epoch": 0, "init": true``), and ``--out`` holds it unless the trained model -- the last epoch, as
``--out`` would hold it (averaged with the start: ``--average-init``) -- scores higher there
(:func:`keeps`). Not the best epoch: on a few held-out frames the best epoch was an early one that
scored lower elsewhere (docs/training.md, "Fine-tuning"). :func:`say_plan` prints the recipe, the
starting model, the learning rate, what is held out and its starting score before the first
epoch; :func:`verdict` the outcome, which the checkpoint records too (``finetune``).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import torch
from torch import nn

from .config import TrainConfig

__all__ = ["score_start", "say_plan", "keeps", "verdict", "finetune_record", "settle"]


def score_start(model: nn.Module, loader, device: torch.device, weight: torch.Tensor | None,
                evaluate) -> dict[str, Any]:
    """Epoch 0 of a fine-tuning run with held-out frames: the starting weights' metrics on them
    (``evaluate``: :func:`vctrain.training.loop.evaluate`)."""
    vm = evaluate(model, loader, device, weight)
    return {"epoch": 0, "step": 0, "init": True, **{f"val_{k}": v for k, v in vm.items()}}


def say_plan(cfg: TrainConfig, info: dict[str, Any], init: dict[str, Any], row0: dict[str, Any] | None) -> None:
    """Before the first epoch (stderr): the recipe, the starting model, the learning rate, what is
    held out and the starting model's score on it."""
    from vcprep.progress import err

    own = (init.get("config") or {}).get("lr")
    rate = f"lr {cfg.lr:g}" + (f" ({cfg.lr / own:.2g} of the model's own {own:g})" if own else "")
    extras = [x for x, on in ((f"averaged {cfg.average_init:g} with the start", cfg.average_init),
                              ("BatchNorm statistics frozen", cfg.freeze_bn),
                              ("encoder frozen", cfg.freeze_encoder),
                              (f"L2-SP {cfg.l2sp:g}", cfg.l2sp)) if on]
    err(f"fine-tuning {cfg.init} ({init['model_args']['arch']}): recipe {cfg.recipe}, {cfg.epochs} epochs, {rate}"
        + "".join(f", {x}" for x in extras) + f", {info['train_items']} frames trained on")
    if row0 is None:
        err("nothing held out (--val-fraction 0): the last epoch is kept whatever it scores")
        return
    took = f" ({row0['val_seconds']:.1f} s)" if "val_seconds" in row0 else ""
    err(f"held out: {info['val_items']} frames, {info.get('held_out') or 'the validation stores'}; the starting "
        f"model scores road IoU {row0['val_iou']:.4f} on them{took}, and the trained one is kept only if it scores "
        "higher")


def keeps(cfg: TrainConfig, epoch: int, better: bool) -> bool:
    """Whether a guarded fine-tuning run writes this epoch (1-based) to ``--out``: the last one, when
    it beats the start on the held-out frames."""
    return better and epoch == cfg.epochs


def finetune_record(history: list[dict[str, Any]], best_epoch: int, epochs: int) -> dict[str, Any] | None:
    """The checkpoint's ``finetune``: the start's held-out score, the trained model's, what ``--out``
    holds; None without a scored start (nothing held out)."""
    start = next((r for r in history if r.get("init")), None)
    if start is None:
        return None
    last = next((r for r in history if r.get("epoch") == epochs and "val_iou" in r), None)
    return {"start_val_iou": start["val_iou"], "trained_val_iou": last["val_iou"] if last else None,
            "kept": "start" if best_epoch == 0 else f"epoch {best_epoch}"}


def settle(out: Path, history: list[dict[str, Any]], best_epoch: int, epochs: int) -> dict[str, Any] | None:
    """The run's :func:`finetune_record`, written into ``out`` too where ``out`` still holds the start
    (saved before the first epoch, it knew neither the trained model's score nor the history)."""
    from .checkpoint import load_checkpoint, save_checkpoint

    fine = finetune_record(history, best_epoch, epochs)
    if fine is not None and fine["kept"] == "start" and fine["trained_val_iou"] is not None:
        ck = load_checkpoint(out)
        save_checkpoint(out, {**ck, "finetune": fine, "history": history})
    return fine


def verdict(out: str, fine: dict[str, Any], val_items: int) -> str:
    """The closing line of a guarded fine-tuning run."""
    start, trained = fine["start_val_iou"], fine["trained_val_iou"]
    if fine["kept"] == "start":
        return (f"{out}: the starting model, unchanged: the trained one scored road IoU {trained:.4f} on the "
                f"{val_items} held-out frames against the start's {start:.4f}, no better (nothing was lost)")
    return (f"{out}: the trained model: road IoU {trained:.4f} on the {val_items} held-out frames against the "
            f"start's {start:.4f} ({100 * (trained - start):+.1f} points)")
