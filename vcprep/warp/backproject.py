"""Back-projection: virtual-domain masks / probability maps -> the item's original camera.

For a store item with ``H = virt_H_src`` (source pixel -> store pixel), the way back samples the
store image at ``H @ (u, v, 1)`` for every source pixel centre (u, v): the exact inverse of the
forward warp. That is one ``cv2.warpPerspective(..., WARP_INVERSE_MAP)`` with the record's ``H``
(no maps to build or cache: a source image lies inside the store, so every pixel is
interpolated and computing the coordinates on the fly is cheaper than reading them). Labels/
masks use nearest neighbour, probabilities bilinear; source pixels that fall outside the store
image get ``fill`` (0: not road; bilinear blends toward it over the store's last half pixel).

The result always has the item's full source size ``record["size"]``. An item whose camera sees
its own vehicle (record ``ego_rows``: the bottom rows cut off before warping) is back-projected
like any other: its H is the full frame's, and the store pixels its ego rows map to hold the
completion of the visible image, so the prediction there continues the scene seen above the
vehicle (the vehicle's own pixels never reached the network; labels mark them ignore, e.g.
CamVid's class 11). A bonnet rarely spans the whole width: the road beside it is predicted, not
declared "not road".
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from ..errors import InputError
from ..io.images import read_image, write_png
from ..store.layout import Store

__all__ = ["src_H_virt", "backproject_array", "ray_clamped", "backproject_rays", "backproject_folder"]


def src_H_virt(record: dict) -> np.ndarray:
    """Store pixel -> source pixel for one item record."""
    return np.linalg.inv(np.asarray(record["H"], dtype=np.float64).reshape(3, 3))


def backproject_array(arr: np.ndarray, record: dict, kind: str = "mask", fill: int = 0) -> np.ndarray:
    """Map ``arr`` (store-sized) back to the source image of ``record``.

    ``kind='mask'``: nearest neighbour (values never mixed); ``'prob'``: bilinear. Every source
    pixel, ego rows included (module docstring)."""
    sw, sh = record["store_size"]
    if arr.shape[:2] != (sh, sw):
        raise InputError(f"map is {arr.shape[1]}x{arr.shape[0]} but the store is {sw}x{sh}", record.get("id"),
                         "back-project maps predicted on this store")
    if kind not in ("mask", "prob"):
        raise InputError(f"unknown kind '{kind}'", None, "use --kind mask or --kind prob")
    w, h = record["size"]
    H = np.asarray(record["H"], dtype=np.float64).reshape(3, 3)
    interp = cv2.INTER_NEAREST if kind == "mask" else cv2.INTER_LINEAR
    return cv2.warpPerspective(arr, H, (int(w), int(h)), flags=interp | cv2.WARP_INVERSE_MAP,
                               borderMode=cv2.BORDER_CONSTANT, borderValue=fill)


def ray_clamped(x: np.ndarray, y: np.ndarray, centre: tuple[float, float],
                rect: tuple[float, float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Store coordinates ``x``, ``y`` (float arrays, their dtype kept) moved onto ``rect`` = (x0, y0,
    x1, y1) along the ray from ``centre`` (inside it): a point outside goes to where that ray leaves
    the rectangle, a point inside stays. Non-finite points stay non-finite."""
    cx, cy = float(centre[0]), float(centre[1])
    dx, dy = x - cx, y - cy
    s = np.ones_like(dx)
    with np.errstate(divide="ignore", invalid="ignore"):
        for d, lo, hi, c in ((dx, rect[0], rect[2], cx), (dy, rect[1], rect[3], cy)):
            r = (hi - c) / d
            r[~(d > 0)] = np.inf
            np.minimum(s, r, out=s)
            r = (lo - c) / d
            r[~(d < 0)] = np.inf
            np.minimum(s, r, out=s)
    np.clip(s, 0.0, 1.0, out=s)
    return cx + s * dx, cy + s * dy


def backproject_rays(arr: np.ndarray, record: dict, vp: tuple[float, float], fill: float = 0.0,
                     rect: tuple[float, float, float, float] | None = None) -> np.ndarray:
    """A store-sized probability map in the source image of ``record``, bilinear as
    ``backproject_array(..., kind='prob')``, except that a source pixel whose store position lies
    outside the store image takes the value where the ray from ``vp`` (the road VP in store pixels)
    through that position leaves the image (its outermost pixel centres, :func:`ray_clamped`): the
    projective completion's rule (method.md, section 4.3) run backwards. Road edges are lines
    through the VP, so the road a low camera sees below the rectangle, or a wide one beside it,
    continues the road at the rectangle's edge. ``rect`` (x0, y0, x1, y1 pixel centres; default the
    whole store image): a smaller rectangle inside the store whose edge the rays stop at. A pixel
    whose position is undefined (the line H sends to infinity) gets ``fill``."""
    sw, sh = record["store_size"]
    if arr.shape[:2] != (sh, sw):
        raise InputError(f"map is {arr.shape[1]}x{arr.shape[0]} but the store is {sw}x{sh}", record.get("id"),
                         "back-project maps predicted on this store")
    w, h = (int(v) for v in record["size"])
    H = np.asarray(record["H"], dtype=np.float64).reshape(3, 3)
    H = H.astype(np.float32)  # float32 coordinates: ~2e-4 px from float64's, 40 % less time per frame
    u = np.arange(w, dtype=np.float32)[None, :]
    v = np.arange(h, dtype=np.float32)[:, None]
    d = H[2, 0] * u + (H[2, 1] * v + H[2, 2])
    with np.errstate(divide="ignore", invalid="ignore"):
        x = (H[0, 0] * u + (H[0, 1] * v + H[0, 2])) / d
        y = (H[1, 0] * u + (H[1, 1] * v + H[1, 2])) / d
    mx, my = ray_clamped(x, y, vp, rect if rect is not None else (0.0, 0.0, sw - 1.0, sh - 1.0))
    bad = ~(np.isfinite(mx) & np.isfinite(my))
    mx[bad], my[bad] = -8.0, -8.0  # outside: fill
    return cv2.remap(np.ascontiguousarray(arr, dtype=np.float32), mx, my, cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=fill)


def backproject_folder(store: str | Path, masks: str | Path, out: str | Path, kind: str = "mask",
                       progress: bool = True) -> int:
    """Back-project every ``<id>.png`` in ``masks`` that names an item of ``store`` into ``out``."""
    st = Store.open(store)
    masks, out = Path(masks), Path(out)
    if not masks.is_dir():
        raise InputError("mask folder not found", masks, "give the folder of virtual-domain PNGs named <id>.png")
    files = sorted(p for p in masks.glob("*.png") if p.stem in st.items)
    if not files:
        raise InputError(f"no PNG named after an item of store {store}", masks, "masks must be named <id>.png")
    if out.exists() and not out.is_dir():
        raise InputError("exists and is not a directory", out, "choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    for f in tqdm(files, desc="backproject", unit="img", disable=None if progress else True, leave=False):
        arr = read_image(f, label=(kind == "mask")).array
        write_png(out / f.name, backproject_array(arr, st.items[f.stem], kind), kind="mask" if kind == "mask" else "photo")
    return len(files)
