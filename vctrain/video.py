"""Video in, per-frame road masks and overlay videos out.

:func:`predict_video` reads a video file frame by frame (``cv2.VideoCapture``: whatever OpenCV's
FFmpeg reads, :data:`VIDEO_EXTENSIONS`), predicts each frame in memory
(:class:`vctrain.frames.FramePredictor`: the numbers of ``vctrain predict`` on the frames as
images) and writes, for ``drive.mp4`` into ``OUT``:

- ``OUT/drive/drive_<frame>_mask.png`` and ``_prob.png`` (frame: 6 digits, counted from 0 in the
  video's order, undecodable frames included), as ``vctrain predict`` writes for images; or, with
  ``mask_video``, ``OUT/drive_mask.mkv`` instead: the masks (0/255) as a lossless FFV1 video;
- with ``overlay``, ``OUT/drive_overlay.mp4`` (MPEG-4 Part 2, the input's frame rate and size):
  every frame with the predicted road tinted green (:func:`vcprep.figures.overlay_label`), the
  horizon of the frame's pose (cyan line) and its road vanishing point (red cross).

The own vehicle (a virtual-camera model): a camera that states no ``ego_rows`` gets them from
:data:`EGO_SAMPLES` frames spread over the video (:func:`ego_camera`, :func:`vcprep.ego.ego_rows_from_frames`,
said on stderr; ``ego`` 'none' skips the search, a number sets the rows), before the first frame is
predicted: the bottom rows that show the rig's own car are never warped and never vote for a VP.

Per-frame VPs (``within`` 'estimate', or 'auto' for a model trained with per-image VPs) are
estimated and smoothed over time as the frames stream by (:class:`vctrain.frames.StreamingVPs`:
a frame is predicted once ``vp_window`` later frames have their VP; each frame's VP is estimated in a
worker thread while the frames before it are predicted and written, :data:`VP_AHEAD` frame ahead). A frame that cannot be decoded is
said on stderr and skipped (no mask; the videos repeat the previous frame, so they keep the
input's length and timing); a video that ends before the frame count in its header says so.
Videos are written under a temporary name and renamed when complete, so an interrupted run
leaves no half-written video (each PNG is written atomically anyway).
"""
from __future__ import annotations

import os
import sys
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

import cv2
import numpy as np
from tqdm import tqdm

from vcprep.camera import Camera
from vcprep.errors import InputError
from vcprep.homography import ground_to_image, pose_from_vp, vp_from_pose

from .frames import FramePredictor, StageTimes, StreamingVPs

__all__ = ["VIDEO_EXTENSIONS", "EGO_SAMPLES", "VideoInfo", "is_video", "check_video_stems", "open_video",
           "read_frames", "sample_frames", "ego_camera", "predict_video", "draw_overlay", "horizon_segment"]

# FFmpeg's own log lines ("[mjpeg @ 0x...] No JPEG data found") would break the one-line errors and
# repeat what read_frames says per frame; read once, when OpenCV first opens a video. A user's
# OPENCV_FFMPEG_LOGLEVEL wins.
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET

VIDEO_EXTENSIONS = (".mp4", ".avi", ".mkv", ".mov", ".m4v", ".webm", ".mpg", ".mpeg", ".wmv")
MAX_BAD_RUN = 16  # this many undecodable frames in a row (and no header count left) end the video
HORIZON_CYAN, VP_RED = (255, 255, 0), (0, 0, 255)  # BGR
VP_AHEAD = 1  # per-frame VPs: frames whose estimate runs in a worker thread while earlier frames are predicted


def is_video(path: str | Path) -> bool:
    """Whether ``path`` names a video file (by its extension)."""
    return Path(path).suffix.lower() in VIDEO_EXTENSIONS


def check_video_stems(videos: list[Path]) -> list[Path]:
    """``videos`` unchanged; two with one stem (their outputs would collide) raise InputError."""
    seen: dict[str, Path] = {}
    for v in map(Path, videos):
        if v.stem in seen:
            raise InputError(f"two videos named '{v.stem}' (also {seen[v.stem]})", v,
                             "outputs are named by stem; predict them into separate --out folders")
        seen[v.stem] = v
    return list(videos)


