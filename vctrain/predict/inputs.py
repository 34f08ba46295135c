"""What ``vctrain predict`` was given, checked and routed: image files and folders, videos or a
store, through a model (:class:`~vctrain.predict.Predictor`), the geometric prior
(:class:`~vctrain.adapt.PriorPredictor`) or a graph written by ``vctrain export``
(:class:`~vctrain.deploy.runtime.OnnxPredictor`). :func:`predict_inputs` returns the files written
and what was predicted (:class:`Predicted`)."""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Optional, Sequence

from vcprep.progress import count, rate_text
from vcprep.errors import InputError, one_of

__all__ = ["CameraFor", "Predicted", "predict_inputs"]

# the camera of the frames from --camera: camera_for(sample_image, per_frame=..., frames=...) -> Camera
# (or FrameCameras); the caller's, so that an estimated camera is said where the caller says things
CameraFor = Callable[..., Any]


@dataclass
class Predicted:
    """What :func:`predict_inputs` did: the mask files ``written`` (in order), how many images
    (None: no images or store given) and videos, through what (``source``), and the frames that
    ``failed`` (:meth:`said` names them)."""

    written: list[Path]
    images: Optional[int]
    videos: int
    source: str
    failed: list = field(default_factory=list)  # (file, VCError) of the frames that were skipped
    frames: int = 0       # frames predicted: images, and every video's frames
    seconds: float = 0.0  # wall-clock time of the whole run
    masks: list = field(default_factory=list)  # the masks of image files and store items (what eval scores)
    engine: str = ""      # what ran the network ('onnxruntime 1.32.0', 'PyTorch 2.13.0 (cuda:0)'; vctrain.deploy.engine)

    def said(self) -> list[str]:
        """One line per skipped frame: 'skipped: <file>: <problem> (<fix>)'."""
        from .road import skipped_lines

        return skipped_lines(self.failed)

    def line(self) -> str:
        """'3 images predicted (virtual model); 1.2 s, 2.5 frames/s', '1 image and 2 videos predicted
        (geometric prior); ...' (the rate counts every frame predicted, a video's included)."""
        what = " and ".join(([count(self.images, "image")] if self.images is not None else [])
                            + ([count(self.videos, "video")] if self.videos else []))
        engine = f"; {self.engine}" if self.engine else ""
        return f"{what} predicted ({self.source}{engine}); {rate_text(self.frames, self.seconds, 'frame')}"


