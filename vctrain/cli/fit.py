"""``vctrain fit``: train a road segmentation network. Each option sets the TrainConfig field it
is named after (:data:`FIT_OPTION_FIELD` for the others); the defaults are TrainConfig's."""
from __future__ import annotations

from pathlib import Path
from typing import Any, List, Optional

import typer

from vcprep.cliutil import check_data_folders, count, ensure_parent, err
from vcprep.errors import InputError

from ..shipped import SHIPPED
from ..training.config import TrainConfig
from .common import (LABEL_FORMAT_HELP, TRAIN, app, command_seconds, model_arg, parse_size, path_or_json, pin_threads,
                     threads_option)

RECIPE_HELP = ("defaults of every setting below: 'cpu' (resfpn, AdamW, cosine, augmentation, full-height windows of "
               "4/9 of the width; 305 CamVid frames in about 3 min on 2 cores at the default store's 638x271), "
               "'multicamera' (several cameras merged, the shipped model's recipe: cpu with the ImageNet-pretrained "
               "lite0fpn, 30 epochs, --balance datasets, --shading-aug 0.4) or 'paper' (segnet, SGD 0.005, poly, "
               "whole images); default: cpu on every device, a GPU included")
MODEL_HELP = ("resfpn (residual encoder + FPN decoder, 1.3 M parameters, from scratch; 305 CamVid frames in about 3 min "
              "on 2 cores), lite0fpn (EfficientNet-Lite0 encoder from ImageNet weights + the same decoder, 3.0 M; about "
              "17 min, level with resfpn on other cameras: docs/training.md; lite0fpn-std: each image given ImageNet's colour "
              "statistics first), lite1fpn / lite2fpn (the larger Lite1 / Lite2 encoders, 3.8 / 4.4 M), segnet (VGG16 "
              "SegNet, 29 M) or segnet-narrow (same topology, 1/4 width, 1.8 M); default: the recipe's")
PRETRAINED_HELP = "start the encoder from its ImageNet weights (lite<k>fpn; default: yes where the model has them)"
SIZE_HELP = ("working size WxH (default: the store size; --baseline resize: the store's pixel count at the frames' "
             "own aspect)")
CROP_HELP = ("train on random windows of the working image: WxH pixels, a share of each side (0.67) or of width and "
             "height (0.44x1: full height); 1: the whole image; validation and prediction see the whole image "
             "(default: the recipe's: cpu 0.4444x1, the measured design of 'vctrain crossval'; paper: 1)")
