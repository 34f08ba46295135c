"""The on-disk virtual-camera image store (format v1).

Layout::

    STORE/store.json       store parameters: format, version, virtual camera, scale, store_size
    STORE/manifest.jsonl   one JSON item record per line, sorted by id
    STORE/images/ID.png    warped image (source depth/channels kept)
    STORE/labels/ID.png    warped label: 0 not road, 1 road, 255 ignore (absent without labels)
    STORE/valid/ID.png     1 where a source pixel landed, 0 elsewhere

Item record (``vcprep store show --json``)::

    id, source, source_sha256, label_source, label_sha256, label_format,
    camera (name), camera_params ({name, image_size, fx, fy, cx, cy, height, tilt, pan} of the
    camera at this image's size), size [w, h] of the source,
    vp [u, v] (source pixels), vp_status ('camera' = the camera's average pose; later 'accepted',
    'fallback', 'given'), pan_deg, tilt_deg (the pose used for H),
    H (9 floats, row-major, source pixel -> store pixel, pixel centres at integers),
    image, label, valid (paths relative to the store; label null without labels),
    store_size [w, h], completion ('none' for v1), key (hash of everything the outputs depend on),
    tool_version.

Every file is written atomically (temp + rename); the manifest is rewritten atomically.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Iterator

from . import __version__
from .camera import Camera, camera_from_dict
from .errors import StoreError
from .imageio import write_bytes_atomic

__all__ = ["Store", "STORE_FORMAT", "STORE_VERSION"]

STORE_FORMAT = "vcseg-store"
STORE_VERSION = 1


class Store:
    """A store directory: parameters plus item records; files are addressed relative to ``root``."""

    def __init__(self, root: Path, params: dict[str, Any], items: dict[str, dict[str, Any]]):
        self.root = Path(root)
        self.params = params
        self.items = items

    # -- parameters ---------------------------------------------------------------------------
    @property
    def virtual(self) -> Camera:
        """The virtual camera at the store's scale (the camera of the stored images)."""
        return camera_from_dict(self.params["virtual_scaled"], self.root / "store.json")

    @property
    def scale(self) -> float:
        return float(self.params["scale"])

    @property
    def store_size(self) -> tuple[int, int]:
        w, h = self.params["store_size"]
        return int(w), int(h)

    # -- open / create ------------------------------------------------------------------------
    @classmethod
    def open(cls, root: str | Path) -> "Store":
        root = Path(root)
        meta = root / "store.json"
        if not root.is_dir():
            raise StoreError("no such store directory", root, "build one with 'vcprep warp ... --out STORE'")
        if not meta.is_file():
            raise StoreError("not a vcprep store (no store.json)", root, "build one with 'vcprep warp ... --out STORE'")
        try:
            params = json.loads(meta.read_text())
        except (OSError, ValueError):
            raise StoreError("store.json is unreadable or corrupt", meta, "rebuild the store into a new directory") from None
        if not isinstance(params, dict) or params.get("format") != STORE_FORMAT:
            raise StoreError("store.json is not a vcprep store description", meta, "use a directory built by vcprep warp")
        if params.get("version") != STORE_VERSION:
            raise StoreError(f"store format version {params.get('version')} is not supported (this tool reads "
                             f"{STORE_VERSION})", meta, "rebuild the store with this version of vcprep")
        items: dict[str, dict[str, Any]] = {}
        manifest = root / "manifest.jsonl"
        if manifest.exists():
            for n, line in enumerate(manifest.read_text().splitlines(), 1):
                if not line.strip():
                    continue
                try:
                    rec = json.loads(line)
                    items[rec["id"]] = rec
                except (ValueError, KeyError, TypeError):
                    raise StoreError(f"manifest line {n} is corrupt", manifest, "rebuild the store") from None
        return cls(root, params, items)

    @classmethod
    def open_or_create(cls, root: str | Path, params: dict[str, Any]) -> "Store":
        """Open ``root`` if it is a store with the same parameters, create it if it does not
        exist (or is an empty directory); refuse a store built with other parameters."""
        root = Path(root)
        if root.exists() and not root.is_dir():
            raise StoreError("exists and is not a directory", root, "choose another --out")
        if root.is_dir() and (root / "store.json").exists():
            store = cls.open(root)
            mine = {k: store.params.get(k) for k in ("virtual", "scale", "store_size")}
            theirs = {k: params.get(k) for k in ("virtual", "scale", "store_size")}
            if mine != theirs:
                diff = [k for k in mine if mine[k] != theirs[k]]
                raise StoreError(f"store was built with another {' and '.join(diff)} "
                                 f"(store: {', '.join(f'{k}={mine[k]}' for k in diff if k != 'virtual') or 'other virtual camera'})",
                                 root, "write to a new --out directory; one store holds one virtual camera at one scale")
            return store
        if root.is_dir() and any(p for p in root.iterdir() if not p.name.startswith(".")):
            raise StoreError("directory exists, is not empty and is not a vcprep store", root,
                             "choose a new or empty --out directory")
        try:
            for sub in ("images", "labels", "valid"):
                (root / sub).mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise StoreError(f"cannot create store: {e.strerror or e}", root, "check permissions or choose another --out") from None
        full = dict(format=STORE_FORMAT, version=STORE_VERSION, created_by=f"vcprep {__version__}", **params)
        store = cls(root, full, {})
        store._write_params()
        store.save()
        return store

    def _write_params(self) -> None:
        try:
            write_bytes_atomic(self.root / "store.json", (json.dumps(self.params, indent=2) + "\n").encode())
        except OSError as e:
            raise StoreError(f"cannot write: {e.strerror or e}", self.root / "store.json",
                             "check permissions or choose another --out") from None

    # -- items ---------------------------------------------------------------------------------
    def save(self) -> None:
        """Rewrite the manifest atomically (sorted by id)."""
        lines = [json.dumps(self.items[k], separators=(",", ":")) for k in sorted(self.items)]
        data = ("\n".join(lines) + "\n").encode() if lines else b""
        try:
            write_bytes_atomic(self.root / "manifest.jsonl", data)
        except OSError as e:
            raise StoreError(f"cannot write: {e.strerror or e}", self.root / "manifest.jsonl",
                             "check permissions and free disk space") from None

    def __iter__(self) -> Iterator[dict[str, Any]]:
        return (self.items[k] for k in sorted(self.items))

    def __len__(self) -> int:
        return len(self.items)

    def get(self, item_id: str) -> dict[str, Any]:
        try:
            return self.items[item_id]
        except KeyError:
            raise StoreError(f"no item '{item_id}'", self.root, "list ids with 'vcprep store show STORE'") from None

    def path(self, rel: str) -> Path:
        return self.root / rel

    def is_complete(self, rec: dict[str, Any]) -> bool:
        """All files of ``rec`` exist."""
        return all(self.path(rec[k]).is_file() for k in ("image", "label", "valid") if rec.get(k))
