"""Completion of the virtual image (paper §4.3): fill every store pixel that no source pixel
covers, fused with the warp: one inverse map (store pixel -> source point), applied in one pass.

Methods (:data:`METHODS`):

- ``projective`` (the paper's): polar coordinates centred on the road VP in store coordinates;
  an uncovered pixel takes the value where the ray from the VP through it leaves the covered
  region, linearly interpolated in angle along the region's boundary.
- ``zero``: image 0, label 0 (not road) -- the paper's zero-padding ablation.
- ``replicate``: the value of the nearest covered store pixel (border replication in the
  virtual image) -- the paper's pixel-replication ablation.
- ``none``: the bare warp (image 0, label 255 = ignore).

Why one remap is enough: the homography ``virt_H_src`` maps lines to lines and the VP to the VP,
so the ray from the VP ``c`` through an uncovered store pixel ``p`` is the image of a ray from
``c_src = src_H_virt c`` in the source. Its source direction is ``J (p - c)`` with ``J`` the
Jacobian of ``src_H_virt`` at ``c`` (exact: a homography maps a ray from ``c`` onto a ray from
``c_src``), and the point where the store ray leaves the covered region is the image of the
point where the source ray leaves the source region. So every uncovered store pixel gets a
*source* coordinate, like the covered ones (``map_x``/``map_y``). As that coordinate depends only
on the ray's angle, it is kept as a 1-D table of angles, and applying the maps remaps the covered
pixels and looks the uncovered ones up in the table sampled once per image
(:class:`CompletionMaps`): each pixel is computed once, and only the covered ones interpolate.

Labels are completed from LABEL_RIM (8) px inside the image edge: a ray that leaves through the
edge takes its label where it leaves the rectangle inset by 8 px on every side
(:func:`label_exit_points`). Annotations often carry a thin rim that disagrees with the rows
just inside it (KITTI road's ``gt_image_2`` marks its last 4-5 rows "not road" even under the
road); sampled at the edge itself, that rim would fill the whole region below a frame. The
image keeps the exact edge exit (its pixels there are real); ``replicate`` clamps its label
points into the same inset rectangle.

The covered region is the source rectangle (pixel centres ``[0, w-1] x [0, h-1]``) minus the
label's ignore pixels that touch the image border (an ego-vehicle bonnet, a rectification
border). A ray's exit point is the exact ray/rectangle intersection, unless the ray meets such
pixels first: then it is looked up in a table of the region's boundary pixels next to them,
sorted by angle; the image point interpolates linearly in angle between boundary pixels and
steps 1 px inward (so bilinear sampling never reaches into the ignore pixels); the label takes
the boundary pixel nearest in angle (values are never mixed). Ignore pixels inside the covered region keep their warped
value (the bonnet stays ignore). Ignore holes that do not touch the border are not boundary.

VP outside the covered region (a bad estimate, or a VP above the source image): rays from an
outside point do not leave the region once, so the rays are centred instead on the covered
pixel nearest to the VP, moved 10 % of the way toward the region's centroid (strictly inside).
The result says so (``vp_inside=False``, ``centre``), and stores record it.

Modules: the ray geometry in the source is :mod:`vcprep.warp.completion_rays`, the fill table and its
caches :mod:`vcprep.warp.completion_tables`; the maps and the method are here (every name importable
from here).

Conventions as in :mod:`vcprep.warp`: (x, y) = (u, v), pixel centres at integers, maps are
store pixel -> source pixel.
"""
from __future__ import annotations

import hashlib
import sys
import threading
from collections import OrderedDict
from functools import cached_property

import cv2
import numpy as np

from .completion_rays import (FALLBACK_TOWARD, INSET, LABEL_RIM, _centre, _exit_table, _src_H_dst,  # noqa: F401
                              _to_source, exit_points_rectangle, label_exit_points)
from .completion_tables import (_CACHE_MAX, BAND_ROWS, TABLE_ARC, TABLE_COLS, AngleFill, AngleIndex,  # noqa: F401
                                _angle_index, _build_angle_index, _lru, _rays)
from ..errors import GeometryError, InputError, one_of
from ..labels import IGNORE
from .remap import RemapMaps, is_bgr8, maps_for

__all__ = ["METHODS", "COMPLETION_VERSION", "LABEL_RIM", "CompletionMaps", "check_method", "border_ignore",
           "completion_maps", "complete_maps", "clear_cache", "exit_points_rectangle", "label_exit_points", "store_vp"]

