"""A network from its :class:`~vctrain.networks.args.ModelArgs`, whether it starts from ImageNet
weights, and the network made ready for prediction (BatchNorm folded)."""
from __future__ import annotations

from torch import nn
from torch.nn.utils.fusion import fuse_conv_bn_eval

from vcprep.errors import InputError

from .args import PRETRAINED, ModelArgs
from .efficientnet import Lite0FPN
from .resnet import ResFPN
from .segnet import SegNet

__all__ = ["build_model", "resolve_pretrained", "fold_batchnorm", "encoder_modules"]

ENCODER_PARTS = ("encoder", "stem", "stages", "encoders")  # lite0fpn's; resfpn's; segnet's


def encoder_modules(model: nn.Module) -> list[nn.Module]:
    """The network's encoder (what ImageNet features or a first training learnt; the rest is the
    decoder): ``encoder`` (lite0fpn), ``stem`` and ``stages`` (resfpn), ``encoders`` (segnet)."""
    parts = [getattr(model, k) for k in ENCODER_PARTS if isinstance(getattr(model, k, None), nn.Module)]
    if not parts:
        raise InputError(f"{type(model).__name__} has no encoder to freeze", None, "leave --freeze-encoder out")
    return parts


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
    if args.arch in PRETRAINED:  # the EfficientNet-Lite family
        return Lite0FPN(args)
    return ResFPN(args) if args.arch == "resfpn" else SegNet(args)
