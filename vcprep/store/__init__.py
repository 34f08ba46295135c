"""The on-disk virtual-camera image store: its layout, one record per item, the build loop that
warps (``vcprep warp``) or completes (``vcprep complete``) items, the worker pool, and checks.

Modules: :mod:`.layout` (store.json, manifest, locks, shards), :mod:`.record` (:class:`ItemRecord`
and its up-to-date key), :mod:`.build` (:func:`warp_dataset`: the loop, serial or
:mod:`.parallel`'s pool), :mod:`.complete` (:func:`complete_store`: completion of a built store in
the same loop), :mod:`.check` (verify, info, merge).
"""
from __future__ import annotations

from .build import (WarpSettings, item_geometry, item_magnification, item_maps, record_magnification,
                    say_on_stderr, store_params, warp_arrays, warp_dataset)
from .check import merge_store, store_info, verify_and_repair, verify_store
from .complete import CompleteSettings, complete_store
from .layout import Shard, Store, store_lock
from .parallel import default_jobs

__all__ = ["WarpSettings", "item_geometry", "item_magnification", "record_magnification", "item_maps",
           "say_on_stderr", "store_params", "warp_arrays", "warp_dataset", "merge_store", "store_info",
           "verify_and_repair", "verify_store", "CompleteSettings", "complete_store", "Shard", "Store", "store_lock", "default_jobs"]
