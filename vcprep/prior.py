"""The geometric road prior in the virtual camera (paper §4.5, after GeoSeg).

``p_g(x, y)`` is the mean road label over the labelled items of one or more stores, in store
pixels (the virtual camera at the stores' scale)::

    p_g(x, y) = #items with label 1 at (x, y) / #items with label 0 or 1 at (x, y)

Ignore pixels (255) count in neither the numerator nor the denominator; a pixel that no item
labels gets 0 (and is counted, so that a user knows how much of the image the prior does not
know). All stores must share one virtual camera and scale.

Three layers (style.md): :func:`compute_prior` / :func:`surrogate_labels` / :func:`mean_image`
are in-memory; :func:`write_prior` / :func:`read_prior` are the file formats::

    prior.npy        float32 (h, w) = p_g at the store size
    prior.png        uint8 (h, w) = round(255 * p_g)
    <prior>.json     beside either (``prior.npy.json``): the stores' virtual camera, scale and
                     store size, their completion and VP modes, item and unlabelled-pixel counts,
                     so that ``vctrain predict --prior`` can warp images into the prior's frame
                     and ``vctrain adapt`` can check that a prior fits its model.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from vcprep import __version__
from .errors import InputError
from .figures import to_bgr8
from .io.images import read_image, write_bytes_atomic, write_png
from .labels import IGNORE, ROAD
from .store.layout import Store

__all__ = ["PRIOR_FORMAT", "PRIOR_SUFFIXES", "open_stores", "compute_prior", "prior_counts", "prior_from_counts",
           "check_thresholds", "prior_meta", "surrogate_labels",
           "mean_image", "write_prior", "read_prior", "meta_path", "check_prior_fits"]

PRIOR_FORMAT = "vcseg-prior"
PRIOR_SUFFIXES = (".npy", ".png")
_SAME = ("virtual", "scale", "store_size")  # what one virtual-camera frame is made of


def open_stores(stores: Iterable[Store | str | Path]) -> list[Store]:
    """Open stores (paths or :class:`Store`) and check that they share one virtual camera,
    scale and store size; raises :class:`InputError` naming the odd store."""
    out = [s if isinstance(s, Store) else Store.open(s) for s in stores]
    if not out:
        raise InputError("no stores given", None, "give one or more stores built by 'vcprep warp'")
    first = out[0]
    for s in out[1:]:
        for k in _SAME:
            if s.params.get(k) != first.params.get(k):
                what = {"virtual": "virtual camera", "store_size": "store size"}.get(k, k)
                raise InputError(f"store has another {what} than {first.root} ({_show(s.params, k)} vs "
                                 f"{_show(first.params, k)})", s.root,
                                 "use stores built with the same --virtual and --scale")
    return out


def _show(params: dict[str, Any], key: str) -> str:
    v = params.get(key)
    if key == "virtual" and isinstance(v, dict):
        return f"'{v.get('name')}' fx {v.get('fx')} {v.get('image_size')}"
    if key == "store_size" and v:
        return f"{v[0]}x{v[1]}"
    return str(v)


def _labelled(stores: Sequence[Store]) -> Iterable[tuple[Store, dict[str, Any]]]:
    return ((s, rec) for s in stores for rec in s if rec.get("label"))


def compute_prior(stores: Iterable[Store | str | Path]) -> tuple[np.ndarray, int]:
    """``(p_g, n_unlabelled)``: the prior (float32, (h, w) at the store size, values in [0, 1])
    and the number of pixels no item labels (set to 0). Stores must share one virtual camera
    and scale; items without a label are skipped; no labelled item at all is an error."""
    road, known, _ = prior_counts(stores)
    return prior_from_counts(road, known), int(np.count_nonzero(known == 0))


def prior_from_counts(road: np.ndarray, known: np.ndarray) -> np.ndarray:
    """``road / known`` as float32, 0 where ``known`` is 0."""
    return np.divide(road, known, out=np.zeros(road.shape, np.float64), where=known > 0).astype(np.float32)


def prior_counts(stores: Iterable[Store | str | Path]) -> tuple[np.ndarray, np.ndarray, int]:
    """``(road, known, n_items)``: per store pixel, how many labelled items say road (1) and how
    many say road or not road (not 255); int64 (h, w). The prior is ``road / known``."""
    stores = open_stores(stores)
    w, h = stores[0].store_size
    road = np.zeros((h, w), np.int64)
    known = np.zeros((h, w), np.int64)
    n = 0
    for s, rec in _labelled(stores):
        lab = read_image(s.path(rec["label"]), label=True).array
        if lab.shape != (h, w):
            raise InputError(f"label is {lab.shape[1]}x{lab.shape[0]} but the store is {w}x{h}", s.path(rec["label"]),
                             "rebuild the store ('vcprep store verify' lists damaged items)")
        road += lab == ROAD
        known += lab != IGNORE
        n += 1
    if n == 0:
        raise InputError("stores hold no labelled item", stores[0].root, "build them with --labels and --label-format")
    return road, known, n


def prior_meta(stores: Iterable[Store | str | Path], n_unlabelled: int) -> dict[str, Any]:
    """The description written beside a prior (see the module docstring)."""
    stores = open_stores(stores)
    p = stores[0].params
    recs = [rec for _, rec in _labelled(stores)]
    rules = sorted({json.dumps(r["vp_rule"], sort_keys=True) for r in recs if r.get("vp_rule")})
    return {"format": PRIOR_FORMAT, "version": 1, "tool_version": __version__,
            "store_params": {k: p.get(k) for k in (*_SAME, "virtual_scaled")},
            "completion": sorted({r.get("completion", "none") for r in recs}),
            "vp_status": sorted({r.get("vp_status", "camera") for r in recs}),
            **({"vp_rule": json.loads(rules[0])} if rules else {}),  # (estimated VPs: the rule, as a model keeps it)
            "stores": [str(s.root) for s in stores], "items": len(recs), "unlabelled_pixels": int(n_unlabelled)}


def check_thresholds(lo: float, hi: float) -> None:
    """The surrogate-label thresholds must satisfy 0 <= lo <= hi <= 1."""
    if not (0.0 <= lo <= hi <= 1.0):
        raise InputError(f"thresholds lo {lo:g} and hi {hi:g} are not 0 <= lo <= hi <= 1", None,
                         "use e.g. --lo 0.25 --hi 0.75")


def surrogate_labels(prior: np.ndarray, lo: float = 0.25, hi: float = 0.75) -> np.ndarray:
    """The tri-mask of §4.5: 1 (road) where ``p > hi``, 0 (not road) where ``p < lo``, 255
    (ignore) elsewhere (strict inequalities: a pixel exactly at a threshold is ignored).
    uint8, the shape of ``prior``."""
    check_thresholds(lo, hi)
    p = np.asarray(prior, dtype=np.float32)
    out = np.full(p.shape, IGNORE, np.uint8)
    out[p > hi] = ROAD
    out[p < lo] = 0
    return out


def mean_image(stores: Iterable[Store | str | Path], max_items: int | None = None) -> np.ndarray:
    """Mean of the stores' images (all items, labelled or not), uint8 BGR at the store size."""
    stores = open_stores(stores)
    w, h = stores[0].store_size
    acc = np.zeros((h, w, 3), np.float64)
    n = 0
    for s in stores:
        for rec in s:
            if max_items is not None and n >= max_items:
                break
            acc += to_bgr8(read_image(s.path(rec["image"])).array)
            n += 1
    return np.clip(np.rint(acc / max(n, 1)), 0, 255).astype(np.uint8)