METHODS = ("projective", "zero", "replicate", "none")
COMPLETION_VERSION = "completion-v3"  # bump when completed outputs of identical inputs would change
# v3: labels are sampled LABEL_RIM px inside the image edge (annotation rims, e.g. KITTI's bottom rows)


class CompletionMaps:
    """Warp + completion of one item, built once per (homography, sizes, method, VP, border-ignore
    mask) and applied to its image and label.

    ``valid`` is 1 only where a source pixel landed. ``label_border``: label value for pixels left
    uncovered (255 for 'none', 0 for 'zero'). ``centre``: the store point the projective rays
    start from (the VP, or the fallback when ``vp_inside`` is False).

    Applying them (``warp_image`` / ``warp_label``): 'none' and 'zero' are the bare warp; 'replicate'
    is one remap of completed maps; 'projective' is one pass over the pixels in two parts that never
    overlap: the covered pixels are remapped from the source (bilinear), the uncovered ones are
    looked up (nearest in angle) in a table of the source sampled (bilinear) at the exit point of
    each of ``n`` angles; the table is so fine (<= ``TABLE_ARC`` px of arc at the farthest pixel)
    that this is the continuous definition sampled below pixel resolution. ``map_x``/``map_y``
    (computed on first use) are the same source points per pixel, so ``warp_image(exact=True)``
    -- one remap of every pixel -- is the reference the fast path is tested against.
    """

    def __init__(self, base: RemapMaps, method: str, label_border: int, centre: tuple[float, float] | None = None,
                 vp_inside: bool = True, full: RemapMaps | None = None, angles: AngleIndex | None = None,
                 fill: AngleFill | None = None):
        self.base, self.method, self.label_border = base, method, label_border
        self.centre, self.vp_inside = centre, vp_inside
        self.valid = base.valid
        self._full, self.angles, self.fill = full, angles, fill
        self._shift_cache: dict = {}  # the covered pass's shifted maps, built on first use

    @property
    def size(self) -> tuple[int, int]:
        return self.base.size

    @property
    def note(self) -> str | None:
        """A sentence for the user when the result is not the plain method (VP outside)."""
        if self.method == "projective" and not self.vp_inside:
            return (f"VP outside the covered region; completion rays start at the nearest covered point "
                    f"({self.centre[0]:.1f}, {self.centre[1]:.1f}) instead")
        return None

    @cached_property
    def exact_maps(self) -> RemapMaps:
        """Float source coordinates of every store pixel (image: bilinear; ``nearest``: label)."""
        if self._full is not None:
            return self._full
        if self.fill is None:
            return self.base
        unc = self.valid == 0
        k = self.angles.k(unc)
        coords = []
        for tx, ty in ((self.fill.image_x, self.fill.image_y), (self.fill.label_x, self.fill.label_y)):
            mx, my = self.base.map_x.copy(), self.base.map_y.copy()
            mx[unc] = tx.ravel()[k]
            my[unc] = ty.ravel()[k]
            coords.append((mx, my))
        return _finish(*coords[0], *coords[1], self.valid)

    # the per-pixel maps of :class:`RemapMaps`, from the exact maps (built on first use)
    map_x = property(lambda self: self.exact_maps.map_x)
    map_y = property(lambda self: self.exact_maps.map_y)
    linear = property(lambda self: self.exact_maps.linear)
    nearest = property(lambda self: self.exact_maps.nearest)
    roi = property(lambda self: self.exact_maps.roi)

    def remap_image(self, img: np.ndarray) -> np.ndarray:
        if self.fill is None:
            return (self._full or self.base).remap_image(img)
        return self._fused(img, self.base.linear, cv2.INTER_LINEAR, self.fill.image_x, self.fill.image_y)

    def remap_label(self, label: np.ndarray, border_value: int) -> np.ndarray:
        if self.fill is None:
            return (self._full or self.base).remap_label(label, border_value)
        return self._fused(label, (self.base.nearest, None), cv2.INTER_NEAREST, self.fill.label_x, self.fill.label_y)

    def _fused(self, src, maps, interp, table_x, table_y) -> np.ndarray:
        """The two passes, chunk by chunk of rows (:meth:`AngleIndex.chunks`). With torch loaded
        (vctrain) every pixel is first looked up in the table (``torch.index_select``, ~1.5x a
        nearest ``cv2.remap``) and the covered ones are remapped over it (``BORDER_TRANSPARENT``
        leaves the uncovered ones, at :data:`OUTSIDE`, alone); else (vcprep) the covered pixels are
        remapped first and the uncovered ones looked up after (a nearest ``cv2.remap`` through the
        angle index; covered pixels hold (-1, -1), which ``BORDER_TRANSPARENT`` leaves alone). Both
        remap the covered pixels with the bare warp's fixed-point maps: the same values."""
        # 8-bit BGR goes through BGRA: the fill copies one 32-bit word per pixel (~1.5x 3 bytes), the
        # covered remap is faster on 4 channels too, and a chunk's BGRA rows stay in cache until
        # converted back
        packed = is_bgr8(src)
        W, H = self.size
        out = np.empty((H, W) + ((3,) if packed else src.shape[2:]), dtype=src.dtype)
        torch = sys.modules.get("torch") if packed and _FILL_TORCH else None
        rim = None
        if torch is not None:
            rim = _with_rim(src)
            src = rim[1:-1, 1:-1]
        elif packed:
            src = cv2.cvtColor(src, cv2.COLOR_BGR2BGRA)
        table = cv2.remap(src, table_x, table_y, interp, borderMode=cv2.BORDER_REPLICATE)
        if packed:
            table = table.view(np.int32)[..., 0]
        for r0, r1, rects, fills in self.angles.chunks(packed):
            work = _scratch((r1 - r0, W, 4)) if packed else out[r0:r1]
            fill_dst = work.view(np.int32)[..., 0] if packed else work
            if torch is not None:
                _gather(torch, table, self.angles.flat[r0:r1], fill_dst)
                self._covered(rim, maps, interp, rects, r0, work, transparent=True)
            else:
                self._covered(src, maps, interp, rects, r0, work, transparent=False)
                for y0, y1, x0, x1 in fills:
                    cv2.remap(table, self.angles.index[y0:y1, x0:x1], None, cv2.INTER_NEAREST,
                              dst=fill_dst[y0 - r0:y1 - r0, x0:x1], borderMode=cv2.BORDER_TRANSPARENT)
            if packed:
                cv2.cvtColor(work, cv2.COLOR_BGRA2BGR, dst=out[r0:r1])
        return out

    def _covered(self, src, maps, interp, rects, r0: int, work: np.ndarray, transparent: bool) -> None:
        """The covered pass over ``rects`` into ``work`` (rows from ``r0``). ``transparent``: from
        the source with its rim (``src``) through maps moved by 1 px (:meth:`_shifted`): OpenCV's
        fixed-point remap leaves a transparent pixel whose taps reach past the edge unwritten, even
        at weight 0; with the rim the values are the same."""
        if transparent:
            (bx, by), m1, m2 = self._shifted(maps)
        else:
            (bx, by), (m1, m2) = (0, 0), maps
        for y0, y1, x0, x1 in rects:
            box = slice(y0 - by, y1 - by), slice(x0 - bx, x1 - bx)
            cv2.remap(src, m1[box], None if m2 is None else m2[box], interp, dst=work[y0 - r0:y1 - r0, x0:x1],
                      borderMode=cv2.BORDER_TRANSPARENT if transparent else cv2.BORDER_CONSTANT, borderValue=0)

    def _shifted(self, maps) -> tuple[tuple[int, int], np.ndarray, np.ndarray | None]:
        """((x0, y0), map1, map2): the fixed-point ``maps`` over the box of the covered rects (from
        (x0, y0)), their integer source coordinates + 1 for the source with its rim; built once."""
        key = id(maps[0])
        hit = self._shift_cache.get(key)
        if hit is None:
            rects = self.angles.covered_rects
            x0, y0 = min(r[2] for r in rects), min(r[0] for r in rects)
            x1, y1 = max(r[3] for r in rects), max(r[1] for r in rects)
            m1 = maps[0][y0:y1, x0:x1] + np.int16(1)  # OUTSIDE (-64) stays outside
            hit = self._shift_cache[key] = ((x0, y0), m1, None if maps[1] is None else maps[1][y0:y1, x0:x1])
        return hit


