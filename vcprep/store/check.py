"""Checking and describing a store: ``vcprep store verify``, ``store info``, ``store merge``.

Verify checks, for every recorded item: each PNG exists, decodes, has the store size, holds only
the values its kind allows (label 0/1/255, valid 0/1) and has the SHA-256 its record gives
(``files_sha256``); the record's ``store_size`` is the store's; its source image and label still
hash to the recorded ``source_sha256`` / ``label_sha256``. Then, for the store as a whole, that
no PNG in ``images/ labels/ valid/`` is unrecorded (an orphan: e.g. the items in flight when a
build was killed) and no temp file of an interrupted write is left.

Damage is a problem of a record (its file missing or not matching, its source changed or gone):
:attr:`VerifyReport.damaged`. Orphan and temp files are what any interrupted build leaves (the
next unsharded build or ``store merge`` removes them): reported, and a failure only when asked
for (``strict``).
"""
from __future__ import annotations

import hashlib
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import cv2
import numpy as np

from .parallel import ItemError, run_items
from .layout import LAYOUT_DIRS, Store, store_lock, temp_files

__all__ = ["Problem", "VerifyReport", "verify_store", "check_item", "repair_store", "verify_and_repair", "store_info",
           "merge_store"]

# problems of the stored files (a rebuild fixes them) vs of the sources (the user must)
FILE_PROBLEMS = ("missing", "corrupt", "size", "values", "checksum", "record")

_ALLOWED = {"label": {0, 1, 255}, "valid": {0, 1}}


@dataclass(frozen=True)
class Problem:
    """One thing wrong: the item (None for a file no record owns), the file, what is wrong."""

    id: str | None
    path: str
    kind: str  # missing | corrupt | size | values | checksum | record | source missing | source changed | orphan | temp
    detail: str

    def line(self) -> str:
        return f"{self.id or '-'}\t{self.kind}\t{self.path}\t{self.detail}"


@dataclass
class VerifyReport:
    items: int = 0
    files: int = 0
    problems: list[Problem] = field(default_factory=list)

    @property
    def bad_items(self) -> list[str]:
        return sorted({p.id for p in self.problems if p.id is not None})

    @property
    def orphans(self) -> list[Problem]:
        return [p for p in self.problems if p.id is None]

    @property
    def damaged(self) -> bool:
        """A record is damaged (a file missing or not matching, its source changed or gone)."""
        return bool(self.bad_items)

    def failed(self, strict: bool = False) -> bool:
        """Damage; with ``strict`` also orphan or temp files (an interrupted build's leftovers)."""
        return self.damaged or (strict and bool(self.orphans))

    def summary(self) -> str:
        text = (f"{self.items} items, {self.files} files checked: {len(self.bad_items)} bad items, "
                f"{len(self.orphans)} orphan or temp files")
        if self.orphans and not self.damaged:
            text += (" (left by an interrupted build, no damage: the next build or 'vcprep store merge' removes "
                     "them)")
        return text


@dataclass(frozen=True)
class _VerifyContext:
    root: Path
    store_size: tuple[int, int]
    check_sources: bool


