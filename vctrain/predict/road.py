"""One road for a frame: image files and folders, through a model, the prior or an exported graph.

Every frame goes the way a video's frames go (:class:`~vctrain.predict.frames.FramePredictor`, in
memory): read, its road VP, warp into the model's virtual camera (a graph warps inside itself),
the network, back-projection to the frame's own pixels, write. One set of checks and rules serves
all of them:

* which VPs the frames get (:func:`within_rule`): the model's own rule for ``--within auto``;
* the virtual camera's rectangle: the training's, and beyond it the model's rule
  (:mod:`vctrain.predict.frames`; ``extend``, the default: the rectangle extended once for every
  frame of the folder at the pose it is warped with, :func:`rectangle_views`, so all frames share
  one rectangle);
* a frame that cannot be read or predicted is skipped: its outputs are removed, the other frames
  are still predicted, and :class:`RoadRun` names it (``vctrain predict`` says it on stderr and
  exits 1); a frame that cannot be written (a full disk) ends the run with its error.

Frames are read on one thread, predicted on the caller's and written on a third, in order
(:mod:`vctrain.predict.pipeline`).

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

import cv2
import numpy as np
from tqdm import tqdm

from vcprep.camera import Camera, FrameCameras, camera_of_image
from vcprep.dataset import Job, collect_images
from vcprep.errors import InputError, VCError
from vcprep.io import image_size, read_image
from vcprep.vp import frame_poses as poses_of
from vcprep.warp import pose_from_vp

from .frames import NEEDS_CAMERA, FramePredictor, extends, warps_frames
from .pipeline import DEPTH, Prefetch, Writer
from .written import write_prediction

__all__ = ["own_vehicle", "ego_rows", "frames_ego_rows", "sources_ego_rows",
           "rows_at", "folder_ego_camera", "RoadRun", "skipped_lines", "within_rule", "virtual_within",
           "model_vp_rule", "frame_poses", "rectangle_views", "frames_canvas", "geometry_line", "run_road",
           "out_dir"]


@dataclass
class RoadRun:
    """What a run of :func:`predict_images` did: the mask files ``written`` (in order) and the
    frames that ``failed`` ((file, error) pairs, each already said on stderr)."""

    written: list[Path] = field(default_factory=list)
    failed: list[tuple[Path, VCError]] = field(default_factory=list)
    seconds: float = 0.0
    ids: list[str] = field(default_factory=list)  # the frames predicted (their item ids), in order

    def fail(self, job: Job, error: VCError) -> None:
        """Count ``job`` as failed (the caller names the failed frames: :meth:`said`)."""
        self.failed.append((job.image, error))

    def said(self) -> list[str]:
        return skipped_lines(self.failed)


def skipped_lines(failed: list[tuple[Path, VCError]]) -> list[str]:
    """One line per failed frame: 'skipped: <file>: <problem> (<fix>)'."""
    return [f"skipped: {e}" if e.file else f"skipped: {f}: {e}" for f, e in failed]


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
    pose. A resize model takes a VP only through its VP channel, by the same rule (crossval's
    ``resize-vp``: each frame's own estimated VP, as it was trained)."""
    if getattr(predictor, "takes_frames", False):
        if not predictor.vp_input:
            if within not in ("auto", "none"):
                raise InputError("this graph has the camera's mount pose built in (exported without --vp-input)",
                                 predictor.path, "drop --within, or export with --vp-input")
            return "none"
        return "estimate" if within == "auto" else within
    if not warps_frames(predictor) and not getattr(predictor, "vp_channel", False):
        return "none"
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


# said (through ``warn``, even under --quiet) when the search from frames finds no own vehicle: it misses a
# bonnet that reflects the road and one seen from several mounts (Cityscapes': its edge changes sign and
# place from frame to frame; docs/cameras.md), and a missed bonnet is warped as road
MISSED_VEHICLE = ("the search misses a bonnet that reflects the road or sits at several places (frames of "
                  "several mounts), as Cityscapes' does: if the frames show your own vehicle give --ego N (its bottom "
                  "rows) or ego_rows in the camera file; --ego 0 or 'ego_rows: 0' in the camera file says there is "
                  "none and ends this warning")