HELP = {  # the options whose help does not fit on their line
    "out": "the checkpoint: the best epoch by validation road IoU (the last without validation; with --init the "
           "start, unless the last epoch -- averaged with the start, --average-init -- scores higher); the latest "
           "epoch goes beside it, for --resume: runs/vc.pt -> runs/vc.last.pt. The same command again resumes an "
           "interrupted run or says a finished one is done; where its frames, labels or stores changed since, the "
           "model there is kept as runs/vc.old1.pt (its log beside it) and the run trains afresh; a model of "
           "another run is refused (--overwrite)",
    "resume": "continue from the latest epoch's checkpoint (runs/vc.last.pt for --out runs/vc.pt) up to --epochs",
    "baseline": "'resize': the paper's baseline, the same network on the original images simply resized (no virtual "
                "camera); 'mixed': both views of every store frame, one network",
    "schedule": "'poly' (lr*(1-it/total)^0.9; paper), 'cosine' (3 % warm-up; cpu) or 'constant'",
    "hflip": "augment: random horizontal flip (p 0.5; cpu recipe: on)",
    "scale_aug": "augment: random scale in [1/(1+A), 1+A] about the VP (cpu: 0.25, paper: 0)",
    "shift_aug": "augment: random shift up to this share of the size (cpu: 0.05)",
    "shading_aug": "augment: lens shading, a smooth per-channel gain field exp(+-A) on half the items",
    "color_aug": "augment: brightness/contrast/gain jitter (cpu: 0.3)",
    "keep_aspect": "resize baseline: every frame at the working size's pixel count at its own aspect (KITTI's 1242x375 "
                   "not squashed to 4:3), a batch frames of one size; predict sizes frames the same way",
    "ray_channels": "two extra input channels: each pixel's ray angles beside and below the road VP, from the camera's "
                    "focal length",
    "init": "fine-tune: start from this checkpoint's weights, or a shipped model's name from any folder: shipped "
            f"(= {SHIPPED}) or another under models/ (same model, width, input channels and --baseline; "
            "a resize model's working size unless --size); a fifth of the frames is held out (--val-split "
            "sequence), the start is scored on it before the first epoch and kept unless the trained model scores "
            "higher there",
    "val_fraction": "share of the training items held out for validation (default: 0.1; with --init 0.2, the frames "
                    "the start must be beaten on; 0: every frame trains and the last epoch is kept)",
    "val_split": "which items --val-fraction holds out: 'random', 'block' (the last share of each folder or store in "
                 "name order), 'sequence' (whole sequences where the names show five or more, 0001TP_006690 -> "
                 "0001TP; by frame where fewer, e.g. KITTI's um_/umm_/uu_ or one drive: the last stretch of each; "
                 "random where every name is its own) or 'auto' (sequence with --init, else random)",
    "val_images": "resize baseline: validate on these frames instead of a share of the training ones "
                  "(replaces --val-fraction; with --init the start is kept unless the trained model scores higher "
                  "on them): frames of the light or drive the model will be used in",
    "freeze_encoder": "train the decoder only: the encoder's weights and BatchNorm statistics stay the starting "
                      "model's (default: on with --init; --no-freeze-encoder trains every layer)",
    "freeze_bn": "keep BatchNorm's running statistics fixed while training (default: on with --init, off without)",
    "average_init": "with --init: OUT holds A x the starting weights + (1 - A) x the trained ones (WiSE-FT; "
                    "validation scores that average; OUT.last.pt keeps the trained ones for --resume); default: 0.5, 0 without --init",
    "l2sp": "with --init: add L2SP/2 x the squared distance of the weights from the starting ones to the loss (L2-SP); "
            "default: 0",
    "force_labels": "train on labels whose road makes no sense under --label-format, or under the format a store's "
                    "labels were warped with (none, nearly all, or mostly above the horizon: each item's road VP row "
                    "where known, else the frame's middle), which are refused otherwise",
    "overwrite": "replace a model of another run at --out (refused otherwise), or of this run on data changed since "
                 "(kept aside as OUT-stem.old1.pt otherwise; the same command again resumes an interrupted run, or "
                 "says a finished one is done)",
    "outputs": "road (one output: P(road)) or road,drivable (two outputs, one network of three classes: each store "
               "or --label-format supervises the output of its labels' definition: drivable area for idd, bdd and a "
               "values: format given definition=drivable, road for the others; predict --output picks one); "
               "default: road",
    "balance": "several stores: 'items' (each item once an epoch) or 'datasets' (each store equally often); default: "
               "the recipe's (multicamera: datasets; cpu, paper: items)",
}
# fit's options named otherwise than the TrainConfig field they set; every other option is named as
# its field, except FIT_NOT_CONFIG (how the command runs, not what it trains), and fit takes none
# for FIT_NO_OPTION (tests/test_vctrain.py checks both ways)
FIT_OPTION_FIELD = {"model": "arch", "width": "base_width", "val_store": "val_stores", "quiet": "progress"}
FIT_NO_OPTION = ("momentum", "max_steps")
FIT_NOT_CONFIG = ("as_json", "threads", "overwrite")


def _fit_config(options: dict[str, Any]) -> TrainConfig:
    """``vctrain fit``'s parsed options as the TrainConfig they give: each option sets its field
    (:data:`FIT_OPTION_FIELD`), paths as text, WxH and --crop parsed, --quiet as ``progress``."""
    values: dict[str, Any] = {}
    for name, v in options.items():
        if name in FIT_NOT_CONFIG:
            continue
        if isinstance(v, Path):
            v = str(v)
        elif isinstance(v, list) or name in ("stores", "val_store"):
            v = [str(x) for x in v or []]
        values[FIT_OPTION_FIELD.get(name, name)] = v
    values.update(size=parse_size(values["size"]), crop=_parse_crop(values["crop"]), progress=not values["progress"])
    return TrainConfig(**values)


