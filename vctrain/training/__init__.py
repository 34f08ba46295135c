"""A training run, in the order it happens: the recipe, the data, the loop, the checkpoint.

===============  ======================================================================================
config           :class:`TrainConfig` (every setting declared once, ``None`` = the recipe's), the recipes,
                 :class:`AdaptSettings`
data             the training items: reading a store item or a resized frame, decoding, augmenting
trainset         a run's data: its stores, samples, validation split, working size, window, epoch order
parts            training sets of several input sizes, a batch one size's: mixed views, frames at their own aspect
loop             :func:`fit`: the loop (nanoGPT style), validation, resume, fine-tuning, torchrun
finetune         starting from a checkpoint: what --init and --resume take from it, the average with the start, L2-SP
guard            fine-tuning never worse than its start: the held-out frames, the start's score, what --out keeps
distributed      torchrun: ranks, BatchNorm statistics averaged over processes, the group's clean end
rerun            runs never lost: the same command resumes, says it is done, or keeps a model of other data aside
checkpoint       self-describing checkpoints: everything predict and eval need to rebuild the model
checkpoint_data  the checkpoint's ``data`` section typed (:class:`CheckpointData`), read once where a model is loaded
outputs          a model's outputs, one per label definition (road, drivable), and the set-valued loss
===============  ======================================================================================

The networks it trains are :mod:`vctrain.networks`; ``vctrain fit`` is its command.
"""
from __future__ import annotations

from ..lazy import lazy_face

# Each name's module. The face loads a module on first use of one of its names (PEP 562): the
# commands' options take their defaults from TrainConfig (config.py, no torch), so `vctrain --help`
# and `vctrain eval` start without importing torch (about 1.5 s a process).
_HOME = {
    "config": ("TrainConfig", "RECIPES", "DEFAULT_RECIPE", "SCHEDULES", "OPTIMIZERS", "BALANCES", "TRAIN_WINDOW",
               "AdaptSettings", "ADAPT_EPOCHS", "ADAPT_LR_FACTOR", "RUN_ONLY", "VAL_FRACTION"),
    "data": ("Sample", "RoadDataset", "store_samples", "resize_samples", "source_focal", "to_input", "vp_proximity",
             "vp_in_store", "ray_angles", "resize_pair", "class_frequencies", "median_frequency_weights"),
    "trainset": ("BASELINES", "MIN_SIDE", "prepare_data",
                 "training_magnification", "crop_size", "epoch_order", "training_sets", "label_shares", "check_labels",
                 "sequence_of", "sequence_items"),
    "parts": ("Parts", "MixedViews", "AspectParts", "resize_working_size", "view_batches"),
    "loop": ("fit", "evaluate", "get_lr", "resolve_device", "resolve_recipe"),
    "guard": ("score_start", "say_plan", "keeps", "verdict", "finetune_record", "settle"),
    "rerun": ("request_of", "data_files", "data_stamp", "data_change", "keep_aside", "log_path", "rerun_plan"),
    "checkpoint": ("CKPT_FORMAT", "CKPT_VERSION", "save_checkpoint", "load_checkpoint", "model_from_checkpoint",
                   "last_path"),
    "checkpoint_data": ("CheckpointData",),
    "outputs": ("ONE_OUTPUT", "TWO_OUTPUTS", "CLASS_SETS", "parse_outputs", "outputs_of", "check_output", "encode",
                "set_cross_entropy", "loss_of", "output_probability", "output_probability_np"),
}
__all__, __getattr__, __dir__ = lazy_face(__name__, _HOME, globals())