def predict_inputs(checkpoint: Optional[Path], images: Optional[Sequence[Path]], out: Path,
                   camera_for: Optional[CameraFor] = None, prior: Optional[Path] = None, store: Optional[Path] = None,
                   device: str = "auto", keep_store: Optional[Path] = None, within: str = "auto",
                   overlay: bool = False, mask_video: bool = False, ego: Optional[str] = None,
                   progress: bool = True, vp_range: Optional[tuple[float, float]] = None,
                   vp_smooth: Optional[int] = None, vp_sequences: Optional[str] = None,
                   say: Optional[Callable[[str], None]] = None, beyond: Optional[str] = None,
                   engine: str | None = None, bev: Any = None) -> Predicted:
    """``vctrain predict``: ``checkpoint`` (a ``.pt`` model or an ``.onnx`` graph; with ``prior``
    it is the first image) on ``images`` (files, folders, videos) or every item of ``store``.
    ``camera_for`` (None: no --camera) gives the frames' camera. ``vp_range`` (pan, tilt degrees),
    ``vp_smooth`` (frames either side) and ``vp_sequences`` ('name', 'folder') change the rule
    estimated VPs follow (default: the model's, :func:`vctrain.predict.road.model_vp_rule`); ``say``
    (given) hears which VPs, own vehicle and rectangle image files were warped with. ``beyond``
    (a virtual-camera model only): the rule for frame pixels outside its training rectangle
    (:data:`vctrain.predict.frames.BEYOND`; None: the default, extend). ``engine`` runs a ``.pt``
    model's network (:data:`vctrain.deploy.engine.ENGINES`; 'auto': OpenVINO, else onnxruntime, on the
    CPU where installed) and a graph's (None or 'auto': the fastest installed; 'onnx', 'openvino');
    the prior runs in numpy; the summary line says which,
    and ``predict.json`` records it. ``bev`` (given: :class:`vctrain.predict.bev.BevOptions`): every
    frame's bird's-eye view and road in metres too (it needs ``camera_for``, or a graph's own camera).
    Bad combinations raise :class:`InputError` before anything is predicted."""
    if prior is not None:
        if checkpoint is not None and checkpoint.suffix.lower() == ".pt":
            raise InputError("give either a model or --prior, not both", checkpoint, "drop one of them")
        images = [checkpoint, *(images or [])] if checkpoint is not None else images  # all positionals are images
    elif checkpoint is None:
        raise InputError("no model given", None, "give MODEL.pt, or --prior prior.npy to segment with the prior")
    from vcprep.io import is_video

    from .video import check_video_stems

    if mask_video and not any(is_video(p) for p in images or []):
        raise InputError("--mask-video is for videos", None, "give a video file, or drop --mask-video")
    if store is None and not images:
        raise InputError("nothing to predict", None, "give image files/folders, or --store STORE")
    if store is not None and images:
        raise InputError("give either IMAGES or --store, not both", store, "run predict twice")
    graph = prior is None and checkpoint.suffix.lower() == ".onnx"  # an exported graph: its camera is inside
    if graph and store is not None:
        raise InputError("an exported graph takes the camera's own frames, not a store", store,
                         "give the original frames (IMAGES)")
    videos = check_video_stems([p for p in images or [] if is_video(p)])
    images = [p for p in images or [] if not is_video(p)]
    predictor = _predictor(checkpoint, prior, device, engine)
    engine_used = _engine_used(predictor)  # said in the summary line (Predicted.line)
    if beyond is not None:
        _set_beyond(predictor, beyond, checkpoint if prior is None else prior)
    if bev is not None and camera_for is None and getattr(predictor, "camera", None) is None:
        from .bev import BEV_NEEDS_CAMERA

        raise InputError("--bev needs the frames' camera", checkpoint if prior is None else prior, BEV_NEEDS_CAMERA)
    if store is None:  # (frames: a study's candidate model takes stores only, said before any frame is read)
        from .frames import refuse_mixed

        refuse_mixed(predictor)
    existed, poses = Path(out).exists(), {}
    bev = _keeping_poses(bev, poses)
    try:
        result = _predict_all(predictor, prior, images, videos, out, camera_for, store, keep_store, within, overlay,
                              mask_video, ego, progress, vp_range, vp_smooth, vp_sequences, say, bev)
        result.engine = engine_used
    except BaseException:
        if not existed:
            _remove_empty(Path(out))
        raise
    if not existed and not result.written:
        _remove_empty(Path(out))
    elif result.written:
        from ..evaluate import record_predictions

        record_predictions(Path(out), prior if prior is not None else checkpoint, result.masks, engine_used,
                           inputs=[str(p) for p in [*videos, *images, *([store] if store else [])]], poses=poses)
        if poses and say is not None:
            from .bev import poses_line

            say(poses_line(poses))
    return result


def _keeping_poses(bev, poses: dict):
    """``--bev``'s options, each frame's BEV pose also kept in ``poses`` (for predict.json: eval --bev takes them)."""
    if bev is None:
        return None
    from .bev import recording

    return recording(bev, poses)


def _set_beyond(predictor: Any, beyond: str, path: Path) -> None:
    """``--beyond``: checked, and given to a virtual-camera model (the only kind it concerns)."""
    from .frames import BEYOND

    if beyond not in BEYOND:
        raise InputError(f"unknown --beyond '{beyond}'", None, one_of(beyond, BEYOND))
    if getattr(predictor, "beyond_rule", None) is None or getattr(predictor, "mode", None) != "virtual" \
            or getattr(predictor, "takes_frames", False):
        raise InputError("--beyond is for a virtual-camera model (.pt); a resize model, the prior and an "
                         "exported graph (rays, inside it) have no choice to make", path, "drop --beyond")
    predictor.beyond_rule = beyond


def _remove_empty(out: Path) -> None:
    """Remove ``out`` (created by this run) where nothing was written in it: a refused run leaves no
    empty output folder behind (a video's frame folder included)."""
    if not out.is_dir():
        return
    for d in sorted((p for p in out.rglob("*") if p.is_dir()), key=lambda p: len(p.parts), reverse=True):
        if not any(d.iterdir()):
            d.rmdir()
    if not any(out.iterdir()):
        out.rmdir()


