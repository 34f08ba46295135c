"""Self-describing checkpoints: everything predict/eval need to rebuild the model and its input.

A checkpoint is a ``torch.save`` dict (loadable with ``weights_only=True``)::

    format 'vctrain-checkpoint', version 1, tool_version, torch_version
    model        state dict
    model_args   ModelArgs as a dict (arch, base_width, in_channels, num_classes)
    config       the TrainConfig as a dict
    data         mode ('virtual' | 'resize'), input_size [w, h], store_params (store.json of the
                 training store: virtual camera, scale, store_size, virtual_scaled; None for a
                 baseline trained from folders), completion, vp_channel, greyscale, vp_status
                 (per-image VP statuses seen in training), vp_rule (the VPRule of its estimated VPs, when
                 the stores record one: predict estimates with it), source_magnification (the most the
                 warp enlarged a training camera's frames: predictors shrink their working size only for
                 frames enlarged more; absent in models trained before it), keep_aspect (a resize model:
                 each frame at input_size's pixel count at its own aspect; absent: squashed to input_size),
                 train_items, val_items
    epoch, step, metrics (of this epoch), best_iou, best_epoch, history (per-epoch log rows)
    optimizer    optimizer state (for --resume)

The ``data`` section stays a plain dict on disk; readers turn it into a typed
:class:`vctrain.training.checkpoint_data.CheckpointData` once, where they load the checkpoint.
"""
from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import torch

from vcprep.errors import InputError
from vcprep.io import write_bytes_atomic

from vctrain import __version__
from torch import nn

from ..networks.args import ARCHITECTURES
from ..networks.build import build_model

__all__ = ["CKPT_FORMAT", "CKPT_VERSION", "save_checkpoint", "load_checkpoint", "model_from_checkpoint", "last_path"]

CKPT_FORMAT = "vctrain-checkpoint"
CKPT_VERSION = 1


def last_path(out: str | Path) -> Path:
    """The latest epoch's checkpoint beside ``out`` (runs/vc.pt -> runs/vc.last.pt), for --resume."""
    out = Path(out)
    return out.with_name(out.stem + ".last.pt")


def save_checkpoint(path: str | Path, ckpt: dict[str, Any]) -> None:
    """Write atomically (temp file + rename) so that a crash never leaves half a checkpoint."""
    path = Path(path)
    full = {"format": CKPT_FORMAT, "version": CKPT_VERSION, "tool_version": __version__,
            "torch_version": str(torch.__version__), **ckpt}
    buf = io.BytesIO()
    torch.save(full, buf)
    try:
        write_bytes_atomic(path, buf.getvalue())
    except (FileNotFoundError, NotADirectoryError):
        raise InputError("cannot write the checkpoint here (parent folder missing)", path,
                         "create the folder first") from None


def load_checkpoint(path: str | Path) -> dict[str, Any]:
    """Read and validate a checkpoint (on the CPU); raises :class:`InputError` naming the file."""
    path = Path(path)
    if not path.exists():
        raise InputError("checkpoint not found", path, "give the .pt file written by 'vctrain fit'")
    if not path.is_file():
        raise InputError("is not a file", path, "give the .pt file written by 'vctrain fit'")
    try:
        ck = torch.load(path, map_location="cpu", weights_only=True)
    except Exception:  # torch raises many types for foreign/corrupt files
        raise InputError("cannot read checkpoint (corrupt, truncated or not a PyTorch file)", path,
                         "give the .pt file written by 'vctrain fit'") from None
    if not isinstance(ck, dict) or ck.get("format") != CKPT_FORMAT:
        raise InputError("not a vctrain checkpoint (another architecture or tool wrote it)", path,
                         "give a model written by 'vctrain fit'")
    if ck.get("version") != CKPT_VERSION:
        raise InputError(f"checkpoint version {ck.get('version')} is not supported (this vctrain reads "
                         f"{CKPT_VERSION})", path, "retrain with this version of vctrain")
    args = ck.get("model_args") or {}
    if args.get("arch") not in ARCHITECTURES:
        raise InputError(f"checkpoint holds architecture '{args.get('arch')}', this vctrain knows "
                         f"{', '.join(ARCHITECTURES)}", path, "use a checkpoint of a supported model")
    return ck


def model_from_checkpoint(ck: dict[str, Any], path: str | Path | None = None) -> nn.Module:
    """Rebuild the network from ``model_args`` and load its weights (strict)."""
    try:
        model = build_model(ck["model_args"])
        model.load_state_dict(ck["model"], strict=True)
    except (RuntimeError, TypeError, KeyError) as e:
        first = str(e).strip().splitlines()[0][:200]
        raise InputError(f"checkpoint weights do not fit its model arguments ({first})", path,
                         "the file is damaged or was edited; retrain") from None
    return model
