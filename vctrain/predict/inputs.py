"""What ``vctrain predict`` was given, checked and routed: image files and folders, videos or a
store, through a model (:class:`~vctrain.predict.Predictor`), the geometric prior
(:class:`~vctrain.adapt.PriorPredictor`) or a graph written by ``vctrain export``
(:class:`~vctrain.deploy.runtime.OnnxPredictor`). The command builds one :class:`PredictOptions`;
:func:`predict_inputs` takes it and returns the files written and what was predicted
(:class:`Predicted`). Frames take the road the Python face takes (:mod:`vctrain.predict.road`,
:mod:`vctrain.predict.model`)."""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any, Callable, Optional, Sequence

from vcprep.progress import count, rate_text
from vcprep.camera import camera_from_spec
from vcprep.errors import InputError

from .model import engine_used, open_predictor, set_beyond

__all__ = ["CameraFor", "Predicted", "PredictOptions", "predict_inputs"]

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
    load_seconds: float = 0.0     # the model read (a checkpoint, its network built; a graph's file); 0: given loaded
    compile_seconds: float = 0.0  # the network exported and compiled (an exported engine's, a graph's); not in the rate
    engine_note: str = ""         # why auto ran PyTorch on the CPU (vctrain.deploy.engine.engine_note); '' otherwise

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
        return f"{what} predicted ({self.source}{engine}); " \
               f"{rate_text(self.frames, max(0.0, self.seconds - self.compile_seconds), 'frame')}"

    def startup_line(self) -> str:
        """'start-up: loaded in 0.4 s, the network exported and compiled in 1.1 s (OpenVINO 2026.4.1, the
        network exported in memory)': what the run paid once, apart from the frames' time (the summary
        line's rate leaves the export and compile out), the engine, and why auto ran PyTorch where it did."""
        what = "the network exported and compiled" if "exported in memory" in self.engine else "compiled"
        about = "; ".join(filter(None, (self.engine, self.engine_note)))
        return f"start-up: loaded in {self.load_seconds:.1f} s" + \
            (f", {what} in {self.compile_seconds:.1f} s" if self.compile_seconds else "") + (f" ({about})" if about else "")

    @property
    def startup(self) -> dict:
        """What the run paid once, as predict.json records it: {'load_s': .., 'compile_s': ..}."""
        return {"load_s": round(self.load_seconds, 3), "compile_s": round(self.compile_seconds, 3)}


@dataclass(frozen=True)
class PredictOptions:
    """Everything ``vctrain predict`` was asked, one field per option (the defaults are the command's;
    ``vctrain predict --help`` says what each does)."""

    model: Optional[Path] = None          # a .pt, an exported .onnx or a shipped name (with prior: an image)
    images: tuple = ()                    # image files, folders, videos
    out: Path = Path("preds")
    camera: Optional[str] = None          # --camera: a preset, a file, a per-frame folder, 'estimate'
    prior: Optional[Path] = None          # --prior: the geometric prior instead of a model
    store: Optional[Path] = None          # --store: every item of this store instead of images
    device: str = "auto"
    engine: Optional[str] = None          # None: torch for a .pt, the fastest runtime for a graph
    keep_store: Optional[Path] = None
    within: str = "auto"
    overlay: bool = False
    mask_video: bool = False
    ego: Optional[str] = None
    vp_range: Optional[tuple] = None      # (pan, tilt) degrees
    vp_smooth: Optional[int] = None
    vp_sequences: Optional[str] = None
    beyond: Optional[str] = None          # None: vctrain.predict.frames.DEFAULT_BEYOND
    bev: Any = None                       # --bev: a vctrain.predict.bev.BevOptions
    progress: bool = True
    output: str = "road"                  # --output: which output of a two-output model (road, drivable)

    @property
    def source(self) -> Path:
        """What predicts (the prior or the model), as errors and predict.json name it."""
        return self.prior if self.prior is not None else self.model


