"""The segmentation networks: the paper's SegNet, a narrow SegNet, ``resfpn`` and ``lite0fpn``.

``segnet``: the VGG16 encoder-decoder with max-unpooling indices (Badrinarayanan et al.), as used by
the VCSeg paper, plus ``segnet-narrow``, a narrow variant of the same topology.

Topology (both variants): 5 encoder blocks of 2, 2, 3, 3, 3 conv3x3-BN-ReLU layers (the 13 conv
layers of VGG16) each followed by 2x2 max pooling that remembers its argmax indices; 5 mirrored
decoder blocks that max-unpool with those indices and apply 3, 3, 3, 2, 2 conv3x3-BN-ReLU layers;
a final 3x3 conv to ``num_classes`` logits. Widths per block are ``base_width * (1, 2, 4, 8, 8)``:
``segnet`` = 64 (the paper's network, 29 M parameters), ``segnet-narrow`` = 16 (1/16 of the
FLOPs, ~1.8 M parameters; the default when no GPU is present).

``resfpn`` (the default without a GPU): each image's colour channels standardised (zero mean, unit
variance per image and channel: exposure, contrast and white balance differ between cameras),
then a ResNet-style encoder (a stride-2 stem, then four
stages of two residual BasicBlocks at 1/4 ... 1/32, widths ``base_width * (2, 4, 8, 8)``) with a
light feature-pyramid decoder (1x1 lateral projections summed top-down with bilinear upsampling,
one 3x3 conv per level, global-average context added at 1/32) that predicts at 1/4 and upsamples
the logits bilinearly. Skip connections and residual blocks train in minutes where SegNet's
unpooling decoder needs hundreds of epochs; most of its work runs at 1/4 resolution or below,
so it is about 6x faster per image than segnet-narrow on a CPU (benchmarks/real_cameras.py).

``lite0fpn``: the ImageNet-pretrained EfficientNet-Lite0 encoder (vctrain.efficientnet: stem and 16
MBConv blocks, its features at 1/4, 1/8, 1/16 and 1/32, 24/40/112/320 channels) with resfpn's decoder
(width ``2 * base_width``), 3.0 M parameters. The project's input (BGR in [-1, 1]) is turned into the
weights' convention (RGB, ``(x - 127) / 128``) inside the network; no per-image standardisation (the
pretrained statistics expect the colours as they are). Extra input channels (the VP channel) start
at zero weight in the stem. :func:`build_model` gives it random weights; training loads the ImageNet
weights (``pretrained``, vctrain.train), a checkpoint its own. ``lite0fpn-std`` (issue 53's test of
the colour suspect): the same network, each image's colour channels standardised as resfpn's and
then given ImageNet's per-channel mean and standard deviation in the weights' convention.

Shapes (all): input (N, in_channels, H, W) float, output (N, num_classes, H, W) logits, for any
H, W (odd sizes: SegNet unpools to the exact pre-pooling size, resfpn interpolates to it).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import nn
from torch.nn import functional as F
from torch.nn.utils.fusion import fuse_conv_bn_eval

from vcprep.errors import InputError

from .efficientnet import FEATURE_WIDTHS, EfficientNetLite0, from_project_input

__all__ = ["ModelArgs", "SegNet", "ResFPN", "Lite0FPN", "ARCHITECTURES", "PRETRAINED", "build_model",
           "model_args_for", "resolve_pretrained", "fold_batchnorm"]

ARCHITECTURES = {"segnet": 64, "segnet-narrow": 16, "resfpn": 16, "lite0fpn": 16, "lite0fpn-std": 16}  # -> base width
PRETRAINED = ("lite0fpn", "lite0fpn-std")  # architectures whose encoder starts from ImageNet weights (unless --no-pretrained)
# lite0fpn-std: each image's colour channels standardised (as resfpn's), then given ImageNet's mean and
# standard deviation per channel in the weights' convention ((x - 127) / 128, RGB): every image reaches
# the encoder with the colour statistics its weights were trained on, whatever the camera's exposure
IMAGENET_MEAN = tuple((255 * m - 127) / 128 for m in (0.485, 0.456, 0.406))
IMAGENET_STD = tuple(255 * s / 128 for s in (0.229, 0.224, 0.225))
_ENC_LAYERS = (2, 2, 3, 3, 3)  # VGG16's 13 conv layers
_WIDTH_MULT = (1, 2, 4, 8, 8)


@dataclass(frozen=True)
class ModelArgs:
    """Everything needed to rebuild the network (stored in every checkpoint)."""

    arch: str = "segnet-narrow"  # 'segnet', 'segnet-narrow' (same topology, other widths), 'resfpn' or 'lite0fpn'
    base_width: int = 16         # channels of the first block (lite0fpn: half the decoder's); 64 = the paper's SegNet
    in_channels: int = 3         # 3 (colour) or 4 (colour + VP proximity map)
    num_classes: int = 2         # 0 = not road, 1 = road

    def to_dict(self) -> dict:
        return asdict(self)


def model_args_for(arch: str, in_channels: int = 3, base_width: int | None = None) -> ModelArgs:
    if arch not in ARCHITECTURES:
        raise ValueError(f"unknown architecture '{arch}'")
    return ModelArgs(arch=arch, base_width=int(base_width or ARCHITECTURES[arch]), in_channels=int(in_channels))


def _conv_bn_relu(cin: int, cout: int, stride: int = 1) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, 3, stride, padding=1, bias=False), nn.BatchNorm2d(cout),
                         nn.ReLU(inplace=True))


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
        _kaiming(self.modules())

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


class _FPN(nn.Module):
    """The feature-pyramid decoder resfpn and lite0fpn share: 1x1 lateral projections summed top-down
    with bilinear upsampling, one 3x3 conv-BN-ReLU per level, global-average context added at the
    coarsest level, logits at the finest upsampled to the input (attribute names kept: checkpoints)."""

    def _decoder(self, widths, dec: int, num_classes: int) -> None:
        self.lateral = nn.ModuleList(nn.Conv2d(w, dec, 1) for w in widths)
        self.context = nn.Conv2d(widths[-1], dec, 1)
        self.smooth = nn.ModuleList(_conv_bn_relu(dec, dec) for _ in widths[:-1])
        self.classifier = nn.Conv2d(dec, num_classes, 1)

    def _decode(self, feats: list[torch.Tensor], size) -> torch.Tensor:
        p = self.lateral[-1](feats[-1]) + self.context(feats[-1].mean((2, 3), keepdim=True))
        for i in reversed(range(len(feats) - 1)):
            up = F.interpolate(p, size=feats[i].shape[-2:], mode="bilinear", align_corners=False)
            p = self.smooth[i](up + self.lateral[i](feats[i]))
        return F.interpolate(self.classifier(p), size=size, mode="bilinear", align_corners=False)


def _kaiming(modules) -> None:
    for m in modules:
        if isinstance(m, nn.Conv2d):
            nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="relu")
            if m.bias is not None:
                nn.init.zeros_(m.bias)


class ResFPN(_FPN):
    """Residual encoder + feature-pyramid decoder; see the module docstring."""

    def __init__(self, args: ModelArgs = ModelArgs(arch="resfpn")):
        super().__init__()
        self.args = args
        b = args.base_width
        widths = [2 * b, 4 * b, 8 * b, 8 * b]   # stages at 1/4, 1/8, 1/16, 1/32
        self.stem = nn.Sequential(_conv_bn_relu(args.in_channels, b, 2), _conv_bn_relu(b, b))  # 1/2
        self.stages = nn.ModuleList()
        cin = b
        for w in widths:
            self.stages.append(nn.Sequential(_BasicBlock(cin, w, 2), _BasicBlock(w, w)))
            cin = w
        self._decoder(widths, 2 * b, args.num_classes)
        _kaiming(self.modules())
        for blk in self.modules():  # zero-init the last BN of each residual branch (Goyal et al.)
            if isinstance(blk, _BasicBlock):
                nn.init.zeros_(blk.bn2.weight)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        size = x.shape[-2:]
        # exposure, contrast and white balance differ between cameras (and CamVid's own sequences:
        # 0001TP is at dusk)
        x = torch.cat([_standardised(x[:, :3]), x[:, 3:]], 1)
        feats = []
        x = self.stem(x)
        for stage in self.stages:
            x = stage(x)
            feats.append(x)
        return self._decode(feats, size)


def _standardised(c: torch.Tensor) -> torch.Tensor:
    """Each image's channels of ``c`` (N, C, H, W) at zero mean and unit variance (std floored at 0.01)."""
    return (c - c.mean((2, 3), keepdim=True)) / c.std((2, 3), keepdim=True).clamp_min(1e-2)