def _parse_crop(text: Optional[str]) -> Optional[Any]:
    """--crop: 'WxH' pixels, a share of each side ('0.67') or shares of width and height ('0.44x1')."""
    if text is None:
        return None
    parts = text.lower().replace(" ", "").split("x")
    if len(parts) == 2 and all(p.isdigit() for p in parts):
        return parse_size(text)
    try:
        shares = [float(p) for p in parts]
    except ValueError:
        shares = []
    if len(shares) in (1, 2):
        return shares[0] if len(shares) == 1 else tuple(shares)
    raise InputError(f"--crop '{text}' is neither WxH, a share nor two shares", None,
                     "use e.g. --crop 320x240, --crop 0.67 or --crop 0.44x1")


STORES_ARG = typer.Argument(None, help="training stores built by 'vcprep warp' (one virtual camera and scale)")
OUT_OPT = typer.Option(..., "--out", "-o", help=HELP["out"])
RECIPE_OPT = typer.Option(None, "--recipe", help=RECIPE_HELP)
MODEL_OPT = typer.Option(None, "--model", "-m", help=MODEL_HELP)
WIDTH_OPT = typer.Option(None, "--width", help="first-block width override (64 = segnet, 16 = narrow)")
PRETRAINED_OPT = typer.Option(None, "--pretrained/--no-pretrained", help=PRETRAINED_HELP)
BASELINE_OPT = typer.Option(TRAIN.baseline, "--baseline", help=HELP["baseline"])
IMAGES_OPT = typer.Option(None, "--images", help="baseline only: folder of original images")
LABELS_OPT = typer.Option(None, "--labels", help="baseline only: folder of their labels")
LABEL_FORMAT_OPT = typer.Option(None, "--label-format", help=f"baseline only: {LABEL_FORMAT_HELP}")
SIZE_OPT = typer.Option(None, "--size", help=SIZE_HELP)
CROP_OPT = typer.Option(None, "--crop", help=CROP_HELP)
EPOCHS_OPT = typer.Option(None, "--epochs", "-e", help="epochs (cpu recipe: 20, paper recipe: 30; the paper: 600 on a GPU)")
BATCH_SIZE_OPT = typer.Option(None, "--batch-size", "-b", help="global batch size (recipes: 8)")
OPTIMIZER_OPT = typer.Option(None, "--optimizer", help="sgd (momentum 0.9; paper) or adamw (cpu)")
LR_OPT = typer.Option(None, "--lr", help="peak learning rate (paper: 0.005, cpu: 0.002; with --init: a tenth of the checkpoint's)")
WEIGHT_DECAY_OPT = typer.Option(None, "--weight-decay", help="weight decay (paper: 0.0005, cpu: 0.01)")
SCHEDULE_OPT = typer.Option(None, "--schedule", help=HELP["schedule"])
SEED_OPT = typer.Option(TRAIN.seed, "--seed", help="seeds init, validation split, order and augmentation")
DEVICE_OPT = typer.Option(TRAIN.device, "--device", help="auto (cuda if present), cpu, cuda, cuda:N")
VAL_FRACTION_OPT = typer.Option(None, "--val-fraction", help=HELP["val_fraction"])
VAL_SPLIT_OPT = typer.Option(TRAIN.val_split, "--val-split", help=HELP["val_split"])
VAL_STORE_OPT = typer.Option(None, "--val-store", help="validation store (repeatable; replaces --val-fraction)")
VAL_IMAGES_OPT = typer.Option(None, "--val-images", help=HELP["val_images"])
VAL_LABELS_OPT = typer.Option(None, "--val-labels", help="--val-images' labels (in --label-format)")
CLASS_WEIGHTS_OPT = typer.Option(TRAIN.class_weights, "--class-weights", help="'none' or 'median-freq' (median frequency "
                                                                              "balancing; one output only)")
