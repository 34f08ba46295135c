"""The residual family: ``resfpn`` (the default without a GPU).

Each image's colour channels standardised (zero mean, unit variance per image and channel: exposure,
contrast and white balance differ between cameras), then a ResNet-style encoder (a stride-2 stem,
then four stages of two residual BasicBlocks at 1/4 ... 1/32, widths ``base_width * (2, 4, 8, 8)``)
with the feature-pyramid decoder (vctrain.networks.fpn) that predicts at 1/4 and upsamples the logits
bilinearly. Skip connections and residual blocks train in minutes where SegNet's unpooling decoder
needs hundreds of epochs; most of its work runs at 1/4 resolution or below, so it is about 6x faster
per image than segnet-narrow on a CPU (benchmarks/archive/other_cameras/real_cameras.py).

Shapes: input (N, in_channels, H, W) float, output (N, num_classes, H, W) logits, for any H, W.
"""
from __future__ import annotations

import torch
from torch import nn
from torch.nn import functional as F

from .args import ModelArgs
from .fpn import FPN
from .layers import conv_bn_relu, kaiming, standardised

__all__ = ["ResFPN"]


class _BasicBlock(nn.Module):
    """ResNet's BasicBlock: two 3x3 conv-BN with an identity (or 1x1 projection) shortcut."""

    def __init__(self, cin: int, cout: int, stride: int = 1):
        super().__init__()
        self.conv1 = nn.Conv2d(cin, cout, 3, stride, 1, bias=False)
        self.bn1 = nn.BatchNorm2d(cout)
        self.conv2 = nn.Conv2d(cout, cout, 3, 1, 1, bias=False)
        self.bn2 = nn.BatchNorm2d(cout)
        self.shortcut = None
        if stride != 1 or cin != cout:
            self.shortcut = nn.Sequential(nn.Conv2d(cin, cout, 1, stride, bias=False), nn.BatchNorm2d(cout))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = F.relu(self.bn1(self.conv1(x)), inplace=True)
        y = self.bn2(self.conv2(y))
        return F.relu(y + (x if self.shortcut is None else self.shortcut(x)), inplace=True)


class ResFPN(FPN):
    """Residual encoder + feature-pyramid decoder; see the module docstring."""

    def __init__(self, args: ModelArgs = ModelArgs(arch="resfpn")):
        super().__init__()
        self.args = args
        b = args.base_width
        widths = [2 * b, 4 * b, 8 * b, 8 * b]   # stages at 1/4, 1/8, 1/16, 1/32
        self.stem = nn.Sequential(conv_bn_relu(args.in_channels, b, 2), conv_bn_relu(b, b))  # 1/2
        self.stages = nn.ModuleList()
        cin = b
        for w in widths:
            self.stages.append(nn.Sequential(_BasicBlock(cin, w, 2), _BasicBlock(w, w)))
            cin = w
        self._decoder(widths, 2 * b, args.num_classes)
        kaiming(self.modules())
        for blk in self.modules():  # zero-init the last BN of each residual branch (Goyal et al.)
            if isinstance(blk, _BasicBlock):
                nn.init.zeros_(blk.bn2.weight)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        size = x.shape[-2:]
        # exposure, contrast and white balance differ between cameras (and CamVid's own sequences:
        # 0001TP is at dusk)
        x = torch.cat([standardised(x[:, :3]), x[:, 3:]], 1)
        feats = []
        x = self.stem(x)
        for stage in self.stages:
            x = stage(x)
            feats.append(x)
        return self._decode(feats, size)
