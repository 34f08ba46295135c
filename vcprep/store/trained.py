"""The virtual camera and scale a model was trained in, or a store holds: what ``vcprep warp
--virtual MODEL.pt`` (or ``--virtual STORE``) warps new frames into, so that a user's own frames
can fine-tune a virtual-camera model (``vctrain fit STORE --init MODEL.pt``) in the domain it learnt.

A vctrain checkpoint records its training store's parameters (``data.store_params``: virtual
camera, scale, store size); this reads them without building the network (torch only loads the
file, with ``weights_only``), so vcprep does not depend on vctrain.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from ..camera.files import camera_from_dict
from ..camera.pinhole import Camera
from ..errors import InputError

__all__ = ["is_trained_source", "trained_virtual"]

CHECKPOINT_SUFFIXES = (".pt", ".pth")


def is_trained_source(spec: str) -> bool:
    """Whether a ``--virtual`` value names a model checkpoint or a store folder (not a camera)."""
    p = Path(spec)
    return p.suffix.lower() in CHECKPOINT_SUFFIXES or (p.is_dir() and (p / "store.json").is_file())


def trained_virtual(spec: str | Path) -> tuple[Camera, float]:
    """(virtual camera, scale) of a vctrain checkpoint or a store folder."""
    path = Path(spec)
    if path.is_dir():
        from .layout import Store

        store = Store.open(path)
        return camera_from_dict(store.params["virtual"], path / "store.json"), float(store.scale)
    params = _checkpoint_store_params(path)
    return camera_from_dict(params["virtual"], path), float(params["scale"])


def _checkpoint_store_params(path: Path) -> dict[str, Any]:
    """The checkpoint's ``data.store_params``; the format name is vctrain.training.checkpoint.CKPT_FORMAT's."""
    fix = "give a virtual-camera model written by 'vctrain fit STORE' (or its training store)"
    if not path.is_file():
        raise InputError("no such model file", path, fix)
    import torch

    try:
        ck = torch.load(path, map_location="cpu", weights_only=True)
    except Exception:  # torch raises many types for foreign/corrupt files
        raise InputError("cannot read the model (corrupt, truncated or not a PyTorch file)", path, fix) from None
    if not isinstance(ck, dict) or ck.get("format") != "vctrain-checkpoint":
        raise InputError("not a vctrain checkpoint", path, fix)
    data = ck.get("data") or {}
    if data.get("mode") == "resize" or not data.get("store_params"):
        raise InputError("a resize model has no virtual camera to warp into", path,
                         "fine-tune it on the frames themselves: vctrain fit --baseline resize --images ... "
                         "--labels ... --init MODEL.pt")
    return data["store_params"]