OUTPUTS_OPT = typer.Option(TRAIN.outputs, "--outputs", help=HELP["outputs"])
HFLIP_OPT = typer.Option(None, "--hflip/--no-hflip", help=HELP["hflip"])
SCALE_AUG_OPT = typer.Option(None, "--scale-aug", help=HELP["scale_aug"])
SHIFT_AUG_OPT = typer.Option(None, "--shift-aug", help=HELP["shift_aug"])
SHADING_AUG_OPT = typer.Option(None, "--shading-aug", help=HELP["shading_aug"])
COLOR_AUG_OPT = typer.Option(None, "--color-aug", help=HELP["color_aug"])
GREYSCALE_OPT = typer.Option(TRAIN.greyscale, "--greyscale", help="augment: probability of greyscale (1 = a greyscale model)")
VP_CHANNEL_OPT = typer.Option(TRAIN.vp_channel, "--vp-channel", help="extra input channel: the VP proximity map")
KEEP_ASPECT_OPT = typer.Option(TRAIN.keep_aspect, "--keep-aspect", help=HELP["keep_aspect"])
RAY_CHANNELS_OPT = typer.Option(TRAIN.ray_channels, "--ray-channels", help=HELP["ray_channels"])
RESUME_OPT = typer.Option(None, "--resume", help=HELP["resume"])
INIT_OPT = typer.Option(None, "--init", help=HELP["init"])
FREEZE_BN_OPT = typer.Option(None, "--freeze-bn/--no-freeze-bn", help=HELP["freeze_bn"])
FREEZE_ENCODER_OPT = typer.Option(None, "--freeze-encoder/--no-freeze-encoder", help=HELP["freeze_encoder"])
AVERAGE_INIT_OPT = typer.Option(None, "--average-init", help=HELP["average_init"])
BALANCE_OPT = typer.Option(None, "--balance", help=HELP["balance"])
L2SP_OPT = typer.Option(None, "--l2sp", help=HELP["l2sp"])
FORCE_LABELS_OPT = typer.Option(TRAIN.force_labels, "--force-labels", help=HELP["force_labels"])
OVERWRITE_OPT = typer.Option(False, "--overwrite", help=HELP["overwrite"])
WORKERS_OPT = typer.Option(TRAIN.workers, "--workers", help="data loader processes")
LOG_OPT = typer.Option(None, "--log", help="JSON-lines log, one row per epoch (default: beside OUT, runs/vc.log.jsonl)")
AS_JSON_OPT = typer.Option(False, "--json", help="print the run summary as one JSON object instead of the path")
QUIET_OPT = typer.Option(False, "--quiet", "-q", help="no progress bar or epoch lines on stderr")