@dataclass(frozen=True)
class VideoInfo:
    path: Path
    size: tuple[int, int]  # (w, h)
    fps: float             # frames per second (25 when the header gives none)
    frames: int            # frame count from the header; 0 when unknown


def open_video(path: str | Path) -> tuple[cv2.VideoCapture, VideoInfo]:
    """Open a video for reading; a missing file, a folder or a file OpenCV cannot read as a video
    raises :class:`InputError`."""
    path = Path(path)
    if not path.exists():
        raise InputError("video not found", path, "check the path")
    if not path.is_file():
        raise InputError("is not a file, expected a video", path, "give a video file")
    cap = cv2.VideoCapture(str(path))
    w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    if not cap.isOpened() or w <= 0 or h <= 0:
        cap.release()
        raise InputError("cannot read as a video (not a video, or a codec OpenCV's FFmpeg lacks)", path,
                         f"give a video file ({', '.join(VIDEO_EXTENSIONS)}) or convert it, e.g. "
                         "ffmpeg -i IN -c:v libx264 OUT.mp4")
    fps = float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
    n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
    return cap, VideoInfo(path, (w, h), fps if 0 < fps < 1000 else 25.0, max(0, n))


def read_frames(cap: cv2.VideoCapture, info: VideoInfo,
                on_problem: Callable[[str], None]) -> Iterator[tuple[int, np.ndarray | None]]:
    """(index, BGR frame) for every frame in order; an undecodable frame (or one of another
    size) is (index, None) after ``on_problem`` says which. A failed read is a broken frame when
    a later frame still decodes; :data:`MAX_BAD_RUN` failures in a row (or reaching the header's
    count) end the video, and ending before the header's count is said too."""
    i, pending = 0, []
    while True:
        ok = cap.grab()
        frame = None
        if ok:
            ok, frame = cap.retrieve()
        if ok and frame is not None and frame.ndim == 3 and (frame.shape[1], frame.shape[0]) == info.size:
            for j in pending:
                on_problem(f"{info.path}: frame {j} cannot be decoded; skipped")
                yield j, None
            pending = []
            yield i, frame
        elif ok and frame is not None:
            on_problem(f"{info.path}: frame {i} is {frame.shape[1]}x{frame.shape[0]}, not "
                       f"{info.size[0]}x{info.size[1]}; skipped")
            yield i, None
        else:
            pending.append(i)
            if len(pending) >= MAX_BAD_RUN or (info.frames and i + 1 >= info.frames):
                break
        i += 1
    end = pending[0] if pending else i
    if info.frames and end < info.frames:
        on_problem(f"{info.path}: video ends after {end} of the {info.frames} frames its header announces "
                   f"(truncated or damaged); the frames read are predicted")


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
    from vcprep.figures import overlay_label

    out = overlay_label(frame, (mask > 0).astype(np.uint8))
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


EGO_SAMPLES = 48  # frames spread over a video that its own vehicle is looked for in (>= MIN_DISTINCT distinct)


def sample_frames(info: VideoInfo, n: int = EGO_SAMPLES) -> list[np.ndarray]:
    """Up to ``n`` decodable frames spread evenly over the video (header count known; else every
    5th of its first ``5 n``): one pass of ``grab`` up to the last one, so it costs a decode of
    the video, never a seek (which decodes from the previous key frame each time)."""
    total = info.frames or 5 * n
    want = set(np.linspace(0, total - 1, min(n, total)).round().astype(int).tolist())
    cap, out, bad = cv2.VideoCapture(str(info.path)), [], 0
    try:
        for i in range(max(want) + 1):
            if not cap.grab():
                bad += 1
                if bad >= MAX_BAD_RUN:
                    break
                continue
            bad = 0
            if i in want:
                ok, f = cap.retrieve()
                if ok and f is not None and f.ndim == 3 and (f.shape[1], f.shape[0]) == info.size:
                    out.append(f)
    finally:
        cap.release()
    return out


