"""The on-disk virtual-camera image store (format v1).

Layout::

    STORE/store.json       store parameters: format, version, virtual camera, scale, store_size
    STORE/manifest.jsonl   one JSON item record per line, sorted by id
    STORE/images/ID.png    warped image (source depth/channels kept)
    STORE/labels/ID.png    warped label: 0 not road, 1 road, 255 ignore (absent without labels)
    STORE/valid/H-HASH.png 1 where a source pixel landed, 0 elsewhere: one file per geometry (H and
                           sizes), shared by the items that have it (all of a camera's images in
                           between-camera mode); older stores' records name valid/ID.png
    STORE/content.stamp    the SHA-256 of the store's content (:func:`content_digest`), rewritten
                           exactly when that changes: the file a Makefile keys on

Item record (``vcprep store show --json``)::

    id, source (absolute, resolved: :func:`vcprep.store.record.source_path`; relative to the build's
    working directory in stores of older versions), source_sha256, label_source, label_sha256, label_format,
    camera (name), camera_params ({name, image_size, fx, fy, cx, cy, height, tilt, pan} of the
    camera at this image's size), size [w, h] of the source,
    vp [u, v] (source pixels), vp_status ('camera' = the camera's average pose; later 'accepted',
    'fallback', 'given'), pan_deg, tilt_deg (the pose used for H),
    H (9 floats, row-major, source pixel -> store pixel, pixel centres at integers),
    image, label, valid (paths relative to the store; label null without labels; valid shared),
    store_size [w, h], completion ('none' for v1), key (hash of everything the outputs depend on),
    tool_version.

    files_sha256 {image, label, valid}: SHA-256 of the stored PNG bytes (what ``store verify``
    checks the files against; absent in stores built before it existed).

Every file is written atomically (temp + rename). Records reach disk in two steps:

* while a build runs, each finished item's record is *appended* to the writer's part file
  (``manifest.journal.jsonl``, or ``manifest.shard-K-of-N.jsonl`` for ``--shard K/N``) right
  after its PNGs were renamed into place, so a killed build loses at most the items in flight
  (their files are orphans until the next unsharded build or ``store merge`` removes them);
* at the end (or on Ctrl-C) an unsharded build folds everything into ``manifest.jsonl``
  (rewritten atomically), deletes the part files, the shared valid masks no record uses any
  more and the orphans of a killed build (:meth:`Store.prune_orphans`); a shard build rewrites
  only its own part file (compacted), so N machines never write the same file (shards may write
  the same shared valid mask: same bytes, atomic rename), and ``vcprep store merge`` prunes.

:meth:`Store.open` reads ``manifest.jsonl`` and then every ``manifest.*.jsonl`` part (later
records of an id win; a torn last line of a part, from a crash, is ignored): a sharded store is
complete and usable before ``vcprep store merge`` folds the parts.

Concurrent writers: every command that writes a store holds its lock file ``STORE/store.lock``
(:func:`store_lock`, an ``flock``, released by the kernel when the process ends, however it ends)
from before it reads the manifest until its records are saved. An unsharded writer (``warp``,
``complete``, ``store merge``, ``store verify --repair``) holds it exclusively; shard builds hold
it shared, so shards run together but never beside an unsharded writer, which would fold and
delete their part files. A second writer waits for the first (saying so on stderr), then reads
the manifest the first one saved: two writers never lose each other's records.

Make-friendly: a command with nothing to do writes nothing (no record saved, no part file, the
lock file's time set back after its holder's note), and ``content.stamp`` is rewritten only when
the digest of the records changes (:meth:`Store.write_stamp`): its time is the time of the last
change of the store's content, whichever writer made it.
"""
from __future__ import annotations

import errno
import hashlib
import json
import os
import sys
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator

from vcprep import __version__
from ..camera.pinhole import Camera
from ..camera.files import camera_from_dict
from ..errors import StoreError
from ..io.images import write_bytes_atomic

__all__ = ["Store", "Shard", "STORE_FORMAT", "STORE_VERSION", "LAYOUT_DIRS", "VALID_PREFIX", "LOCK", "STAMP",
           "temp_files", "store_lock", "content_digest", "prepare_store_dir"]

VALID_PREFIX = "H-"  # shared valid masks: valid/H-<hash of H and sizes>.png
STORE_FORMAT = "vcseg-store"
STORE_VERSION = 1
LAYOUT_DIRS = ("images", "labels", "valid")
MANIFEST = "manifest.jsonl"
JOURNAL = "manifest.journal.jsonl"  # the part file of an unsharded build
LOCK = "store.lock"  # the writers' lock file (see store_lock)
STAMP = "content.stamp"  # the digest of the store's content, rewritten only when it changes (Store.write_stamp)
# record fields that name where an input lives, not what it holds: the same content under another
# path spelling (a store of an older version, its sources re-recorded absolute) has the same digest
_PATH_FIELDS = ("source", "label_source", "camera_file")
LOCK_POLL_S = 0.1


