"""The store record of one item and its key: what ``manifest.jsonl`` holds per item.

:class:`ItemRecord` is the record (its fields in the order they are written); its
:meth:`ItemRecord.key` is the one up-to-date key: a hash of every input the item's files depend
on (source and label bytes, label format, camera, store parameters, H, VP status, completion).
``vcprep warp`` and ``vcprep complete`` both compute it here, so that they agree: a record
whose key matches (and whose files exist) is not rebuilt.
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from vcprep import __version__
from ..warp.completion import COMPLETION_VERSION
from .layout import VALID_PREFIX

__all__ = ["WARP_ALGORITHM", "ItemRecord", "record_key", "valid_path", "completion_key_part", "completion_fields",
           "source_path", "same_source", "camera_words"]

WARP_ALGORITHM = "warp-v1"  # bump when stored outputs of identical inputs would change
STORE_KEY_PARAMS = ("virtual", "scale", "store_size")  # the store parameters an item key depends on


def _hash(parts: dict[str, Any]) -> str:
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()


def _rounded(H: Any) -> list[float]:
    """H as the key sees it: float64, rounded to 12 decimals (the JSON round trip of a record is exact)."""
    return np.round(np.asarray(H, dtype=np.float64), 12).ravel().tolist()


def source_path(path: str | Path) -> str:
    """How a record names an input file (source image, label, calibration file): its absolute path
    with symlinks and ``..`` resolved. The same file under any spelling is one string, and the
    record means the same from every working directory (the store may be read from anywhere; a
    path relative to the store would break when the store alone is copied elsewhere, e.g. to a
    cluster's scratch space, while the data stay put). Stores of older versions hold the path as
    given, relative to the directory they were built from."""
    return os.path.realpath(path)


def same_source(recorded: str | None, given: str | Path, recorded_sha256: str | None = None,
                given_sha256: str | None = None) -> bool:
    """Whether the file a record names (``recorded``) is the file ``given`` (a path as typed).

    The same path once resolved, or the same file (a hard link, a bind mount). A relative
    ``recorded`` (a store of an older version: relative to the working directory of its build,
    which is unknown) that names no file from here is the same source if the bytes are the same
    (``recorded_sha256`` == ``given_sha256``)."""
    if recorded is None:
        return False
    if source_path(recorded) == source_path(given):
        return True
    try:
        return os.path.samefile(recorded, given)
    except OSError:  # the recorded file is not there (from here)
        pass
    return (not os.path.isabs(recorded) and recorded_sha256 is not None and recorded_sha256 == given_sha256)


def completion_key_part(completion: str) -> str:
    """What an item key records about completion ('none' unchanged; others carry the algorithm)."""
    return completion if completion == "none" else f"{completion}/{COMPLETION_VERSION}"


def completion_fields(maps: Any) -> dict[str, Any]:
    """Record fields that say how an item was completed: the projective ray centre (store
    pixels) and whether it is the item's VP (False: the VP was outside the covered region)."""
    centre = getattr(maps, "centre", None)
    method = getattr(maps, "method", "none")
    return {"completion_centre": [float(centre[0]), float(centre[1])] if centre is not None and method == "projective"
            else None,
            "completion_vp_inside": bool(maps.vp_inside) if method == "projective" else None}


def valid_path(H: Any, src_size: tuple[int, int], store_size: tuple[int, int]) -> str:
    """The store path of the valid mask of one geometry: it depends only on H and the sizes, so
    every item with that geometry (all images of a camera in between-camera mode) shares one
    file, named by a hash of them (``valid/H-<16 hex>.png``)."""
    parts = {"algorithm": WARP_ALGORITHM, "H": _rounded(H),
             "size": [int(src_size[0]), int(src_size[1])], "store_size": [int(store_size[0]), int(store_size[1])]}
    return f"valid/{VALID_PREFIX}{_hash(parts)[:16]}.png"


# written only when set
_OMITTED_WHEN_EMPTY = ("camera_file", "ego_rows", "vp_rule", "completion_unlabelled", "files_sha256")


@dataclass(frozen=True, kw_only=True)
class ItemRecord:
    """One item's store record, fields in the order of ``manifest.jsonl``. Paths are relative to
    the store; sizes are (width, height); ``H`` is ``virt_H_src`` row-major (source pixels of the
    image as stored, ego rows cut off, to store pixels)."""

    id: str
    source: str | None = None                 # the source image (source_path: absolute, resolved)
    source_sha256: str | None = None
    label_source: str | None = None           # the source label (source_path), or None
    label_sha256: str | None = None
    label_format: str | None = None           # the format's name (None without a label)
    camera: str | None = None                 # the camera's name (per-frame: the calibration folder's)
    camera_params: dict[str, Any] | None = None  # the camera at this image's size and pose
    camera_file: str | None = None            # per-frame calibration: this frame's file (source_path)
    size: list[int] | None = None             # source image size (the full frame, ego rows included)
    ego_rows: int = 0                         # bottom rows showing the own vehicle (cut off before warping)
    vp: list[float] | None = None             # road VP [u, v] in source pixels
    vp_status: str | None = None              # 'camera', 'calibrated', 'accepted', 'fallback' or 'given'
    vp_rule: dict[str, Any] | None = None     # estimated VPs: the rule they were found with (VPRule.to_dict)
    pan_deg: float | None = None
    tilt_deg: float | None = None
    H: list[float] | None = None
    image: str | None = None                  # images/<id>.png
    label: str | None = None                  # labels/<id>.png, or None
    valid: str | None = None                  # the shared valid mask (valid_path)
    store_size: list[int] | None = None
    completion: str = "none"
    completion_centre: list[float] | None = None  # see completion_fields
    completion_vp_inside: bool | None = None
    completion_unlabelled: bool = False       # the label did not shape the completion (unlabelled_completion)
    key: str | None = None                    # self.key(params) once built
    tool_version: str = __version__
    files_sha256: dict[str, str] | None = field(default=None)  # SHA-256 of image, label, valid as written

    def key_for(self, params: dict[str, Any], completion: str | None = None) -> str:
        """The item key in a store with ``params`` (:func:`vcprep.store.build.store_params`), for
        ``completion`` (default: this record's)."""
        return _hash({"algorithm": WARP_ALGORITHM, "source_sha256": self.source_sha256,
                      "label_sha256": self.label_sha256, "label_format": self.label_format,
                      "camera": self.camera_params, "store": {k: params[k] for k in STORE_KEY_PARAMS},
                      "H": _rounded(self.H), "vp_status": self.vp_status,
                      **({"vp_rule": self.vp_rule} if self.vp_rule else {}),  # (keys of records without one: as before)
                      **({"completion_unlabelled": True} if self.completion_unlabelled else {}),
                      "completion": completion_key_part(self.completion if completion is None else completion)})

    def keyed(self, params: dict[str, Any]) -> "ItemRecord":
        """This record with its ``key`` set for a store with ``params``."""
        return replace(self, key=self.key_for(params))

    def to_dict(self) -> dict[str, Any]:
        """The record as written (JSON-ready); ``camera_file``, ``ego_rows``, ``vp_rule``,
        ``completion_unlabelled`` and ``files_sha256`` only when set."""
        return {k: v for k, v in asdict(self).items() if v or k not in _OMITTED_WHEN_EMPTY}

    @classmethod
    def from_dict(cls, rec: dict[str, Any]) -> "ItemRecord":
        """A stored record (fields this type does not know are left out)."""
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in rec.items() if k in names})


def record_key(rec: dict[str, Any], params: dict[str, Any], completion: str) -> str:
    """The item key of a stored record for another ``completion`` (``vcprep complete``)."""
    return ItemRecord.from_dict(rec).key_for(params, completion)


def camera_words(rec: dict[str, Any]) -> str:
    """The camera of a store record in words that tell two cameras apart even where both are named
    after their file (``camera.yaml`` -> 'camera'): its name, focal length, height, tilt and pan (a crop
    keeps them; the image size is left out); a frame of per-frame calibration by its folder's name."""
    cp = rec.get("camera_params")
    if not cp or rec.get("camera_file"):
        return f"'{rec.get('camera')}' (per-frame calibration)"
    return (f"'{cp.get('name', rec.get('camera'))}' (fx {cp['fx']:.1f} px, height {cp['height']:g} m, "
            f"tilt {cp.get('tilt', 0):g} deg, pan {cp.get('pan', 0):g} deg)")
