"""``vctrain``: the command line of the trainer. Parses, calls the library, prints; nothing else."""
from __future__ import annotations

from pathlib import Path
from typing import Any, List, Optional

import typer

from vcprep.cliutil import check_data_folders, count, emit_json, ensure_parent, err, run_app
from vcprep.errors import InputError
from vcprep.labels import LABEL_FORMATS

from . import __version__
from .config import AdaptSettings, TrainConfig
from .study.spec import CONDITIONS

app = typer.Typer(rich_markup_mode=None, pretty_exceptions_enable=False, add_completion=False, no_args_is_help=True,
                  help="Train, predict and evaluate road segmentation in the virtual-camera domain.\n\n"
                       "Add --debug to any command to see a traceback on error.")


def _version(value: bool):
    if value:
        print(f"vctrain {__version__}")
        raise typer.Exit()


@app.callback()
def _root(version: bool = typer.Option(False, "--version", callback=_version, is_eager=True, help="Print the version.")):
    pass


@app.command("version")
def version_cmd():
    """Print the version.

    \b
    Example:
      vctrain version
    """
    print(f"vctrain {__version__}")


def _parse_size(text: Optional[str]) -> Optional[tuple[int, int]]:
    from vcprep.cliutil import parse_size

    return None if text is None else parse_size(text)


_TRAIN = TrainConfig()     # the defaults of fit's options, as TrainConfig declares them
_ADAPT = AdaptSettings()  # ... and of adapt's
_LABEL_FORMAT_HELP = f"{', '.join(LABEL_FORMATS)} or values:road=3;ignore=11"
# fit's options named otherwise than the TrainConfig field they set; every other option is named as
# its field, except --json, and fit takes none for FIT_NO_OPTION (tests/test_vctrain.py checks both ways)
FIT_OPTION_FIELD = {"model": "arch", "width": "base_width", "val_store": "val_stores", "quiet": "progress"}
FIT_NO_OPTION = ("momentum", "init", "max_steps")


def _fit_config(options: dict[str, Any]) -> TrainConfig:
    """``vctrain fit``'s parsed options as the TrainConfig they give: each option sets its field
    (:data:`FIT_OPTION_FIELD`), paths as text, WxH and --crop parsed, --quiet as ``progress``."""
    values: dict[str, Any] = {}
    for name, v in options.items():
        if name == "as_json":
            continue
        if isinstance(v, Path):
            v = str(v)
        elif isinstance(v, list) or name in ("stores", "val_store"):
            v = [str(x) for x in v or []]
        values[FIT_OPTION_FIELD.get(name, name)] = v
    values.update(size=_parse_size(values["size"]), crop=_parse_crop(values["crop"]), progress=not values["progress"])
    return TrainConfig(**values)


def _parse_crop(text: Optional[str]) -> Optional[Any]:
    """--crop: 'WxH' pixels, a share of each side ('0.67') or shares of width and height ('0.44x1')."""
    if text is None:
        return None
    parts = text.lower().replace(" ", "").split("x")
    if len(parts) == 2 and all(p.isdigit() for p in parts):
        return _parse_size(text)
    try:
        shares = [float(p) for p in parts]
    except ValueError:
        shares = []
    if len(shares) in (1, 2):
        return shares[0] if len(shares) == 1 else tuple(shares)
    raise InputError(f"--crop '{text}' is neither WxH, a share nor two shares", None,
                     "use e.g. --crop 320x240, --crop 0.67 or --crop 0.44x1")


