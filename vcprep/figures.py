"""Figures drawn with OpenCV: overlays and side-by-side views of store items."""
from __future__ import annotations

import cv2
import numpy as np

from .imageio import read_image
from .labels import IGNORE, ROAD, decode_label, get_label_format
from .store import Store

__all__ = ["to_bgr8", "overlay_label", "warp_figure"]


def to_bgr8(img: np.ndarray) -> np.ndarray:
    """Any stored image (grey/colour, 8/16-bit) -> 3-channel uint8 for drawing."""
    if img.dtype == np.uint16:
        img = (img >> 8).astype(np.uint8)
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    return np.ascontiguousarray(img)


def overlay_label(img: np.ndarray, label: np.ndarray | None, alpha: float = 0.45) -> np.ndarray:
    """Road in green, ignore darkened."""
    out = to_bgr8(img).copy()
    if label is None:
        return out
    road = label == ROAD
    out[road] = ((1 - alpha) * out[road] + alpha * np.array([0, 255, 0])).astype(np.uint8)
    ign = label == IGNORE
    out[ign] = (out[ign] * 0.4).astype(np.uint8)
    return out


def _fit(img: np.ndarray, w: int, h: int) -> np.ndarray:
    s = min(w / img.shape[1], h / img.shape[0])
    r = cv2.resize(img, (max(1, int(img.shape[1] * s)), max(1, int(img.shape[0] * s))), interpolation=cv2.INTER_AREA)
    canvas = np.full((h, w, 3), 32, np.uint8)
    y0, x0 = (h - r.shape[0]) // 2, (w - r.shape[1]) // 2
    canvas[y0:y0 + r.shape[0], x0:x0 + r.shape[1]] = r
    return canvas


def warp_figure(store: Store, ids: list[str] | None = None, width: int = 1400, max_items: int = 6) -> np.ndarray:
    """Rows of (original with label | virtual with label, covered region outlined in yellow)."""
    recs = [store.get(i) for i in ids] if ids else list(store)[:max_items]
    vw, vh = store.store_size
    col = width // 2
    row_h = int(col * vh / vw) + 28
    rows = []
    for rec in recs:
        src = read_image(rec["source"]).array
        lab = None
        if rec.get("label_source") and rec.get("label_format"):
            raw = read_image(rec["label_source"], label=True).array
            lab = decode_label(raw, get_label_format(rec["label_format"]), rec["label_source"])
        left = overlay_label(src, lab)
        vimg = read_image(store.path(rec["image"])).array
        vlab = read_image(store.path(rec["label"]), label=True).array if rec.get("label") else None
        right = overlay_label(vimg, vlab)
        valid = read_image(store.path(rec["valid"]), label=True).array
        contours, _ = cv2.findContours(valid.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        cv2.drawContours(right, contours, -1, (0, 255, 255), max(1, vw // 400))
        u, v = store.virtual.cx, store.virtual.cy
        cv2.drawMarker(right, (int(round(u)), int(round(v))), (0, 0, 255), cv2.MARKER_CROSS, max(8, vw // 40), 2)
        pair = np.hstack([_fit(left, col, row_h - 28), _fit(right, col, row_h - 28)])
        bar = np.full((28, width if pair.shape[1] == width else pair.shape[1], 3), 255, np.uint8)
        cv2.putText(bar, f"{rec['id']}  ({rec['camera']}, {rec['size'][0]}x{rec['size'][1]})", (8, 20),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
        cv2.putText(bar, f"virtual camera {vw}x{vh}", (col + 8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1,
                    cv2.LINE_AA)
        rows.append(np.vstack([bar, pair]))
    return np.vstack(rows)
