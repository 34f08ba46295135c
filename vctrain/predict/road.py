"""One road for a frame: image files and folders, through a model, the prior or an exported graph.

Every frame goes the way a video's frames go (:class:`~vctrain.predict.frames.FramePredictor`, in
memory): read, its road VP, warp into the model's virtual camera (a graph warps inside itself),
the network, back-projection to the frame's own pixels, write. One set of checks and rules serves
all of them:

* which VPs the frames get (:func:`within_rule`): the model's own rule for ``--within auto``;
* the virtual camera's rectangle: the training's, extended once for every frame of the folder at
  the pose it is warped with (:func:`rectangle_views`), so all frames share one rectangle;
* a frame that cannot be read or predicted is skipped: its outputs are removed, the other frames
  are still predicted, and :class:`RoadRun` names it (``vctrain predict`` says it on stderr and
  exits 1).

A virtual-camera model's masks are those of the store path (the frames warped into a store with
:func:`vcprep.store.warp_dataset`, then read back: :func:`vctrain.predict.predictor.predict_store`),
bit for bit: the warp is the store build's own body and the store's PNGs are lossless. That path
stays for stores that exist already (``--store``) and for ``--keep-store``.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np
from tqdm import tqdm

from vcprep.camera import Camera, FrameCameras, camera_of_image
from vcprep.dataset import Job, collect_images
from vcprep.errors import InputError, VCError
from vcprep.io import image_size, read_image, write_png
from vcprep.warp import pose_from_vp

from .frames import FramePredictor, warps_frames

__all__ = ["own_vehicle", "folder_ego_camera", "RoadRun", "skipped_lines", "within_rule", "virtual_within", "rectangle_views", "run_road", "write_prediction", "out_dir"]


@dataclass
class RoadRun:
    """What a run of :func:`predict_images` did: the mask files ``written`` (in order) and the
    frames that ``failed`` ((file, error) pairs, each already said on stderr)."""

    written: list[Path] = field(default_factory=list)
    failed: list[tuple[Path, VCError]] = field(default_factory=list)
    seconds: float = 0.0

    def fail(self, job: Job, error: VCError) -> None:
        """Count ``job`` as failed (the caller names the failed frames: :meth:`said`)."""
        self.failed.append((job.image, error))

    def said(self) -> list[str]:
        return skipped_lines(self.failed)


def skipped_lines(failed: list[tuple[Path, VCError]]) -> list[str]:
    """One line per failed frame: 'skipped: <file>: <problem> (<fix>)'."""
    return [f"skipped: {e}" if e.file else f"skipped: {f}: {e}" for f, e in failed]


def write_prediction(out: Path, stem: str, prob: np.ndarray, overlay_on: str | Path | None = None) -> tuple[Path, Path]:
    """Write ``<stem>_prob.png`` (0-255) and ``<stem>_mask.png`` (0/255); with ``overlay_on``
    (the original image) also ``<stem>_overlay.png``: predicted road in green over the image."""
    p8 = np.clip(np.rint(prob * 255.0), 0, 255).astype(np.uint8)
    mask = np.where(prob >= 0.5, 255, 0).astype(np.uint8)
    pp, mp = out / f"{stem}_prob.png", out / f"{stem}_mask.png"
    write_png(pp, p8)
    write_png(mp, mask, kind="mask")
    if overlay_on is not None:
        from vcprep.figures import overlay_label

        write_png(out / f"{stem}_overlay.png", overlay_label(read_image(overlay_on).array, (mask > 0).astype(np.uint8)),
                  level=3)
    return mp, pp


def out_dir(out: str | Path) -> Path:
    """``out`` as a folder (created): an error if it is a file."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError("exists and is not a directory", out, "choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    return out


def within_rule(predictor: Any, within: str, camera: Camera | FrameCameras | None) -> str:
    """'estimate', 'none' or a CSV path: which road VPs the frames get (``vctrain predict --within``).

    ``auto``: per-frame VPs when the model was trained with them (a virtual-camera model whose
    training store has estimated VPs, a graph exported with ``--vp-input``), else the camera's
    pose. A resize model takes a VP only through its VP channel."""
    if getattr(predictor, "takes_frames", False):
        if not predictor.vp_input:
            if within not in ("auto", "none"):
                raise InputError("this graph has the camera's mount pose built in (exported without --vp-input)",
                                 predictor.path, "drop --within, or export with --vp-input")
            return "none"
        return "estimate" if within == "auto" else within
    if not warps_frames(predictor):
        return within if within != "auto" and getattr(predictor, "vp_channel", False) else "none"
    return virtual_within(predictor.data, within, camera)


