"""The feature-pyramid decoder ``resfpn`` and ``lite0fpn`` share (their encoders: vctrain.networks.resnet,
.efficientnet).

1x1 lateral projections of the encoder's features (1/4 ... 1/32) summed top-down with bilinear
upsampling, one 3x3 conv-BN-ReLU per level, global-average context added at the coarsest level;
logits at 1/4, upsampled bilinearly to the input's (H, W).
"""
from __future__ import annotations

import torch
from torch import nn
from torch.nn import functional as F

from .layers import conv_bn_relu

__all__ = ["FPN"]


class FPN(nn.Module):
    """The feature-pyramid decoder resfpn and lite0fpn share: 1x1 lateral projections summed top-down
    with bilinear upsampling, one 3x3 conv-BN-ReLU per level, global-average context added at the
    coarsest level, logits at the finest upsampled to the input (attribute names kept: checkpoints)."""

    def _decoder(self, widths, dec: int, num_classes: int) -> None:
        self.lateral = nn.ModuleList(nn.Conv2d(w, dec, 1) for w in widths)
        self.context = nn.Conv2d(widths[-1], dec, 1)
        self.smooth = nn.ModuleList(conv_bn_relu(dec, dec) for _ in widths[:-1])
        self.classifier = nn.Conv2d(dec, num_classes, 1)

    def _decode(self, feats: list[torch.Tensor], size) -> torch.Tensor:
        p = self.lateral[-1](feats[-1]) + self.context(feats[-1].mean((2, 3), keepdim=True))
        for i in reversed(range(len(feats) - 1)):
            up = F.interpolate(p, size=feats[i].shape[-2:], mode="bilinear", align_corners=False)
            p = self.smooth[i](up + self.lateral[i](feats[i]))
        return F.interpolate(self.classifier(p), size=size, mode="bilinear", align_corners=False)