def predict_inputs(options: PredictOptions, say: Optional[Callable[[str], None]] = None,
                   note: Optional[Callable[[str], None]] = None, predictor: Any = None) -> Predicted:
    """``vctrain predict`` (:class:`PredictOptions`): a ``.pt`` model, an ``.onnx`` graph or the prior
    on image files, folders and videos, or on every item of a store; writes the masks, returns what
    was done (:class:`Predicted`). ``say`` (given) hears which VPs, own vehicle and rectangle image
    files were warped with; ``note`` (given) hears an estimated camera's line; ``predictor``: the
    model already loaded (a benchmark's, so that its load is not timed). Estimated VPs follow the
    model's rule (:func:`vctrain.predict.road.model_vp_rule`) changed by ``vp_range``, ``vp_smooth``
    and ``vp_sequences``; the summary line and ``predict.json`` say which engine ran the network.
    Bad combinations raise :class:`InputError` before anything is predicted."""
    opts = _checked(options)
    from vcprep.io import is_video

    from .video import check_video_stems

    videos = check_video_stems([p for p in opts.images if is_video(p)])
    images = [p for p in opts.images if not is_video(p)]
    t0, given = time.perf_counter(), predictor is not None
    if hasattr(predictor, "use_output"):  # (a model given loaded: the output asked)
        predictor.use_output(opts.output)
    predictor = predictor or open_predictor(opts.source, opts.device, opts.engine, prior=opts.prior is not None,
                                            output=opts.output)
    spent = _startup(predictor, 0.0 if given else time.perf_counter() - t0, given)
    engine = engine_used(predictor)  # said in the summary line (Predicted.line)
    if opts.beyond is not None:
        set_beyond(predictor, opts.beyond, opts.source)
    if opts.bev is not None and opts.camera is None and predictor.camera is None:
        from .bev import BEV_NEEDS_CAMERA

        raise InputError("--bev needs the frames' camera", opts.source, BEV_NEEDS_CAMERA)
    if opts.store is None:  # (frames: a study's candidate model takes stores only, said before any frame is read)
        from .frames import refuse_mixed

        refuse_mixed(predictor)
    camera_for = partial(camera_from_spec, opts.camera, say=note) if opts.camera is not None else None
    out, existed, poses = Path(opts.out), Path(opts.out).exists(), {}
    opts = _keeping_poses(opts, poses)
    try:
        result = _predict_all(opts, predictor, images, videos, camera_for, say)
        result.engine = engine
        result.load_seconds, result.compile_seconds = spent()
        result.engine_note = getattr(predictor, "engine_note", "")
    except BaseException:
        if not existed:
            _remove_empty(out)
        raise
    if not existed and not result.written:
        _remove_empty(out)
    elif result.written:
        from ..evaluate import record_predictions

        record_predictions(out, opts.source, result.masks, engine, poses=poses, startup=result.startup, output=opts.output,
                           inputs=[str(p) for p in [*videos, *images, *([opts.store] if opts.store else [])]])
        if poses and say is not None:
            from .bev import poses_line

            say(poses_line(poses))
    return result


def _startup(predictor, load_s: float, given: bool) -> Callable[[], tuple[float, float]]:
    """A function giving (load s, export/compile s) of the run so far: ``load_s`` (the predictor's
    load, wall time) less a graph's compile at its load, counted with the compiles (an exported
    engine's: once per input size, at its first frame); ``given``: loaded by the caller, its load
    and earlier compiles not counted."""
    before = getattr(predictor, "compile_seconds", 0.0) if given else 0.0
    load = max(0.0, load_s - (getattr(predictor, "compile_seconds", 0.0) - before))  # (a graph compiles at its load)
    return lambda: (load, getattr(predictor, "compile_seconds", 0.0) - before)


def _keeping_poses(opts: PredictOptions, poses: dict) -> PredictOptions:
    """``opts`` whose ``--bev`` also keeps each frame's BEV pose in ``poses`` (for predict.json: eval --bev
    takes them)."""
    if opts.bev is None:
        return opts
    from dataclasses import replace

    from .bev import recording

    return replace(opts, bev=recording(opts.bev, poses))