def _with_rim(img: np.ndarray) -> np.ndarray:
    """8-bit BGR ``img`` as BGRA with its edge pixels repeated once around it, (h + 2, w + 2, 4)."""
    return cv2.copyMakeBorder(cv2.cvtColor(img, cv2.COLOR_BGR2BGRA), 1, 1, 1, 1, cv2.BORDER_REPLICATE)


def _gather(torch, table: np.ndarray, flat: np.ndarray, dst: np.ndarray) -> None:
    """``dst`` (int32, contiguous) = ``table`` at ``flat`` (the same shape): ``torch.index_select``
    on the arrays' memory; only where torch is already imported (vcprep does not import it)."""
    torch.index_select(torch.from_numpy(table.reshape(-1)), 0, torch.from_numpy(flat.reshape(-1)),
                       out=torch.from_numpy(dst.reshape(-1)))


_FILL_TORCH = True  # with torch loaded, gather with it (benchmarks switch it off to time the cv2 path)


def check_method(method: str) -> str:
    if method not in METHODS:
        raise InputError(f"unknown completion method '{method}'", None, one_of(method, METHODS))
    return method


def border_ignore(label: np.ndarray | None) -> np.ndarray | None:
    """Boolean mask of the ignore pixels connected (8-neighbourhood) to the image border, or None
    when there are none. These cut the covered region; interior ignore holes do not."""
    if label is None:
        return None
    ign = (label == IGNORE).view(np.uint8)
    if not (ign[0].any() or ign[-1].any() or ign[:, 0].any() or ign[:, -1].any()):
        return None
    # a frame of ignore around the label joins every component that touches the border; one
    # 8-connected flood fill from the frame marks them all (value 2)
    framed = cv2.copyMakeBorder(ign, 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=1)
    cv2.floodFill(framed, None, (0, 0), 2, flags=8)
    return framed[1:-1, 1:-1] == 2