def own_vehicle(cam: Camera, source: str | Path, ego: str, say: Callable[[str], None] | None,
                estimate: Callable[[], Any], warn: Callable[[str], None] | None = None) -> Camera:
    """``cam`` with its own vehicle's rows (``ego_rows``), one rule for a video and a folder of one
    camera's frames. ``ego``: 'auto' (the camera's ``ego_rows`` when it states them, else found by
    ``estimate()`` -> :class:`vcprep.camera.EgoEstimate` from frames, said through ``say``; too few
    distinct frames: none, also said), 'none' (the camera as given, no search) or a whole number of
    rows at the camera's size (0: no own vehicle). A search that finds none is a warning
    (``warn``, given: the caller's even under --quiet; else ``say``) with :data:`MISSED_VEHICLE`."""
    from dataclasses import replace

    return replace(cam, ego_rows=ego_rows(cam.size[1], cam.ego_rows, source, ego, say, estimate, warn,
                                          known=cam.ego_stated))


def ego_rows(height: int, stated: int, source: str | Path, ego: str, say: Callable[[str], None] | None,
             estimate: Callable[[], Any], warn: Callable[[str], None] | None = None, known: bool = False) -> int:
    """The own vehicle's bottom rows of frames ``height`` rows high by :func:`own_vehicle`'s rule
    (``stated``: the camera's ``ego_rows``, 0 where none is stated; ``known``: the camera file states
    them, an explicit 'ego_rows: 0' too: no search, nothing said)."""
    from vcprep.camera import rows_at_height

    if ego == "none" or (ego == "auto" and (stated or known)):
        return int(stated)
    if ego != "auto":
        try:
            rows = int(ego)
        except ValueError:
            rows = -1
        if not 0 <= rows < height:
            raise InputError(f"--ego '{ego}' is not auto, none or a number of rows below the frames' "
                             f"{height}", source, "give e.g. --ego 40, --ego 0 or --ego none")
        return rows
    say = say or (lambda _msg: None)
    try:
        est = estimate()
    except InputError as e:
        say(f"own vehicle: not looked for ({e.problem}); set ego_rows in the camera file, or --ego N")
        return int(stated)
    if est.rows:
        say(f"own vehicle: {est.rows} rows found from the frames ({est.describe()}); set ego_rows in the "
            f"camera file to override")
    else:
        (warn or say)(f"own vehicle: none found from the frames ({est.describe()}); {MISSED_VEHICLE}")
    return rows_at_height(est, height)


def frames_ego_rows(camera: Camera | None, files: list[Path], ego: str, say: Callable[[str], None] | None = None,
                    warn: Callable[[str], None] | None = None) -> tuple[int, int] | dict[Path, tuple[int, int]]:
    """(rows, frame height) of the own vehicle in a folder of one camera's frames, for a model that
    reads frames as they are: with a camera, :func:`folder_ego_camera`'s; without, by the same rule
    at the first frame's size (``ego`` 'auto' looks in up to :data:`vcprep.io.EGO_SAMPLES` frames
    spread over the folder). Frames of several sources (``ego`` 'auto', no rows stated; a folder per
    drive, BDD100K- or CamVid-style names): each source's own, file -> (rows, height) (:func:`sources_ego_rows`)."""
    if ego == "auto" and not (camera is not None and (camera.ego_rows or camera.ego_stated)):
        per_source = sources_ego_rows(files, say, warn)
        if per_source is not None:
            return per_source
    if camera is not None:
        cam = folder_ego_camera(camera, files, ego, say, warn)
        return cam.ego_rows, cam.size[1]
    from vcprep.camera import ego_rows_from_frame_files

    files = [Path(f) for f in files]
    height = image_size(files[0])[1]
    rows = ego_rows(height, 0, files[0].parent, ego, say,
                    lambda: ego_rows_from_frame_files(_spread(files), files[0].parent), warn)
    return rows, height