def _predict_all(predictor, prior, images, videos, out, camera_for, store, keep_store, within, overlay, mask_video,
                 ego, progress, vp_range, vp_smooth, vp_sequences, say, bev=None) -> Predicted:
    """:func:`predict_inputs` once its inputs are checked: the videos, the store, the image files."""
    from .frames import StageTimes
    from .video import predict_video

    rule = _vp_rule(predictor, vp_range, vp_smooth, vp_sequences)
    written, t0, times = [], time.perf_counter(), StageTimes()
    if videos:
        for v in videos:  # 'estimate': from a sample of the video's own frames (its overlay draws the horizon)
            vcam = camera_for(None, per_frame=False, frames=[v]) if camera_for is not None else None
            written += predict_video(predictor, v, out, vcam, within=within, mask_video=mask_video, overlay=overlay,
                                     progress=progress, ego=ego, times=times, vp_rule=rule, bev=bev,
                                     **({"vp_window": vp_smooth} if vp_smooth is not None else {}))
    n_images = 0
    if store is not None:
        from vcprep.store import Store

        from .predictor import predict_store

        opened = Store.open(store)
        written = predict_store(predictor, opened, out, progress=progress, overlay=overlay,
                                bev=_store_bev(bev, opened, camera_for, within))
        n_images = len(written)
    failed, masks = [], [p for p in written if Path(p).name.endswith("_mask.png")]  # a video's frames
    masks = list(written) if store is not None else masks
    if images:
        run = _predict_image_files(predictor, images, out, camera_for, keep_store, within, overlay, progress,
                                   ego, rule, say, bev)
        written += run.written
        masks += run.written
        failed = run.failed
        n_images = len(run.written) + len(failed)
    return Predicted(written, n_images if images or store else None, len(videos), _source(predictor, prior), failed,
                     times.frames + n_images - len(failed), time.perf_counter() - t0, masks)


def _store_bev(bev, store, camera_for: Optional[CameraFor], within: str):
    """``--bev``'s :class:`~vctrain.predict.bev.BevRun` for a store's items: their camera from ``--camera``."""
    if bev is None:
        return None
    from .bev import BevRun

    sources = [Path(r["source"]) for r in store]
    return BevRun(bev, camera_for(sources[0], frames=sources) if sources else None, within, store.root)


def _source(predictor, prior: Optional[Path]) -> str:
    """What predicted, for the summary line; a graph also says how many frames' VPs lay beyond its
    pose range (P(road) cut to its rectangle there)."""
    if prior is not None:
        return "geometric prior"
    if not getattr(predictor, "takes_frames", False):
        return predictor.mode + " model"
    source = f"ONNX graph, {predictor.mode} model"
    if predictor.beyond:
        pan, tilt = predictor.info["pose_range"]
        source += (f"; {count(predictor.beyond, 'frame')} with a VP beyond the graph's pose range ({pan:g}, {tilt:g} deg):"
                   " its rectangle holds less of them than vctrain predict's, export with a larger --pose-range")
    return source


def _predictor(checkpoint: Optional[Path], prior: Optional[Path], device: str, engine: str | None = None):
    """The prior's predictor (``prior`` given), an exported graph's (``.onnx``) or the checkpoint's
    model on ``device`` through ``engine`` (None: torch for a checkpoint, the fastest runtime installed
    for a graph)."""
    if prior is None and checkpoint.suffix.lower() == ".onnx":
        from ..deploy.runtime import OnnxPredictor

        if engine == "torch":
            raise InputError("an exported graph runs in OpenVINO or onnxruntime, not PyTorch", checkpoint,
                             "drop --engine torch, or give the .pt model")
        return OnnxPredictor(checkpoint, runtime=engine)
    if prior is not None:
        from ..adapt import PriorPredictor

        return PriorPredictor(prior)
    from .predictor import Predictor

    return Predictor(checkpoint, device, engine or "torch")


def _engine_used(predictor) -> str:
    """What runs the network, as stderr and predict.json say it ('' for the prior: no network)."""
    from ..deploy.engine import engine_name
    from ..deploy.runtime import runtime_name

    if getattr(predictor, "takes_frames", False):
        return f"{runtime_name(predictor.runtime)}, the graph{' (int8)' if predictor.info.get('int8') else ''}"
    kind = getattr(predictor, "engine", None)
    if kind is None:
        return ""
    device = str(predictor.device)
    return engine_name(kind) + (", the network exported in memory" if kind != "torch" else "") + \
        (f" on {device}" if device != "cpu" else "")


def _vp_rule(predictor, vp_range: Optional[tuple[float, float]], vp_smooth: Optional[int],
             vp_sequences: Optional[str] = None):
    """The model's VP rule with ``vp_range``, ``vp_smooth`` and ``vp_sequences`` where given (None:
    none given)."""
    if vp_range is None and vp_smooth is None and vp_sequences is None:
        return None
    from dataclasses import replace

    from .road import model_vp_rule

    rule = model_vp_rule(getattr(predictor, "data", {}))[0]
    if vp_range is not None:
        rule = replace(rule, pan_range=float(vp_range[0]), tilt_range=float(vp_range[1]))
    if vp_sequences is not None:
        rule = replace(rule, sequences=vp_sequences)
    return replace(rule, smooth=int(vp_smooth)) if vp_smooth is not None else rule