def virtual_within(data: dict[str, Any], within: str, camera: Camera | FrameCameras | None) -> str:
    """:func:`within_rule` for a model warped into its virtual camera (checkpoint ``data``): 'auto'
    estimates VPs when its training store had estimated ones; calibrated poses (one file, a
    per-frame folder) are no VPs, and a per-frame folder already gives every frame its pose."""
    if within == "auto":
        trained = set(data.get("vp_status", [])) - {"camera", "calibrated"}
        return "estimate" if trained and not isinstance(camera, FrameCameras) else "none"
    if within != "none" and isinstance(camera, FrameCameras):
        raise InputError("--within needs one camera; a per-frame calibration folder already gives every frame its "
                         "exact pose", camera.folder, "drop --within, or give one camera file or preset")
    return within


def own_vehicle(cam: Camera, source: str | Path, ego: str, say: Callable[[str], None] | None,
                estimate: Callable[[], Any]) -> Camera:
    """``cam`` with its own vehicle's rows (``ego_rows``), one rule for a video and a folder of one
    camera's frames. ``ego``: 'auto' (the camera's ``ego_rows`` when it states them, else found by
    ``estimate()`` -> :class:`vcprep.camera.EgoEstimate` from frames, said through ``say``; too few
    distinct frames: none, also said), 'none' (the camera as given, no search) or a whole number of
    rows at the camera's size (0: no own vehicle)."""
    from dataclasses import replace

    from vcprep.camera import rows_at_height

    if ego == "none" or (ego == "auto" and cam.ego_rows):
        return cam
    if ego != "auto":
        try:
            rows = int(ego)
        except ValueError:
            rows = -1
        if not 0 <= rows < cam.size[1]:
            raise InputError(f"--ego '{ego}' is not auto, none or a number of rows below the frames' "
                             f"{cam.size[1]}", source, "give e.g. --ego 40, --ego 0 or --ego none")
        return replace(cam, ego_rows=rows)
    say = say or (lambda _msg: None)
    try:
        est = estimate()
    except InputError as e:
        say(f"own vehicle: not looked for ({e.problem}); set ego_rows in the camera file, or --ego N")
        return cam
    if est.rows:
        say(f"own vehicle: {est.rows} rows found from the frames ({est.describe()}); set ego_rows in the "
            f"camera file to override")
    else:
        say(f"own vehicle: none found from the frames ({est.describe()}); set ego_rows in the camera file if "
            f"it shows one")
    return replace(cam, ego_rows=rows_at_height(est, cam.size[1]))


def folder_ego_camera(camera: Camera, files: list[Path], ego: str = "auto",
                      say: Callable[[str], None] | None = None) -> Camera:
    """``camera`` at the size of the first of ``files`` (one camera's frames) with its own vehicle's
    rows (:func:`own_vehicle`: 'auto' looks in up to :data:`vcprep.io.EGO_SAMPLES` frames spread
    over the folder, as a video's are)."""
    from vcprep.camera import ego_rows_from_frame_files
    from vcprep.io import EGO_SAMPLES

    files = [Path(f) for f in files]
    cam = camera.for_image_size(image_size(files[0]), files[0])
    picks = sorted({int(round(k)) for k in np.linspace(0, len(files) - 1, min(EGO_SAMPLES, len(files)))})
    return own_vehicle(cam, files[0].parent, ego, say,
                       lambda: ego_rows_from_frame_files([files[k] for k in picks], files[0].parent))