def sources_ego_rows(files: list[Path], say: Callable[[str], None] | None = None,
                     warn: Callable[[str], None] | None = None) -> dict[Path, tuple[int, int]] | None:
    """Each source's own vehicle in frames of several sources (:func:`vcprep.camera.ego_rows_per_source`):
    file -> (rows, at height) for the sources searched; the rule and each source's rows said through
    ``say``, a source found without one or not searched (too few frames) through ``warn``. None: one source."""
    from vcprep.camera import GROUP_MIN_DISTINCT, ego_rows_per_source, source_groups
    from vcprep.progress import count
    from vcprep.io import EGO_SAMPLES

    if len(source_groups(files)[1]) < 2:
        return None
    rule, sources = ego_rows_per_source(files, EGO_SAMPLES)
    say, warn = say or (lambda _m: None), warn or say or (lambda _m: None)
    say(f"own vehicle: {count(len(sources), 'source')} grouped by {rule}, each searched alone")
    for s in sources:
        if s.estimate is not None and s.estimate.rows:
            say(f"own vehicle of {s.name} ({count(len(s.files), 'frame')}): {s.estimate.rows} rows found from the "
                f"frames ({s.estimate.describe()})")
        elif s.estimate is not None:
            warn(f"own vehicle of {s.name}: none found ({s.estimate.describe()}); {MISSED_VEHICLE}")
    left = [s for s in sources if s.estimate is None]
    if left:
        names = ", ".join(s.name for s in left[:6]) + (", ..." if len(left) > 6 else "")
        warn(f"own vehicle not searched in {count(len(left), 'source')} of {len(sources)} ({names}; "
             f"{count(sum(len(s.files) for s in left), 'frame')}): fewer than {GROUP_MIN_DISTINCT} distinct frames "
             "each (a single frame cannot show which edge stays put), so nothing is cut there; give --ego N if "
             "they show your own vehicle")
    return {f: (s.estimate.rows, s.estimate.size[1]) for s in sources if s.estimate is not None for f in s.files}


def _spread(files: list[Path]) -> list[Path]:
    """Up to :data:`vcprep.io.EGO_SAMPLES` of ``files``, spread evenly over them (first and last included)."""
    from vcprep.camera import spread
    from vcprep.io import EGO_SAMPLES

    return spread(files, EGO_SAMPLES)


def rows_at(vehicle: tuple[int, int] | None, height: int) -> int:
    """The own vehicle's rows ``vehicle`` = (rows, at height) in a frame ``height`` rows high (rounded up)."""
    if not vehicle or not vehicle[0]:
        return 0
    rows, at = vehicle
    return min(height, int(np.ceil(height * rows / at - 1e-9)))


def folder_ego_camera(camera: Camera, files: list[Path], ego: str = "auto",
                      say: Callable[[str], None] | None = None, warn: Callable[[str], None] | None = None) -> Camera:
    """``camera`` at the frames' size with its own vehicle's rows (:func:`own_vehicle`: 'auto' looks
    in up to :data:`vcprep.io.EGO_SAMPLES` frames spread over the folder, as a video's are). The
    frames' size is the most common among those sampled that the camera takes (a frame of another
    size, or one that cannot be read, is left to the road, which skips and names it); none: the
    first frame's error."""
    from collections import Counter

    from vcprep.camera import ego_rows_from_frame_files

    picks = _spread([Path(f) for f in files])
    sizes: dict[Path, tuple[int, int]] = {}
    for f in picks:
        try:
            sizes[f] = camera.for_image_size(image_size(f), f).size
        except VCError:
            continue
    if not sizes:
        return camera.for_image_size(image_size(picks[0]), picks[0])  # raises: no frame of this camera
    size = Counter(sizes.values()).most_common(1)[0][0]
    cam = camera.for_image_size(size)
    same = [f for f in picks if sizes.get(f) == size]
    return own_vehicle(cam, picks[0].parent, ego, say, lambda: ego_rows_from_frame_files(same, picks[0].parent), warn)