def ego_camera(camera: Camera, info: VideoInfo, ego: str = "auto", say: Callable[[str], None] | None = None) -> Camera:
    """``camera`` at the video's size with its own vehicle's rows (``ego_rows``). ``ego``: 'auto'
    (the camera's ``ego_rows`` when it states them, else found from :data:`EGO_SAMPLES` frames
    spread over the video by :func:`vcprep.ego.ego_rows_from_frames`, said through ``say``; a
    video with too few distinct frames gets none, also said), 'none' (the camera as given, no
    search) or a whole number of rows at the video's size (0: no own vehicle)."""
    from dataclasses import replace

    from vcprep.ego import ego_rows_from_frames, rows_at_height

    cam = camera.for_image_size(info.size, info.path)
    if ego == "none" or (ego == "auto" and cam.ego_rows):
        return cam
    if ego != "auto":
        try:
            rows = int(ego)
        except ValueError:
            rows = -1
        if not 0 <= rows < info.size[1]:
            raise InputError(f"--ego '{ego}' is not auto, none or a number of rows below the video's "
                             f"{info.size[1]}", info.path, "give e.g. --ego 40, --ego 0 or --ego none")
        return replace(cam, ego_rows=rows)
    say = say or (lambda _msg: None)
    frames = sample_frames(info)
    try:
        est = ego_rows_from_frames(frames, info.path)
    except InputError as e:
        say(f"own vehicle: not looked for ({e.problem}); set ego_rows in the camera file, or --ego N")
        return cam
    if est.rows:
        say(f"own vehicle: {est.rows} rows found from the frames ({est.describe()}); set ego_rows in the "
            f"camera file to override")
    else:
        say(f"own vehicle: none found from the frames ({est.describe()}); set ego_rows in the camera file if "
            f"it shows one")
    return replace(cam, ego_rows=rows_at_height(est, info.size[1]))


def _now(fn, *args) -> Future:
    """``fn(*args)`` computed here, as a finished Future (no worker thread)."""
    done: Future = Future()
    done.set_result(fn(*args))
    return done


def predict_video(predictor, video: str | Path, out: str | Path, camera: Camera | None, within: str = "auto",
                  mask_video: bool = False, overlay: bool = False, progress: bool = True, vp_window: int = 2,
                  times: StageTimes | None = None, ego: str = "auto", vp_ahead: int = VP_AHEAD,
                  vp_rule=None) -> list[Path]:
    """Predict every frame of ``video`` (module docstring); returns the paths written (the mask
    PNGs, or the mask video; the overlay video). ``within``: 'auto' (as the model was trained,
    :func:`vctrain.predict.within_mode`), 'estimate', 'none' or a CSV ``id,u,v`` whose ids are
    ``<stem>_<frame:06d>``; estimated VPs are searched and accepted within the pose ranges of
    ``vp_rule`` or the model's (:func:`vctrain.predict.model_vp_rule`) and smoothed over
    ``vp_window`` frames either side. ``ego``: the own vehicle, as
    :func:`ego_camera` takes it (a virtual-camera model). ``times`` (given) gets the stage timings;
    ``progress`` False also silences the own-vehicle remark. ``vp_ahead``: frames whose VP is
    estimated in a worker thread ahead of the one predicted (0: in this thread, in turn)."""
    from vcprep.vanishing_point import read_vp_csv

    from .predict import model_vp_rule, within_mode

    video = Path(video)
    cap, info = open_video(video)
    try:
        cam = _video_camera(predictor, camera, video, info, ego, progress)
        mode = within_mode(predictor.data, cam, within)
        given = None
        if mode not in ("estimate", "none"):
            given = read_vp_csv(mode)
        fp = FramePredictor(predictor, cam, info.size)
        if times is not None:
            fp.times = times
        if mode == "estimate" and fp.camera is None:
            raise InputError("per-frame VPs need the camera of the video", video, "add --camera, or --within none")
        cfg = model_vp_rule(predictor.data, vp_rule)[0].config()
        vps = StreamingVPs(fp.camera, vp_window, cfg=cfg, times=fp.times) if mode == "estimate" else None
        out = _out_folder(out, video.stem, mask_video)
        pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="vp") if vps is not None and vp_ahead else None
        sink = None
        try:
            sink = _FrameSink(fp, out, video.stem, info, mask_video, overlay, progress)
            frames = read_frames(cap, info, lambda msg: tqdm.write(msg, file=sys.stderr))
            _stream(frames, sink, vps, given, mode, pool.submit if pool is not None else _now, vp_ahead)
            return sink.close()
        except BaseException:
            if sink is not None:
                sink.abort()
            raise
        finally:
            if pool is not None:
                pool.shutdown(wait=True, cancel_futures=True)
    finally:
        cap.release()