def frame_vps(jobs: list[Job], camera: Camera | FrameCameras | None, rule: str,
              on_error=None) -> dict[str, tuple[float, float]]:
    """Each frame's road VP (source pixels) by ``rule`` (:func:`within_rule`); {} for 'none'. The
    sequence rules run over the folder (:func:`vcprep.vp.vps_for_items`); ``on_error(job, error)``
    takes a frame that cannot be read."""
    if rule == "none":
        return {}
    from vcprep.vp import vps_for_items

    res = vps_for_items([j.image for j in jobs], [j.id for j in jobs], camera, rule,
                        on_error=(lambda i, e: on_error(jobs[i], e)) if on_error else None)
    return {j.id: (float(r.vp[0]), float(r.vp[1])) for j, r in zip(jobs, res) if r is not None}


def rectangle_views(jobs: list[Job], camera: Camera | FrameCameras, vps: dict[str, tuple[float, float]],
                    on_error=None) -> list[tuple[Camera, float, float]]:
    """The (camera, pan, tilt) of every frame as it is warped, once each: the training's rectangle
    is extended for all of them (:func:`vcprep.camera.extend_canvas`), so a camera wider or
    steeper than the training cameras is predicted whole, at the training's pixels per degree."""
    views, seen = [], set()
    for j in jobs:
        try:
            cam = camera_of_image(camera, j.image, image_size(j.image))
        except VCError as e:
            if on_error is None:
                raise
            on_error(j, e)
            continue
        pan, tilt = pose_from_vp(cam, vps[j.id]) if vps else (cam.pan, cam.tilt)
        key = (cam, round(pan, 3), round(tilt, 3))
        if key not in seen:
            seen.add(key)
            views.append((cam, pan, tilt))
    return views


def _remove_outputs(out: Path, stem: str) -> None:
    for suffix in ("prob", "mask", "overlay"):
        (out / f"{stem}_{suffix}.png").unlink(missing_ok=True)


def _predict_one(fps: dict, predictor: Any, job: Job, camera, views, vp, out: Path, overlay: bool) -> Path:
    img = read_image(job.image).array
    size = (img.shape[1], img.shape[0])
    if hasattr(predictor, "check_frame_size"):  # a graph holds one frame size: say which graph this frame needs
        predictor.check_frame_size(size, job.image)
    cam = camera_of_image(camera, job.image, size) if camera is not None else None
    fp = fps.get((cam, size))
    if fp is None:
        fp = fps[(cam, size)] = FramePredictor(predictor, cam, size, views=views)
    return write_prediction(out, job.id, fp.predict(img, vp), job.image if overlay else None)[0]


def run_road(predictor: Any, images: Iterable[str | Path], out: str | Path,
             camera: Camera | FrameCameras | None, progress: bool = True, overlay: bool = False,
             within: str = "auto") -> RoadRun:
    """Predict image files/folders taken with ``camera`` (needed for virtual-camera models; a
    :class:`~vcprep.camera.FrameCameras` gives every image its own calibrated camera and pose);
    writes ``<stem>_mask.png``, ``<stem>_prob.png`` (and ``_overlay.png``) in ``out``. A frame that
    fails is skipped and named in the result (module docstring).

    ``within``: per-image pan/tilt from the road VP ('estimate', a CSV ``id,u,v``, 'none', or
    'auto': :func:`within_rule`)."""
    t0 = time.perf_counter()
    jobs = collect_images(images)
    out = out_dir(out)
    if warps_frames(predictor) and camera is None:
        raise InputError("a virtual-camera model needs the camera of the images", None,
                         "add --camera (preset or calibration file)")
    rule = within_rule(predictor, within, camera)
    run = RoadRun()
    vps = frame_vps(jobs, camera if camera is not None else getattr(predictor, "camera", None), rule, run.fail)
    views = None
    if warps_frames(predictor) and not getattr(predictor, "fixed_rectangle", False):
        views = rectangle_views([j for j in jobs if rule == "none" or j.id in vps], camera, vps, run.fail)
    bad = {str(f) for f, _ in run.failed}
    fps: dict = {}
    for job in tqdm([j for j in jobs if str(j.image) not in bad], desc="predict", unit="img",
                    disable=None if progress else True, leave=False):
        try:
            run.written.append(_predict_one(fps, predictor, job, camera, views, vps.get(job.id), out, overlay))
        except VCError as e:
            _remove_outputs(out, job.id)
            run.fail(job, e)
    run.seconds = time.perf_counter() - t0
    return run
