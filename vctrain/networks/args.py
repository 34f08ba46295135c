"""What a checkpoint records to rebuild a network: :class:`ModelArgs`, the architectures by name.

``ARCHITECTURES`` maps each name to its base width (the widths of the families: vctrain.networks.segnet,
.resnet, .efficientnet); ``PRETRAINED`` names those whose encoder starts from ImageNet weights.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

__all__ = ["ModelArgs", "ARCHITECTURES", "PRETRAINED", "model_args_for"]

ARCHITECTURES = {"segnet": 64, "segnet-narrow": 16, "resfpn": 16, "lite0fpn": 16, "lite0fpn-std": 16,
                 "lite1fpn": 16, "lite2fpn": 16}  # -> base width
# architectures whose encoder starts from ImageNet weights (unless --no-pretrained): the EfficientNet-Lite family
PRETRAINED = ("lite0fpn", "lite0fpn-std", "lite1fpn", "lite2fpn")


@dataclass(frozen=True)
class ModelArgs:
    """Everything needed to rebuild the network (stored in every checkpoint)."""

    arch: str = "segnet-narrow"  # 'segnet', 'segnet-narrow' (same topology, other widths), 'resfpn', 'lite<k>fpn'
    base_width: int = 16         # channels of the first block (lite0fpn: half the decoder's); 64 = the paper's SegNet
    in_channels: int = 3         # 3 (colour) or 4 (colour + VP proximity map)
    num_classes: int = 2         # 0 = not road, 1 = road; 3: 0 not drivable, 1 drivable not road, 2 road
                                 # (two outputs, vctrain.training.outputs)

    def to_dict(self) -> dict:
        return asdict(self)


def model_args_for(arch: str, in_channels: int = 3, base_width: int | None = None, num_classes: int = 2) -> ModelArgs:
    if arch not in ARCHITECTURES:
        raise ValueError(f"unknown architecture '{arch}'")
    return ModelArgs(arch=arch, base_width=int(base_width or ARCHITECTURES[arch]), in_channels=int(in_channels),
                     num_classes=int(num_classes))
