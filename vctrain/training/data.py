"""Training data: store items (virtual camera) or original images simply resized (the baseline).

Both datasets yield ``(x, y)``: ``x`` float32 (C, h, w) with C = 3 (colour, scaled to [-1, 1]) or
4 (+ VP proximity map in [0, 1]), ``y`` int64 (h, w) with 0 not road, 1 road, 255 ignore. (h, w)
is the working size. Images are resized bilinearly, labels by nearest neighbour.

Augmentations (Bormans et al., domain-shift factors): horizontal flip with probability 0.5 (left/right
hand traffic) and greyscale with probability ``greyscale`` (1.0 = train on greyscale only; the
checkpoint remembers it and predict converts too). Geometric: a random scale ``s`` with
log-uniform ``s`` in [1/(1+a), 1+a] about the item's VP (the image centre when it has none) plus a
random shift of up to ``shift_aug`` of the width/height — one affine map, images bilinear with
reflected borders, labels nearest with 255 (ignore) outside the item. In the virtual camera a
scale about the VP is exactly a change of camera height for the road plane (and the shift a
small pan/tilt), so the network learns a tolerance to the pose errors it meets at test time.
Colour shading (``shading_aug`` a, lens shading of cheap cameras: a low camera's bottom corners tinted
green and magenta, which a network reads as "not road"): with probability 1/2 each channel is multiplied
by a smooth gain field exp(g), g bicubically interpolated from a 3 x 3 grid of values uniform in [-a, a]
(per channel, so both the brightness and the colour vary over the image). Applied after the
photometric jitter below, to the image only.
Photometric: brightness, contrast and per-channel gain drawn in 1 ± ``color_aug`` (gain ±1/3 of it)
and a gamma in [1/(1+c), 1+c] (dusk and over-exposed frames differ by more than a linear map).

A training run's data (its stores, samples, working size, window and epochs): :mod:`vctrain.training.trainset`.

Random crops (``crop`` (cw, ch), training only): each item is a random window of the
(augmented) working-size image, drawn uniformly over the positions that keep it inside; the
affine map above and the crop are one warp, so a crop costs no more than the augmentation alone.
A model trains on windows of a finer store at the pixel cost of the window and predicts on the
whole working size (the networks are fully convolutional).

Ray-angle channels (``ray_channels``, CAM-Convs; issue 53's camera-aware resize candidate): two more
inputs, each pixel's signed angles (radians) beside and below the road VP, ``atan((x - x_vp) / f_x)``
and ``atan((y - y_vp) / f_y)`` with the camera's focal lengths in working pixels (the source camera's,
scaled with the image, and with the random scale above: a zoom changes the focal length), so the
network knows what each pixel looks at whatever the camera's field of view.

VP proximity map (VPSeg): ``1 - max(|x - x_vp| / w, |y - y_vp| / h)`` over working-size pixel
centres, with the VP in working coordinates (flipped with the image); (w, h) is always the working
size, so a crop sees exactly its window of the whole image's map.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import cv2
import numpy as np
import torch

from vcprep.camera import scale_matrix
from vcprep.errors import InputError
from vcprep.warp import apply_homography
from vcprep.io import read_image
from vcprep.labels import IGNORE, decode_label, get_label_format
from vcprep.store import Store

from .outputs import ONE_OUTPUT, encode

__all__ = ["Sample", "store_samples", "resize_samples", "source_focal", "RoadDataset", "to_input", "vp_proximity",
           "vp_in_store", "ray_angles", "resize_pair", "class_frequencies", "median_frequency_weights"]


@dataclass(frozen=True)
class Sample:
    """One training item: where its image and label are and how to decode them.

    ``label_format`` None: the label is a store label (0/1/255 already). ``vp`` is the road VP in
    the coordinates of ``image`` (None: unknown, only needed for the VP and ray channels); ``focal``
    the camera's focal lengths in its pixels (ray channels). ``source`` is the
    store (or image folder) it comes from: the group ``balance: datasets`` draws equally often.
    ``warped_from``: a store label's, the label format its source label was read with when it was warped
    (the record's ``label_format``; what a label check names).
    """

    id: str
    image: Path
    label: Path | None
    label_format: str | None = None
    vp: tuple[float, float] | None = None
    source: str = ""
    focal: tuple[float, float] | None = None  # (f_x, f_y) in the pixels of ``image`` (ray channels)
    warped_from: str | None = None  # a store label: the format its source label was read with

    @property
    def definition(self) -> str:
        """What the label's road means (:data:`vcprep.labels.DEFINITIONS`): its format's ``definition``
        (a store label's: the format it was warped from); 'road' where no format is known (an older store)."""
        spec = self.label_format or self.warped_from
        return get_label_format(spec).definition if spec else "road"


def vp_in_store(record: dict[str, Any], store: Store | None = None) -> tuple[float, float]:
    """The road VP of a store item in store pixels: the record's own ``vp_store`` if present, else
    its source VP mapped through H (= the virtual principal point after within-camera
    correction), else the virtual principal point."""
    if record.get("vp_store") is not None:
        return float(record["vp_store"][0]), float(record["vp_store"][1])
    if record.get("vp") is not None and record.get("H") is not None:
        H = np.asarray(record["H"], dtype=np.float64).reshape(3, 3)
        p = apply_homography(H, [record["vp"]])[0]
        return float(p[0]), float(p[1])
    if store is None:
        raise InputError("item has no VP and no store to take the virtual principal point from", record.get("id"),
                         "rebuild the store with vcprep")
    vs = store.virtual
    return vs.cx, vs.cy


def store_samples(store: Store) -> list[Sample]:
    """Samples for every labelled item of ``store`` (items without a label are skipped)."""
    vs = store.params.get("virtual_scaled") or {}
    focal = (float(vs["fx"]), float(vs["fy"])) if vs.get("fx") else None
    out = []
    for rec in store:
        if not rec.get("label"):
            continue
        out.append(Sample(rec["id"], store.path(rec["image"]), store.path(rec["label"]), None, vp_in_store(rec, store),
                          str(store.root), focal, rec.get("label_format")))
    return out


def source_focal(rec: dict[str, Any]) -> tuple[float, float] | None:
    """A store record's source camera's focal lengths (f_x, f_y) in the source image's pixels (None:
    the record has no camera parameters)."""
    cp = rec.get("camera_params") or {}
    if not cp.get("fx"):
        return None
    sx = rec["size"][0] / cp["image_size"][0] if cp.get("image_size") and rec.get("size") else 1.0
    sy = rec["size"][1] / cp["image_size"][1] if cp.get("image_size") and rec.get("size") else 1.0
    return float(cp["fx"]) * sx, float(cp["fy"]) * sy


def resize_samples(store: Store) -> list[Sample]:
    """Baseline samples: the ORIGINAL images and labels the store's items were built from."""
    out = []
    for rec in store:
        if not rec.get("label_source"):
            continue
        out.append(Sample(rec["id"], Path(rec["source"]), Path(rec["label_source"]), rec["label_format"],
                          tuple(rec["vp"]) if rec.get("vp") else None, str(store.root), source_focal(rec)))
    return out


def to_input(image: np.ndarray, greyscale: bool = False) -> np.ndarray:
    """Image (h, w[, 3]) uint8/uint16 -> float32 (3, h, w) in [-1, 1]; greyscale is replicated."""
    img = image.astype(np.float32) / (65535.0 if image.dtype == np.uint16 else 255.0)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    elif greyscale:
        g = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
        img = np.repeat(g[..., None], 3, axis=2)
    return np.ascontiguousarray((img * 2.0 - 1.0).transpose(2, 0, 1))


def vp_proximity(size: tuple[int, int], vp: tuple[float, float], norm: tuple[int, int] | None = None) -> np.ndarray:
    """VP proximity map (h, w) float32: ``1 - max(|x - x_vp| / W, |y - y_vp| / H)`` with (W, H) =
    ``norm`` (default: ``size``; a crop passes the whole image's size)."""
    w, h = size
    nw, nh = norm if norm is not None else size
    x = np.abs(np.arange(w, dtype=np.float32) - np.float32(vp[0])) / np.float32(nw)
    y = np.abs(np.arange(h, dtype=np.float32) - np.float32(vp[1])) / np.float32(nh)
    return (1.0 - np.maximum(x[None, :], y[:, None])).astype(np.float32)  # (a NumPy-float VP kept it float64)


def ray_angles(size: tuple[int, int], vp: tuple[float, float], focal: tuple[float, float]) -> np.ndarray:
    """Ray-angle channels (2, h, w) float32 at ``size`` (w, h): each pixel centre's signed angle (radians)
    beside the road VP, ``atan((x - x_vp) / f_x)``, and below it, ``atan((y - y_vp) / f_y)`` (module
    docstring); ``vp`` and ``focal`` in the same pixels."""
    w, h = size
    ax = np.arctan((np.arange(w, dtype=np.float64) - vp[0]) / focal[0]).astype(np.float32)
    ay = np.arctan((np.arange(h, dtype=np.float64) - vp[1]) / focal[1]).astype(np.float32)
    return np.stack([np.broadcast_to(ax[None, :], (h, w)), np.broadcast_to(ay[:, None], (h, w))])


def resize_pair(image: np.ndarray, label: np.ndarray | None, size: tuple[int, int]):
    """Resize an image (bilinear) and its label (nearest) to ``size`` (w, h)."""
    if (image.shape[1], image.shape[0]) != tuple(size):
        image = cv2.resize(image, tuple(size), interpolation=cv2.INTER_LINEAR)
    if label is not None and (label.shape[1], label.shape[0]) != tuple(size):
        label = cv2.resize(label, tuple(size), interpolation=cv2.INTER_NEAREST)
    return image, label


def _load(sample: Sample) -> tuple[np.ndarray, np.ndarray]:
    img = read_image(sample.image).array
    raw = read_image(sample.label, label=True).array
    if sample.label_format is None:
        lab = raw if raw.ndim == 2 else raw[..., 0]
    else:
        lab = decode_label(raw, get_label_format(sample.label_format), sample.label)
    if lab.shape[:2] != img.shape[:2]:
        raise InputError(f"label is {lab.shape[1]}x{lab.shape[0]} but its image is {img.shape[1]}x{img.shape[0]}",
                         sample.label, "labels must have the size of their images")
    return img, lab.astype(np.uint8)


class RoadDataset(torch.utils.data.Dataset):
    """Samples resized to the working size ``size`` (w, h), decoded once and kept in memory;
    with ``crop`` (cw, ch) every item is a random window of that size (module docstring). ``outputs``
    (:mod:`vctrain.training.outputs`): with road and drivable, each item's target is its label's set codes
    (:func:`~vctrain.training.outputs.encode` by its format's definition); road alone: the label itself."""

    def __init__(self, samples: Sequence[Sample], size: tuple[int, int], hflip: bool = False,
                 greyscale: float = 0.0, vp_channel: bool = False, scale_aug: float = 0.0, shift_aug: float = 0.0,
                 color_aug: float = 0.0, crop: tuple[int, int] | None = None, shading_aug: float = 0.0,
                 ray_channels: bool = False, outputs: Sequence[str] = ONE_OUTPUT):
        self.samples = list(samples)
        self.definitions = None if tuple(outputs) == ONE_OUTPUT else [s.definition for s in self.samples]
        self.size = (int(size[0]), int(size[1]))
        self.crop = None
        if crop is not None and (int(crop[0]), int(crop[1])) != self.size:
            if not (0 < crop[0] <= self.size[0] and 0 < crop[1] <= self.size[1]):
                raise ValueError(f"crop {crop[0]}x{crop[1]} does not fit the working size {self.size[0]}x{self.size[1]}")
            self.crop = (int(crop[0]), int(crop[1]))
        self.hflip = bool(hflip)
        self.scale_aug, self.shift_aug, self.color_aug = float(scale_aug or 0), float(shift_aug or 0), float(color_aug or 0)
        self.shading_aug = float(shading_aug or 0)
        self.greyscale = float(greyscale)
        self.vp_channel = vp_channel
        self.ray_channels = bool(ray_channels)
        self._cache: dict[int, tuple[np.ndarray, np.ndarray, tuple[float, float] | None]] = {}
        self._focal: dict[int, tuple[float, float]] = {}  # (ray channels: f_x, f_y in working pixels)

    def __len__(self) -> int:
        return len(self.samples)

    def item(self, i: int) -> tuple[np.ndarray, np.ndarray, tuple[float, float] | None]:
        """(image, label, vp) at the working size, un-augmented."""
        hit = self._cache.get(i)
        if hit is None:
            s = self.samples[i]
            img, lab = _load(s)
            h0, w0 = img.shape[:2]
            img, lab = resize_pair(img, lab, self.size)
            vp = None
            if s.vp is not None:
                S = scale_matrix(self.size[0] / w0, self.size[1] / h0)
                vp = tuple(float(v) for v in (S @ np.array([s.vp[0], s.vp[1], 1.0]))[:2])
            if self.vp_channel and vp is None:
                raise InputError("item has no vanishing point, needed for the VP channel", s.image,
                                 "train without --vp-channel or rebuild the store with VPs")
            if self.ray_channels and (vp is None or s.focal is None):
                raise InputError("item has no vanishing point or camera focal length, needed for the ray channels",
                                 s.image, "train without --ray-channels, or on a store built with 'vcprep warp'")
            if s.focal is not None:
                self._focal[i] = (s.focal[0] * self.size[0] / w0, s.focal[1] * self.size[1] / h0)
            hit = (img, lab, vp)
            self._cache[i] = hit
        return hit

    def _crop_origin(self) -> tuple[int, int]:
        """A random window position (x0, y0) for ``crop``, uniform over those inside the image."""
        (w, h), (cw, ch) = self.size, self.crop
        r = torch.rand(2).tolist()  # torch RNG: seeded per run, epoch and worker
        return min(int(r[0] * (w - cw + 1)), w - cw), min(int(r[1] * (h - ch + 1)), h - ch)

    def focal(self, i: int) -> tuple[float, float]:
        """Item ``i``'s camera focal lengths (f_x, f_y) in working pixels (un-augmented)."""
        self.item(i)
        return self._focal[i]

    def _affine(self, img: np.ndarray, lab: np.ndarray, vp: tuple[float, float] | None,
                origin: tuple[int, int] = (0, 0)):
        """Random scale about the VP (or the centre) plus a random shift, then the window at
        ``origin`` of the crop size (the whole image without a crop); see the module docstring.
        Returns (image, label, vp, scale)."""
        w, h = self.size
        r = torch.rand(3).tolist()  # torch RNG: seeded per run, epoch and worker
        s = math.exp((2 * r[0] - 1) * math.log1p(self.scale_aug))
        ax, ay = vp if vp is not None else ((w - 1) / 2.0, (h - 1) / 2.0)
        dx, dy = (2 * r[1] - 1) * self.shift_aug * w, (2 * r[2] - 1) * self.shift_aug * h
        M = np.array([[s, 0.0, (1 - s) * ax + dx - origin[0]], [0.0, s, (1 - s) * ay + dy - origin[1]]])
        out = self.crop or self.size
        img = cv2.warpAffine(img, M, out, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT_101)
        lab = cv2.warpAffine(lab, M, out, flags=cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT,
                             borderValue=IGNORE)
        if vp is not None:
            vp = (s * vp[0] + M[0, 2], s * vp[1] + M[1, 2])
        return img, lab, vp, s

    def _photometric_draw(self) -> tuple[float, float, np.ndarray, float]:
        """One draw of (brightness, contrast, per-channel gain (3,), gamma); see the module docstring."""
        c = self.color_aug
        r = (2 * torch.rand(6) - 1).tolist()
        gain = np.array([1 + c / 3 * v for v in r[2:5]], dtype=np.float32)
        return 1 + c * r[0], 1 + c * r[1], gain, math.exp(r[5] * math.log1p(c))

    def _photometric(self, x: np.ndarray) -> np.ndarray:
        """Brightness, contrast, per-channel gain and gamma on an input in [-1, 1] (3, h, w)."""
        bright, contrast, gain, gamma = self._photometric_draw()
        img = ((x[:3] + 1) * 0.5) ** gamma
        m = float(img.mean())
        img = ((img - m) * contrast + m) * (bright * gain[:, None, None])
        x = x.copy()
        x[:3] = np.clip(img, 0.0, 1.0) * 2 - 1
        return x

    def _shading(self, x: np.ndarray) -> np.ndarray:
        """One draw of ``shading_aug`` on an input in [-1, 1] (C, h, w): the colour channels times a
        smooth per-channel gain field (module docstring); unchanged in half the draws."""
        r = torch.rand(28).tolist()  # torch RNG: seeded per run, epoch and worker
        if r[0] >= 0.5:
            return x
        h, w = x.shape[1:]
        a = self.shading_aug
        grid = np.array(r[1:], dtype=np.float32).reshape(3, 3, 3) * (2 * a) - a  # (gy, gx, channel)
        gain = np.exp(np.clip(cv2.resize(grid, (w, h), interpolation=cv2.INTER_CUBIC), -a, a))  # (h, w, 3)
        x = x.copy()
        x[:3] = np.clip((x[:3] + 1) * 0.5 * gain.transpose(2, 0, 1), 0.0, 1.0) * 2 - 1
        return x

    def _photometric_u8(self, img: np.ndarray) -> np.ndarray:
        """:meth:`_photometric` of ``to_input(img)`` for an 8-bit BGR ``img`` (h, w, 3), in one
        table lookup: every output value is a function of its channel's input byte, so the whole
        map is a 256 x 3 float table (the contrast's mean from the image's histogram). Same draw,
        same values (float rounding aside), a fraction of the time. Returns (3, h, w) float32."""
        bright, contrast, gain, gamma = self._photometric_draw()
        g = (np.arange(256, dtype=np.float32) / 255.0) ** np.float32(gamma)    # gamma of every byte value
        hist = np.bincount(img.reshape(-1), minlength=256)
        m = float(hist @ g.astype(np.float64)) / img.size                    # mean over pixels and channels
        lut = np.clip(((g[:, None] - m) * contrast + m) * (bright * gain[None, :]), 0.0, 1.0) * 2 - 1
        out = cv2.LUT(img, np.ascontiguousarray(lut.astype(np.float32)[None]))  # (h, w, 3) float32
        return np.ascontiguousarray(out.transpose(2, 0, 1))

    def __getitem__(self, i: int):
        img, lab, vp = self.item(i)
        origin = self._crop_origin() if self.crop else (0, 0)
        zoom = 1.0
        if self.scale_aug > 0 or self.shift_aug > 0:
            img, lab, vp, zoom = self._affine(img, lab, vp, origin)
        elif self.crop:
            (x0, y0), (cw, ch) = origin, self.crop
            img = np.ascontiguousarray(img[y0:y0 + ch, x0:x0 + cw])
            lab = np.ascontiguousarray(lab[y0:y0 + ch, x0:x0 + cw])
            vp = (vp[0] - x0, vp[1] - y0) if vp is not None else None
        out_w = img.shape[1]
        grey = self.greyscale >= 1.0 or (self.greyscale > 0 and float(torch.rand(())) < self.greyscale)
        if self.color_aug > 0 and not grey and img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3:
            x = self._photometric_u8(img)
        else:
            x = to_input(img, greyscale=grey)
            if self.color_aug > 0:
                x = self._photometric(x)
        if self.shading_aug > 0 and not grey:
            x = self._shading(x)
        y = lab
        if self.hflip and float(torch.rand(())) < 0.5:  # torch RNG: seeded per run and per worker
            x = np.ascontiguousarray(x[:, :, ::-1])
            y = np.ascontiguousarray(y[:, ::-1])
            if vp is not None:
                vp = (out_w - 1 - vp[0], vp[1])
        if self.definitions is not None:  # two outputs: the label's set codes (vctrain.training.outputs)
            y = encode(y, self.definitions[i])
        if self.vp_channel:
            x = np.concatenate([x, vp_proximity((out_w, img.shape[0]), vp, norm=self.size)[None]], axis=0)
        if self.ray_channels:  # (after the flip: the VP is flipped, so the angle beside it changes sign)
            f = self.focal(i)
            x = np.concatenate([x, ray_angles((out_w, img.shape[0]), vp, (f[0] * zoom, f[1] * zoom))], axis=0)
        return torch.from_numpy(x), torch.from_numpy(y.astype(np.int64))


def class_frequencies(dataset: RoadDataset, num_classes: int = 2) -> np.ndarray:
    """Median-frequency-balancing frequencies (Eigen & Fergus; SegNet): f_c = pixels of class c /
    pixels of the images in which c is present (ignore pixels excluded)."""
    count = np.zeros(num_classes)
    total = np.zeros(num_classes)
    for i in range(len(dataset)):
        lab = dataset.item(i)[1]
        valid = lab != IGNORE
        n = valid.sum()
        for c in range(num_classes):
            k = np.count_nonzero(lab[valid] == c)
            if k:
                count[c] += k
                total[c] += n
    return np.where(total > 0, count / np.maximum(total, 1), 0.0)


def median_frequency_weights(freq: np.ndarray) -> np.ndarray:
    """w_c = median(f) / f_c (classes never seen get weight 0)."""
    seen = freq > 0
    if not seen.any():
        return np.ones_like(freq)
    med = np.median(freq[seen])
    return np.where(seen, med / np.where(seen, freq, 1.0), 0.0)
