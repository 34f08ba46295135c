"""The settings of a training run and of an adaptation, declared once (no torch import here).

:class:`TrainConfig` is what ``vctrain fit`` builds from its options, what a study's ``train:``
section may set (:data:`vctrain.study.TRAIN_KEYS` derives from its fields) and what a checkpoint
records; :data:`RECIPES` fill the fields left at ``None`` (:func:`vctrain.training.resolve_recipe`).
:class:`AdaptSettings` are the settings of :func:`vctrain.adapt.adapt` (``vctrain adapt``).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Optional

__all__ = ["TrainConfig", "TRAIN_WINDOW", "RECIPES", "DEFAULT_RECIPE", "SCHEDULES", "OPTIMIZERS", "BALANCES", "AdaptSettings", "ADAPT_EPOCHS",
           "ADAPT_LR_FACTOR", "VAL_SPLITS", "RUN_ONLY", "FINETUNE_FREEZE_BN",
           "FINETUNE_AVERAGE_INIT", "FINETUNE_FREEZE_ENCODER", "FINETUNE_L2SP", "VAL_FRACTION", "FINETUNE_VAL_FRACTION"]

# full-height training windows of 4/9 of the working width: the measured best design (a crossval study's
# and the cpu recipe's default; 76800 px a step at 172800-px stores)
TRAIN_WINDOW = (4 / 9, 1.0)
# recipe -> the defaults it gives every TrainConfig field left at None (vctrain.training.loop's docstring)
RECIPES: dict[str, dict[str, Any]] = {
    "paper": {"arch": "segnet", "epochs": 30, "batch_size": 8, "optimizer": "sgd", "lr": 0.005, "momentum": 0.9,
              "weight_decay": 0.0005, "schedule": "poly", "hflip": False, "scale_aug": 0.0, "shift_aug": 0.0,
              "color_aug": 0.0, "shading_aug": 0.0, "balance": "items"},
    "cpu": {"arch": "resfpn", "epochs": 20, "batch_size": 8, "optimizer": "adamw", "lr": 0.002, "momentum": 0.9,
            "weight_decay": 0.01, "schedule": "cosine", "hflip": True, "scale_aug": 0.25, "shift_aug": 0.05,
            "color_aug": 0.3, "shading_aug": 0.0, "crop": TRAIN_WINDOW, "balance": "items"},
}
# several cameras merged (the shipped model's recipe, benchmarks/what_a_user_gets/shipped_model.py): the cpu recipe with the
# ImageNet-pretrained lite0fpn (on the shipped model's six held-out splits 81.3 against resfpn's 78.3 at
# four times the steps, every split higher), every store an equal share of each epoch, lens-shading colour
# fields (issue 44: LUMS's near field), 30 epochs (issue 53)
RECIPES["multicamera"] = {**RECIPES["cpu"], "arch": "lite0fpn", "epochs": 30, "shading_aug": 0.4,
                          "balance": "datasets"}
# the default on every device, a GPU included: every benchmark of the project was measured with it (on an H100
# too, issue 44); 'paper' (the paper's segnet, SGD, no augmentation) has no measurement behind it and is on request
DEFAULT_RECIPE = "cpu"
SCHEDULES = ("poly", "cosine", "constant")
OPTIMIZERS = ("sgd", "adamw")
# how an epoch draws from several training stores (vctrain.training.trainset.epoch_order): 'items' every item
# once (a store's share is its size), 'datasets' every store equally often (small ones repeated)
BALANCES = ("items", "datasets")


@dataclass
class TrainConfig:
    """All settings of a training run (saved in the checkpoint)."""

    stores: list[str] = field(default_factory=list)  # training stores (one virtual camera and scale)
    out: str = "model.pt"              # best checkpoint; '<stem>.last.pt' beside it is the latest epoch
    baseline: str = "none"             # 'none': train on the stores; 'resize': original images resized;
                                       # 'mixed': both views of every store frame (vctrain.training.trainset.MixedViews)
    images: Optional[str] = None       # baseline from folders instead of stores: image folder
    labels: Optional[str] = None       #   ... label folder
    label_format: Optional[str] = None  #  ... label format (camvid, kitti, values:road=..)
    recipe: Optional[str] = None       # 'cpu' | 'multicamera' | 'paper' (vctrain.training.loop); None: DEFAULT_RECIPE
    arch: Optional[str] = None         # 'resfpn' | 'lite0fpn' | 'segnet' | 'segnet-narrow'; None: the recipe's
    base_width: Optional[int] = None   # override the architecture's first-block width
    pretrained: Optional[bool] = None  # start the encoder from ImageNet weights (lite0fpn); None: yes where the
                                       # architecture has them (vctrain.networks.PRETRAINED), no elsewhere
    size: Optional[tuple[int, int]] = None  # working size (w, h); None: the store size (first image for folders)
    crop: Optional[Any] = None         # training window: (w, h) pixels (ints), a share of each side (float) or
                                       # of width and height (two floats); 1.0: the whole image; None: the
                                       # recipe's (cpu: TRAIN_WINDOW; paper: the whole image). Validation and
                                       # prediction always see the image whole
    epochs: Optional[int] = None       # None: the recipe's (the paper trains 600 on a GPU)
    batch_size: Optional[int] = None   # global batch (paper Table 2: 8)
    optimizer: Optional[str] = None    # 'sgd' (momentum) | 'adamw'
    lr: Optional[float] = None         # peak learning rate
    momentum: Optional[float] = None   # SGD momentum (AdamW: beta1)
    weight_decay: Optional[float] = None  # L2 (SGD) or decoupled (AdamW) weight decay
    schedule: Optional[str] = None     # 'poly' (power 0.9), 'cosine' (with warm-up) or 'constant'
    scale_aug: Optional[float] = None  # random scale in [1/(1+a), 1+a] about the VP (0: off)
    shift_aug: Optional[float] = None  # random shift up to this share of the width/height
    color_aug: Optional[float] = None  # photometric jitter strength (0: off)
    shading_aug: Optional[float] = None  # colour shading: smooth per-channel log-gain field up to +-this (0: off)
    seed: int = 0                      # seeds init, split, order and augmentation
    device: str = "auto"               # 'auto' (cuda if present), 'cpu', 'cuda', 'cuda:1'
    val_fraction: Optional[float] = None  # held-out share of the training items (0: none); None: VAL_FRACTION,
                                       # with init FINETUNE_VAL_FRACTION
    val_split: str = "auto"            # which items: 'random' (seeded), 'block' (the last share of each source's
                                       # items in name order: whole drives or a stretch of one, not neighbours
                                       # of training frames) or 'auto' (block with init, random without)
    val_stores: list[str] = field(default_factory=list)  # validation stores (replace val_fraction)
    val_images: Optional[str] = None   # resize baseline: validation frames (with val_labels, in label_format;
    val_labels: Optional[str] = None   #   replace val_fraction): e.g. a few of the light the model will see
    class_weights: str = "none"        # 'none' or 'median-freq' (median frequency balancing; one output only)
    outputs: str = "road"              # 'road' (2 classes, P(road)) or 'road,drivable' (3 classes: each dataset
                                       # supervises the output of its label format's definition; training/outputs.py)
    hflip: Optional[bool] = None       # random horizontal flip, p = 0.5
    greyscale: float = 0.0             # probability of a greyscale image (1.0: greyscale model)
    vp_channel: bool = False           # 4th input channel: VP proximity map
    ray_channels: bool = False         # 2 more input channels: each pixel's ray angles beside/below the road VP
    resume: Optional[str] = None       # continue from this checkpoint ('.last.pt') up to `epochs`
    init: Optional[str] = None         # start from this checkpoint's network and weights (fine-tuning, vctrain adapt)
    freeze_bn: Optional[bool] = None   # keep BatchNorm's running statistics fixed (layers in eval mode while
                                       # training); None: FINETUNE_FREEZE_BN with init, no without
    freeze_encoder: Optional[bool] = None  # train the decoder only: the encoder's weights and BatchNorm statistics
                                       # stay the starting model's; None: FINETUNE_FREEZE_ENCODER with init, no without
    average_init: Optional[float] = None  # with init: the checkpoint holds A x the init's weights + (1 - A) x the
                                       # trained ones (WiSE-FT); None: FINETUNE_AVERAGE_INIT with init, 0 without
    l2sp: Optional[float] = None       # with init: loss + l2sp/2 x the squared distance of the weights from the start's
                                       # (L2-SP, Li et al. 2018); None: FINETUNE_L2SP with init, 0 without
    force_labels: bool = False         # train on labels whose road makes no sense under label_format (refused otherwise)
    workers: int = 0                   # DataLoader worker processes
    log: Optional[str] = None          # JSON-lines log; None: '<out stem>.log.jsonl'
    progress: bool = True              # tqdm bar on stderr
    max_steps: Optional[int] = None    # stop each epoch after this many steps (smoke tests)
    balance: Optional[str] = None      # 'items': each training item once an epoch; 'datasets': each training
                                       # store (and the --images folder) drawn equally often (BALANCES); None:
                                       # the recipe's (multicamera: datasets; cpu, paper: items)
    keep_aspect: bool = False          # resize baseline: every frame at the working size's pixel count at its own
                                       # aspect, a batch frames of one such size (training/parts.py; its windows the
                                       # crop's share of that size); prediction sizes each frame the same way. False:
                                       # every frame squashed to the working size (issue 82's pixel budget of wide frames)

    @property
    def in_channels(self) -> int:
        """The network's input channels: colour, the VP map, the two ray angles."""
        return 3 + int(bool(self.vp_channel)) + 2 * int(bool(self.ray_channels))

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["size"] = list(self.size) if self.size else None
        return d


