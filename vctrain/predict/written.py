"""What ``vctrain predict`` writes of a frame's P(road): the ``_prob.png`` (0-255), the ``_mask.png``
(0/255) and the ``_overlay.png`` (the road tinted green), each a few milliseconds at camera sizes so
that writing costs less than the network (benchmarks/speed/predict_e2e.py)."""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from vcprep.io import read_image, write_png

__all__ = ["ROAD_ALPHA", "ROAD_GREEN", "prob_u8", "road_mask", "tint_road", "write_prediction"]


def prob_u8(prob: np.ndarray) -> np.ndarray:
    """P(road) as the ``_prob.png``'s 0-255: ``clip(rint(prob * 255), 0, 255)`` bit for bit (rounding
    half to even); for float32 through OpenCV's SIMD conversion (~0.3 ms for 1280x720 against ~2.4)."""
    if prob.dtype == np.float32 and prob.ndim == 2 and prob.size and cv2.minMaxLoc(prob)[0] >= 0:
        return cv2.convertScaleAbs(prob, alpha=255.0)  # (abs: the identity on values >= 0)
    return np.clip(np.rint(prob * 255.0), 0, 255).astype(np.uint8)


def road_mask(prob: np.ndarray) -> np.ndarray:
    """The ``_mask.png``: 255 where ``prob >= 0.5``, else 0 (NaN: 0), uint8 (~0.2 ms for 1280x720 against ~1)."""
    if prob.dtype in (np.float32, np.float64) and prob.ndim == 2 and prob.size:
        return cv2.compare(prob, 0.5, cv2.CMP_GE)
    return np.where(prob >= 0.5, 255, 0).astype(np.uint8)


def write_prediction(out: Path, stem: str, prob: np.ndarray, overlay_on: str | Path | np.ndarray | None = None,
                     inset: Callable[[np.ndarray], np.ndarray] | None = None,
                     mask: np.ndarray | None = None) -> tuple[Path, Path]:
    """Write ``<stem>_prob.png`` (0-255) and ``<stem>_mask.png`` (0/255; ``mask``: its
    :func:`road_mask`, computed once by a caller that needs it too); with ``overlay_on``
    (the original image, or its decoded array) also ``<stem>_overlay.png``: predicted road in green
    over the image (:func:`tint_road`), ``inset`` (given: ``--bev``'s) drawn on it. A ``stem`` with
    folders (a tree's frame, ``drive1/000123``) is written in those folders of ``out``."""
    if "/" in stem:
        (out / stem).parent.mkdir(parents=True, exist_ok=True)
    p8 = prob_u8(prob)
    mask = road_mask(prob) if mask is None else mask
    pp, mp = out / f"{stem}_prob.png", out / f"{stem}_mask.png"
    write_png(pp, p8)
    write_png(mp, mask, kind="mask")
    if overlay_on is not None:
        frame = overlay_on if isinstance(overlay_on, np.ndarray) else read_image(overlay_on).array
        shown = tint_road(frame, mask)
        write_png(out / f"{stem}_overlay.png", inset(shown) if inset is not None else shown, level=3)
    return mp, pp


ROAD_GREEN, ROAD_ALPHA = (0, 255, 0), 0.45  # BGR; vcprep.figures.overlay_label's tint


def tint_road(frame: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``frame`` with the road of ``mask`` (> 0) tinted green: :func:`vcprep.figures.overlay_label`'s
    numbers bit for bit (the same float64 expression, truncated, tabulated once per grey level) at
    a fraction of its cost (a lookup table and a masked copy: ~1-2 ms for a 1280x720 frame against
    ~12 ms), so an overlay costs less than the network. The table is applied within the mask's bounding
    box only (the road is the lower part of a frame: about 1 ms of CPU a 1280x720 frame saved, issue 81)."""
    from vcprep.figures import to_bgr8

    frame = to_bgr8(frame)
    out = frame.copy()
    x, y, w, h = cv2.boundingRect(mask)
    if w and h:
        box = (slice(y, y + h), slice(x, x + w))
        cv2.copyTo(cv2.LUT(frame[box], _TINT), mask[box], out[box])
    return out


_TINT = ((1 - ROAD_ALPHA) * np.arange(256, dtype=np.float64)[:, None]
         + ROAD_ALPHA * np.array(ROAD_GREEN)).astype(np.uint8).reshape(256, 1, 3)
