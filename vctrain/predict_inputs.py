"""What ``vctrain predict`` was given, checked and routed: image files and folders, videos or a
store, through a model (:class:`~vctrain.predict.Predictor`), the geometric prior
(:class:`~vctrain.adapt.PriorPredictor`) or a graph written by ``vctrain export``
(:class:`~vctrain.onnx_predict.OnnxPredictor`). :func:`predict_inputs` returns the files written
and what was predicted (:class:`Predicted`)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Optional, Sequence

from vcprep.cliutil import count
from vcprep.errors import InputError

__all__ = ["CameraFor", "Predicted", "predict_inputs"]

# the camera of the frames from --camera: camera_for(sample_image, per_frame=..., frames=...) -> Camera
# (or FrameCameras); the caller's, so that an estimated camera is said where the caller says things
CameraFor = Callable[..., Any]


@dataclass
class Predicted:
    """What :func:`predict_inputs` did: the mask files ``written`` (in order), how many images
    (None: no images or store given) and videos, and through what (``source``)."""

    written: list[Path]
    images: Optional[int]
    videos: int
    source: str

    def line(self) -> str:
        """'3 images predicted (virtual model)', '1 image and 2 videos predicted (geometric prior)'."""
        what = " and ".join(([count(self.images, "image")] if self.images is not None else [])
                            + ([count(self.videos, "video")] if self.videos else []))
        return f"{what} predicted ({self.source})"


def predict_inputs(checkpoint: Optional[Path], images: Optional[Sequence[Path]], out: Path,
                   camera_for: Optional[CameraFor] = None, prior: Optional[Path] = None, store: Optional[Path] = None,
                   device: str = "auto", keep_store: Optional[Path] = None, within: str = "auto",
                   overlay: bool = False, mask_video: bool = False, ego: str = "auto",
                   progress: bool = True, vp_range: Optional[tuple[float, float]] = None,
                   vp_smooth: Optional[int] = None, vp_sequences: Optional[str] = None,
                   say: Optional[Callable[[str], None]] = None) -> Predicted:
    """``vctrain predict``: ``checkpoint`` (a ``.pt`` model or an ``.onnx`` graph; with ``prior``
    it is the first image) on ``images`` (files, folders, videos) or every item of ``store``.
    ``camera_for`` (None: no --camera) gives the frames' camera. ``vp_range`` (pan, tilt degrees),
    ``vp_smooth`` (frames either side) and ``vp_sequences`` ('name', 'folder') change the rule
    estimated VPs follow (default: the model's, :func:`vctrain.predict.model_vp_rule`); ``say``
    (given) hears which VPs, own vehicle and rectangle image files were warped with. Bad
    combinations raise :class:`InputError` before anything is predicted."""
    if prior is not None:
        if checkpoint is not None and checkpoint.suffix.lower() == ".pt":
            raise InputError("give either a model or --prior, not both", checkpoint, "drop one of them")
        images = [checkpoint, *(images or [])] if checkpoint is not None else images  # all positionals are images
    elif checkpoint is None:
        raise InputError("no model given", None, "give MODEL.pt, or --prior prior.npy to segment with the prior")
    from .video import check_video_stems, is_video, predict_video

    if mask_video and not any(is_video(p) for p in images or []):
        raise InputError("--mask-video is for videos", None, "give a video file, or drop --mask-video")
    if store is None and not images:
        raise InputError("nothing to predict", None, "give image files/folders, or --store STORE")
    if store is not None and images:
        raise InputError("give either IMAGES or --store, not both", store, "run predict twice")
    if prior is None and checkpoint.suffix.lower() == ".onnx":  # an exported graph: its camera is inside
        return _predict_onnx(checkpoint, images, out, camera_for, store, within, overlay, progress)
    videos = check_video_stems([p for p in images or [] if is_video(p)])
    images = [p for p in images or [] if not is_video(p)]
    predictor = _predictor(checkpoint, prior, device)
    rule = _vp_rule(predictor, vp_range, vp_smooth, vp_sequences)
    written = []
    if videos:
        vcam = camera_for(None, per_frame=False) if camera_for is not None else None  # ('estimate': said not possible)
        for v in videos:
            written += predict_video(predictor, v, out, vcam, within=within, mask_video=mask_video, overlay=overlay,
                                     progress=progress, ego=ego, vp_rule=rule,
                                     **({"vp_window": vp_smooth} if vp_smooth is not None else {}))
    n_images = 0
    if store is not None:
        from vcprep.store import Store

        from .predict import predict_store

        written = predict_store(predictor, Store.open(store), out, progress=progress, overlay=overlay)
        n_images = len(written)
    elif images:
        n_images = len(written)
        written += _predict_image_files(predictor, images, out, camera_for, keep_store, within, overlay, progress,
                                        _Geometry(rule, ego, say))
        n_images = len(written) - n_images
    return Predicted(written, n_images if images or store else None, len(videos),
                     "geometric prior" if prior else predictor.mode + " model")


def _predictor(checkpoint: Optional[Path], prior: Optional[Path], device: str):
    """The prior's predictor (``prior`` given) or the checkpoint's model on ``device``."""
    if prior is not None:
        from .adapt import PriorPredictor

        return PriorPredictor(prior)
    from .predict import Predictor

    return Predictor(checkpoint, device)


def _vp_rule(predictor, vp_range: Optional[tuple[float, float]], vp_smooth: Optional[int],
             vp_sequences: Optional[str] = None):
    """The model's VP rule with ``vp_range``, ``vp_smooth`` and ``vp_sequences`` where given (None:
    none given)."""
    if vp_range is None and vp_smooth is None and vp_sequences is None:
        return None
    from dataclasses import replace

    from .predict import model_vp_rule

    rule = model_vp_rule(getattr(predictor, "data", {}))[0]
    if vp_range is not None:
        rule = replace(rule, pan_range=float(vp_range[0]), tilt_range=float(vp_range[1]))
    if vp_sequences is not None:
        rule = replace(rule, sequences=vp_sequences)
    return replace(rule, smooth=int(vp_smooth)) if vp_smooth is not None else rule


@dataclass(frozen=True)
class _Geometry:
    """How image files are warped besides the camera: the VP rule (None: the model's), ``--ego``
    and who hears what was used."""

    vp_rule: Any
    ego: str
    say: Optional[Callable[[str], None]]


def _with_ego(cam, ego: str, sample: Path):
    """(the camera of the images with ``--ego``'s own-vehicle rows, where they come from): 'auto' and
    'none' keep the camera as given (a folder of images is not searched: a video is); N sets the
    bottom N rows at the images' size (0: none)."""
    from vcprep.camera import Camera

    given = "the camera's ego_rows" if isinstance(cam, Camera) and cam.ego_rows else ""
    if ego in ("auto", "none"):
        return cam, given
    try:
        rows = int(ego)
    except ValueError:
        rows = -1
    if not isinstance(cam, Camera):
        raise InputError("--ego N needs one camera; per-frame calibration files give the frames' cameras", sample,
                         "write ego_rows in a camera file, or drop --ego")
    from dataclasses import replace

    from vcprep.imageio import image_size

    size = image_size(sample)
    if not 0 <= rows < size[1]:
        raise InputError(f"--ego '{ego}' is not auto, none or a number of rows below the images' {size[1]}", sample,
                         "give e.g. --ego 40, --ego 0 or --ego none")
    return replace(cam.for_image_size(size, sample), ego_rows=rows), f"--ego {rows}"


def _needs_no_camera(predictor) -> bool:
    """A resize model without the VP channel reads frames as they are: --camera changes nothing (and
    is not estimated: a folder of three frames is enough for it)."""
    return getattr(predictor, "mode", None) == "resize" and not getattr(predictor, "vp_channel", False)


def _predict_image_files(predictor, images: Sequence[Path], out: Path, camera_for: Optional[CameraFor],
                         keep_store: Optional[Path], within: str, overlay: bool, progress: bool,
                         geo: _Geometry) -> list[Path]:
    """Image files and folders: their camera from ``camera_for`` (a virtual-camera model needs
    one) with ``geo.ego``'s rows, then :func:`vctrain.predict.predict_images`."""
    from .predict import collect_images, predict_images

    cam, ego_source = None, ""
    if camera_for is not None and not _needs_no_camera(predictor):
        frames = [j.image for j in collect_images(images)]
        cam = camera_for(frames[0], frames=frames)
        if predictor.mode == "virtual":
            cam, ego_source = _with_ego(cam, geo.ego, frames[0])
    elif predictor.mode == "virtual":
        raise InputError("a virtual-camera model needs the camera of the images", predictor.path,
                         "add --camera (preset or calibration file)")
    return predict_images(predictor, images, out, cam, progress=progress, keep_store=keep_store, overlay=overlay,
                          within=within, vp_rule=geo.vp_rule, say=geo.say, ego_source=ego_source)


def _predict_onnx(graph: Path, images, out: Path, camera_for: Optional[CameraFor], store: Optional[Path],
                  within: str, overlay: bool, progress: bool) -> Predicted:
    """``vctrain predict GRAPH.onnx``: frames through a graph written by 'vctrain export'."""
    from .onnx_predict import OnnxPredictor, predict_images_onnx
    from .predict import collect_images

    if store is not None:
        raise InputError("an exported graph takes the camera's own frames, not a store", store,
                         "give the original frames (IMAGES)")
    predictor = OnnxPredictor(graph)
    cam = None
    if camera_for is not None:  # only for estimating the VPs of a --vp-input graph (the graph holds its own camera)
        frames = [j.image for j in collect_images(images)]
        cam = camera_for(frames[0], per_frame=False, frames=frames)
    written = predict_images_onnx(predictor, images, out, cam, progress=progress, overlay=overlay, within=within)
    source = f"ONNX graph, {predictor.mode} model"
    if predictor.beyond:
        pan, tilt = predictor.info["pose_range"]
        source += (f"; {count(predictor.beyond, 'frame')} with a VP beyond the graph's pose range ({pan:g}, {tilt:g} deg):"
                   " P(road) cut to its rectangle, export with a larger --pose-range")
    return Predicted(written, len(written), 0, source)
