"""Pieces several network families share: conv-BN-ReLU, Kaiming initialisation, per-image
channel standardisation."""
from __future__ import annotations

import torch
from torch import nn

__all__ = ["conv_bn_relu", "kaiming", "standardised"]


def conv_bn_relu(cin: int, cout: int, stride: int = 1) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, 3, stride, padding=1, bias=False), nn.BatchNorm2d(cout),
                         nn.ReLU(inplace=True))


def kaiming(modules) -> None:
    for m in modules:
        if isinstance(m, nn.Conv2d):
            nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="relu")
            if m.bias is not None:
                nn.init.zeros_(m.bias)


def standardised(c: torch.Tensor) -> torch.Tensor:
    """Each image's channels of ``c`` (N, C, H, W) at zero mean and unit variance (std floored at 0.01)."""
    return (c - c.mean((2, 3), keepdim=True)) / c.std((2, 3), keepdim=True).clamp_min(1e-2)