def store_vp(H: np.ndarray, vp_src: tuple[float, float]) -> tuple[float, float]:
    """The VP ``vp_src`` (source pixels) in store coordinates: ``H @ vp``."""
    p = np.asarray(H, dtype=np.float64) @ np.array([vp_src[0], vp_src[1], 1.0])
    return float(p[0] / p[2]), float(p[1] / p[2])


def _finish(map_x, map_y, lab_x, lab_y, valid) -> RemapMaps:
    map_x = np.ascontiguousarray(map_x, dtype=np.float32)
    map_y = np.ascontiguousarray(map_y, dtype=np.float32)
    linear = cv2.convertMaps(map_x, map_y, cv2.CV_16SC2)
    nearest = cv2.convertMaps(np.ascontiguousarray(lab_x, dtype=np.float32),
                              np.ascontiguousarray(lab_y, dtype=np.float32), cv2.CV_16SC2, nninterpolation=True)[0]
    return RemapMaps(map_x, map_y, linear, nearest, valid)


def complete_maps(base: RemapMaps, dst_H_src: np.ndarray, src_size: tuple[int, int], method: str,
                  vp: tuple[float, float] | None = None, src_ignore: np.ndarray | None = None) -> CompletionMaps:
    """Fill the uncovered pixels of the bare-warp maps ``base`` by ``method``.

    ``vp``: the ray centre in store coordinates (projective; default: the store centre).
    ``src_ignore``: boolean (h, w) source mask of border ignore pixels (see :func:`border_ignore`),
    excluded from the region that values are taken from.
    """
    check_method(method)
    valid = base.valid
    if method == "none":
        return CompletionMaps(base, method, IGNORE)
    if method == "zero":
        return CompletionMaps(base, method, 0)
    w, h = src_size
    unc = valid == 0
    if not unc.any():  # nothing to fill (also makes completion idempotent)
        return CompletionMaps(base, method, IGNORE, None if vp is None else tuple(map(float, vp)))
    region_src = None
    if src_ignore is not None and src_ignore.any():
        region_src = (~src_ignore).astype(np.uint8)
        if not region_src.any():
            raise InputError("the whole label is ignore at the border, nothing to complete from", None,
                             "check the label, or use --complete none")

    def region_dst() -> np.ndarray:
        r = valid.astype(bool)
        if region_src is not None:
            r &= cv2.remap(region_src, base.nearest, None, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT,
                           borderValue=0) == 1
        if not r.any():
            raise GeometryError("no source pixel lands in the virtual image, nothing to complete from", None,
                                "check the camera, pose and scale")
        return r

    if method == "replicate":
        rdst = region_dst()
        map_x, map_y = base.map_x.copy(), base.map_y.copy()
        vs, us = np.nonzero(unc)
        # nearest region pixel of every store pixel (labels of the zero pixels of 1 - region)
        _, lab = cv2.distanceTransformWithLabels((~rdst).astype(np.uint8), cv2.DIST_L2, 5,
                                                 labelType=cv2.DIST_LABEL_PIXEL)
        ry, rx = np.nonzero(rdst)
        lut = np.zeros(int(lab.max()) + 1, dtype=np.int64)
        lut[lab[ry, rx]] = np.arange(len(rx))
        k = lut[lab[vs, us]]
        map_x[vs, us] = base.map_x[ry[k], rx[k]]
        map_y[vs, us] = base.map_y[ry[k], rx[k]]
        # labels: the same points clamped into the rectangle LABEL_RIM px inside the edge (an
        # annotation rim is not replicated), unless that lands in the cut
        lab_x, lab_y = map_x.copy(), map_y.copy()
        rx_, ry_ = min(LABEL_RIM, (w - 1) / 2), min(LABEL_RIM, (h - 1) / 2)
        cx_ = np.clip(map_x[vs, us], rx_, w - 1 - rx_)
        cy_ = np.clip(map_y[vs, us], ry_, h - 1 - ry_)
        if region_src is not None:
            inside = region_src[np.rint(cy_).astype(np.int64), np.rint(cx_).astype(np.int64)] == 1
            cx_, cy_ = np.where(inside, cx_, map_x[vs, us]), np.where(inside, cy_, map_y[vs, us])
        lab_x[vs, us], lab_y[vs, us] = cx_, cy_
        return CompletionMaps(base, method, IGNORE, full=_finish(map_x, map_y, lab_x, lab_y, valid))

    # projective
    if vp is None:
        vp = ((valid.shape[1] - 1) / 2, (valid.shape[0] - 1) / 2)
    M = _src_H_dst(dst_H_src)
    centre, vp_inside = _centre(vp, M, src_size, valid.shape, region_src, region_dst)
    c_src, J = _to_source(M, centre)
    if c_src is None:  # cannot happen for a covered centre
        raise GeometryError("the completion centre has no source point", None, "check the VP")
    c_src = np.clip(c_src, [0, 0], [w - 1, h - 1])
    H = np.ascontiguousarray(dst_H_src, dtype=np.float64)
    angles = _angle_index(valid, centre, (H.tobytes(), tuple(src_size), base.size, centre))
    rays = _rays(angles.n, J, c_src, src_size, (H.tobytes(), tuple(src_size), base.size, centre))
    tx, ty, lx, ly = _exit_table(rays, src_size, region_src)
    fill = AngleFill(angles.table(tx), angles.table(ty), angles.table(lx), angles.table(ly))
    return CompletionMaps(base, method, IGNORE, centre, vp_inside, angles=angles, fill=fill)