def meta_path(path: str | Path) -> Path:
    """Where a prior's description lives: ``prior.npy`` -> ``prior.npy.json``."""
    path = Path(path)
    return path.with_name(path.name + ".json")


def _suffix(path: Path) -> str:
    suf = path.suffix.lower()
    if suf not in PRIOR_SUFFIXES:
        raise InputError(f"unknown prior file type '{path.suffix}'", path,
                         "name it .npy (float32 p_g) or .png (uint8 round(255 p_g))")
    return suf


def write_prior(path: str | Path, prior: np.ndarray, meta: dict[str, Any] | None = None) -> Path:
    """Write ``prior`` as ``.npy`` (float32) or ``.png`` (uint8 round(255 p)), atomically, and
    ``meta`` beside it (:func:`meta_path`). Returns ``path``."""
    path = Path(path)
    suf = _suffix(path)
    if not path.parent.is_dir():
        raise InputError("output folder does not exist", path.parent, "create it first")
    p = np.asarray(prior, dtype=np.float32)
    if suf == ".npy":
        import io

        buf = io.BytesIO()
        np.save(buf, p, allow_pickle=False)
        write_bytes_atomic(path, buf.getvalue())
    else:
        write_png(path, np.clip(np.rint(p * 255.0), 0, 255).astype(np.uint8), kind="mask")
    if meta is not None:
        write_bytes_atomic(meta_path(path), (json.dumps(meta, indent=2) + "\n").encode())
    return path


