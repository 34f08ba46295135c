"""SegNet: the VGG16 encoder-decoder with max-unpooling indices (Badrinarayanan et al.), as used by
the VCSeg paper, plus a narrow variant of the same topology for CPU training.

Topology (both variants): 5 encoder blocks of 2, 2, 3, 3, 3 conv3x3-BN-ReLU layers (the 13 conv
layers of VGG16) each followed by 2x2 max pooling that remembers its argmax indices; 5 mirrored
decoder blocks that max-unpool with those indices and apply 3, 3, 3, 2, 2 conv3x3-BN-ReLU layers;
a final 3x3 conv to ``num_classes`` logits. Widths per block are ``base_width * (1, 2, 4, 8, 8)``:
``segnet`` = 64 (the paper's network, 29 M parameters), ``segnet-narrow`` = 16 (1/16 of the
FLOPs, ~1.8 M parameters; the default when no GPU is present).

Shapes: input (N, in_channels, H, W) float, output (N, num_classes, H, W) logits, for any H, W
(odd sizes are handled by unpooling to the exact pre-pooling size).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import nn
from torch.nn import functional as F

__all__ = ["ModelArgs", "SegNet", "ARCHITECTURES", "build_model", "model_args_for"]

ARCHITECTURES = {"segnet": 64, "segnet-narrow": 16}  # name -> base width
_ENC_LAYERS = (2, 2, 3, 3, 3)  # VGG16's 13 conv layers
_WIDTH_MULT = (1, 2, 4, 8, 8)


@dataclass(frozen=True)
class ModelArgs:
    """Everything needed to rebuild the network (stored in every checkpoint)."""

    arch: str = "segnet-narrow"  # 'segnet' or 'segnet-narrow' (same topology, other widths)
    base_width: int = 16         # channels of the first block; 64 = the paper's VGG16 SegNet
    in_channels: int = 3         # 3 (colour) or 4 (colour + VP proximity map)
    num_classes: int = 2         # 0 = not road, 1 = road

    def to_dict(self) -> dict:
        return asdict(self)


def model_args_for(arch: str, in_channels: int = 3, base_width: int | None = None) -> ModelArgs:
    if arch not in ARCHITECTURES:
        raise ValueError(f"unknown architecture '{arch}'")
    return ModelArgs(arch=arch, base_width=int(base_width or ARCHITECTURES[arch]), in_channels=int(in_channels))


def _conv_bn_relu(cin: int, cout: int) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, 3, padding=1, bias=False), nn.BatchNorm2d(cout), nn.ReLU(inplace=True))


class SegNet(nn.Module):
    """VGG16-topology SegNet; see the module docstring."""

    def __init__(self, args: ModelArgs = ModelArgs()):
        super().__init__()
        self.args = args
        widths = [args.base_width * m for m in _WIDTH_MULT]
        self.encoders = nn.ModuleList()
        cin = args.in_channels
        for n, w in zip(_ENC_LAYERS, widths):
            layers = []
            for _ in range(n):
                layers.append(_conv_bn_relu(cin, w))
                cin = w
            self.encoders.append(nn.Sequential(*layers))
        # decoder block i mirrors encoder block i; its last layer maps to the width of block i-1
        self.decoders = nn.ModuleList()
        for i in reversed(range(len(widths))):
            w = widths[i]
            out = widths[i - 1] if i > 0 else widths[0]
            n = _ENC_LAYERS[i]
            layers = [_conv_bn_relu(w, w) for _ in range(n - 1)] + [_conv_bn_relu(w, out)]
            self.decoders.append(nn.Sequential(*layers))
        self.classifier = nn.Conv2d(widths[0], args.num_classes, 3, padding=1)
        for m in self.modules():
            if isinstance(m, nn.Conv2d):
                nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="relu")
                if m.bias is not None:
                    nn.init.zeros_(m.bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        indices, sizes = [], []
        for enc in self.encoders:
            x = enc(x)
            sizes.append(x.shape[-2:])
            x, idx = F.max_pool2d(x, 2, 2, ceil_mode=False, return_indices=True)
            indices.append(idx)
        for dec, idx, size in zip(self.decoders, reversed(indices), reversed(sizes)):
            x = F.max_unpool2d(x, idx, 2, 2, output_size=size)
            x = dec(x)
        return self.classifier(x)


def build_model(args: ModelArgs | dict) -> SegNet:
    if isinstance(args, dict):
        args = ModelArgs(**args)
    return SegNet(args)