@dataclass(frozen=True)
class Shard:
    """Shard ``k`` of ``n`` (1 <= k <= n): the items whose id hashes to ``k - 1`` modulo ``n``.

    The hash is SHA-256 of the id, so the split is the same on every machine and Python version
    and does not depend on the order or number of the files listed."""

    k: int
    n: int

    @classmethod
    def parse(cls, text: str) -> "Shard":
        """'K/N' (e.g. '3/8'; K counts from 1, as in SLURM_ARRAY_TASK_ID=1..N)."""
        try:
            k, n = (int(x) for x in str(text).split("/"))
        except ValueError:
            raise StoreError(f"--shard '{text}' is not K/N", None, "give e.g. --shard 1/4 (K from 1 to N)") from None
        if not (n >= 1 and 1 <= k <= n):
            raise StoreError(f"--shard {text}: K must be between 1 and N", None, "give e.g. --shard 1/4 (K from 1 to N)")
        return cls(k, n)

    def contains(self, item_id: str) -> bool:
        h = int.from_bytes(hashlib.sha256(item_id.encode()).digest()[:8], "big")
        return h % self.n == self.k - 1

    @property
    def part_name(self) -> str:
        return f"manifest.shard-{self.k}-of-{self.n}.jsonl"

    def __str__(self) -> str:
        return f"{self.k}/{self.n}"


def temp_files(root: Path) -> list[Path]:
    """Temp files an interrupted atomic write left in a store (``.NAME.XXXX.tmp``)."""
    out: list[Path] = []
    for d in (root, *(root / sub for sub in LAYOUT_DIRS)):
        if d.is_dir():
            out += sorted(p for p in d.iterdir() if p.name.startswith(".") and p.name.endswith(".tmp"))
    return out


def _our_name(p: Path) -> bool:
    """A name a store (or a build creating one) may hold."""
    return (p.name.startswith(".") or p.name in LAYOUT_DIRS or p.name.startswith("manifest.")
            or p.name in (LOCK, STAMP))


def prepare_store_dir(root: Path) -> None:
    """Make ``root`` ready to hold the lock file: an existing store, an empty directory (created
    if missing), or a directory only a store build has written to; anything else is refused
    before a lock file is put into it."""
    if root.exists() and not root.is_dir():
        raise StoreError("exists and is not a directory", root, "choose another --out")
    if root.is_dir():
        if (root / "store.json").exists() or all(_our_name(p) for p in root.iterdir()):
            return
        raise StoreError("directory exists, is not empty and is not a vcprep store", root,
                         "choose a new or empty --out directory")
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise StoreError(f"cannot create store: {e.strerror or e}", root, "check permissions or choose another --out") from None


def _holder(fd: int) -> str:
    try:
        text = os.pread(fd, 512, 0).decode(errors="replace").strip()
    except OSError:
        text = ""
    return text or "another vcprep writer"


@contextmanager
def store_lock(root: str | Path, shared: bool = False, on_wait: Callable[[str], None] | None = None) -> Iterator[Path]:
    """Hold the writers' lock of the store ``root`` (created as an empty directory if missing).

    ``shared``: for shard builds (any number at once); otherwise exclusive. If another writer
    holds it, wait for it, telling ``on_wait`` once who holds it (an exclusive holder writes its
    pid and command into the lock file, and empties it again on release). The lock is an
    ``flock`` on ``STORE/store.lock``: the kernel releases it when its process ends, so a
    killed writer never leaves a stale lock. On a file system without ``flock`` support the
    writers are not serialised (``on_wait`` is told)."""
    root = Path(root)
    prepare_store_dir(root)
    path = root / LOCK
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock
        yield path
        return
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError as e:
        raise StoreError(f"cannot open the store lock: {e.strerror or e}", path,
                         "check the store directory's permissions") from None
    try:
        mode = fcntl.LOCK_SH if shared else fcntl.LOCK_EX
        t0, told, locked = time.monotonic(), False, True
        while True:
            try:
                fcntl.flock(fd, mode | fcntl.LOCK_NB)
                break
            except OSError as e:
                if e.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    locked = False  # e.g. ENOLCK on a file system without flock
                    if on_wait:
                        on_wait(f"{path}: cannot lock ({e.strerror}); concurrent writers to this store are not "
                                "serialised on this file system")
                    break
            if not told and on_wait:
                on_wait(f"{root}: waiting for the store lock {path}, held by {_holder(fd)} ...")
                told = True
            time.sleep(LOCK_POLL_S)
        if told and on_wait:
            on_wait(f"{root}: got the store lock after {time.monotonic() - t0:.1f} s")
        note = locked and not shared
        if note:
            before = os.fstat(fd)  # the holder's note is no change of the store: its time is set back on release
            cmd = " ".join(Path(a).name if i == 0 else a for i, a in enumerate(sys.argv))
            info = f"pid {os.getpid()} ({cmd})"[:500].encode()
            os.ftruncate(fd, 0)
            os.pwrite(fd, info, 0)
        try:
            yield path
        finally:
            if note:
                try:
                    os.ftruncate(fd, 0)
                    os.utime(fd, ns=(before.st_atime_ns, before.st_mtime_ns))
                except (OSError, NotImplementedError):
                    pass
    finally:
        os.close(fd)  # releases the flock