def _needs_no_camera(predictor) -> bool:
    """A resize model without the VP channel reads frames as they are, and a graph holds its camera
    (a --vp-input graph's VPs are estimated with the given one): --camera changes nothing there (it is
    checked, not estimated: a folder of three frames is enough)."""
    if getattr(predictor, "takes_frames", False):
        return not predictor.vp_input
    from .frames import reads_road_vps

    return not reads_road_vps(predictor)


def _predict_image_files(predictor, images: Sequence[Path], out: Path, camera_for: Optional[CameraFor],
                         keep_store: Optional[Path], within: str, overlay: bool, progress: bool,
                         ego: Optional[str] = None, vp_rule: Any = None, say: Optional[Callable[[str], None]] = None,
                         bev: Any = None):
    """Image files and folders: their camera from ``camera_for`` (a virtual-camera model needs
    one; with one camera, its own vehicle found from the frames unless the camera states it: ``ego``
    as for a video; a resize model cuts it only when ``ego`` asks), then
    :func:`vctrain.predict.predictor.predict_frames` (the one road for a frame) with ``vp_rule``
    (None: the model's); ``say`` hears what the frames were warped with; ``bev``: as run_road takes it."""
    from vcprep.camera import Camera
    from vcprep.progress import err
    from vcprep.dataset import collect_images

    from .frames import NEEDS_CAMERA, reads_road_vps, warps_frames
    from .predictor import predict_frames
    from .road import folder_ego_camera, frames_ego_rows

    cam, ego_source, rows = None, "", None
    if camera_for is not None:  # checked even where the model needs none: a typo is never silent
        jobs = collect_images(images, trees=True)
        needed = bev is not None or not _needs_no_camera(predictor)  # (--bev: the road in metres needs it)
        cam = camera_for(jobs[0].image, frames=[j.image for j in jobs], needed=needed)
    if camera_for is None and warps_frames(predictor):
        raise InputError("a virtual-camera model needs the camera of the images", predictor.path, NEEDS_CAMERA)
    if camera_for is None and reads_road_vps(predictor):
        raise InputError("this model reads each frame's road vanishing point (VP channel): it needs the camera of "
                         "the images", predictor.path, NEEDS_CAMERA)
    files = [j.image for j in collect_images(images, trees=True)]
    tell = (lambda msg: err(f"{files[0].parent}: {msg}")) if progress else None
    warn = lambda msg: err(f"{files[0].parent}: warning: {msg}")  # noqa: E731
    one = cam if isinstance(cam, Camera) else None
    if ego not in (None, "none", "auto") and cam is not None and one is None:
        raise InputError("--ego N needs one camera; per-frame calibration files give the frames' cameras",
                         files[0], "write ego_rows in a camera file, or drop --ego")
    if _reads_frames_as_they_are(predictor) and ego not in (None, "none"):  # asked for: its own vehicle cut
        rows = frames_ego_rows(one, files, ego, tell, warn)
        ego_source = f"--ego {ego}" if ego != "auto" else "the camera's ego_rows" if cam and cam.ego_rows else ""
    elif reads_road_vps(predictor) and isinstance(cam, Camera):  # one camera's frames: its own vehicle, as a video's
        ego = ego or "auto"
        stated = cam.ego_rows or cam.ego_stated  # (an explicit 'ego_rows: 0': none, and no search)
        cam = folder_ego_camera(cam, files, ego, tell, warn)
        ego_source = (f"--ego {ego}" if ego not in ("auto", "none") else "the camera's ego_rows" if stated
                      else "found from the frames" if cam.ego_rows else "")
    return predict_frames(predictor, images, out, cam, progress=progress, keep_store=keep_store, overlay=overlay,
                          within=within, vp_rule=vp_rule, say=say, ego_source=ego_source, vehicle=rows, bev=bev)


def _reads_frames_as_they_are(predictor) -> bool:
    """A model (not a graph) that neither warps frames nor reads their road VPs: a resize model."""
    from .frames import reads_road_vps, warps_frames

    return not getattr(predictor, "takes_frames", False) and not warps_frames(predictor) \
        and not reads_road_vps(predictor)
