"""Video in, per-frame road masks and overlay videos out.

:func:`predict_video` reads a video file frame by frame (``cv2.VideoCapture``: whatever OpenCV's
FFmpeg reads, :data:`vcprep.io.VIDEO_EXTENSIONS`; opened and read by :mod:`vcprep.io.video`), predicts each frame in memory
(:class:`vctrain.predict.frames.FramePredictor`: the numbers of ``vctrain predict`` on the frames as
images) and writes, for ``drive.mp4`` into ``OUT``:

- ``OUT/drive/drive_<frame>_mask.png`` and ``_prob.png`` (frame: 6 digits, counted from 0 in the
  video's order, undecodable frames included), as ``vctrain predict`` writes for images; or, with
  ``mask_video``, ``OUT/drive_mask.mkv`` instead: the masks (0/255) as a lossless FFV1 video;
- with ``overlay``, ``OUT/drive_overlay.mp4`` (MPEG-4 Part 2, the input's frame rate and size):
  every frame with the predicted road tinted green (:func:`vctrain.predict.written.tint_road`), the
  horizon of the frame's pose (cyan line) and its road vanishing point (red cross).

The own vehicle (a virtual-camera model): a camera that states no ``ego_rows`` gets them from
:data:`vcprep.io.EGO_SAMPLES` frames spread over the video (:func:`ego_camera`, :func:`vcprep.camera.ego.ego_rows_from_frames`,
said on stderr; ``ego`` 'none' skips the search, a number sets the rows), before the first frame is
predicted: the bottom rows that show the rig's own car are never warped and never vote for a VP.

Per-frame VPs (``within`` 'estimate', or 'auto' for a model trained with per-image VPs) are
estimated and smoothed over time as the frames stream by (:class:`vctrain.predict.frames.StreamingVPs`:
a frame is predicted once ``vp_window`` later frames have their VP; each frame's VP is estimated in a
worker thread while the frames before it are predicted and written, :data:`VP_AHEAD` frame ahead). A frame that cannot be decoded is
said on stderr and skipped (no mask; the videos repeat the previous frame, so they keep the
input's length and timing); a video that ends before the frame count in its header says so.
Videos are written under a temporary name and renamed when complete, so an interrupted run
leaves no half-written video (each PNG is written atomically anyway). Frames are decoded and
written on threads of their own while the network runs (:mod:`vctrain.predict.pipeline`), in order.
"""
from __future__ import annotations

import os
import sys
from collections import deque
from contextlib import closing
from dataclasses import dataclass
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any, Callable, Iterator

import cv2
import numpy as np
from tqdm import tqdm

from vcprep.camera import Camera
from vcprep.errors import InputError
from vcprep.io import VideoInfo, open_video, read_frames, sample_frames
from vcprep.warp import ground_to_image, pose_from_vp, vp_from_pose

from .frames import NEEDS_CAMERA, FramePredictor, StageTimes, StreamingVPs, reads_road_vps, warps_frames
from .pipeline import DEPTH, Prefetch, Writer
from .road import ego_rows, model_vp_rule, own_vehicle, within_rule
from .written import road_mask, tint_road

__all__ = ["check_video_stems", "ego_camera", "predict_video", "draw_overlay", "horizon_segment", "VideoRoad",
           "VideoStream", "video_road"]

HORIZON_CYAN, VP_RED = (255, 255, 0), (0, 0, 255)  # BGR
VP_AHEAD = 1  # per-frame VPs: frames whose estimate runs in a worker thread while earlier frames are predicted


def check_video_stems(videos: list[Path]) -> list[Path]:
    """``videos`` unchanged; two with one stem (their outputs would collide) raise InputError."""
    seen: dict[str, Path] = {}
    for v in map(Path, videos):
        if v.stem in seen:
            raise InputError(f"two videos named '{v.stem}' (also {seen[v.stem]})", v,
                             "outputs are named by stem; predict them into separate --out folders")
        seen[v.stem] = v
    return list(videos)


def horizon_segment(cam: Camera, pan: float, tilt: float) -> tuple[tuple[int, int], tuple[int, int]] | None:
    """The horizon of ``cam`` at (pan, tilt) across the image, as two pixel points: the image of
    the road plane's line at infinity, ``l = G^-T (0, 0, 1)`` with ``G`` = :func:`ground_to_image`."""
    l = np.linalg.inv(ground_to_image(cam, pan, tilt)).T @ np.array([0.0, 0.0, 1.0])
    if abs(l[1]) < 1e-12:
        return None
    w = cam.size[0]
    y = lambda x: -(l[0] * x + l[2]) / l[1]
    return (0, int(round(y(0.0)))), (w - 1, int(round(y(w - 1.0))))


