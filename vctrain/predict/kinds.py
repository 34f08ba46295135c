"""What a predictor offers the road for a frame (:class:`RoadPredictor`, a :class:`typing.Protocol`):
the one description of the three kinds that predict frames -- a checkpoint's network
(:class:`vctrain.predict.predictor.Predictor`: a virtual-camera or a resize model), the geometric
prior (:class:`vctrain.adapt.PriorPredictor`) and an exported graph
(:class:`vctrain.deploy.runtime.OnnxPredictor`). Each declares every attribute, so the road reads
them instead of probing for them; what a kind implies is :mod:`vctrain.predict.frames`'
(:func:`~vctrain.predict.frames.warps_frames`, :func:`~vctrain.predict.frames.reads_road_vps`)."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Protocol, runtime_checkable

if TYPE_CHECKING:
    from vcprep.camera import Camera

    from ..training.checkpoint_data import CheckpointData

__all__ = ["RoadPredictor"]


@runtime_checkable
class RoadPredictor(Protocol):
    """What the road (:mod:`vctrain.predict.road`, :mod:`vctrain.predict.video`, :mod:`vctrain.predict.model`)
    asks of a predictor."""

    path: Path                   # the model's file (errors name it)
    mode: str                    # 'virtual' (frames warped into its camera), 'resize', 'mixed' (stores only)
    data: CheckpointData         # the checkpoint's data section (all defaults for a graph: its camera is inside)
    takes_frames: bool           # a graph: warp, network and back-projection inside it
    beyond_rule: str | None      # frame pixels outside the training rectangle (None: the prior's 0, a graph's rays)
    vp_channel: bool             # reads each frame's road VP as an input channel
    ray_channels: bool           # reads each pixel's ray angles (store items only)
    camera: "Camera | None"      # a graph's own camera (None: the frames' camera is given)

    def check_frame_size(self, size: tuple[int, int], name: str | Path | None = None) -> None:
        """Raise :class:`~vcprep.errors.InputError` for frames of ``size`` (w, h) it cannot take."""