def read_prior(path: str | Path, size: tuple[int, int] | None = None) -> tuple[np.ndarray, dict[str, Any] | None]:
    """``(p_g float32 (h, w) in [0, 1], meta or None)`` from a ``.npy`` or ``.png`` prior.
    ``size`` (w, h): the size the caller needs (e.g. a model's store size); another is an error."""
    path = Path(path)
    suf = _suffix(path)
    if not path.is_file():
        raise InputError("prior not found" if not path.exists() else "prior is not a file", path,
                         "write one with 'vcprep prior STORE... -o prior.npy'")
    if suf == ".npy":
        try:
            arr = np.load(path, allow_pickle=False)
        except (ValueError, OSError, EOFError):
            raise InputError("cannot read the prior (corrupt or not a NumPy .npy file)", path,
                             "write it again with 'vcprep prior'") from None
        if arr.ndim != 2 or arr.dtype.kind != "f":
            raise InputError(f"prior is {arr.dtype} of shape {arr.shape}, expected a 2-D float array", path,
                             "write it with 'vcprep prior'")
        p = arr.astype(np.float32)
        if not np.isfinite(p).all() or p.min() < 0 or p.max() > 1:
            raise InputError("prior has values outside [0, 1] (or NaN)", path, "write it with 'vcprep prior'")
    else:
        arr = read_image(path, label=True).array
        if arr.ndim != 2 or arr.dtype != np.uint8:
            raise InputError(f"prior PNG is {arr.dtype} with shape {arr.shape}, expected 8-bit grey", path,
                             "write it with 'vcprep prior'")
        p = arr.astype(np.float32) / 255.0
    if size is not None and (p.shape[1], p.shape[0]) != (int(size[0]), int(size[1])):
        raise InputError(f"prior is {p.shape[1]}x{p.shape[0]} but the model's store is {size[0]}x{size[1]}", path,
                         "compute the prior from stores of the model's virtual camera and scale")
    meta = None
    mp = meta_path(path)
    if mp.is_file():
        try:
            meta = json.loads(mp.read_text())
        except (OSError, ValueError):
            raise InputError("prior description is unreadable or corrupt", mp, "write the prior again") from None
        if not isinstance(meta, dict) or meta.get("format") != PRIOR_FORMAT:
            raise InputError("not a prior description", mp, "write the prior again with 'vcprep prior'")
    return p, meta


def check_prior_fits(path: str | Path, meta: dict[str, Any] | None, store_params: dict[str, Any]) -> None:
    """Refuse a prior whose description says another virtual camera or scale than ``store_params``
    (a prior without a description is checked by size only, in :func:`read_prior`)."""
    if meta is None:
        return
    mine = meta.get("store_params") or {}
    for k in ("virtual", "scale"):
        if mine.get(k) != store_params.get(k):
            what = "virtual camera" if k == "virtual" else k
            raise InputError(f"prior was computed in another {what} than the model's ({_show(mine, k)} vs "
                             f"{_show(store_params, k)})", path,
                             "compute it from stores built with the model's virtual camera and scale")