def draw_overlay(frame: np.ndarray, mask: np.ndarray, cam: Camera | None, vp: tuple[float, float] | None) -> np.ndarray:
    """``frame`` with the road of ``mask`` (0/255) tinted green, the horizon at the pose of
    ``vp`` (cyan) and ``vp`` itself (red cross); ``vp`` None: the camera's average pose; no
    ``cam`` (a resize model run without --camera): the road only."""
    out = tint_road(frame, mask)
    if cam is None:
        return out
    vp = vp_from_pose(cam) if vp is None else vp
    pan, tilt = pose_from_vp(cam, vp)
    lw = max(1, cam.size[0] // 640)
    seg = horizon_segment(cam, pan, tilt)
    if seg is not None:
        cv2.line(out, seg[0], seg[1], HORIZON_CYAN, lw, cv2.LINE_AA)
    cv2.drawMarker(out, (int(round(vp[0])), int(round(vp[1]))), VP_RED, cv2.MARKER_CROSS,
                   max(12, cam.size[0] // 40), 2 * lw, cv2.LINE_AA)
    return out


class _VideoOut:
    """A video written under a temporary name in its folder, renamed when :meth:`close` d."""

    def __init__(self, path: Path, fourcc: str, fps: float, size: tuple[int, int]):
        self.path = path
        self.tmp = path.with_name(f".{path.stem}.tmp-{os.getpid()}{path.suffix}")  # the extension picks the container
        self.writer = cv2.VideoWriter(str(self.tmp), cv2.VideoWriter_fourcc(*fourcc), fps, size)
        if not self.writer.isOpened():
            self.tmp.unlink(missing_ok=True)
            raise InputError(f"cannot write a {fourcc} video here", path, "check the folder's permissions")
        self.last: np.ndarray | None = None

    def write(self, frame: np.ndarray | None) -> None:
        """Write ``frame``; None repeats the last one (a skipped frame keeps the timing)."""
        frame = self.last if frame is None else frame
        if frame is not None:
            self.writer.write(frame)
            self.last = frame

    def close(self) -> None:
        self.writer.release()
        os.replace(self.tmp, self.path)

    def abort(self) -> None:
        self.writer.release()
        self.tmp.unlink(missing_ok=True)




def ego_camera(camera: Camera, info: VideoInfo, ego: str = "auto", say: Callable[[str], None] | None = None,
               warn: Callable[[str], None] | None = None) -> Camera:
    """``camera`` at the video's size with its own vehicle's rows (:func:`vctrain.predict.road.own_vehicle`:
    'auto' looks in :data:`vcprep.io.EGO_SAMPLES` frames spread over the video)."""
    from vcprep.camera import ego_rows_from_frames

    return own_vehicle(camera.for_image_size(info.size, info.path), info.path, ego, say,
                       lambda: ego_rows_from_frames(sample_frames(info), info.path), warn)


def _now(fn, *args) -> Future:
    """``fn(*args)`` computed here, as a finished Future (no worker thread)."""
    done: Future = Future()
    done.set_result(fn(*args))
    return done


@dataclass
class VideoRoad:
    """What a video's frames are predicted with (:func:`video_road`): the frame predictor (its camera at
    the video's size with the own vehicle's rows), the streamed VPs (``vps``, per-frame VPs) or the
    given ones (``given``, read from the CSV ``mode``), whether the model takes them (``model_vps``;
    else only ``--bev`` does) and ``--bev``'s run."""

    fp: FramePredictor
    mode: str
    vps: StreamingVPs | None = None
    given: dict | None = None
    model_vps: bool = True
    bev_run: Any = None


def video_road(predictor, info: VideoInfo, camera: Camera | None, within: str = "auto", ego: str | None = None,
               progress: bool = True, vp_window: int = 2, vp_rule=None, bev=None,
               times: StageTimes | None = None) -> VideoRoad:
    """The :class:`VideoRoad` of the video ``info`` (:func:`predict_video` says what each argument does)."""
    from vcprep.vp import read_vp_csv

    predictor.check_frame_size(info.size, info.path)  # (a graph takes frames of its own size only)
    cam = _video_camera(predictor, camera, Path(info.path), info, ego, progress)
    mode = within_rule(predictor, within, cam)
    bev_run = _bev_run(bev, cam, within, info.path)
    model_vps, mode = mode != "none", _vp_mode(mode, bev_run)  # (--bev: the VPs its poses need)
    given = read_vp_csv(mode) if mode not in ("estimate", "none") else None
    fp = FramePredictor(predictor, cam, info.size, ego_rows=_resize_ego_rows(predictor, cam, info, ego, progress))
    if times is not None:
        fp.times = times
    if mode == "estimate" and fp.camera is None:
        raise InputError("per-frame VPs need the camera of the video", info.path, "add --camera, or --within none")
    cfg = model_vp_rule(predictor.data, vp_rule)[0].config()
    vps = StreamingVPs(fp.camera, vp_window, cfg=cfg, times=fp.times) if mode == "estimate" else None
    return VideoRoad(fp, mode, vps, given, model_vps, bev_run)


class VideoStream:
    """A video's frames on the one road, in order: iterating gives (index, frame or None (undecodable),
    P(road) or None, the road VP used or None, its status or None) of every frame, the network run in
    the iterating thread (frames decoded on a thread of their own, VPs estimated ``vp_ahead`` frames
    ahead on another). ``info`` and ``road`` (:class:`VideoRoad`) are known before the first frame.
    What ``vctrain predict`` writes of a video and :meth:`vctrain.RoadModel.segment_video` yields."""

    def __init__(self, predictor, video: str | Path, camera: Camera | None, within: str = "auto",
                 ego: str | None = None, progress: bool = True, vp_window: int = 2, vp_rule=None, bev=None,
                 times: StageTimes | None = None, vp_ahead: int = VP_AHEAD):
        self.path = Path(video)
        self.cap, self.info = open_video(self.path)
        self.vp_ahead = vp_ahead
        try:
            self.road = video_road(predictor, self.info, camera, within, ego, progress, vp_window, vp_rule, bev, times)
        except BaseException:
            self.cap.release()
            raise

    def __iter__(self) -> Iterator[tuple[int, np.ndarray | None, np.ndarray | None, Any, str | None]]:
        road = self.road
        pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="vp") \
            if road.vps is not None and self.vp_ahead else None
        # decoded on a thread of its own, DEPTH frames ahead (vctrain.predict.pipeline)
        frames = Prefetch(read_frames(self.cap, self.info, lambda msg: tqdm.write(msg, file=sys.stderr)), DEPTH)
        try:
            for i, frame, vp, status in _ordered(frames, road, self.path.stem, pool.submit if pool else _now,
                                                 self.vp_ahead):
                prob = None if frame is None else road.fp.predict(frame, vp if road.model_vps else None)
                yield i, frame, prob, vp, status
        finally:
            frames.close()
            if pool is not None:
                pool.shutdown(wait=True, cancel_futures=True)

    def close(self) -> None:
        self.cap.release()


def predict_video(predictor, video: str | Path, out: str | Path, camera: Camera | None, within: str = "auto",
                  mask_video: bool = False, overlay: bool = False, progress: bool = True, vp_window: int = 2,
                  times: StageTimes | None = None, ego: str | None = None, vp_ahead: int = VP_AHEAD,
                  vp_rule=None, bev=None) -> list[Path]:
    """Predict every frame of ``video`` (module docstring); returns the paths written (the mask
    PNGs, or the mask video; the overlay video). ``within``: 'auto' (as the model was trained,
    :func:`vctrain.predict.road.within_rule`), 'estimate', 'none' or a CSV ``id,u,v`` whose ids are
    ``<stem>_<frame:06d>``; estimated VPs are searched and accepted within the pose ranges of
    ``vp_rule`` or the model's (:func:`vctrain.predict.road.model_vp_rule`) and smoothed over
    ``vp_window`` frames either side. ``ego``: the own vehicle, as :func:`ego_camera` takes it (a
    virtual-camera model: None is 'auto'; a resize model cuts it only when asked). ``times`` (given) gets the stage timings;
    ``progress`` False also silences the own-vehicle remark. ``vp_ahead``: frames whose VP is
    estimated in a worker thread ahead of the one predicted (0: in this thread, in turn). ``bev`` (given:
    :class:`vctrain.predict.bev.BevOptions`): each frame's BEV PNGs (in ``OUT/<stem>/``, also with
    ``mask_video``) and road in metres too, its record with ``"frame"``; its VPs streamed as the
    model's are where the model takes none."""
    stream = VideoStream(predictor, video, camera, within, ego, progress, vp_window, vp_rule, bev, times, vp_ahead)
    try:
        out = _out_folder(out, stream.path.stem, mask_video)
        sink = None
        try:
            sink = _FrameSink(stream.road.fp, out, stream.path.stem, stream.info, mask_video, overlay, progress,
                              stream.road.bev_run)
            with closing(iter(stream)) as frames:
                for i, frame, prob, vp, status in frames:
                    sink.emit(i, frame, prob, vp, status)
            return sink.close()
        except BaseException:
            if sink is not None:
                sink.abort()
            raise
    finally:
        stream.close()


def _bev_run(bev, cam: Camera | None, within: str, video: Path):
    """``--bev``'s :class:`~vctrain.predict.bev.BevRun` for the video (None without ``bev``)."""
    if bev is None:
        return None
    from .bev import BevRun

    return BevRun(bev, cam, within, video)


def _vp_mode(mode: str, bev_run) -> str:
    """Which VPs the frames are streamed with: the model's (``mode``), or ``--bev``'s where the
    model takes none."""
    return mode if bev_run is None or mode != "none" else bev_run.rule


def _video_camera(predictor, camera: Camera | None, video: Path, info: VideoInfo, ego: str,
                  progress: bool) -> Camera | None:
    """The camera at the video's frame size (a virtual-camera model needs one), with its own
    vehicle's rows (:func:`ego_camera`) for a virtual-camera model."""
    if camera is None:
        if warps_frames(predictor):
            raise InputError("a virtual-camera model needs the camera of the video", video,
                             NEEDS_CAMERA)
        if reads_road_vps(predictor):
            raise InputError("this model reads each frame's road vanishing point (VP channel): it needs the camera "
                             "of the video", video, NEEDS_CAMERA)
        camera = predictor.camera  # a graph's own (its VPs, the overlay's horizon)
        if camera is None:
            return None
    cam = camera.for_image_size(info.size, video)
    if reads_road_vps(predictor):
        say = (lambda msg: tqdm.write(f"{video}: {msg}", file=sys.stderr)) if progress else None
        cam = ego_camera(cam, info, ego or "auto", say,
                         lambda msg: tqdm.write(f"{video}: warning: {msg}", file=sys.stderr))
    return cam


def _resize_ego_rows(predictor, camera: Camera | None, info: VideoInfo, ego: str | None, progress: bool) -> int:
    """The own vehicle's rows a model that reads frames as they are cuts from the video's frames,
    where ``ego`` asks (:func:`vctrain.predict.road.ego_rows`'s rule); 0 otherwise."""
    if ego in (None, "none") or warps_frames(predictor) or reads_road_vps(predictor) \
            or predictor.takes_frames:
        return 0
    from vcprep.camera import ego_rows_from_frames

    say = (lambda msg: tqdm.write(f"{info.path}: {msg}", file=sys.stderr)) if progress else None
    return ego_rows(info.size[1], camera.ego_rows if camera is not None else 0, info.path, ego, say,
                    lambda: ego_rows_from_frames(sample_frames(info), info.path),
                    lambda msg: tqdm.write(f"{info.path}: warning: {msg}", file=sys.stderr),
                    known=bool(camera is not None and camera.ego_stated))


def _out_folder(out: str | Path, stem: str, mask_video: bool) -> Path:
    """OUT (a folder, created), and OUT/<stem> for the mask PNGs unless ``mask_video``."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError("exists and is not a directory", out, "choose another --out")
    (out if mask_video else out / stem).mkdir(parents=True, exist_ok=True)
    return out


class _FrameSink:
    """Where a video's predicted frames go, in frame order: the mask PNGs (or the mask video), the
    overlay video and the progress bar. Frames read wait in ``held`` (in ``order``) until their
    VP is final (per-frame VPs). The network runs in the caller's thread (:meth:`emit`); what is
    written of a frame is written on the :class:`~vctrain.predict.pipeline.Writer`'s thread, in order."""

    def __init__(self, fp: FramePredictor, out: Path, stem: str, info: VideoInfo, mask_video: bool,
                 overlay: bool, progress: bool, bev=None):
        from .predictor import write_prediction

        self.fp, self.stem, self.frame_dir, self._write_prediction = fp, stem, out / stem, write_prediction
        self.bev, self.source = bev, info.path
        self.outs: list[_VideoOut] = []
        self.written: list[Path] = []
        self.mv = self.ov = None
        try:
            self.mv = _VideoOut(out / f"{stem}_mask.mkv", "FFV1", info.fps, info.size) if mask_video else None
            self.outs += [self.mv] if self.mv else []
            self.ov = _VideoOut(out / f"{stem}_overlay.mp4", "mp4v", info.fps, info.size) if overlay else None
            self.outs += [self.ov] if self.ov else []
        except BaseException:
            self.abort()  # the one opened before
            raise
        self.bar = tqdm(total=info.frames or None, desc=stem, unit="frame", disable=None if progress else True,
                        leave=False)
        self.writer = Writer(DEPTH)

    def emit(self, i: int, frame: np.ndarray | None, prob: np.ndarray | None, vp, status: str | None = None) -> None:
        """Hand frame ``i`` and its P(road) ``prob`` to the writer (an undecodable frame, None: the
        videos repeat their last frame)."""
        self.writer.submit(self._write, i, frame, prob, vp, status)

    def _write(self, i: int, frame: np.ndarray | None, prob: np.ndarray | None, vp, status: str | None = None) -> None:
        """Frame ``i``'s outputs (on the writer's thread)."""
        if frame is None:
            for o in self.outs:
                o.write(None)
        else:
            inset = None if self.bev is None else self.bev.write(self.frame_dir, f"{self.stem}_{i:06d}", prob,
                                                                 self.source, vp, status, frame=i)
            mask = road_mask(prob)
            if self.mv is None:
                self.written.append(self._write_prediction(self.frame_dir, f"{self.stem}_{i:06d}", prob, mask=mask)[0])
            if self.mv is not None:
                self.mv.write(cv2.cvtColor(mask, cv2.COLOR_GRAY2BGR))
            if self.ov is not None:
                shown = draw_overlay(frame, mask, self.fp.camera, vp)
                self.ov.write(inset(shown) if inset is not None else shown)
        self.bar.update(1)

    def close(self) -> list[Path]:
        """Finish the writes and the videos; the paths written (mask PNGs or mask video, then the
        overlay video)."""
        self.writer.close()
        self.bar.close()
        for o in self.outs:
            o.close()
            self.written.append(o.path)
        return self.written

    def abort(self) -> None:
        if getattr(self, "writer", None) is not None:
            self.writer.abort()
        for o in self.outs:
            o.abort()


def _ordered(frames: Iterator[tuple[int, np.ndarray | None]], road: VideoRoad, stem: str,
             submit: Callable[..., Future], vp_ahead: int) -> Iterator[tuple[int, np.ndarray | None, Any, str | None]]:
    """(index, frame, vp, status) of every frame, in order: at once with a given VP (``road.given``,
    read from the CSV ``road.mode``) or none; with per-frame VPs (``road.vps``) once its VP is final.
    The VP of the frame just read is estimated (``submit``: in another thread) while the frames
    before it are predicted and written, ``vp_ahead`` frames ahead (the estimate is pure: the same
    numbers, in the same order)."""
    vps, held, order = road.vps, {}, []
    ahead: deque[tuple[int, Future]] = deque()
    for i, frame in frames:
        if vps is None:
            yield i, frame, _given_vp(road, stem, i, frame), None
            continue
        held[i] = frame
        order.append(i)
        if frame is not None:
            ahead.append((i, submit(vps.estimate, frame)))
        while len(ahead) > vp_ahead:
            j, est = ahead.popleft()
            yield from _release(held, order, vps.push(j, estimate=est.result()))
    if vps is not None:
        while ahead:
            j, est = ahead.popleft()
            yield from _release(held, order, vps.push(j, estimate=est.result()))
        yield from _release(held, order, vps.flush())


def _given_vp(road: VideoRoad, stem: str, i: int, frame: np.ndarray | None):
    """Frame ``i``'s VP from the CSV (None: no CSV, or an undecodable frame)."""
    if road.given is None or frame is None:
        return None
    key = f"{stem}_{i:06d}"
    if key not in road.given:
        raise InputError(f"no VP row for frame id '{key}'", road.mode, "add an 'id,u,v' row per frame")
    return road.given[key]


def _release(held: dict, order: list[int], final: list[tuple[int, object]]):
    """Every held frame up to the last whose VP is final, in order: (index, frame, vp, status)."""
    done = dict(final)
    while order and (held[order[0]] is None or order[0] in done):
        i = order.pop(0)
        yield (i, held.pop(i), *((done[i].vp, done[i].status) if i in done else (None, None)))
