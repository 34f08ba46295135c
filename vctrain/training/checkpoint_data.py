"""The checkpoint's ``data`` section, typed: what a model was trained on and how its input is made.

A checkpoint keeps the section as a plain dict (``torch.load(..., weights_only=True)`` reads it;
:func:`vctrain.training.prepare_data` writes it); code that reads a model turns it into a
:class:`CheckpointData` once, where the checkpoint is loaded, and reads attributes, not string keys.
Keys a model trained by an older vctrain lacks take their defaults (``source_magnification``: None,
the model runs as it was trained; ``ray_channels``: off; ...); keys this version does not know are
kept (:attr:`CheckpointData.extra`), so :meth:`~CheckpointData.to_dict` gives the section back as it
was read. No torch here.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, Mapping, Optional

__all__ = ["CheckpointData"]

_PAIRS = ("input_size", "crop_size", "resize_size", "resize_crop_size")  # [w, h] in the dict, (w, h) here


@dataclass(frozen=True)
class CheckpointData:
    """A checkpoint's ``data`` section (vctrain/training/checkpoint.py's docstring)."""

    mode: str = "virtual"                        # 'virtual' (warped into its virtual camera) | 'resize' | 'mixed'
    input_size: Optional[tuple[int, int]] = None  # the network's working size (w, h)
    store_params: Optional[dict] = None          # the training store's store.json (virtual camera, scale,
                                                 # store_size, virtual_scaled); None: a baseline from folders
    completion: str = "none"                     # the training store's completion method
    vp_channel: bool = False                     # a 4th input channel: proximity to the frame's road VP
    ray_channels: bool = False                   # 3 more input channels: the pixels' ray directions
    greyscale: float = 0.0                       # the share of training items made grey (>= 1: the model reads grey)
    vp_status: tuple[str, ...] = ()              # the training stores' per-item VP statuses
    vp_rule: Optional[dict] = None               # the VPRule its stores' estimated VPs were found with
    source_magnification: Optional[float] = None  # the most the warp enlarged a training camera's frames
    crop_size: Optional[tuple[int, int]] = None  # the training windows (w, h)
    resize_size: Optional[tuple[int, int]] = None       # 'mixed': the resize view's working size
    resize_crop_size: Optional[tuple[int, int]] = None  # 'mixed': the resize view's windows
    keep_aspect: bool = False                    # 'resize': each frame at input_size's pixel count at its own aspect
    outputs: tuple[str, ...] = ("road",)        # the network's outputs (vctrain.training.outputs): road, or road and
                                                 # drivable (3 classes); a model of an older vctrain: road
    train_items: Optional[int] = None
    val_items: Optional[int] = None
    extra: Mapping[str, Any] = field(default_factory=dict)  # every other key, as it was read
    keys: tuple[str, ...] = field(default=(), repr=False, compare=False)  # the dict's keys in order (to_dict)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> CheckpointData:
        """The section ``d`` (a checkpoint's ``data``, or ``{}``/None: every default), missing keys
        at their defaults."""
        d = dict(d or {})
        known = {f.name for f in fields(cls)} - {"extra", "keys"}
        kw: dict[str, Any] = {k: v for k, v in d.items() if k in known and v is not None}
        for k in _PAIRS:
            if k in kw:
                kw[k] = tuple(int(v) for v in kw[k])
        for k in ("vp_status", "outputs"):
            if k in kw:
                kw[k] = tuple(kw[k])
        for k, kind in (("vp_channel", bool), ("ray_channels", bool), ("keep_aspect", bool), ("greyscale", float)):
            if k in kw:
                kw[k] = kind(kw[k])
        return cls(**kw, extra={k: v for k, v in d.items() if k not in known}, keys=tuple(d))

    def to_dict(self) -> dict[str, Any]:
        """The section as a checkpoint stores it (lists, not tuples): the keys it was read with, in
        their order; one made here: every field that is set."""
        out: dict[str, Any] = {}
        for f in fields(self):
            if f.name in ("extra", "keys"):
                continue
            v = getattr(self, f.name)
            if f.name in self.keys or (not self.keys and v is not None):
                out[f.name] = list(v) if isinstance(v, tuple) else v
        out.update(self.extra)
        return {k: out[k] for k in self.keys if k in out} | {k: v for k, v in out.items() if k not in self.keys}

    @property
    def virtual(self) -> bool:
        """Whether the model reads frames warped into a virtual camera (a store it was trained on)."""
        return self.mode == "virtual" and bool(self.store_params)

    @property
    def store_size(self) -> Optional[tuple[int, int]]:
        """The training store's image size (w, h), or None (no store)."""
        size = (self.store_params or {}).get("store_size")
        return (int(size[0]), int(size[1])) if size else None

    @property
    def virtual_scaled(self) -> Optional[dict]:
        """The training store's virtual camera at the store's scale (a camera dict), or None."""
        return (self.store_params or {}).get("virtual_scaled")