@app.command("fit")
def fit_cmd(
    stores: Optional[List[Path]] = typer.Argument(None, help="training stores built by 'vcprep warp' (one virtual camera and scale)"),
    out: Path = typer.Option(..., "--out", "-o", help="best checkpoint (by validation road IoU); OUT-stem.last.pt holds the latest epoch"),
    recipe: Optional[str] = typer.Option(None, "--recipe", help="defaults of every setting below: 'cpu' (resfpn, AdamW, "
                                                                 "cosine, augmentation; CamVid train in 3.3 min on "
                                                                 "2 cores at --size 344x176, 14.2 at 688x350) or "
                                                                 "'paper' (segnet, SGD 0.005, poly); default: paper "
                                                                 "on a GPU, cpu without"),
    model: Optional[str] = typer.Option(None, "--model", "-m",
                                        help="resfpn (residual encoder + FPN decoder, 1.3 M parameters), segnet "
                                             "(VGG16 SegNet, 29 M) or segnet-narrow (same topology, 1/4 width, 1.8 M); "
                                             "default: the recipe's"),
    width: Optional[int] = typer.Option(None, "--width", help="first-block width override (64 = segnet, 16 = narrow)"),
    baseline: str = typer.Option(_TRAIN.baseline, "--baseline", help="'resize': the paper's baseline, the same network on the "
                                                            "original images simply resized (no virtual camera)"),
    images: Optional[Path] = typer.Option(None, "--images", help="baseline only: folder of original images"),
    labels: Optional[Path] = typer.Option(None, "--labels", help="baseline only: folder of their labels"),
    label_format: Optional[str] = typer.Option(None, "--label-format", help=f"baseline only: {_LABEL_FORMAT_HELP}"),
    size: Optional[str] = typer.Option(None, "--size", help="working size WxH (default: the store size)"),
    crop: Optional[str] = typer.Option(None, "--crop", help="train on random windows of the working image: WxH "
                                                            "pixels, a share of each side (0.67) or of width and "
                                                            "height (0.44x1: full height); validation and "
                                                            "prediction see the whole image (default: no crop)"),
    epochs: Optional[int] = typer.Option(None, "--epochs", "-e", help="epochs (cpu recipe: 20, paper recipe: 30; the paper: 600 on a GPU)"),
    batch_size: Optional[int] = typer.Option(None, "--batch-size", "-b", help="global batch size (recipes: 8)"),
    optimizer: Optional[str] = typer.Option(None, "--optimizer", help="sgd (momentum 0.9; paper) or adamw (cpu)"),
    lr: Optional[float] = typer.Option(None, "--lr", help="peak learning rate (paper: 0.005, cpu: 0.002)"),
    weight_decay: Optional[float] = typer.Option(None, "--weight-decay", help="weight decay (paper: 0.0005, cpu: 0.01)"),
    schedule: Optional[str] = typer.Option(None, "--schedule", help="'poly' (lr*(1-it/total)^0.9; paper), 'cosine' "
                                                                    "(3 % warm-up; cpu) or 'constant'"),
    seed: int = typer.Option(_TRAIN.seed, "--seed", help="seeds init, validation split, order and augmentation"),
    device: str = typer.Option(_TRAIN.device, "--device", help="auto (cuda if present), cpu, cuda, cuda:N"),
    val_fraction: float = typer.Option(_TRAIN.val_fraction, "--val-fraction", help="share of the training items held out for validation"),
    val_store: Optional[List[Path]] = typer.Option(None, "--val-store", help="validation store (repeatable; replaces --val-fraction)"),
    class_weights: str = typer.Option(_TRAIN.class_weights, "--class-weights", help="'none' or 'median-freq' (median frequency balancing)"),
    hflip: Optional[bool] = typer.Option(None, "--hflip/--no-hflip", help="augment: random horizontal flip (p 0.5; "
                                                                          "cpu recipe: on)"),
    scale_aug: Optional[float] = typer.Option(None, "--scale-aug", help="augment: random scale in [1/(1+A), 1+A] "
                                                                        "about the VP (cpu: 0.25, paper: 0)"),
    shift_aug: Optional[float] = typer.Option(None, "--shift-aug", help="augment: random shift up to this share of "
                                                                        "the size (cpu: 0.05)"),
    color_aug: Optional[float] = typer.Option(None, "--color-aug", help="augment: brightness/contrast/gain jitter "
                                                                        "(cpu: 0.3)"),
    greyscale: float = typer.Option(_TRAIN.greyscale, "--greyscale", help="augment: probability of greyscale (1 = a greyscale model)"),
    vp_channel: bool = typer.Option(_TRAIN.vp_channel, "--vp-channel", help="extra input channel: the VP proximity map"),
    resume: Optional[Path] = typer.Option(None, "--resume", help="continue from a checkpoint (OUT-stem.last.pt) up to --epochs"),
    workers: int = typer.Option(_TRAIN.workers, "--workers", help="data loader processes"),
    log: Optional[Path] = typer.Option(None, "--log", help="JSON-lines log, one row per epoch (default OUT-stem.log.jsonl)"),
    as_json: bool = typer.Option(False, "--json", help="print the run summary as one JSON object instead of the path"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar or epoch lines on stderr"),
):
    """Train a road segmentation network on virtual-camera stores (or the resize baseline).

    Cross-entropy over not road / road, label 255 ignored. Two recipes set the defaults: 'cpu'
    (without a GPU: resfpn, AdamW 0.002, cosine, flip/scale/shift/colour augmentation, 20
    epochs) and 'paper' (on a GPU: segnet, SGD 0.005 momentum 0.9,
    weight decay 0.0005, batch 8, poly decay); any option given wins. The checkpoint describes
    itself (model, training config, virtual camera, scale, completion, metrics), so predict and
    eval need no repeated flags. Prints the checkpoint path; OUT's folder is created. Launch
    with 'torchrun --nproc-per-node N' for data-parallel training.

    Time, measured with the cpu recipe on 2 cores for CamVid train (367 images): 3.3 minutes
    at --size 344x176 (half the default store's size), 14.2 minutes at the default store's
    688x350.

    \b
    Example:
      vctrain fit stores/camvid_train --size 344x176 --out runs/vc.pt    # 3.3 min on 2 cores
      vctrain fit stores/camvid_train --val-store stores/camvid_val --epochs 20 --out runs/vc.pt
      vctrain fit stores/camvid_train --baseline resize --size 344x176 --out runs/resize.pt
      vctrain fit stores/camvid_train --out runs/vc.pt --resume runs/vc.last.pt --epochs 40
      vctrain fit stores/camvid_train_fine --crop 0.67 --out runs/vc_fine.pt
    """
    cfg = _fit_config(locals())  # (first: locals() are the options, each named as its TrainConfig field)
    from .train import fit

    check_data_folders(images, labels)  # --baseline resize
    ensure_parent(out)  # runs/vc.pt: runs/ is created, as warp and predict create their folders
    if log is not None:
        ensure_parent(log)
    summary = fit(cfg)
    if not quiet:
        best = summary["best_val_iou"]
        err(f"{out}: {summary['model_args']['arch']}, {count(summary['epochs'], 'epoch')}, "
            f"{summary['seconds_per_epoch']:.1f} s/epoch, {summary['train_images_per_s']:.1f} img/s"
            + (f", best val IoU {best:.4f} (epoch {summary['best_epoch']})" if best is not None else ""))
    if as_json:
        emit_json(summary)
    else:
        print(out)


@app.command("predict")
def predict_cmd(
    checkpoint: Optional[Path] = typer.Argument(None, help="model written by 'vctrain fit' (left out with --prior)"),
    images: Optional[List[Path]] = typer.Argument(None, help="image files or folders, or video files (.mp4 .avi .mkv .mov ...)"),
    out: Path = typer.Option(..., "--out", "-o", help="output folder (created)"),
    camera: Optional[str] = typer.Option(None, "--camera", "-c",
                                         help="camera of the images: preset or file (.yaml, KITTI .txt, Cityscapes .json), "
                                              "or a folder of per-frame calibration files matched by stem, or "
                                              "'estimate' (from these images, as 'vcprep camera estimate' does); a .yaml "
                                              "camera's ego_rows (its own vehicle) are never warped; the prediction there "
                                              "continues the scene above them"),
    prior: Optional[Path] = typer.Option(None, "--prior", help="no model: segment with the geometric prior written by "
                                                                "'vcprep prior' (p_g >= 0.5, back-projected)"),
    store: Optional[Path] = typer.Option(None, "--store", help="predict every item of this store instead of IMAGES"),
    device: str = typer.Option("auto", "--device", help="auto, cpu, cuda, cuda:N"),
    keep_store: Optional[Path] = typer.Option(None, "--keep-store", help="keep the warped images in this store"),
    within: str = typer.Option("auto", "--within", help="per-image VP correction: auto (as the model was trained), "
                                                         "estimate, a CSV id,u,v, or none"),
    overlay: bool = typer.Option(False, "--overlay", help="also write OUT/<stem>_overlay.png (road in green); for a "
                                                           "video OUT/<stem>_overlay.mp4 (also the horizon and the VP)"),
    mask_video: bool = typer.Option(False, "--mask-video", help="a video's masks as one lossless video "
                                                                "OUT/<stem>_mask.mkv instead of a PNG per frame"),
    ego: str = typer.Option("auto", "--ego", help="a video's own vehicle: auto (the camera's ego_rows, else found "
                                                  "from 48 frames spread over the video, said on stderr), none (no "
                                                  "search: the camera as given) or N bottom rows"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar"),
):
    """Predict road in original camera images with the checkpoint's own preprocessing.

    A virtual-camera model warps the images into its virtual camera (same scale and completion
    as its training store), infers, and back-projects to the original image; a resize-baseline
    model resizes in and out. With --prior instead of a model, the geometric prior is the
    segmentation (the paper's Table 5 "Geo-Prior" baseline): the images are warped into the
    prior's virtual camera (from its description, e.g. prior.npy.json) and p_g is back-projected.
    Writes OUT/<stem>_mask.png (0/255) and OUT/<stem>_prob.png (0-255 road probability) at the
    image size; prints the mask paths. A video is predicted frame by frame in memory (the same
    numbers), into OUT/<stem>/<stem>_<frame>_mask.png (frame: 6 digits from 0) or, with
    --mask-video, OUT/<stem>_mask.mkv; per-frame VPs are smoothed over time.

    \b
    Example:
      vctrain predict runs/vc.pt --camera kitti data/kitti/image_2 --out preds/kitti
      vctrain predict runs/vc.pt --store stores/camvid_val --out preds/camvid_val
      vctrain predict --prior prior.npy --camera kitti data/kitti/image_2 --out preds/geoprior
      vctrain predict runs/vc.pt --camera camvid drive.mp4 --overlay --out preds/drive
    """
    from vcprep.store import Store

    from .predict import Predictor, collect_images, predict_images, predict_store
    from .video import check_video_stems, is_video, predict_video

    if prior is not None:
        from .adapt import PriorPredictor

        if checkpoint is not None and checkpoint.suffix.lower() == ".pt":
            raise InputError("give either a model or --prior, not both", checkpoint, "drop one of them")
        images = [checkpoint, *(images or [])] if checkpoint is not None else images  # all positionals are images
    elif checkpoint is None:
        raise InputError("no model given", None, "give MODEL.pt, or --prior prior.npy to segment with the prior")
    if mask_video and not any(is_video(p) for p in images or []):
        raise InputError("--mask-video is for videos", None, "give a video file, or drop --mask-video")
    if store is None and not images:
        raise InputError("nothing to predict", None, "give image files/folders, or --store STORE")
    if store is not None and images:
        raise InputError("give either IMAGES or --store, not both", store, "run predict twice")
    if prior is None and checkpoint.suffix.lower() == ".onnx":  # an exported graph: its camera is inside
        return _predict_onnx(checkpoint, images, out, camera, store, within, overlay, quiet)
    videos = check_video_stems([p for p in images or [] if is_video(p)])
    images = [p for p in images or [] if not is_video(p)]
    predictor = PriorPredictor(prior) if prior is not None else Predictor(checkpoint, device)
    written = []
    if videos:
        vcam = None
        if camera is not None:
            from vcprep.cli import camera_for

            vcam = camera_for(camera, None, per_frame=False, quiet=quiet)  # ('estimate': said not possible here)
        for v in videos:
            written += predict_video(predictor, v, out, vcam, within=within, mask_video=mask_video, overlay=overlay,
                                     progress=not quiet, ego=ego)
    n_images = 0
    if store is not None:
        written = predict_store(predictor, Store.open(store), out, progress=not quiet, overlay=overlay)
        n_images = len(written)
    elif images:
        cam = None
        if camera is not None:
            from vcprep.cli import camera_for

            cam = camera_for(camera, collect_images(images)[0].image,
                             frames=[j.image for j in collect_images(images)], quiet=quiet)
        elif predictor.mode == "virtual":
            raise InputError("a virtual-camera model needs the camera of the images", predictor.path,
                             "add --camera (preset or calibration file)")
        n_images = len(written)
        written += predict_images(predictor, images, out, cam, progress=not quiet, keep_store=keep_store,
                                  overlay=overlay, within=within)
        n_images = len(written) - n_images
    for p in written:
        print(p)
    if not quiet:
        what = " and ".join(([count(n_images, "image")] if images or store else [])
                            + ([count(len(videos), "video")] if videos else []))
        err(f"{out}: {what} predicted ({'geometric prior' if prior else predictor.mode + ' model'})")


def _predict_onnx(graph: Path, images, out: Path, camera: Optional[str], store: Optional[Path], within: str,
                  overlay: bool, quiet: bool) -> None:
    """``vctrain predict GRAPH.onnx``: frames through a graph written by 'vctrain export'."""
    from .export import OnnxPredictor, predict_images_onnx
    from .predict import collect_images

    if store is not None:
        raise InputError("an exported graph takes the camera's own frames, not a store", store,
                         "give the original frames (IMAGES)")
    predictor = OnnxPredictor(graph)
    cam = None
    if camera is not None:  # only for estimating the VPs of a --vp-input graph (the graph holds its own camera)
        from vcprep.cli import camera_for

        frames = [j.image for j in collect_images(images)]
        cam = camera_for(camera, frames[0], per_frame=False, frames=frames, quiet=quiet)
    written = predict_images_onnx(predictor, images, out, cam, progress=not quiet, overlay=overlay, within=within)
    for p in written:
        print(p)
    if not quiet:
        err(f"{out}: {count(len(written), 'image')} predicted (ONNX graph, {predictor.mode} model)")


@app.command("export")
def export_cmd(
    checkpoint: Path = typer.Argument(..., help="model written by 'vctrain fit' (virtual-camera or resize baseline)"),
    camera: str = typer.Option(..., "--camera", "-c", help="the camera the graph is for: preset or file (.yaml, KITTI "
                                                          ".txt, Cityscapes .json); its image size is the graph's "
                                                          "input size, its ego_rows are never warped"),
    out: Path = typer.Option(..., "--out", "-o", help="the ONNX file to write"),
    vp_input: bool = typer.Option(False, "--vp-input", help="the graph takes each frame's road VP (u, v) as a second "
                                                            "input and corrects pan/tilt per frame (else the "
                                                            "camera's mount pose is built in)"),
    pose_range: float = typer.Option(5.0, "--pose-range", min=0.0,
                                     help="with --vp-input: the virtual rectangle holds the camera at pan and tilt "
                                          "within this many degrees of its mount"),
    frame: Optional[Path] = typer.Option(None, "--frame", help="a frame of the camera (gives the image size to "
                                                               "calibration files that carry none)"),
    as_json: bool = typer.Option(False, "--json", help="print the graph's description as one JSON object"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no summary on stderr"),
):
    """Export a model with its camera inside as one ONNX graph (needs pip install 'vcseg[deploy]').

    The graph takes the camera's raw frame (uint8 H x W x 3 BGR, as cv2.imread gives it, at the
    camera's image size) and returns P(road) (float32 H x W) in the camera's own pixels: inside
    are the warp into the model's virtual camera with the training store's completion, the
    normalisation, the network, softmax and the back-projection -- what 'vctrain predict' does
    for this camera (a resize baseline: resize in and back). Run it with 'vctrain predict
    OUT.onnx FRAMES --out DIR' or any ONNX runtime. Prints the ONNX path.

    \b
    Example:
      vctrain export runs/vc.pt --camera kitti --frame data/kitti/image_2/000000.png -o road.onnx
      vctrain export runs/vc.pt --camera mycam.yaml --vp-input -o road_vp.onnx
      vctrain predict road.onnx data/kitti/image_2 --out preds/kitti
    """
    from vcprep.cli import camera_for

    from .export import export_onnx

    cam = camera_for(camera, frame, per_frame=False, quiet=quiet)
    ensure_parent(out)
    info = export_onnx(checkpoint, cam, out, vp_input=vp_input, pose_range=(pose_range, pose_range))
    if not quiet:
        w, h = info["inputs"]["frame"][1][1], info["inputs"]["frame"][1][0]
        inner = (f"virtual store {info['store_size'][0]}x{info['store_size'][1]}, completion {info['completion']}"
                 if info["mode"] == "virtual" else f"resized to {info['work'][0]}x{info['work'][1]}")
        err(f"{out}: {info['mode']} model for camera {info['camera_name']} ({w}x{h}; {inner}; "
            f"{'VP input' if vp_input else 'mount pose built in'}; opset {info['opset']}; onnxruntime vs torch max "
            f"|diff| {info['max_abs_diff_vs_torch']:.1e})")
    if as_json:
        emit_json(info)
    else:
        print(out)


@app.command("adapt")
def adapt_cmd(
    checkpoint: Path = typer.Argument(..., help="virtual-camera model written by 'vctrain fit'"),
    images: Path = typer.Option(..., "--images", "-i", help="folder (or file) of UNLABELLED target images"),
    camera: str = typer.Option(..., "--camera", "-c", help="camera of the target images: preset or file (.yaml, "
                                                           "KITTI .txt, Cityscapes .json), or a folder of per-frame "
                                                           "calibration files (every frame its exact pose), or "
                                                           "'estimate' (from these images)"),
    prior: Path = typer.Option(..., "--prior", help="geometric prior written by 'vcprep prior' (.npy or .png) in the "
                                                    "model's virtual camera and scale"),
    out: Path = typer.Option(..., "--out", "-o", help="adapted checkpoint; OUT-stem.last.pt and OUT-stem.log.jsonl "
                                                      "beside it"),
    lo: float = typer.Option(_ADAPT.lo, "--lo", help="surrogate 'not road' where the (fused) probability is below this"),
    hi: float = typer.Option(_ADAPT.hi, "--hi", help="surrogate 'road' where the (fused) probability is above this"),
    combine: str = typer.Option(_ADAPT.combine, "--combine", help="'prior': the prior's tri-mask alone (paper §4.5); 'fuse': "
                                                           "prior and the model's own prediction fused per image "
                                                           "(p_g p_n / (p_g p_n + (1-p_g)(1-p_n))) before the thresholds"),
    epochs: int = typer.Option(_ADAPT.epochs, "--epochs", "-e", help="fine-tuning epochs"),
    lr: Optional[float] = typer.Option(None, "--lr", help="learning rate (default: a tenth of the model's own)"),
    store: Optional[Path] = typer.Option(None, "--store", help="store for the warped target images and their surrogate "
                                                               "labels (default OUT-stem.store; reused)"),
    within: str = typer.Option("auto", "--within", help="per-image VP correction: auto (as the model was trained), "
                                                         "estimate, a CSV id,u,v, or none"),
    seed: Optional[int] = typer.Option(None, "--seed", help="seed (default: the model's)"),
    device: str = typer.Option("auto", "--device", help="auto, cpu, cuda, cuda:N"),
    as_json: bool = typer.Option(False, "--json", help="print the run summary as one JSON object instead of the path"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar or epoch lines on stderr"),
):
    """Fine-tune a virtual-camera model on unlabelled target images with surrogate labels from
    the geometric prior (paper §4.5, after GeoSeg). The images are warped exactly as the model's
    training store was built (virtual camera, scale, completion, within mode); surrogate labels
    are road where p_g > --hi, not road where p_g < --lo, ignore elsewhere (--combine fuse: the
    model's own prediction fused in first). Training settings are the model's own, for --epochs
    at --lr, without validation. The checkpoint records that it was adapted, from which model,
    with which prior and thresholds. Prints the checkpoint path.

    \b
    Example:
      vcprep prior stores/camvid stores/kitti -o prior.npy
      vctrain adapt runs/vc.pt --images data/qian/train --camera qian --prior prior.npy --out runs/vc_qian.pt
      vctrain adapt runs/vc.pt -i data/qian/train -c qian --prior prior.npy --combine fuse -o runs/fused.pt
    """
    from vcprep.cli import camera_for

    from .adapt import adapt
    from .predict import collect_images

    cam = camera_for(camera, collect_images([images])[0].image, frames=[j.image for j in collect_images([images])],
                     quiet=quiet)
    ensure_parent(out)
    settings = AdaptSettings(lo=lo, hi=hi, combine=combine, epochs=epochs, lr=lr, store=store, within=within,
                             device=device, seed=seed, progress=not quiet)
    summary = adapt(checkpoint, images, cam, prior, out, settings)
    if not quiet:
        sh = summary["adapted"]["label_shares"]
        err(f"{out}: adapted {checkpoint} on {count(len(summary['adapted']['images']), 'image')}, {count(summary['epochs'], 'epoch')} at "
            f"lr {summary['adapted']['lr']:g}; surrogate labels {sh['road']:.1%} road, {sh['not_road']:.1%} not road, "
            f"{sh['ignore']:.1%} ignore")
    if as_json:
        emit_json(summary)
    else:
        print(out)


@app.command("eval")
def eval_cmd(
    pred_dir: Path = typer.Argument(..., help="folder of <stem>_mask.png / <stem>_prob.png from 'vctrain predict'"),
    labels: Path = typer.Option(..., "--labels", "-l", help="folder of ground-truth labels"),
    label_format: str = typer.Option(..., "--label-format", "-f", help=_LABEL_FORMAT_HELP),
    as_json: bool = typer.Option(False, "--json", help="print one JSON object (values in [0, 1])"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bar"),
):
    """Road IoU (ΣTP/Σ(TP+FP+FN), ignore pixels excluded), mean per-image IoU, precision, recall,
    F1; with probability maps also the KITTI road metrics: MaxF, AP (11-point) and
    precision/recall/FPR/FNR at the MaxF threshold (KITTI devkit definitions).

    \b
    Example:
      vctrain eval preds/camvid_val --labels data/camvid/valannot --label-format camvid
      vctrain eval preds/kitti --labels data/kitti/gt_image_2 --label-format kitti --json
    """
    from vcprep.labels import get_label_format

    from .evaluate import evaluate_folder

    result, n = evaluate_folder(pred_dir, labels, get_label_format(label_format), progress=not quiet)
    if as_json:
        emit_json(result)
    else:
        for k, v in result.items():
            print(f"{k:<16} {v:.4f}")
    if not quiet:
        err(f"{pred_dir}: {count(n, 'image')} evaluated")


@app.command("crossval")
def crossval_cmd(
    study: Path = typer.Argument(..., help="study YAML: datasets (camera, label format, role, train/test images and "
                                           "labels, optional VPs) and settings; schema in docs/studies.md"),
    out: Path = typer.Option(..., "--out", "-o", help="study folder (created; an existing one is resumed)"),
    conditions: Optional[str] = typer.Option(None, "--conditions",
                                             help=f"comma-separated subset of {','.join(CONDITIONS)} (default: "
                                                  "the study file's, else the first five)"),
    heldout: Optional[str] = typer.Option(None, "--heldout", help="comma-separated datasets to evaluate (default: "
                                                                   "every dataset of role both or test)"),
    epochs: Optional[int] = typer.Option(None, "--epochs", "-e", min=1, help="override the study's training epochs"),
    seed: Optional[int] = typer.Option(None, "--seed", help="override the study's training seed (one study folder "
                                                            "per seed)"),
    jobs: int = typer.Option(1, "--jobs", "-j", min=1, help="worker processes for building stores"),
    as_json: bool = typer.Option(False, "--json", help="print {condition: mean road IoU over the evaluated datasets} "
                                                        "as one JSON object instead of the table"),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="no progress bars or run lines on stderr"),
):
    """Cross-camera study: for each condition, hold out each dataset of role 'both' in turn (train
    on the other trainable datasets) and, if there are datasets of role 'test', train once on every
    trainable dataset and test on each of them; road IoU on the evaluated dataset's test images in
    its own camera ("will my model work on camera X?": give camera X's labelled frames role test).

    Conditions: resize (baseline: images resized), between (virtual camera, average pose),
    within (plus each image's estimated VP), within-gt (the study's given VPs), zero (within with
    zero padding instead of projective completion), prior (no training: the training datasets'
    geometric prior, p_g >= 0.5), adapt (the within model adapted to the evaluated dataset's
    unlabelled images with that prior's tri-mask), adapt-fuse (as adapt, the prior fused with the
    model's own prediction; prior, adapt and adapt-fuse are not among the defaults). Prints the
    table (rows: evaluated dataset and mean; columns: conditions; road IoU in %) and writes
    OUT/table.md, table.csv, results.jsonl,
    summary.json and per-run logs under OUT/runs. Training settings the study does not give are
    vctrain fit's defaults. Finished runs are not redone: run the same command again to resume.

    \b
    Example:
      vctrain crossval study.yaml --out studies/cams
      vctrain crossval study.yaml --out studies/cams --conditions resize,within --epochs 5
      vctrain crossval study.yaml --out studies/cams --json | tail -n 1
      vctrain crossval study.yaml --out studies/seed1 --seed 1
    """
    from .report import format_table, summary_of
    from .study import check_conditions, evaluated_datasets, load_study, run_study

    st = load_study(study)
    conds = check_conditions([c.strip() for c in conditions.split(",") if c.strip()]) if conditions else st.conditions
    held = evaluated_datasets(st, [h.strip() for h in heldout.split(",") if h.strip()] if heldout else None)
    overrides = {k: v for k, v in (("epochs", epochs), ("seed", seed)) if v is not None}
    rows = run_study(st, out, conds, held, progress=not quiet, jobs=jobs, train_overrides=overrides,
                     say=(lambda s: None) if quiet else err)
    if as_json:
        emit_json(summary_of(rows, conds))
    else:
        print(format_table(rows, held, conds), end="")


def main() -> None:
    run_app(app, "vctrain")


if __name__ == "__main__":
    main()