class Lite0FPN(_FPN):
    """EfficientNet-Lite0 encoder + resfpn's decoder; see the module docstring."""

    def __init__(self, args: ModelArgs = ModelArgs(arch="lite0fpn")):
        super().__init__()
        self.args = args
        self.standardise = args.arch == "lite0fpn-std"
        self.encoder = EfficientNetLite0(args.in_channels)
        self._decoder(FEATURE_WIDTHS, 2 * args.base_width, args.num_classes)
        _kaiming(m for name, m in self.named_modules() if not name.startswith("encoder"))

    def load_pretrained(self) -> None:
        """The encoder's ImageNet weights (vctrain.efficientnet.pretrained_state)."""
        self.encoder.load_pretrained()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        size = x.shape[-2:]
        x = from_project_input(x)
        if self.standardise:  # (lite0fpn-std: ImageNet's colour statistics for every image)
            z = _standardised(x[:, :3])
            mean = torch.tensor(IMAGENET_MEAN, dtype=x.dtype, device=x.device).view(1, 3, 1, 1)
            std = torch.tensor(IMAGENET_STD, dtype=x.dtype, device=x.device).view(1, 3, 1, 1)
            x = torch.cat([z * std + mean, x[:, 3:]], 1)
        return self._decode(self.encoder.features(x), size)