def model_vp_rule(data: dict[str, Any], override: Any = None) -> tuple[Any, str]:
    """(the :class:`~vcprep.vp.VPRule` frames are estimated with, where it comes from): ``override``
    (given), else the rule the model's training VPs were found with, else the detector's defaults
    (a model whose stores record none)."""
    from vcprep.vp import VPRule

    if override is not None:
        return override, "the given"
    recorded = VPRule.from_dict(data.get("vp_rule"))
    return (recorded, "the model's") if recorded is not None else (VPRule(), "the detector's defaults")


def frame_poses(predictor: Any, jobs: list[Job], camera: Camera | FrameCameras | None, rule: str, vp_rule: Any = None,
                on_error=None) -> dict:
    """Each frame's pose (:class:`vcprep.vp.ItemPose`: its road VP in source pixels, status, rule)
    by ``rule`` (:func:`within_rule`); {} for 'none'. Estimated VPs follow ``vp_rule`` or the model's
    (:func:`model_vp_rule`) over the folder's sequences (:func:`vcprep.vp.frame_poses`, the
    one rule of ``vcprep warp``, the store path and a study's stores); ``on_error(job, error)``
    takes a frame that cannot be read."""
    if rule == "none":
        return {}
    poses, _ = poses_of(jobs, camera, rule, model_vp_rule(getattr(predictor, "data", {}), vp_rule)[0],
                        on_error=(lambda i, e: on_error(jobs[i], e)) if on_error else None)
    return poses or {}


def rectangle_views(jobs: list[Job], camera: Camera | FrameCameras, poses: dict,
                    on_error=None) -> list[tuple[Camera, float, float]]:
    """The (camera, pan, tilt) views the training's rectangle is extended for, once each: every frame
    at its camera's average pose and at the pose it is warped with (``poses``: :func:`frame_poses`;
    :func:`vcprep.camera.extend_canvas`), so a camera wider or steeper than the training cameras is
    predicted whole, at the training's pixels per degree. The one rectangle rule of ``vctrain
    predict`` (a folder, a video: :class:`~vctrain.predict.frames.FramePredictor`) and a study's
    test stores."""
    views, seen = [], set()
    for j in jobs:
        try:
            cam = camera_of_image(camera, j.image, image_size(j.image))
        except VCError as e:
            if on_error is None:
                raise
            on_error(j, e)
            continue
        at = pose_from_vp(cam, poses[j.id].vp) if j.id in poses else (cam.pan, cam.tilt)
        for pan, tilt in ((cam.pan, cam.tilt), at):
            key = (cam, round(pan, 3), round(tilt, 3))
            if key not in seen:
                seen.add(key)
                views.append((cam, pan, tilt))
    return views


def frames_canvas(virtual: Camera, jobs: list[Job], camera: Camera | FrameCameras, poses: dict | None) -> Camera:
    """``virtual`` (the training's) with its rectangle extended for :func:`rectangle_views`."""
    from vcprep.camera import extend_canvas

    return extend_canvas(virtual, rectangle_views(jobs, camera, poses or {}))


def geometry_line(geo: dict[str, Any], rule_source: str = "", ego_source: str = "") -> str:
    """One line for stderr from what frames were warped with (``vp_status`` counts, ``vp_rule``,
    ``ego_rows``, ``rectangle``): 'VPs: 2 accepted, 1 fallback (the model's rule: ...); own vehicle: 3
    bottom rows never warped (the camera's ego_rows); virtual rectangle 554x240'."""
    from vcprep.vp import VPRule

    counts = ", ".join(f"{n} {k}" for k, n in geo["vp_status"].items())
    rule = VPRule.from_dict(geo["vp_rule"]) if isinstance(geo["vp_rule"], dict) else None
    vps = f"VPs: {counts}" + (f" ({rule_source + ' rule: ' if rule_source else ''}{rule.describe()})" if rule else "")
    rows = "/".join(map(str, geo["ego_rows"]))
    ego = (f"own vehicle: {rows} bottom rows never warped" if geo["ego_rows"] != [0] else "own vehicle: none")
    ego += f" ({ego_source})" if ego_source else ""
    dense = geo.get("density")  # (frames the warp enlarges more than the training's: Predictor.density_scale)
    scale = (f"; frames enlarged {dense['magnification']:.2f}x by the warp, so the network runs at "
             f"{dense['scale']:.2f} of its working size (their own pixel density)" if dense else "")
    return f"{vps}; {ego}; virtual rectangle {geo['rectangle'][0]}x{geo['rectangle'][1]}{scale}"


