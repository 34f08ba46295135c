"""The detector's road VPs kept on disk, one JSON line a frame, so that a run stopped part way
(Ctrl-C in ``vcprep warp``) does not estimate them again: :class:`VPCache`.

A line holds the detector's own result for one frame (before the reliability rule, smoothing and
fallbacks, which a rerun applies again over all the frames) under a key that changes with anything
that changes the result: the image file's bytes, the camera at the image's size and the detector's
settings. Floats are kept at full precision (JSON's shortest repr), so a result read back equals
the one computed and a resumed warp writes the store an uninterrupted one writes. Lines are
appended and flushed one at a time; a torn last line (a killed process) is skipped when read
and the next line starts after it.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import asdict
from pathlib import Path

from ..camera.pinhole import Camera
from .estimate import VPConfig, VPResult

__all__ = ["VPCache", "VP_CACHE"]

VP_CACHE = ".vp-cache.jsonl"  # in a store's folder (a hidden name: a store build's own)


class VPCache:
    """Detector results by :meth:`key`, read from ``path`` (if it exists) and appended to it."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._table: dict[str, dict] = {}
        self._torn = False  # the file ends inside a line (a killed writer): the next line starts anew
        if self.path.is_file():
            text = self.path.read_text(errors="replace")
            self._torn = bool(text) and not text.endswith("\n")
            for line in text.splitlines():
                try:
                    row = json.loads(line)
                    self._table[str(row["key"])] = dict(row["result"])
                except (ValueError, KeyError, TypeError):
                    continue  # a torn line

    def __len__(self) -> int:
        return len(self._table)

    @staticmethod
    def key(data: bytes, camera: Camera, cfg: VPConfig) -> str:
        """The key of a frame's result: its file's bytes, its camera (at its size) and the settings."""
        h = hashlib.sha256(hashlib.sha256(data).digest())
        h.update(json.dumps([camera.to_dict(), asdict(cfg)], sort_keys=True, default=str).encode())
        return h.hexdigest()

    def get(self, key: str) -> VPResult | None:
        row = self._table.get(key)
        if row is None:
            return None
        try:
            return VPResult(vp=(float(row["vp"][0]), float(row["vp"][1])), confidence=float(row["confidence"]),
                            n_support=int(row["n_support"]), pan_deg=float(row["pan_deg"]),
                            tilt_deg=float(row["tilt_deg"]), status=str(row["status"]), reason=str(row["reason"]),
                            detected=None if row["detected"] is None else (float(row["detected"][0]),
                                                                           float(row["detected"][1])))
        except (KeyError, TypeError, ValueError, IndexError):
            return None

    def put(self, key: str, result: VPResult) -> None:
        """Keep ``result`` (appended and flushed at once: a stop loses at most this line)."""
        row = {"vp": [float(result.vp[0]), float(result.vp[1])], "confidence": float(result.confidence),
               "n_support": int(result.n_support), "pan_deg": float(result.pan_deg),
               "tilt_deg": float(result.tilt_deg), "status": result.status, "reason": result.reason,
               "detected": None if result.detected is None else [float(result.detected[0]), float(result.detected[1])]}
        self._table[key] = row
        with open(self.path, "a") as f:
            f.write(("\n" if self._torn else "") + json.dumps({"key": key, "result": row}) + "\n")
        self._torn = False
