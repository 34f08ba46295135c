"""A training run, in the order it happens: the recipe, the data, the loop, the checkpoint.

==========  ==========================================================================================
config      :class:`TrainConfig` (every setting declared once, ``None`` = the recipe's), the recipes,
            :class:`AdaptSettings`
data        the training items: reading a store item or a resized frame, decoding, augmenting
trainset    a run's data: its stores, samples, validation split, working size, window, epoch order
loop        :func:`fit`: the loop (nanoGPT style), validation, resume, fine-tuning, torchrun
checkpoint  self-describing checkpoints: everything predict and eval need to rebuild the model
==========  ==========================================================================================

The networks it trains are :mod:`vctrain.networks`; ``vctrain fit`` is its command.
"""
from __future__ import annotations

from .checkpoint import CKPT_FORMAT, CKPT_VERSION, load_checkpoint, model_from_checkpoint, save_checkpoint
from .config import (ADAPT_EPOCHS, ADAPT_LR_FACTOR, BALANCES, DEFAULT_RECIPE, OPTIMIZERS, RECIPES, SCHEDULES,
                     TRAIN_WINDOW, AdaptSettings, TrainConfig)
from .data import (RoadDataset, Sample, class_frequencies, median_frequency_weights, ray_angles, resize_pair,
                   resize_samples, source_focal, store_samples, to_input, vp_in_store, vp_proximity)
from .loop import evaluate, fit, get_lr, last_path, resolve_device, resolve_recipe
from .trainset import (BASELINES, MIN_SIDE, MixedViews, crop_size, epoch_order, prepare_data, resize_working_size,
                       training_sets, view_batches)

__all__ = ["TrainConfig", "RECIPES", "DEFAULT_RECIPE", "SCHEDULES", "OPTIMIZERS", "BALANCES", "TRAIN_WINDOW",
           "AdaptSettings", "ADAPT_EPOCHS", "ADAPT_LR_FACTOR",
           "Sample", "RoadDataset", "store_samples", "resize_samples", "source_focal", "to_input", "vp_proximity",
           "vp_in_store", "ray_angles", "resize_pair", "class_frequencies", "median_frequency_weights",
           "BASELINES", "MIN_SIDE", "MixedViews", "view_batches", "prepare_data", "resize_working_size", "crop_size",
           "epoch_order", "training_sets",
           "fit", "evaluate", "get_lr", "resolve_device", "resolve_recipe", "last_path",
           "CKPT_FORMAT", "CKPT_VERSION", "save_checkpoint", "load_checkpoint", "model_from_checkpoint"]