def _sha256(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except FileNotFoundError:
        return None


def check_item(ctx: _VerifyContext, rec: dict[str, Any]) -> list[Problem]:
    """Every problem of one recorded item (empty: the item is good)."""
    rid = rec.get("id")
    out: list[Problem] = []
    if list(rec.get("store_size") or []) != list(ctx.store_size):
        out.append(Problem(rid, "manifest", "record", f"store_size {rec.get('store_size')} is not the store's "
                                                       f"{list(ctx.store_size)}"))
    sums = rec.get("files_sha256") or {}
    for kind in ("image", "label", "valid"):
        rel = rec.get(kind)
        if not rel:
            continue
        path = ctx.root / rel
        try:
            data = path.read_bytes()
        except FileNotFoundError:
            out.append(Problem(rid, rel, "missing", "recorded file does not exist"))
            continue
        arr = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED) if data else None
        if arr is None:
            out.append(Problem(rid, rel, "corrupt", "does not decode as PNG"))
            continue
        if (arr.shape[1], arr.shape[0]) != tuple(ctx.store_size):
            out.append(Problem(rid, rel, "size", f"{arr.shape[1]}x{arr.shape[0]}, store is "
                                                 f"{ctx.store_size[0]}x{ctx.store_size[1]}"))
        if kind in _ALLOWED:
            if arr.ndim != 2 or arr.dtype != np.uint8:
                out.append(Problem(rid, rel, "values", f"expected one 8-bit channel, got {arr.dtype} {arr.shape}"))
            else:
                bad = set(np.flatnonzero(np.bincount(arr.ravel(), minlength=256)).tolist()) - _ALLOWED[kind]
                if bad:
                    out.append(Problem(rid, rel, "values", f"values {sorted(bad)[:5]} not allowed in a {kind} "
                                                           f"({sorted(_ALLOWED[kind])})"))
        want = sums.get(kind)
        if want is not None and hashlib.sha256(data).hexdigest() != want:
            out.append(Problem(rid, rel, "checksum", "bytes differ from the recorded files_sha256"))
    if ctx.check_sources:
        for kind, pkey, hkey in (("image", "source", "source_sha256"), ("label", "label_source", "label_sha256")):
            src, want = rec.get(pkey), rec.get(hkey)
            if not src or not want:
                continue
            got = _sha256(Path(src))
            if got is None:
                hint = "" if Path(src).is_absolute() else (
                    " (a relative path, from a store of an older version: it is read from the working directory; "
                    "run from the directory the store was built from, or re-run its vcprep warp once to record "
                    "the sources absolute)")
                out.append(Problem(rid, src, "source missing", f"source {kind} not found{hint}"))
            elif got != want:
                out.append(Problem(rid, src, "source changed", f"source {kind} changed since it was stored"))
    return out


def verify_store(root: str | Path, check_sources: bool = True, workers: int = 1,
                 progress: bool = False) -> VerifyReport:
    """Check a store (see the module docstring); problems sorted by item, orphans last."""
    store = Store.open(root)
    ctx = _VerifyContext(store.root, store.store_size, check_sources)
    recs = list(store)
    report = VerifyReport(items=len(recs))

    def on_result(rec, res) -> None:
        if isinstance(res, ItemError):  # not expected: check_item reports rather than raises
            report.problems.append(Problem(rec["id"], "manifest", "record", str(res.error)))
        else:
            report.problems.extend(res)

    run_items(check_item, ctx, recs, on_result, jobs=workers, progress=progress, desc="verify")
    recorded = {r[k] for r in recs for k in ("image", "label", "valid") if r.get(k)}
    for sub in LAYOUT_DIRS:
        d = store.root / sub
        if not d.is_dir():
            continue
        for p in sorted(d.iterdir()):
            if p.name.startswith("."):
                continue
            report.files += 1
            if f"{sub}/{p.name}" not in recorded:
                report.problems.append(Problem(None, f"{sub}/{p.name}", "orphan",
                                               "no record owns this file (an interrupted build? re-run it)"))
    for p in temp_files(store.root):
        report.problems.append(Problem(None, str(p.relative_to(store.root)), "temp",
                                       "temp file of an interrupted write (re-run the build, or delete it)"))
    report.problems.sort(key=lambda p: (p.id is None, p.id or "", p.path))
    return report


