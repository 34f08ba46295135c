"""The SegNet family: the paper's ``segnet`` and ``segnet-narrow``.

``segnet``: the VGG16 encoder-decoder with max-unpooling indices (Badrinarayanan et al.), as used by
the VCSeg paper, plus ``segnet-narrow``, a narrow variant of the same topology.

Topology (both variants): 5 encoder blocks of 2, 2, 3, 3, 3 conv3x3-BN-ReLU layers (the 13 conv
layers of VGG16) each followed by 2x2 max pooling that remembers its argmax indices; 5 mirrored
decoder blocks that max-unpool with those indices and apply 3, 3, 3, 2, 2 conv3x3-BN-ReLU layers;
a final 3x3 conv to ``num_classes`` logits. Widths per block are ``base_width * (1, 2, 4, 8, 8)``:
``segnet`` = 64 (the paper's network, 29 M parameters), ``segnet-narrow`` = 16 (1/16 of the
FLOPs, ~1.8 M parameters).

Shapes: input (N, in_channels, H, W) float, output (N, num_classes, H, W) logits, for any H, W (odd
sizes: SegNet unpools to the exact pre-pooling size).
"""
from __future__ import annotations

import torch
from torch import nn
from torch.nn import functional as F

from .args import ModelArgs
from .layers import conv_bn_relu, kaiming

__all__ = ["SegNet"]

_ENC_LAYERS = (2, 2, 3, 3, 3)  # VGG16's 13 conv layers
_WIDTH_MULT = (1, 2, 4, 8, 8)


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
                layers.append(conv_bn_relu(cin, w))
                cin = w
            self.encoders.append(nn.Sequential(*layers))
        # decoder block i mirrors encoder block i; its last layer maps to the width of block i-1
        self.decoders = nn.ModuleList()
        for i in reversed(range(len(widths))):
            w = widths[i]
            out = widths[i - 1] if i > 0 else widths[0]
            n = _ENC_LAYERS[i]
            layers = [conv_bn_relu(w, w) for _ in range(n - 1)] + [conv_bn_relu(w, out)]
            self.decoders.append(nn.Sequential(*layers))
        self.classifier = nn.Conv2d(widths[0], args.num_classes, 3, padding=1)
        kaiming(self.modules())

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        indices, sizes = [], []
        for enc in self.encoders:
            x = enc(x)
            sizes.append(x.shape[-2:])
            x, idx = F.max_pool2d(x, 2, 2, ceil_mode=False, return_indices=True)
            indices.append(idx)
        for dec, idx, size in zip(self.decoders, reversed(indices), reversed(sizes)):
            x = _max_unpool(x, idx, size)
            x = dec(x)
        return self.classifier(x)


def _max_unpool(x: torch.Tensor, idx: torch.Tensor, size) -> torch.Tensor:
    """2x2 max-unpooling to ``size`` (h, w). ONNX has no export of ``max_unpool2d``: while
    exporting (vctrain.deploy.export) the same values are scattered to their per-plane argmax index."""
    if not torch.onnx.is_in_onnx_export():
        return F.max_unpool2d(x, idx, 2, 2, output_size=size)
    h, w = int(size[0]), int(size[1])
    n, c = x.shape[0], x.shape[1]
    out = torch.zeros(n, c, h * w, dtype=x.dtype, device=x.device)
    return out.scatter(2, idx.flatten(2), x.flatten(2)).reshape(n, c, h, w)