def _read_records(path: Path, items: dict[str, dict[str, Any]], torn_ok: bool) -> dict[str, dict[str, Any]]:
    """Add the records of one manifest file to ``items`` (later lines win); returns them too."""
    mine: dict[str, dict[str, Any]] = {}
    try:
        text = path.read_text()
    except FileNotFoundError:  # a part folded by a concurrent merge
        return mine
    lines = text.split("\n")
    for n, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
            rid = rec["id"]
        except (ValueError, KeyError, TypeError):
            if torn_ok and n == len(lines):  # the last line, without its newline: a torn append
                continue
            raise StoreError(f"manifest line {n} is corrupt", path, "rebuild the store") from None
        mine[rid] = rec
    items.update(mine)
    return mine


def content_digest(items: dict[str, dict[str, Any]]) -> str:
    """SHA-256 (hex) of a store's content: every record (what its files hold, how they were made,
    their SHA-256) sorted by id, without the fields that only say where an input lives
    (:data:`_PATH_FIELDS`). Equal for equal content, whatever wrote it (shards or one build)."""
    h = hashlib.sha256()
    for k in sorted(items):
        rec = {f: v for f, v in items[k].items() if f not in _PATH_FIELDS}
        h.update(json.dumps(rec, sort_keys=True, separators=(",", ":")).encode() + b"\n")
    return h.hexdigest()