@app.command("fit")
def fit_cmd(
    stores: Optional[List[Path]] = STORES_ARG, out: Path = OUT_OPT, recipe: Optional[str] = RECIPE_OPT,
    model: Optional[str] = MODEL_OPT, width: Optional[int] = WIDTH_OPT, pretrained: Optional[bool] = PRETRAINED_OPT,
    baseline: str = BASELINE_OPT, images: Optional[Path] = IMAGES_OPT, labels: Optional[Path] = LABELS_OPT,
    label_format: Optional[str] = LABEL_FORMAT_OPT, size: Optional[str] = SIZE_OPT, crop: Optional[str] = CROP_OPT,
    epochs: Optional[int] = EPOCHS_OPT, batch_size: Optional[int] = BATCH_SIZE_OPT,
    optimizer: Optional[str] = OPTIMIZER_OPT, lr: Optional[float] = LR_OPT,
    weight_decay: Optional[float] = WEIGHT_DECAY_OPT, schedule: Optional[str] = SCHEDULE_OPT, seed: int = SEED_OPT,
    device: str = DEVICE_OPT, val_fraction: Optional[float] = VAL_FRACTION_OPT, val_split: str = VAL_SPLIT_OPT,
    val_store: Optional[List[Path]] = VAL_STORE_OPT, val_images: Optional[Path] = VAL_IMAGES_OPT,
    val_labels: Optional[Path] = VAL_LABELS_OPT, class_weights: str = CLASS_WEIGHTS_OPT, outputs: str = OUTPUTS_OPT,
    hflip: Optional[bool] = HFLIP_OPT, scale_aug: Optional[float] = SCALE_AUG_OPT,
    shift_aug: Optional[float] = SHIFT_AUG_OPT, shading_aug: Optional[float] = SHADING_AUG_OPT,
    color_aug: Optional[float] = COLOR_AUG_OPT, greyscale: float = GREYSCALE_OPT, vp_channel: bool = VP_CHANNEL_OPT,
    ray_channels: bool = RAY_CHANNELS_OPT, resume: Optional[Path] = RESUME_OPT, init: Optional[Path] = INIT_OPT,
    freeze_bn: Optional[bool] = FREEZE_BN_OPT, freeze_encoder: Optional[bool] = FREEZE_ENCODER_OPT,
    average_init: Optional[float] = AVERAGE_INIT_OPT, balance: Optional[str] = BALANCE_OPT,
    keep_aspect: bool = KEEP_ASPECT_OPT,
    l2sp: Optional[float] = L2SP_OPT, force_labels: bool = FORCE_LABELS_OPT, overwrite: bool = OVERWRITE_OPT,
    workers: int = WORKERS_OPT, log: Optional[Path] = LOG_OPT, as_json: bool = AS_JSON_OPT,
    threads: Optional[int] = threads_option(), quiet: bool = QUIET_OPT,
):
    """Train a road segmentation network on virtual-camera stores (or the resize baseline).

    Cross-entropy over not road / road, label 255 ignored (--outputs road,drivable: one network with
    a road and a drivable-area output, each dataset supervising the output its labels define). Three recipes set the defaults: 'cpu'
    (the default on every device, a GPU included: resfpn, AdamW 0.002, cosine, flip/scale/shift/
    colour augmentation, full-height windows of 4/9 of the width, 20 epochs; on a store of
    'vcprep warp' with no flags, this is what 'vctrain crossval' trains for one camera),
    'multicamera' (several cameras merged, the shipped model's recipe: cpu with the ImageNet-
    pretrained lite0fpn, 30 epochs, every store an equal share of each epoch, lens-shading colour
    augmentation; add --baseline resize, which wins when cameras are merged) and 'paper' (on
    request: segnet, SGD 0.005 momentum 0.9, weight decay 0.0005, batch 8, poly decay); any option
    given wins. The checkpoint describes itself (model, config, virtual camera, scale, completion,
    metrics), so predict and eval need no repeated flags. Prints the checkpoint path; OUT's folder
    is created. The same command again resumes an interrupted run, or says a finished one is done;
    where the frames, labels or stores changed since, the model at OUT and its log are kept beside it
    (runs/vc.old1.pt, the name printed) and the run trains afresh; a model of another run at OUT is
    refused (--overwrite). --init (fine-tuning) holds out a fifth of the frames (whole sequences
    where the names show five or more, else by frame), scores the starting model on them first and
    keeps it unless the trained one scores higher there. Labels whose road makes no sense under
    --label-format (a store's: the format it was warped with) are refused. 'torchrun
    --nproc-per-node N vctrain fit ...' trains data-parallel. Each epoch's line gives its training
    and validation times apart; the closing line's total is the command's wall clock. Time (cpu
    recipe, 2 cores): about 3 minutes for 305 CamVid frames at the default store's 638x271.

    \b
    Example:
      vctrain fit stores/camvid_train --out runs/vc.pt    # about 3 min on 2 cores
      vctrain fit stores/camvid_train --baseline resize --out runs/resize.pt   # store's pixels, frames' aspect
      vctrain fit stores/camvid_train --out runs/vc.pt --resume runs/vc.last.pt --epochs 40
      vctrain fit stores/camvid_train_fine --crop 0.67 --out runs/vc_fine.pt
      vctrain fit stores/camvid_train --model lite0fpn --out runs/vc_lite0.pt   # ImageNet encoder
      vctrain fit stores/cam_a stores/cam_b stores/cam_c --recipe multicamera --baseline resize --out runs/road.pt
      vctrain fit stores/kitti stores/camvid --recipe multicamera --baseline resize --keep-aspect --out runs/aspect.pt
      vctrain fit --baseline resize --images my/images --labels my/labels --label-format camvid --init shipped --out runs/mine_ft.pt
      vctrain fit stores/camvid stores/idd --outputs road,drivable --out runs/two.pt   # road and drivable area
    """
    init = model_arg(init)  # 'shipped' -> the shipped model's file; a missing file is refused naming it
    cfg = _fit_config(locals())  # (first: locals() are the options, each named as its TrainConfig field)
    _run_fit(cfg, out, log, images, labels, val_images, val_labels, overwrite=overwrite, threads=threads,
             as_json=as_json, quiet=quiet)