def repair_store(root: str | Path, report: VerifyReport) -> tuple[list[str], int]:
    """Drop the records of items whose stored files are bad (and delete those files), delete
    orphan and temp files, so that re-running the build redoes exactly those items. Items whose
    *sources* changed or are missing are kept (the build redoes a changed source by itself).
    Run it when no build writes the store (:func:`verify_and_repair` makes sure of that).
    Returns (dropped ids, files deleted)."""
    store = Store.open(root)
    drop = sorted({p.id for p in report.problems if p.id is not None and p.kind in FILE_PROBLEMS})
    files = [store.path(p.path) for p in report.problems if p.id is None]
    for rid in drop:
        rec = store.items.pop(rid, None) or {}
        files += [store.path(rec[k]) for k in ("image", "label", "valid") if rec.get(k)]
    kept = {store.path(r[k]) for r in store for k in ("image", "label", "valid") if r.get(k)}
    files = list(dict.fromkeys(f for f in files if f not in kept))  # a shared valid mask other items still use stays
    if drop or store.parts:  # the records first: a crash in between leaves orphans, never a record without files
        store.save()
    removed = 0
    for f in files:
        try:
            f.unlink()
            removed += 1
        except FileNotFoundError:
            pass
    return drop, removed


def _disk(root: Path) -> dict[str, dict[str, int]]:
    out = {}
    for sub in LAYOUT_DIRS:
        files = [p for p in (root / sub).iterdir() if p.is_file()] if (root / sub).is_dir() else []
        out[sub] = {"files": len(files), "bytes": sum(p.stat().st_size for p in files)}
    meta = [p for p in root.iterdir() if p.is_file()]
    out["metadata"] = {"files": len(meta), "bytes": sum(p.stat().st_size for p in meta)}
    return out


def store_info(root: str | Path) -> dict[str, Any]:
    """Counts, parameters and disk use of a store, as one JSON-ready dict."""
    store = Store.open(root)
    recs = list(store)

    def count(key: str) -> dict[str, int]:
        return dict(sorted(Counter(str(r.get(key)) for r in recs).items()))

    disk = _disk(store.root)
    p = store.params
    return {
        "store": str(store.root),
        "format": p.get("format"), "version": p.get("version"), "created_by": p.get("created_by"),
        "virtual": p.get("virtual", {}).get("name"), "scale": store.scale, "store_size": list(store.store_size),
        "virtual_scaled": p.get("virtual_scaled"),
        "items": len(recs),
        "with_labels": sum(1 for r in recs if r.get("label")),
        "cameras": count("camera"), "completion": count("completion"), "vp_status": count("vp_status"),
        "label_format": count("label_format"), "tool_version": count("tool_version"),
        "pending_parts": [q.name for q in store.pending_parts],
        "disk": disk, "disk_bytes": sum(v["bytes"] for v in disk.values()),
    }


def verify_and_repair(root: str | Path, check_sources: bool = True, workers: int = 1, progress: bool = False,
                      on_wait: Callable[[str], None] | None = None) -> tuple[VerifyReport, list[str], int]:
    """:func:`verify_store`, then :func:`repair_store` if there are problems, both under the
    store's exclusive writer lock (waiting for a running build first: files it has in flight
    would otherwise look like orphans and be deleted). Returns (report, dropped ids, files
    deleted)."""
    Store.open(root)  # a clear error for a missing or foreign directory, before any lock file
    with store_lock(root, on_wait=on_wait):
        report = verify_store(root, check_sources, workers, progress)
        dropped, removed = repair_store(root, report) if report.problems else ([], 0)
    return report, dropped, removed


def merge_store(root: str | Path, on_wait: Callable[[str], None] | None = None) -> tuple[Store, int]:
    """Fold every part file (shard manifests, the journal of a killed build) into
    ``manifest.jsonl``, remove leftover temp files, unused shared valid masks and the orphans of
    a killed build (:meth:`vcprep.store.Store.prune_orphans`). Holds the
    store's exclusive writer lock, so it waits for running builds (shards included) to finish.
    Returns the store and the number of part files folded."""
    Store.open(root)
    with store_lock(root, on_wait=on_wait):
        store = Store.open(root)
        n = len(store.parts)
        if n:  # (nothing to fold: nothing is written)
            store.save()
        else:
            store.write_stamp()  # (only if missing or untrue: a store of an older version, or shards' partial views)
        for tmp in temp_files(store.root):
            tmp.unlink(missing_ok=True)
        store.prune_orphans()
    return store, n