def _checked(opts: PredictOptions) -> PredictOptions:
    """``opts`` with every positional of a ``--prior`` run an image, and its bad combinations refused."""
    from dataclasses import replace

    from vcprep.io import is_video

    model, images = opts.model, tuple(opts.images or ())
    if opts.prior is not None:
        if model is not None and Path(model).suffix.lower() == ".pt":
            raise InputError("give either a model or --prior, not both", model, "drop one of them")
        images, model = ((Path(model), *images) if model is not None else images), None  # all positionals are images
    elif model is None:
        raise InputError("no model given", None, "give MODEL.pt, or --prior prior.npy to segment with the prior")
    opts = replace(opts, model=model, images=images)
    if opts.mask_video and not any(is_video(p) for p in images):
        raise InputError("--mask-video is for videos", None, "give a video file, or drop --mask-video")
    if opts.store is None and not images:
        raise InputError("nothing to predict", None, "give image files/folders, or --store STORE")
    if opts.store is not None and images:
        raise InputError("give either IMAGES or --store, not both", opts.store, "run predict twice")
    if opts.prior is None and Path(model).suffix.lower() == ".onnx" and opts.store is not None:
        raise InputError("an exported graph takes the camera's own frames, not a store", opts.store,
                         "give the original frames (IMAGES)")  # (its camera is inside)
    return opts


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


def _predict_all(opts: PredictOptions, predictor, images: list[Path], videos: list[Path],
                 camera_for: Optional[CameraFor], say) -> Predicted:
    """:func:`predict_inputs` once its inputs are checked: the videos, the store, the image files."""
    from .frames import StageTimes
    from .video import predict_video

    rule = _vp_rule(predictor, opts.vp_range, opts.vp_smooth, opts.vp_sequences)
    written, t0, times, out = [], time.perf_counter(), StageTimes(), opts.out
    for v in videos:  # 'estimate': from a sample of the video's own frames (its overlay draws the horizon)
        vcam = camera_for(None, per_frame=False, frames=[v]) if camera_for is not None else None
        written += predict_video(predictor, v, out, vcam, within=opts.within, mask_video=opts.mask_video,
                                 overlay=opts.overlay, progress=opts.progress, ego=opts.ego, times=times, vp_rule=rule,
                                 bev=opts.bev, **({"vp_window": opts.vp_smooth} if opts.vp_smooth is not None else {}))
    n_images = 0
    if opts.store is not None:
        from vcprep.store import Store

        from .predictor import predict_store

        opened = Store.open(opts.store)
        written = predict_store(predictor, opened, out, progress=opts.progress, overlay=opts.overlay,
                                bev=_store_bev(opts.bev, opened, camera_for, opts.within))
        n_images = len(written)
    failed, masks = [], [p for p in written if Path(p).name.endswith("_mask.png")]  # a video's frames
    masks = list(written) if opts.store is not None else masks
    if images:
        run = _predict_image_files(opts, predictor, images, camera_for, rule, say)
        written += run.written
        masks += run.written
        failed = run.failed
        n_images = len(run.written) + len(failed)
    return Predicted(written, n_images if images or opts.store else None, len(videos), _source(predictor, opts.prior, opts.output),
                     failed, times.frames + n_images - len(failed), time.perf_counter() - t0, masks)


def _store_bev(bev, store, camera_for: Optional[CameraFor], within: str):
    """``--bev``'s :class:`~vctrain.predict.bev.BevRun` for a store's items: their camera from ``--camera``."""
    if bev is None:
        return None
    from .bev import BevRun

    sources = [Path(r["source"]) for r in store]
    return BevRun(bev, camera_for(sources[0], frames=sources) if sources else None, within, store.root)


def _source(predictor, prior: Optional[Path], output: str = "road") -> str:
    """What predicted, for the summary line (the output written where it is not road); a graph also says
    how many frames' VPs lay beyond its pose range (P(road) cut to its rectangle there)."""
    if prior is not None:
        return "geometric prior"
    which = "" if output == "road" else f", its {output} output"
    if not predictor.takes_frames:
        return predictor.mode + " model" + which
    source = f"ONNX graph, {predictor.mode} model{which}"
    if predictor.beyond:
        pan, tilt = predictor.info["pose_range"]
        source += (f"; {count(predictor.beyond, 'frame')} with a VP beyond the graph's pose range ({pan:g}, {tilt:g} deg):"
                   " its rectangle holds less of them than vctrain predict's, export with a larger --pose-range")
    return source