def _road_geometry(run: "RoadRun", poses: dict, fps: dict, camera) -> dict[str, Any]:
    """What a road's frames were warped with, as :func:`vctrain.predict.predictor.warp_geometry`
    reads it from a store's records (an estimated VP's pose carries its rule; a given one none)."""
    from collections import Counter

    per_frame = isinstance(camera, FrameCameras)
    statuses = Counter(poses[i].status if i in poses else ("calibrated" if per_frame else "camera") for i in run.ids)
    rules = [dict(poses[i].rule) for i in run.ids if i in poses and poses[i].rule]
    rects = {tuple(fp.virtual.size) for fp in fps.values() if fp.virtual is not None}
    dense = [(fp.magnification, fp.predictor.density_scale(fp.magnification)) for fp in fps.values()
             if fp.virtual is not None and hasattr(fp.predictor, "density_scale")]
    dense = [d for d in dense if d[1] < 1.0]
    return {"vp_status": dict(sorted(statuses.items())), "vp_rule": rules[0] if rules else None,
            "ego_rows": sorted({int(k[0].ego_rows) for k in fps if k[0] is not None}) or [0],
            "rectangle": list(rects.pop()) if len(rects) == 1 else [0, 0],
            **({"density": {"magnification": max(dense)[0], "scale": max(dense)[1]}} if dense else {})}


def _remove_outputs(out: Path, stem: str) -> None:
    for suffix in ("prob", "mask", "overlay"):
        (out / f"{stem}_{suffix}.png").unlink(missing_ok=True)


def _read(jobs: list[Job]):
    """(job, decoded image or None, the VCError that stopped it or None) of each job, in order."""
    for job in jobs:
        try:
            yield job, read_image(job.image).array, None
        except VCError as e:
            yield job, None, e


def _predict_one(fps: dict, predictor: Any, job: Job, img: np.ndarray, camera, views, vp,
                 vehicle: tuple[int, int] | dict | None = None) -> np.ndarray:
    """P(road) of ``job``'s decoded image ``img`` (its FramePredictor made once per camera, size and own
    vehicle; ``vehicle`` a dict: per source, file -> (rows, height))."""
    size = (img.shape[1], img.shape[0])
    if hasattr(predictor, "check_frame_size"):  # a graph takes frames of its own size only
        predictor.check_frame_size(size, job.image)
    cam = camera_of_image(camera, job.image, size) if camera is not None else None
    rows = rows_at(vehicle.get(job.image) if isinstance(vehicle, dict) else vehicle, size[1])  # dict: per source
    fp = fps.get((cam, size, rows))
    if fp is None:
        fp = fps[(cam, size, rows)] = FramePredictor(predictor, cam, size, views=views, ego_rows=rows)
    return fp.predict(img, vp)


def _bev_poses(predictor: Any, bev: Any, jobs: list[Job], camera, within: str, rule: str, poses: dict, vp_rule: Any,
               run: RoadRun) -> tuple[Any, dict]:
    """(``--bev``'s :class:`~vctrain.predict.bev.BevRun`, each frame's pose for it: the model's
    ``poses`` where it takes the same rule, else found by its own); (None, {}) without ``bev``."""
    if bev is None:
        return None, {}
    from .bev import BevRun

    camera = camera if camera is not None else getattr(predictor, "camera", None)  # a graph's own
    bev_run = BevRun(bev, camera, within, jobs[0].image if jobs else None)
    if bev_run.rule == rule:
        return bev_run, poses
    return bev_run, frame_poses(predictor, jobs, camera, bev_run.rule, vp_rule, run.fail)


