"""Scores cached beside what they were made for: a cached score is read back only when the model's bytes and
the test frames are the ones it was made with (its ``<name>.key`` file). A folder reused with another model
under the same path (a retrained or newly shipped ``road.pt``) or with other test frames is scored again.

One source for every benchmark that caches a model's scores across runs: ``finetune_guard`` (zero-shot and
fine-tuned cells), ``ship_mix`` and ``ship_geometry`` (the baselines scored on the study's test stores).
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Callable

from vcprep.store.layout import MANIFEST


def digest(path: Path) -> str:
    """The first 16 hex digits of ``path``'s SHA-256 (streamed: a checkpoint is read in 1 MiB pieces)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()[:16]


def model_key(model: Path, **test) -> dict:
    """The key of a score of ``model`` on the test frames that ``test`` names (JSON-able values)."""
    return {"model_sha256": digest(model), **test}


def store_key(model: Path, store: Path) -> dict:
    """The key of a score of ``model`` on the virtual-camera store ``store``: its manifest's bytes name the
    items (a store rebuilt on other frames has another manifest)."""
    return model_key(model, store_manifest=digest(store / MANIFEST))


def cached(path: Path, key: dict) -> dict | None:
    """``path``'s scores if they were made for ``key`` (its ``<path>.key`` file), else None. A score with no
    key file (an earlier run's, whose model is unknown) is not trusted."""
    k = path.with_suffix(".key")
    if path.is_file() and k.is_file() and json.loads(k.read_text()) == key:
        return json.loads(path.read_text())
    return None


def store(path: Path, key: dict, res: dict) -> dict:
    """``res`` into ``path`` with the ``key`` it was made for; the key is written last, so a run cut off
    between the two leaves a score that is not read back."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.with_suffix(".key").unlink(missing_ok=True)
    path.write_text(json.dumps(res))
    path.with_suffix(".key").write_text(json.dumps(key))
    return res


def scored(path: Path, key: dict, score: Callable[[], dict]) -> dict:
    """The cached score at ``path`` for ``key``, else ``score()``, stored there with its key."""
    hit = cached(path, key)
    return hit if hit is not None else store(path, key, score())


def scored_on_store(cache: Path, model: Path, store_dir: Path, score: Callable[[], dict]) -> dict | None:
    """``model``'s score on the store ``store_dir``, cached at ``cache`` (:func:`scored` with
    :func:`store_key`). Where the store is gone (a workdir cleaned of its stores), the score cached for these
    model bytes, else None."""
    if store_dir.is_dir():
        return scored(cache, store_key(model, store_dir), score)
    k = cache.with_suffix(".key")
    if cache.is_file() and k.is_file() and json.loads(k.read_text()).get("model_sha256") == digest(model):
        return json.loads(cache.read_text())
    return None