_SCRATCH = threading.local()


def _scratch(shape: tuple[int, int, int]) -> np.ndarray:
    """A reused uint8 work buffer of ``shape`` for this thread (a chunk of the packed BGRA image,
    which never leaves :meth:`CompletionMaps._fused`): a fresh one costs page faults."""
    buf = getattr(_SCRATCH, "buf", None)
    if buf is None or buf.shape != shape:
        buf = _SCRATCH.buf = np.empty(shape, dtype=np.uint8)
    return buf


_CACHE: "OrderedDict[tuple, CompletionMaps]" = OrderedDict()


def completion_maps(dst_H_src: np.ndarray, src_size: tuple[int, int], dst_size: tuple[int, int], method: str,
                    vp: tuple[float, float] | None = None, src_ignore: np.ndarray | None = None) -> CompletionMaps:
    """Warp + completion maps for one (homography, sizes, method, VP, border-ignore mask), with a
    small LRU cache: in between-camera mode every image of a camera shares H and VP, so the maps
    are built once (per distinct ignore mask when labels cut the region)."""
    check_method(method)
    H = np.ascontiguousarray(dst_H_src, dtype=np.float64)
    if src_ignore is not None and src_ignore.shape != (src_size[1], src_size[0]):
        raise InputError(f"ignore mask is {src_ignore.shape[1]}x{src_ignore.shape[0]}, image is "
                         f"{src_size[0]}x{src_size[1]}", None, "labels must have the size of their images")
    if src_ignore is not None and not src_ignore.any():
        src_ignore = None
    mask_key = None if src_ignore is None else hashlib.sha1(np.packbits(src_ignore).tobytes()).hexdigest()
    vp_key = None if (vp is None or method != "projective") else (round(float(vp[0]), 9), round(float(vp[1]), 9))
    key = (H.tobytes(), tuple(src_size), tuple(dst_size), method, vp_key,
           mask_key if method in ("projective", "replicate") else None)
    return _lru(_CACHE, key, lambda: complete_maps(maps_for(H, src_size, dst_size), H, src_size, method, vp,
                                                   src_ignore if method in ("projective", "replicate") else None))


def clear_cache() -> None:
    """Forget the maps :func:`completion_maps` keeps, so the next call completes them afresh (a
    benchmark's cold start). The ray and angle tables they are built from stay cached, and so do the
    warp maps (:func:`vcprep.warp.clear_cache`)."""
    _CACHE.clear()
