"""Starting from a checkpoint: what a fine-tuning run (``init``) or a resumed one takes from it, and
the average of the trained weights with the start that a fine-tuning checkpoint holds (WiSE-FT).

:func:`vctrain.training.loop.fit` calls these; the defaults they fill for ``--init`` are
config.FINETUNE_* (measured by benchmarks/what_a_user_gets/own_frames.py).
"""
from __future__ import annotations

import copy
import hashlib
from pathlib import Path
from typing import Any

import torch
from torch import nn

from vcprep.errors import InputError

from .checkpoint import load_checkpoint
from .checkpoint_data import CheckpointData
from .config import (ADAPT_LR_FACTOR, FINETUNE_AVERAGE_INIT, FINETUNE_FREEZE_BN, FINETUNE_FREEZE_ENCODER, FINETUNE_L2SP,
                     TrainConfig)
from ..networks.args import ARCHITECTURES
from ..networks.build import encoder_modules

__all__ = ["check_init", "unset_from_checkpoints", "init_record", "anchor_weights", "averaged", "as_saved",
           "l2sp_penalty", "freeze_encoder", "trainable", "train_mode"]


def check_init(cfg: TrainConfig, init: dict[str, Any], info: dict[str, Any]) -> None:
    """Refuse an ``init`` checkpoint whose network or domain differs from the run's: architecture,
    first-block width, input channels, or mode (virtual camera vs resize baseline)."""
    args = init["model_args"]
    if cfg.arch != args["arch"]:
        raise InputError(f"checkpoint is a '{args['arch']}' but --model {cfg.arch} was asked", cfg.init,
                         f"use --model {args['arch']} or leave --model out")
    width = int(cfg.base_width or ARCHITECTURES[cfg.arch])
    if width != int(args["base_width"]):
        raise InputError(f"checkpoint has width {args['base_width']} but --width {width} was asked", cfg.init,
                         f"use --width {args['base_width']} or leave --width out")
    if args["in_channels"] != cfg.in_channels:
        raise InputError(f"checkpoint takes {args['in_channels']} input channels, the data "
                         f"{cfg.in_channels}", cfg.init,
                         "fine-tune with the model's own --vp-channel and --ray-channels settings")
    mode = CheckpointData.from_dict(init.get("data")).mode
    if mode != info["mode"]:
        raise InputError(f"checkpoint was trained in mode '{mode}' but this run is '{info['mode']}'", cfg.init,
                         "fine-tune a resize model with --baseline resize, a virtual-camera model on stores")


def init_network(cfg: TrainConfig, init: dict[str, Any]) -> None:
    """Fill the settings a fine-tuning run left unset from the ``init`` checkpoint (in place): the
    network (``--model``, ``--width``), so :func:`check_init` only refuses what was asked otherwise;
    a resize model's working size (the frames' own would show the network another scale than it
    learnt, and CamVid's 960x720 costs four times the steps) and its frames' own aspect (``keep_aspect``); BatchNorm frozen or not
    (:data:`FINETUNE_FREEZE_BN`); and the learning rate, ``ADAPT_LR_FACTOR`` (a tenth) of the checkpoint's own (benchmarks/archive/what_a_user_gets/finetune.py
    measured that rule: 20 frames of an unseen camera, +4.2 over training on them from scratch)."""
    if cfg.lr is None and (init.get("config") or {}).get("lr"):
        cfg.lr = ADAPT_LR_FACTOR * float(init["config"]["lr"])
    data = CheckpointData.from_dict(init.get("data"))
    if cfg.size is None and cfg.baseline == "resize" and data.mode == "resize" and data.input_size:
        cfg.size = data.input_size  # the scale the model learnt, not the frames' own
    if cfg.baseline == "resize" and data.mode == "resize" and data.keep_aspect:
        cfg.keep_aspect = True  # every frame at its own aspect, as the model learnt them
    if cfg.freeze_bn is None:
        cfg.freeze_bn = FINETUNE_FREEZE_BN
    if cfg.freeze_encoder is None:
        cfg.freeze_encoder = FINETUNE_FREEZE_ENCODER
    if cfg.average_init is None:
        cfg.average_init = FINETUNE_AVERAGE_INIT
    if cfg.l2sp is None:
        cfg.l2sp = FINETUNE_L2SP
    if cfg.arch is None:
        cfg.arch = init["model_args"]["arch"]
    if cfg.base_width is None and cfg.arch == init["model_args"]["arch"]:
        cfg.base_width = int(init["model_args"]["base_width"])


def unset_from_checkpoints(cfg: TrainConfig, resume: dict[str, Any] | None, init: dict[str, Any] | None) -> None:
    """Fill what a run left unset from the checkpoints it starts from (in place), before the recipe
    fills the rest: a resumed run keeps its own peak rate (a fine-tuning run's too); a fine-tuning run
    takes its network and rate from ``init`` (:func:`init_network`)."""
    if resume is not None and cfg.lr is None:
        cfg.lr = (resume.get("config") or {}).get("lr")
    if resume is not None and cfg.arch is None:  # the checkpoint's network, not the recipe's
        cfg.arch = resume["model_args"]["arch"]
    # a resumed fine-tuning run goes on as it began
    for k in ("freeze_bn", "freeze_encoder", "average_init", "val_fraction", "l2sp"):
        if resume is not None and getattr(cfg, k) is None:
            setattr(cfg, k, (resume.get("config") or {}).get(k))
    if init is not None:
        init_network(cfg, init)