# settings of how a run runs, not of what it trains: a rerun that differs only in these is the same run
# (vctrain.training.rerun)
RUN_ONLY = ("progress", "resume", "workers", "device", "log")
VAL_SPLITS = ("auto", "random", "block", "sequence")
VAL_FRACTION = 0.1  # a run's validation share unless set
FINETUNE_VAL_FRACTION = 0.2  # fit --init's held-out share: the starting model is scored on it before the first epoch,
                             # and the trained one replaces it only with a higher score there (vctrain.training.guard)
FINETUNE_FREEZE_BN = True  # fit --init's default for freeze_bn: issue 72's screening (finetune_guard.py, seed 0, 60 frames,
                           # 4 epochs) gained more on a camera never seen (+4.8 against +2.7) and lost less on another
                           # drive of a known one (-0.1 against -0.4); L2-SP 0.1 lost more (-0.7)
FINETUNE_FREEZE_ENCODER = True  # fit --init's default for freeze_encoder: issue 72 (finetune_guard.py, 3 seeds): another
                                # drive in other light -0.03 (worst -0.09) with 20 frames against -0.31 (-0.38) when the
                                # encoder learns too; a camera never seen +6.5 (worst +6.4) with 60 frames against +7.2
FINETUNE_L2SP = 0.0  # fit --init's default for l2sp (benchmarks/what_a_user_gets/finetune_guard.py)
FINETUNE_AVERAGE_INIT = 0.5  # fit --init's default for average_init: WiSE-FT's (benchmarks/what_a_user_gets/own_frames.py)