def resolve_pretrained(arch: str, asked: bool | None) -> bool:
    """Whether a fresh ``arch`` starts from ImageNet weights: ``asked`` (``--pretrained/--no-pretrained``),
    or by default where the architecture has them (:data:`PRETRAINED`); asking for weights an
    architecture does not have is an InputError."""
    if asked is None:
        return arch in PRETRAINED
    if asked and arch not in PRETRAINED:
        raise InputError(f"model '{arch}' has no pretrained weights", None,
                         f"use --model {' or '.join(PRETRAINED)}, or leave --pretrained out")
    return bool(asked)


def fold_batchnorm(model: nn.Module) -> nn.Module:
    """``model`` (in eval mode) with every BatchNorm folded into the convolution before it, in place:
    the conv's weight scaled by gamma / sqrt(var + eps) per output channel and a bias added, the BN
    replaced by ``nn.Identity`` (the same function to float rounding, one pass over each feature map
    fewer: about a fifth of lite0fpn's time on a CPU). A pair is a Conv2d followed by the BatchNorm2d
    registered right after it in the same module, which is how every network here applies them.
    For prediction only: the folded model has no batch statistics to train."""
    if model.training:
        raise ValueError("fold_batchnorm: put the model in eval mode first")
    for module in list(model.modules()):
        kids = list(module.named_children())
        for (conv_name, conv), (bn_name, bn) in zip(kids, kids[1:]):
            if isinstance(conv, nn.Conv2d) and isinstance(bn, nn.BatchNorm2d):
                setattr(module, conv_name, fuse_conv_bn_eval(conv, bn))
                setattr(module, bn_name, nn.Identity())
    return model


def build_model(args: ModelArgs | dict) -> nn.Module:
    if isinstance(args, dict):
        args = ModelArgs(**args)
    if args.arch in ("lite0fpn", "lite0fpn-std"):
        return Lite0FPN(args)
    return ResFPN(args) if args.arch == "resfpn" else SegNet(args)