def init_record(path: str, init: dict[str, Any]) -> dict[str, Any]:
    """What a fine-tuned checkpoint records of the one it started from."""
    return {"path": str(path), "sha256": hashlib.sha256(Path(path).read_bytes()).hexdigest(),
            "epoch": init.get("epoch"), "best_iou": init.get("best_iou"), "model_args": init["model_args"]}


def anchor_weights(cfg: TrainConfig, model: nn.Module, resume: dict[str, Any] | None,
            init: dict[str, Any] | None) -> dict[str, torch.Tensor] | None:
    """The starting weights a fine-tuning run averages its checkpoint with (``cfg.average_init`` > 0):
    the ``init`` checkpoint's (the model holds them now), or, resuming, those of the checkpoint its
    first run started from; None when nothing is averaged."""
    share = float(cfg.average_init or 0.0)
    if not 0 <= share < 1:
        raise InputError(f"average-init must be in [0, 1), got {share}", None, "use e.g. 0.5, or 0 for none")
    if share == 0:
        return None
    if init is not None:
        return {k: v.detach().clone() for k, v in model.state_dict().items()}
    record = (resume or {}).get("init") or {}
    if not record.get("path"):
        raise InputError("--average-init averages with the weights a run started from, and this run starts from none",
                         cfg.resume, "add --init MODEL.pt, or leave --average-init out")
    if not Path(record["path"]).is_file():
        raise InputError("the run averages with the checkpoint it started from, which is gone", record["path"],
                         "put it back, or resume with --average-init 0")
    return load_checkpoint(record["path"])["model"]


def averaged(model: nn.Module, anchor: dict[str, torch.Tensor] | None, share: float) -> dict[str, torch.Tensor]:
    """The weights a checkpoint holds: ``share`` x the starting weights + (1 - share) x the trained
    ones (WiSE-FT, Wortsman et al. 2022: the fine-tuned model keeps what the start knew of other
    drives and cameras), BatchNorm statistics included; the trained ones when nothing is averaged."""
    state = model.state_dict()
    if anchor is None:
        return state
    return {k: (share * anchor[k].to(v.dtype) + (1 - share) * v) if v.is_floating_point() else v
            for k, v in state.items()}


def as_saved(model: nn.Module, weights: dict[str, torch.Tensor], anchor: dict[str, torch.Tensor] | None) -> nn.Module:
    """The network validation scores: the model itself, or a copy holding the averaged weights."""
    if anchor is None:
        return model
    net = copy.deepcopy(model)
    net.load_state_dict(weights)
    return net


def l2sp_penalty(model: nn.Module, cfg: TrainConfig, resume: dict[str, Any] | None, init: dict[str, Any] | None):
    """L2-SP (Li et al. 2018): a callable giving ``l2sp / 2`` x the squared distance of the model's
    parameters from the weights the run started from (the ``init`` checkpoint's, or a resumed run's
    first start); None when ``cfg.l2sp`` is 0 or unset."""
    alpha = float(cfg.l2sp or 0.0)
    if alpha < 0:
        raise InputError(f"l2sp must be >= 0, got {alpha}", None, "use e.g. 0.01, or 0 for none")
    if alpha == 0:
        return None
    if init is not None:
        start = {k: v.detach().clone() for k, v in model.state_dict().items()}
    elif (resume or {}).get("init", {}).get("path") and Path(resume["init"]["path"]).is_file():
        start = load_checkpoint(resume["init"]["path"])["model"]
    else:
        raise InputError("--l2sp pulls toward the weights a run started from, and this run starts from none",
                         cfg.resume, "add --init MODEL.pt, or leave --l2sp out")
    pairs = [(p, start[name].to(p.device)) for name, p in model.named_parameters()]

    def penalty() -> torch.Tensor:
        return 0.5 * alpha * sum(((p - p0) ** 2).sum() for p, p0 in pairs)
    return penalty


def freeze_encoder(model: nn.Module, cfg: TrainConfig) -> None:
    """``cfg.freeze_encoder``: the encoder's weights take no gradient (the optimizer gets only the
    decoder's, :func:`trainable`), and :func:`train_mode` keeps its BatchNorm statistics."""
    if not cfg.freeze_encoder:
        return
    if cfg.init is None and cfg.resume is None:
        raise InputError("--freeze-encoder keeps the weights a run starts from, and this run starts from none", None,
                         "add --init MODEL.pt, or leave --freeze-encoder out")
    for part in encoder_modules(model):
        part.requires_grad_(False)


def trainable(model: nn.Module) -> list[nn.Parameter]:
    """The parameters the optimizer updates: all but a frozen encoder's."""
    return [p for p in model.parameters() if p.requires_grad]


def train_mode(net: nn.Module, cfg: TrainConfig) -> None:
    """``net`` in training mode, with the BatchNorm layers that keep their running statistics in eval
    mode: every one with ``freeze_bn``, the encoder's with ``freeze_encoder``."""
    net.train()
    frozen = [net] if cfg.freeze_bn else encoder_modules(getattr(net, "module", net)) if cfg.freeze_encoder else []
    for part in frozen:
        for m in part.modules():
            if isinstance(m, nn.modules.batchnorm._BatchNorm):
                m.eval()
