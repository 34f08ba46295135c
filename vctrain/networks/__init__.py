"""The segmentation networks, one file a family, in the order a network is put together:

============  ========================================================================================
args          :class:`ModelArgs` (what a checkpoint records to rebuild a network), ``ARCHITECTURES``
layers        pieces the families share: conv-BN-ReLU, Kaiming initialisation, standardised channels
segnet        the paper's SegNet (VGG16 encoder-decoder with unpooling indices): ``segnet``, ``segnet-narrow``
fpn           the feature-pyramid decoder of ``resfpn`` and ``lite<k>fpn``
resnet        the residual encoder and ``resfpn`` (the default without a GPU)
efficientnet  the ImageNet-pretrained EfficientNet-Lite0/1/2 encoders, their weights, ``lite<k>fpn``
build         a network from its arguments, ImageNet weights or not, BatchNorm folded for prediction
============  ========================================================================================

Shapes (all): input (N, in_channels, H, W) float (BGR in [-1, 1], then any extra channels), output
(N, num_classes, H, W) logits, for any H, W. A new encoder family is a new module here with its
network, one entry in ``ARCHITECTURES`` and one branch of :func:`build_model`.
"""
from __future__ import annotations

from .args import ARCHITECTURES, PRETRAINED, ModelArgs, model_args_for
from .build import build_model, fold_batchnorm, resolve_pretrained
from .efficientnet import (FEATURE_WIDTHS, IMAGENET_MEAN, IMAGENET_STD, WEIGHTS_LICENCE, WEIGHTS_PACKAGE,
                           EfficientNetLite, EfficientNetLite0, Lite0FPN, SameConv2d, from_project_input,
                           pretrained_state, weights_path)
from .resnet import ResFPN
from .segnet import SegNet

__all__ = ["ModelArgs", "ARCHITECTURES", "PRETRAINED", "model_args_for", "build_model", "fold_batchnorm",
           "resolve_pretrained", "SegNet", "ResFPN", "Lite0FPN", "EfficientNetLite", "EfficientNetLite0", "SameConv2d",
           "FEATURE_WIDTHS", "IMAGENET_MEAN", "IMAGENET_STD", "WEIGHTS_PACKAGE", "WEIGHTS_LICENCE",
           "from_project_input", "pretrained_state", "weights_path"]