ADAPT_EPOCHS = 5       # a short fine-tune
ADAPT_LR_FACTOR = 0.1  # of the model's own training learning rate (vctrain adapt; vctrain fit --init without --lr)


@dataclass(frozen=True)
class AdaptSettings:
    """How :func:`vctrain.adapt.adapt` fine-tunes a model on unlabelled images (its module docstring)."""

    lo: float = 0.25                   # surrogate 'not road' where the (fused) probability is below this
    hi: float = 0.75                   # surrogate 'road' where it is above this
    combine: str = "prior"             # 'prior' (the prior's tri-mask, paper §4.5) | 'fuse' (with the model's own)
                                       # | 'self' (the model's own alone: the control without the prior)
    epochs: int = ADAPT_EPOCHS         # fine-tuning epochs
    lr: Optional[float] = None         # None: ADAPT_LR_FACTOR times the model's own learning rate
    store: Optional[Path] = None       # store of the warped target images; None: OUT-stem.store
    within: str = "auto"               # per-image VP correction: auto (as trained), estimate, a CSV, none
    device: str = "auto"               # 'auto', 'cpu', 'cuda', 'cuda:N'
    seed: Optional[int] = None         # None: the model's
    batch_size: Optional[int] = None   # None: the model's
    max_steps: Optional[int] = None    # stop each epoch after this many steps (smoke tests)
    progress: bool = True              # progress bars and epoch lines on stderr
