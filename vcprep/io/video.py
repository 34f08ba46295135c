"""Video files: opening one, reading its frames in order (undecodable ones named and skipped), and
a sample of frames spread over it (for what is found from a few frames: the own vehicle, an
estimated camera). Whatever OpenCV's FFmpeg reads (:data:`VIDEO_EXTENSIONS`)."""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

import cv2
import numpy as np

from ..errors import InputError

__all__ = ["VIDEO_EXTENSIONS", "VideoInfo", "is_video", "open_video", "read_frames", "sample_frames",
           "sampled_frame_files", "frames_of", "EGO_SAMPLES"]

# FFmpeg's own log lines ("[mjpeg @ 0x...] No JPEG data found") would break the one-line errors and
# repeat what read_frames says per frame; read once, when OpenCV first opens a video. A user's
# OPENCV_FFMPEG_LOGLEVEL wins.
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET

VIDEO_EXTENSIONS = (".mp4", ".avi", ".mkv", ".mov", ".m4v", ".webm", ".mpg", ".mpeg", ".wmv")
MAX_BAD_RUN = 16  # this many undecodable frames in a row (and no header count left) end the video
EGO_SAMPLES = 48  # frames sampled over a video for what a few frames tell (the own vehicle)


def is_video(path: str | Path) -> bool:
    """Whether ``path`` names a video file (by its extension)."""
    return Path(path).suffix.lower() in VIDEO_EXTENSIONS


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
        if _cut_off_mp4(path):
            raise InputError("an MP4/MOV file without its index ('moov' box): the recording was cut off before it "
                             "was finished", path, "copy the whole file again, or recover it with a tool such as "
                             "untrunc; re-encoding cannot help")
        raise InputError("cannot read as a video (not a video, or a codec OpenCV's FFmpeg lacks)", path,
                         f"give a video file ({', '.join(VIDEO_EXTENSIONS)}) or convert it, e.g. "
                         "ffmpeg -i IN -c:v libx264 OUT.mp4")
    fps = float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
    n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
    return cap, VideoInfo(path, (w, h), fps if 0 < fps < 1000 else 25.0, max(0, n))


def _cut_off_mp4(path: Path) -> bool:
    """An ISO media file (MP4, MOV: an 'ftyp' box first) whose top-level boxes end before a 'moov'
    box: a recording cut off before its index was written (the index comes last by default). Reads
    the box headers only."""
    end = path.stat().st_size
    with open(path, "rb") as f:
        pos, first = 0, True
        while pos + 8 <= end:
            f.seek(pos)
            head = f.read(16)
            size, kind = int.from_bytes(head[:4], "big"), head[4:8]
            if first and kind != b"ftyp":
                return False
            first = False
            if kind == b"moov":
                return False
            if size == 1 and len(head) == 16:
                size = int.from_bytes(head[8:16], "big")
            if size < 8:
                return size == 0 and kind == b"mdat"  # 'to the end of the file': no moov after it
            pos += size
    return not first


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


def sampled_frame_files(video: str | Path, folder: str | Path, n: int = EGO_SAMPLES) -> list[Path]:
    """Up to ``n`` frames spread over ``video`` (:func:`sample_frames`) written as PNGs
    ``<stem>_<k>.png`` into ``folder``: a video as the image files a frame-based tool reads."""
    from .images import write_png

    _, info = open_video(video)
    out = []
    for k, frame in enumerate(sample_frames(info, n)):
        path = Path(folder) / f"{info.path.stem}_{k:03d}.png"
        write_png(path, frame)
        out.append(path)
    if not out:
        raise InputError("no frame of the video can be decoded", video, "check the file, or convert it with ffmpeg")
    return out


def frames_of(paths, folder: str | Path, n: int = EGO_SAMPLES) -> list[Path]:
    """``paths`` with every video replaced by a sample of its frames written into ``folder``."""
    out: list[Path] = []
    for p in map(Path, paths):
        out += sampled_frame_files(p, folder, n) if is_video(p) else [p]
    return out
