"""Image files: safe reads (one read of the bytes, header checks before any large allocation, one clear
error per bad file) and atomic PNG writes.

Modules: :mod:`.images` (read, write, sizes), :mod:`.png` (the PNG encoder the store writes with),
:mod:`.video` (video files: frames in order, a sample of frames).
"""
from __future__ import annotations

from .images import (IMAGE_EXTENSIONS, MAX_PIXELS, PNG_KINDS, image_size, image_size_from_header, read_image, read_text,
                     write_bytes_atomic, write_png)
from .png import encode_png
from .video import (EGO_SAMPLES, VIDEO_EXTENSIONS, VideoInfo, frames_of, is_video, open_video, read_frames,
                    sample_frames, sampled_frame_files)

__all__ = ["EGO_SAMPLES", "VIDEO_EXTENSIONS", "VideoInfo", "frames_of", "is_video", "open_video", "read_frames",
           "sample_frames", "sampled_frame_files", "IMAGE_EXTENSIONS", "MAX_PIXELS", "PNG_KINDS", "image_size", "image_size_from_header", "read_image",
           "read_text", "write_bytes_atomic", "write_png", "encode_png"]