def _vp_rule(predictor, vp_range: Optional[tuple[float, float]], vp_smooth: Optional[int],
             vp_sequences: Optional[str] = None):
    """The model's VP rule with ``vp_range``, ``vp_smooth`` and ``vp_sequences`` where given (None:
    none given)."""
    if vp_range is None and vp_smooth is None and vp_sequences is None:
        return None
    from dataclasses import replace

    from .road import model_vp_rule

    rule = model_vp_rule(predictor.data)[0]
    if vp_range is not None:
        rule = replace(rule, pan_range=float(vp_range[0]), tilt_range=float(vp_range[1]))
    if vp_sequences is not None:
        rule = replace(rule, sequences=vp_sequences)
    return replace(rule, smooth=int(vp_smooth)) if vp_smooth is not None else rule


def _needs_no_camera(predictor) -> bool:
    """A resize model without the VP channel reads frames as they are, and a graph holds its camera
    (a --vp-input graph's VPs are estimated with the given one): --camera changes nothing there (it is
    checked, not estimated: a folder of three frames is enough)."""
    if predictor.takes_frames:
        return not predictor.vp_input
    from .frames import reads_road_vps

    return not reads_road_vps(predictor)


def _predict_image_files(opts: PredictOptions, predictor, images: Sequence[Path], camera_for: Optional[CameraFor],
                         vp_rule: Any = None, say: Optional[Callable[[str], None]] = None):
    """Image files and folders: their camera from ``camera_for`` (a virtual-camera model needs
    one; with one camera, its own vehicle found from the frames unless the camera states it:
    ``opts.ego`` as for a video; a resize model cuts it only when ``ego`` asks), then
    :func:`vctrain.predict.road.run_road` (the one road for a frame; ``--keep-store``: through a store,
    :func:`vctrain.predict.predictor.predict_frames`) with ``vp_rule`` (None: the model's); ``say``
    hears what the frames were warped with."""
    from vcprep.camera import Camera
    from vcprep.dataset import collect_images

    from .frames import NEEDS_CAMERA, reads_road_vps, warps_frames
    from vcprep.progress import err

    from .predictor import predict_frames
    from .road import run_road
    from .vehicle import files_vehicle

    if camera_for is None and warps_frames(predictor):
        raise InputError("a virtual-camera model needs the camera of the images", predictor.path, NEEDS_CAMERA)
    if camera_for is None and reads_road_vps(predictor):
        raise InputError("this model reads each frame's road vanishing point (VP channel): it needs the camera of "
                         "the images", predictor.path, NEEDS_CAMERA)
    jobs = collect_images(images, trees=True)  # (once: the camera, the own vehicle and the road take them)
    cam, files = None, [j.image for j in jobs]
    if camera_for is not None:  # checked even where the model needs none: a typo is never silent
        needed = opts.bev is not None or not _needs_no_camera(predictor)  # (--bev: the road in metres needs it)
        cam = camera_for(files[0], frames=files, needed=needed)
    if opts.ego not in (None, "none", "auto") and cam is not None and not isinstance(cam, Camera):
        raise InputError("--ego N needs one camera; per-frame calibration files give the frames' cameras",
                         files[0], "write ego_rows in a camera file, or drop --ego")
    tell = (lambda msg: err(f"{files[0].parent}: {msg}")) if opts.progress else None
    warn = lambda msg: err(f"{files[0].parent}: warning: {msg}")  # noqa: E731
    cam, rows, ego_source = files_vehicle(predictor, cam, files, opts.ego, tell, warn)
    if opts.keep_store is not None and warps_frames(predictor):  # the store path: warped into a store kept
        return predict_frames(predictor, images, opts.out, cam, progress=opts.progress, keep_store=opts.keep_store,
                              overlay=opts.overlay, within=opts.within, vp_rule=vp_rule, say=say,
                              ego_source=ego_source, vehicle=rows, bev=opts.bev)
    return run_road(predictor, images, opts.out, cam, progress=opts.progress, overlay=opts.overlay,
                    within=opts.within, vp_rule=vp_rule, say=say, ego_source=ego_source, vehicle=rows, bev=opts.bev,
                    jobs=jobs)
