"""One way of hashing for everything a study keys its finished work by (:mod:`.keys`, the camera
estimates of :mod:`.resolve`)."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

__all__ = ["settings_sha", "file_sha256"]


def settings_sha(obj: Any) -> str:
    """The key of ``obj`` (JSON-able settings; other values by ``str``): 16 hex digits of the
    SHA-256 of its JSON with sorted keys."""
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:16]


def file_sha256(path: str | Path) -> str:
    """The SHA-256 (hex) of a file's bytes (read in 1 MiB blocks): which model an adapted model was adapted
    from, which model wrote a prediction folder."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
