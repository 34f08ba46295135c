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
    """The SHA-256 (hex) of a file's bytes: which model an adapted model was adapted from."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()