def _video_camera(predictor, camera: Camera | None, video: Path, info: VideoInfo, ego: str,
                  progress: bool) -> Camera | None:
    """The camera at the video's frame size (a virtual-camera model needs one), with its own
    vehicle's rows (:func:`ego_camera`) for a virtual-camera model."""
    if camera is None:
        if predictor.mode == "virtual":
            raise InputError("a virtual-camera model needs the camera of the video", video,
                             "add --camera (preset or calibration file)")
        return None
    cam = camera.for_image_size(info.size, video)
    if predictor.mode == "virtual":
        say = (lambda msg: tqdm.write(f"{video}: {msg}", file=sys.stderr)) if progress else None
        cam = ego_camera(cam, info, ego, say)
    return cam


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
    VP is final (per-frame VPs)."""

    def __init__(self, fp: FramePredictor, out: Path, stem: str, info: VideoInfo, mask_video: bool,
                 overlay: bool, progress: bool):
        from .predict import write_prediction

        self.fp, self.stem, self.frame_dir, self._write_prediction = fp, stem, out / stem, write_prediction
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
        self.held: dict[int, np.ndarray | None] = {}
        self.order: list[int] = []

    def emit(self, i: int, vp) -> None:
        """Predict held frame ``i`` with ``vp`` and write it (an undecodable frame: the videos
        repeat their last frame)."""
        frame = self.held.pop(i)
        if frame is None:
            for o in self.outs:
                o.write(None)
        else:
            prob = self.fp.predict(frame, vp)
            if self.mv is None:
                self.written.append(self._write_prediction(self.frame_dir, f"{self.stem}_{i:06d}", prob)[0])
            mask = np.where(prob >= 0.5, 255, 0).astype(np.uint8)
            if self.mv is not None:
                self.mv.write(cv2.cvtColor(mask, cv2.COLOR_GRAY2BGR))
            if self.ov is not None:
                self.ov.write(draw_overlay(frame, mask, self.fp.camera, vp))
        self.bar.update(1)

    def release(self, final: list[tuple[int, object]]) -> None:
        """Predict, in order, every held frame up to the last whose VP is final."""
        done = {i: r.vp for i, r in final}
        while self.order and (self.held[self.order[0]] is None or self.order[0] in done):
            i = self.order.pop(0)
            self.emit(i, done.get(i))

    def close(self) -> list[Path]:
        """Finish the videos; the paths written (mask PNGs or mask video, then the overlay video)."""
        self.bar.close()
        for o in self.outs:
            o.close()
            self.written.append(o.path)
        return self.written

    def abort(self) -> None:
        for o in self.outs:
            o.abort()


def _stream(frames: Iterator[tuple[int, np.ndarray | None]], sink: _FrameSink, vps: StreamingVPs | None, given,
            mode: str, submit: Callable[..., Future], vp_ahead: int) -> None:
    """Every frame into ``sink``, in order: at once with a given VP (``given``, read from the CSV
    ``mode``) or none; with per-frame VPs (``vps``) once its VP is final. The VP of the frame just
    read is estimated (``submit``: in another thread) while the frames before it are predicted and
    written, ``vp_ahead`` frames ahead (the estimate is pure: the same numbers, in the same order)."""
    ahead: deque[tuple[int, Future]] = deque()
    for i, frame in frames:
        sink.held[i] = frame
        if vps is None:
            vp = None
            if given is not None and frame is not None:
                key = f"{sink.stem}_{i:06d}"
                if key not in given:
                    raise InputError(f"no VP row for frame id '{key}'", mode, "add an 'id,u,v' row per frame")
                vp = given[key]
            sink.emit(i, vp)
            continue
        sink.order.append(i)
        if frame is not None:
            ahead.append((i, submit(vps.estimate, frame)))
        while len(ahead) > vp_ahead:
            j, est = ahead.popleft()
            sink.release(vps.push(j, estimate=est.result()))
    if vps is not None:
        while ahead:
            j, est = ahead.popleft()
            sink.release(vps.push(j, estimate=est.result()))
        sink.release(vps.flush())
