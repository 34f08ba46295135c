"""Completion of an existing store (``vcprep complete``): fill its uncovered pixels in place.

Each item is rebuilt from its recorded sources, H and VP by the same warp + completion remap
as ``vcprep warp --complete METHOD`` (:func:`vcprep.store.build.warp_item_full`), in the same loop
(:func:`vcprep.store.build.build_loop`), with the same record key (:class:`vcprep.store.record.ItemRecord`):
the files, record fields and key are identical to a store warped with that method.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from .build import (BuildSummary, ItemResult, LoopStep, build_loop, files_present, off_vp_note, say_on_stderr, sha256_file,
    warp_item_full, write_item)
from ..dataset import Job
from ..warp.completion import check_method
from ..errors import InputError
from ..warp.homography import apply_homography
from ..labels import get_label_format
from .record import ItemRecord, completion_fields, valid_path
from .layout import Shard, Store, store_lock

__all__ = ["CompleteSettings", "complete_store", "complete_item"]


@dataclass(frozen=True)
class CompleteSettings:
    """How :func:`complete_store` runs (the build fields as in :class:`vcprep.store.build.WarpSettings`)."""

    method: str = "projective"           # 'projective', 'zero', 'replicate' or 'none' (vcprep.warp.completion)
    workers: int = 1                     # worker processes (results identical to 1)
    shard: Shard | None = None           # complete only this shard's items, into its own part file
    keep_going: bool = False             # skip (and list) bad items instead of stopping at the first
    progress: bool = True                # tqdm bar and lock-wait messages on stderr


def _check_unchanged(path: Path, sha: str | None, kind: str) -> None:
    digest, _ = sha256_file(path, kind)
    if sha is not None and digest != sha:
        raise InputError(f"{kind} changed since the store was built", path,
                         "re-run 'vcprep warp' with the same options to rebuild the store")


@dataclass(frozen=True)
class _CompleteContext:
    root: Path
    params: dict[str, Any]
    method: str
    written: dict[str, str] = field(default_factory=dict, compare=False, repr=False)  # see build.write_item


def complete_item(ctx: _CompleteContext, rec: dict[str, Any]) -> ItemResult:
    """One item of :func:`complete_store`: rebuild it from its recorded sources with ``method``
    unless it is completed that way already."""
    base = ItemRecord.from_dict(rec)
    key = base.key_for(ctx.params, ctx.method)
    if rec.get("completion") == ctx.method and rec.get("key") == key and files_present(ctx.root, rec):
        return ItemResult(rec["id"], "up_to_date", rec)
    src = Path(rec["source"])
    _check_unchanged(src, rec.get("source_sha256"), "image")
    lab = Path(rec["label_source"]) if rec.get("label_source") else None
    if lab is not None:
        _check_unchanged(lab, rec.get("label_sha256"), "label")
    fmt = get_label_format(rec["label_format"]) if rec.get("label_format") else None
    H = np.asarray(rec["H"], dtype=np.float64).reshape(3, 3)
    store_size = (int(ctx.params["store_size"][0]), int(ctx.params["store_size"][1]))
    vp_store = tuple(apply_homography(H, [rec["vp"]])[0])
    ego = int(rec.get("ego_rows", 0))
    item = warp_item_full(Job(rec["id"], src, lab), store_size, H, fmt, ctx.method, vp_store, ego_rows=ego,
                          unlabelled=bool(rec.get("completion_unlabelled")))
    changed = {"completion": ctx.method, **completion_fields(item.maps), "key": key,
               "valid": valid_path(H, (int(rec["size"][0]), int(rec["size"][1]) - ego), store_size)}
    # the record as stored, these fields changed (fields this version does not know kept in place);
    # files_sha256 last, as in a record built by warp
    new = {k: v for k, v in rec.items() if k != "files_sha256"}
    new.update(changed)
    new["files_sha256"] = write_item(ctx.root, replace(base, **changed), item, ctx.written)
    return ItemResult(rec["id"], "built", new, *off_vp_note(rec["id"], item.maps, vp_store, ctx.root))


def complete_store(store_dir: str | Path, settings: CompleteSettings = CompleteSettings()) -> tuple[Store, BuildSummary]:
    """Complete every item of an already-warped store in place with ``settings.method``.

    Each item is rebuilt from its recorded source image and label (their SHA-256 must still
    match), its H and VP, as one warp + completion remap: the files, record fields and key are
    identical to ``vcprep warp --complete METHOD``. Items already completed that way are skipped;
    files and records are written as by :func:`vcprep.store.build.warp_dataset` (``workers``,
    ``shard``, ``keep_going`` likewise).
    """
    check_method(settings.method)
    shard = settings.shard
    Store.open(store_dir)  # a clear error for a missing or foreign directory, before any lock file
    with store_lock(store_dir, shared=shard is not None, on_wait=say_on_stderr if settings.progress else None):
        store = Store.open(store_dir, shard=shard)
        recs = [r for r in store if shard is None or shard.contains(r["id"])]
        ctx = _CompleteContext(store.root, store.params, settings.method)
        summary = build_loop(store, LoopStep(complete_item, ctx, "complete"), recs, [r["id"] for r in recs], settings)
    return store, summary