class Store:
    """A store directory: parameters plus item records; files are addressed relative to ``root``."""

    def __init__(self, root: Path, params: dict[str, Any], items: dict[str, dict[str, Any]],
                 parts: list[Path] | None = None, shard: Shard | None = None):
        self.root = Path(root)
        self.params = params
        self.items = items
        self.parts = list(parts or [])  # part files read at open (folded by an unsharded save)
        self.shard = shard  # this writer's shard (None: unsharded)
        self._part_items: dict[str, dict[str, Any]] = {}  # records in this writer's own part file
        self._journal = None

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
    def open(cls, root: str | Path, shard: Shard | None = None) -> "Store":
        """Open a store: parameters plus the union of its manifest and part files. ``shard``:
        this process will write as that shard (see the module docstring)."""
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
        _read_records(root / MANIFEST, items, torn_ok=False)
        parts = sorted(p for p in root.glob("manifest.*.jsonl") if p.name != MANIFEST)
        store = cls(root, params, items, parts=parts)
        for part in parts:
            _read_records(part, items, torn_ok=True)
        return store._attach(shard)

    @classmethod
    def open_or_create(cls, root: str | Path, params: dict[str, Any], shard: Shard | None = None) -> "Store":
        """Open ``root`` if it is a store with the same parameters, create it if it does not
        exist (or is an empty directory); refuse a store built with other parameters.

        ``shard``: this process writes only its shard's part file (see the module docstring).
        Shards may create the same store at the same moment: they write identical store.json."""
        return cls._open_or_create(Path(root), params)._attach(shard)

    def _attach(self, shard: Shard | None) -> "Store":
        """Make this process the writer of ``shard`` (None: unsharded)."""
        self.shard = shard
        own = self.root / shard.part_name if shard else None
        self._part_items = _read_records(own, {}, torn_ok=True) if own is not None and own.exists() else {}
        return self

    @classmethod
    def _open_or_create(cls, root: Path, params: dict[str, Any]) -> "Store":
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
        if root.is_dir() and any(not _our_name(p) for p in root.iterdir()):  # (a shard may be creating it too)
            raise StoreError("directory exists, is not empty and is not a vcprep store", root,
                             "choose a new or empty --out directory")
        try:
            for sub in LAYOUT_DIRS:
                (root / sub).mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise StoreError(f"cannot create store: {e.strerror or e}", root, "check permissions or choose another --out") from None
        full = dict(format=STORE_FORMAT, version=STORE_VERSION, created_by=f"vcprep {__version__}", **params)
        store = cls(root, full, {})
        store._write_params()
        if not (root / MANIFEST).exists():
            store._write_manifest()
        return store

    def _write_params(self) -> None:
        try:
            write_bytes_atomic(self.root / "store.json", (json.dumps(self.params, indent=2) + "\n").encode())
        except OSError as e:
            raise StoreError(f"cannot write: {e.strerror or e}", self.root / "store.json",
                             "check permissions or choose another --out") from None

    # -- items ---------------------------------------------------------------------------------
    def record(self, rec: dict[str, Any]) -> None:
        """Add or replace one item record, durably: one appended line in this writer's part file
        (call it after the item's files are in place)."""
        self.items[rec["id"]] = rec
        self._part_items[rec["id"]] = rec
        path = self.root / (self.shard.part_name if self.shard else JOURNAL)
        line = (json.dumps(rec, separators=(",", ":")) + "\n").encode()
        try:
            if self._journal is None:
                self._journal = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
            os.write(self._journal, line)  # one write per record: a crash tears at most the last line
        except OSError as e:
            raise StoreError(f"cannot write: {e.strerror or e}", path, "check permissions and free disk space") from None

    def save(self) -> None:
        """Make the records compact and permanent. Unsharded: rewrite ``manifest.jsonl`` with
        every record (sorted by id, atomically), then delete the part files it now contains.
        Shard: rewrite only this shard's part file, compacted. Then :meth:`write_stamp`."""
        self._close_journal()
        if self.shard is not None:
            self._write_lines(self.root / self.shard.part_name, self._part_items)
            self.write_stamp()
            return
        self._write_manifest()
        self.write_stamp()
        for part in {*self.parts, self.root / JOURNAL}:
            try:
                part.unlink()
            except FileNotFoundError:
                pass
        self.parts = []
        self._part_items = {}

    def write_stamp(self) -> bool:
        """Rewrite ``content.stamp`` with :func:`content_digest` of the records if it differs (or
        the stamp is missing: a store of an older version); returns whether it was written. A
        shard writer digests what it sees (the manifest, the parts read at open, its own records);
        ``store merge`` then digests the whole."""
        path = self.root / STAMP
        text = content_digest(self.items) + "\n"
        try:
            if path.read_text() == text:
                return False
        except (OSError, UnicodeDecodeError):
            pass
        try:
            write_bytes_atomic(path, text.encode())
        except OSError as e:
            raise StoreError(f"cannot write: {e.strerror or e}", path, "check permissions and free disk space") from None
        return True

    def _write_manifest(self) -> None:
        self._write_lines(self.root / MANIFEST, self.items)

    @staticmethod
    def _write_lines(path: Path, items: dict[str, dict[str, Any]]) -> None:
        lines = [json.dumps(items[k], separators=(",", ":")) for k in sorted(items)]
        data = ("\n".join(lines) + "\n").encode() if lines else b""
        try:
            write_bytes_atomic(path, data)
        except OSError as e:
            raise StoreError(f"cannot write: {e.strerror or e}", path, "check permissions and free disk space") from None

    def _close_journal(self) -> None:
        if self._journal is not None:
            os.close(self._journal)
            self._journal = None

    @property
    def pending_parts(self) -> list[Path]:
        """Part files not yet folded into manifest.jsonl (a running, killed or sharded build)."""
        return sorted(p for p in self.root.glob("manifest.*.jsonl") if p.name != MANIFEST)

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

    def prune_valid(self) -> int:
        """Delete the valid masks no record uses: shared ones (``valid/H-*.png``) left by items
        rebuilt with another geometry or in flight when a build was killed, and the per-item
        ``valid/ID.png`` of older stores once their items were rebuilt. Only when no build writes
        the store. Returns how many were deleted."""
        d = self.root / "valid"
        if not d.is_dir():
            return 0
        used = {r.get("valid") for r in self.items.values()}
        n = 0
        for p in d.iterdir():
            if not p.name.startswith(".") and p.suffix == ".png" and f"valid/{p.name}" not in used:
                p.unlink(missing_ok=True)
                n += 1
        return n

    def prune_orphans(self) -> int:
        """Delete the PNGs in ``images/``, ``labels/`` and ``valid/`` that no record names: the files
        of items in flight when a build was killed (an item the build redoes is written again;
        one whose source is gone meanwhile would stay), and the valid masks :meth:`prune_valid`
        deletes. Only when no build writes the store. Returns how many were deleted."""
        used = {r.get(k) for r in self.items.values() for k in ("image", "label")}
        n = self.prune_valid()
        for sub in ("images", "labels"):
            d = self.root / sub
            for p in sorted(d.iterdir()) if d.is_dir() else []:
                if not p.name.startswith(".") and p.suffix == ".png" and f"{sub}/{p.name}" not in used:
                    p.unlink(missing_ok=True)
                    n += 1
        return n

    def is_complete(self, rec: dict[str, Any]) -> bool:
        """All files of ``rec`` exist."""
        return all(self.path(rec[k]).is_file() for k in ("image", "label", "valid") if rec.get(k))