def _run_fit(cfg: TrainConfig, out: Path, log: Optional[Path], images: Optional[Path], labels: Optional[Path],
             val_images: Optional[Path], val_labels: Optional[Path], *, overwrite: bool, threads: Optional[int],
             as_json: bool, quiet: bool) -> None:
    """``vctrain fit``'s run of ``cfg``: the folders checked, the rerun plan (resume, done, aside, refused),
    the training, and its summary on stderr and stdout."""
    from vcprep.cliutil import Interrupted

    from ..training.checkpoint import last_path
    from ..training.checkpoint_data import CheckpointData
    from ..training.guard import verdict
    from ..training.loop import fit
    from ..training.rerun import rerun_plan
    pin_threads(threads)
    check_data_folders(images, labels)  # --baseline resize
    check_data_folders(val_images, val_labels, ("--val-images", "--val-labels"))
    for path in filter(None, (out, log)):  # runs/vc.pt: runs/ is created, as warp and predict create theirs
        ensure_parent(path)
    what, note = rerun_plan(cfg, overwrite)  # the same command resumes, or finds its run done; another's is refused
    if note and (what == "aside" or not quiet):  # (where a model of other data went is said even under --quiet)
        err(note)
    if what == "done":
        path_or_json(out, {"out": str(out), "done": True}, as_json)
        return
    try:
        summary = fit(cfg)
    except KeyboardInterrupt:  # Ctrl-C: the epochs done are in OUT.last.pt, and the same command goes on from there
        raise Interrupted(f"the epochs finished are saved ({last_path(out)})") from None
    summary["command_seconds"] = command_seconds()  # the command's wall clock: imports, data, scoring, saves
    if not quiet:
        err(_fit_line(out, summary))
        if summary.get("finetune"):
            err(verdict(str(out), summary["finetune"], CheckpointData.from_dict(summary["data"]).val_items))
    path_or_json(out, summary, as_json)


def _fit_line(out: Path, summary: dict[str, Any]) -> str:
    """The one line on stderr that sums up a training run; each time the wall clock of what it names
    (issue 80: "in all" had been the training steps alone, 35 s of a 3-minute command)."""
    best, val = summary["best_val_iou"], summary["val_seconds"]
    start = f", scoring the start {summary['start_seconds']:.1f} s" if summary.get("start_seconds") else ""
    return (f"{out}: {summary['model_args']['arch']}, {count(summary['epochs'], 'epoch')}, "
            f"training {summary['seconds_per_epoch']:.1f} s/epoch ({summary['train_images_per_s']:.1f} img/s)"
            + (f", validation {summary['val_seconds_per_epoch']:.1f} s/epoch" if val else "") + start
            + f", {summary['command_seconds']:.1f} s in all (the command's wall clock)"
            + (f", best val IoU {best:.4f} (epoch {summary['best_epoch']})" if best is not None else ""))