def run_road(predictor: Any, images: Iterable[str | Path], out: str | Path,
             camera: Camera | FrameCameras | None, progress: bool = True, overlay: bool = False,
             within: str = "auto", vp_rule: Any = None, say: Callable[[str], None] | None = None,
             ego_source: str = "", vehicle: tuple[int, int] | dict | None = None, bev: Any = None) -> RoadRun:
    """Predict image files/folders taken with ``camera`` (needed for virtual-camera models; a
    :class:`~vcprep.camera.FrameCameras` gives every image its own calibrated camera and pose);
    writes ``<stem>_mask.png``, ``<stem>_prob.png`` (and ``_overlay.png``) in ``out``. A frame that
    fails is skipped and named in the result (module docstring).

    ``within``: per-image pan/tilt from the road VP ('estimate', a CSV ``id,u,v``, 'none', or
    'auto': :func:`within_rule`); estimated VPs follow ``vp_rule`` or the model's
    (:func:`model_vp_rule`). ``say`` (given) hears one line: which VPs, own vehicle (``ego_source``:
    where its rows come from) and rectangle a virtual-camera model's frames were warped with. ``vehicle``
    (rows, at frame height, or file -> that per source; :func:`frames_ego_rows`): a model that reads
    frames as they are predicts 'not road' on the own vehicle's rows. ``bev`` (given:
    :class:`vctrain.predict.bev.BevOptions`): each frame's BEV and road in metres too, at its pose by
    ``within`` (:mod:`vctrain.predict.bev`)."""
    t0 = time.perf_counter()
    jobs = collect_images(images, trees=True)  # a tree whose frames repeat names: outputs mirror it
    out = out_dir(out)
    if warps_frames(predictor) and camera is None:
        raise InputError("a virtual-camera model needs the camera of the images", None,
                         NEEDS_CAMERA)
    rule = within_rule(predictor, within, camera)
    run = RoadRun()
    poses = frame_poses(predictor, jobs, camera if camera is not None else getattr(predictor, "camera", None), rule,
                        vp_rule, run.fail)
    bev_run, bev_poses = _bev_poses(predictor, bev, jobs, camera, within, rule, poses, vp_rule, run)
    views = None
    if extends(predictor):
        views = rectangle_views([j for j in jobs if rule == "none" or j.id in poses], camera, poses, run.fail)
    bad = {str(f) for f, _ in run.failed}
    fps: dict = {}
    todo = [j for j in jobs if str(j.image) not in bad]
    # read on one thread, the network on this one, written on a third, in order (vctrain.predict.pipeline)
    writer = Writer(DEPTH)

    def write(job: Job, prob: np.ndarray, img: np.ndarray) -> None:
        pose = bev_poses.get(job.id)
        inset = bev_run.write(out, job.id, prob, job.image, *((pose.vp, pose.status) if pose else ())) \
            if bev_run is not None else None
        run.written.append(write_prediction(out, job.id, prob, img if overlay else None, inset)[0])
    try:
        with Prefetch(_read(todo), DEPTH) as frames:
            for job, img, error in tqdm(frames, total=len(todo), desc="predict", unit="img",
                                        disable=None if progress else True, leave=False):
                vp = poses[job.id].vp if job.id in poses else None
                try:
                    if error is not None:
                        raise error
                    prob = _predict_one(fps, predictor, job, img, camera, views, vp, vehicle)
                except VCError as e:
                    _remove_outputs(out, job.id)
                    run.fail(job, e)
                    continue
                writer.submit(write, job, prob, img)
                run.ids.append(job.id)
        writer.close()
    except BaseException:
        writer.abort()
        raise
    if say is not None and warps_frames(predictor) and run.ids:
        source = model_vp_rule(getattr(predictor, "data", {}), vp_rule)[1]
        say(geometry_line(_road_geometry(run, poses, fps, camera), source, ego_source))
    run.seconds = time.perf_counter() - t0
    return run
