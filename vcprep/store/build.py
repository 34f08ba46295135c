"""Building a store: pair images with labels, warp each item into the virtual camera, record it.

Three layers (style.md): :func:`vcprep.dataset.list_dataset` (files -> jobs), :func:`warp_item`
(one item, in memory), :func:`warp_dataset` (the loop: up-to-date check, atomic writes, manifest,
progress), which takes its settings whole as one :class:`WarpSettings` (cameras, scale, labels,
completion, poses, workers, shard, keep_going, progress). Each item's record is a
:class:`vcprep.store.record.ItemRecord` (its key says when it is up to date).
:func:`build_item` / :func:`vcprep.store.complete.complete_item` are the per-item steps of
``warp`` / ``complete``; both run in the one loop :func:`build_loop` (serial or a process pool,
:mod:`vcprep.store.parallel`).
"""
from __future__ import annotations

import functools
import hashlib
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from ..camera.files import camera_from_dict
from ..camera.pinhole import Camera
from ..camera.sources import FrameCameras, camera_of_image
from ..dataset import Job
from ..progress import rate_text
from ..errors import InputError, StoreError, VCError
from ..warp.homography import (apply_homography, check_not_folded, pose_from_vp, road_magnification, virt_H_src,
                               virtual_at_scale, vp_from_pose)
from ..io.images import image_size_from_header, read_image, write_png
from ..labels import LabelFormat, decode_label
from .parallel import ItemError, run_items
from .record import ItemRecord, camera_words, completion_fields, same_source, source_path, valid_path
from .layout import STAMP, Shard, Store, store_lock, temp_files
from ..warp.completion import border_ignore, check_method, completion_maps
from ..warp.remap import warp_image, warp_label
from ..vp.poses import ItemPose

@dataclass(frozen=True)
class WarpSettings:
    """How a store is built: everything :func:`warp_dataset` needs besides the items and the
    store folder. Built once by the caller (``vcprep warp``, a crossval study, ``vctrain
    predict``) and passed whole; the store's own parameters are ``virtual`` and ``scale``
    (:func:`store_params`), the rest says how its items are made and how the build runs."""

    camera: Camera | FrameCameras        # source camera of every image, or per-frame calibration (a folder)
    virtual: Camera                      # the virtual camera the store is in (full size; no ego_rows)
    scale: float                         # store scale of the full virtual camera (1/8: 688x350 for 'virtual')
    label_format: LabelFormat | None = None  # how the source labels are decoded; None: no labels
    completion: str = "none"             # fills uncovered store pixels: 'projective', 'zero' or 'none'
    poses: Mapping[str, ItemPose] | None = None  # within-camera correction: item id -> its own VP pose;
                                         # items without one (or None) take the camera's average pose
    unlabelled_completion: bool = False  # True: labels never shape the completion (it keeps clear of their border
                                         # ignore otherwise), so each image is what its frame gives without a
                                         # label, as vctrain predict warps it (a study's test stores)
    workers: int = 1                     # worker processes building items (results identical to 1)
    shard: Shard | None = None           # build only this shard's items, into its own part file
    keep_going: bool = False             # skip (and list) bad items instead of stopping at the first
    progress: bool = True                # tqdm bar and lock-wait messages on stderr


@dataclass
class BuildSummary:
    total: int = 0
    built: int = 0
    up_to_date: int = 0
    failed: list[str] = field(default_factory=list)  # ids of items that failed (with keep_going)
    errors: list[str] = field(default_factory=list)  # their error messages, in the same order
    notes: list[str] = field(default_factory=list)  # per-item remarks for the user, each with its verdict
    off_vp: dict[str, int] = field(default_factory=lambda: {"fine": 0, "check": 0})  # see off_vp_note
    seconds: float = 0.0  # wall-clock time of the loop
    held: int = 0  # items the store held before this build (vcprep warp)
    held_cameras: list[str] = field(default_factory=list)  # their cameras, in words (record.camera_words)
    cameras: list[str] = field(default_factory=list)  # the cameras of this build's items, in words

    def line(self, detail: str = "") -> str:
        """The summary: counts, ``detail`` (e.g. " (store 688x350)"), items completed off their VP."""
        text = (f"{self.total} item{'' if self.total == 1 else 's'}: {self.built} built, {self.up_to_date} up to date, "
                f"{len(self.failed)} failed{detail}")
        if self.held:
            text += f"; the store held {self.held} item{'' if self.held == 1 else 's'} before"
        if any(self.off_vp.values()):
            text += (f"; VP outside the covered region: {self.off_vp['fine']} fine as is (completion rays start "
                     f"within {OFF_VP_FINE:.0%} of the width from it), {self.off_vp['check']} to check "
                     f"(warnings below)")
        return text + f"; {rate_text(self.total, self.seconds, 'item')}"

    def count(self, res: "ItemResult") -> None:
        """Count one item's result: built (with its remark) or up to date."""
        if res.status != "built":
            self.up_to_date += 1
            return
        self.built += 1
        if res.note:
            self.notes.append(res.note)
        if res.off_vp:
            self.off_vp[res.off_vp] += 1


# An item whose VP lies outside the covered region is completed from the covered point next to it
# (vcprep.warp.completion). How much that moves the filled-in labels, measured on the synthetic CamVid
# road of tests/test_completion.py at 688x350 (ray centre moved d px across / along the road; the
# completed labels' agreement with the true ones drops by): d = 5 px 0.2-0.6 points, 10 px 0.4-1.4,
# 20 px 0.9-2.9, 50 px 2.9-7.3.
# Up to 1 % of the store width (7 px at 688x350) the item is fine as is; farther, it is worth a look.
OFF_VP_FINE = 0.01


def off_vp_note(item_id: str, maps, vp_store: tuple[float, float], store_dir: Path) -> tuple[str | None, str | None]:
    """(note, verdict) for an item built with ``maps``: (None, None) for a completion from the VP
    itself; (None, 'fine') for one that starts within :data:`OFF_VP_FINE` of the store width
    from it (counted in the summary only); else one line with the verdict and what to do, 'check'."""
    if maps.method != "projective" or maps.vp_inside:
        return None, None
    d = float(np.hypot(maps.centre[0] - vp_store[0], maps.centre[1] - vp_store[1]))
    if d <= OFF_VP_FINE * maps.size[0]:
        return None, "fine"
    return (f"{item_id}: VP outside the covered region; completion rays start {d:.0f} px from it, at "
            f"({maps.centre[0]:.1f}, {maps.centre[1]:.1f}), so the filled-in pixels may bend (the real ones are "
            f"exact). Look: vcprep figure completion {store_dir} {item_id} -o {item_id}.png; if the VP is right the "
            f"item is usable as is, if not give the right one with --within vps.csv"), "check"


def store_params(virtual: Camera, scale: float) -> dict[str, Any]:
    """The parameters that define a store: one virtual camera at one scale."""
    if virtual.ego_rows:
        raise InputError(f"virtual camera '{virtual.name}' has ego_rows {virtual.ego_rows}", None,
                         "ego_rows describes a physical camera that sees its own vehicle; drop it from the virtual "
                         "camera")
    vs = virtual_at_scale(virtual, scale)
    return {"virtual": virtual.to_dict(), "scale": float(scale), "store_size": list(vs.size),
            "virtual_scaled": vs.to_dict()}


def item_geometry(camera: Camera, size: tuple[int, int], virtual_scaled: Camera, file: Path | None = None,
                  pan: float | None = None, tilt: float | None = None) -> tuple[Camera, np.ndarray]:
    """The camera at this image's size and ``virt_H_src`` to the scaled virtual camera, checked
    not to fold the image (its visible part: the ego-vehicle rows are never warped). ``H`` is
    read-only: it is shared by every image with the same camera,
    size and pose (cached; a failure is not, and raises naming ``file``)."""
    try:
        return _geometry(camera, (int(size[0]), int(size[1])), virtual_scaled, pan, tilt)
    except VCError:
        pass
    cam = camera.for_image_size(size, file)
    H = virt_H_src(cam, virtual_scaled, pan, tilt)
    check_not_folded(H, cam.visible_size, str(file) if file else cam.name)
    return cam, H


@functools.lru_cache(maxsize=64)
def _geometry(camera: Camera, size: tuple[int, int], virtual_scaled: Camera, pan: float | None,
              tilt: float | None) -> tuple[Camera, np.ndarray]:
    cam = camera.for_image_size(size)
    H = virt_H_src(cam, virtual_scaled, pan, tilt)
    check_not_folded(H, cam.visible_size, cam.name)
    H.setflags(write=False)
    return cam, H


@functools.lru_cache(maxsize=64)
def item_magnification(camera: Camera, size: tuple[int, int], virtual_scaled: Camera) -> float:
    """Store pixels per source pixel on the road for frames of ``size`` from ``camera`` at its average
    pose (:func:`vcprep.warp.road_magnification` of :func:`item_geometry`'s ``H``; the canvas's extent
    and a frame's own pose change it by a few per cent at most, so one figure stands for the camera)."""
    cam, H = item_geometry(camera, size, virtual_scaled, None, camera.pan, camera.tilt)
    return road_magnification(H, cam.visible_size, vp_from_pose(cam)[1])


def record_magnification(rec: Mapping[str, Any], virtual_scaled: Camera) -> float | None:
    """:func:`item_magnification` of a store record's camera (``camera_params``, at the record's
    ``size``): every item of a camera gets the figure ``vctrain predict`` and an export compute for
    its frames; None for a record without its camera's parameters."""
    if not rec.get("camera_params") or not rec.get("size"):
        return None
    size = (int(rec["size"][0]), int(rec["size"][1]))
    return item_magnification(camera_from_dict(rec["camera_params"]), size, virtual_scaled)


def sha256_file(path: Path, kind: str) -> tuple[str, bytes]:
    try:
        data = path.read_bytes()
    except OSError as e:
        raise InputError(f"cannot read {kind}: {e.strerror or e}", path, "check the file") from None
    return hashlib.sha256(data).hexdigest(), data


def item_maps(H: np.ndarray, src_size: tuple[int, int], store_size: tuple[int, int], completion: str = "none",
              vp_store: tuple[float, float] | None = None, src_ignore: np.ndarray | None = None):
    """The remap maps of one item: warp and completion in one inverse map (:mod:`vcprep.warp.completion`).

    ``src_ignore``: the label's border ignore pixels (source), which completion must not smear."""
    return completion_maps(H, src_size, store_size, completion, vp_store, src_ignore)


@dataclass(frozen=True)
class WarpedItem:
    """One warped (and completed) item in memory; ``maps`` says how (centre, vp_inside, note)."""

    image: np.ndarray
    label: np.ndarray | None
    valid: np.ndarray
    maps: Any


def warp_item_full(job: Job, store_size: tuple[int, int], H: np.ndarray, fmt: LabelFormat | None,
                   completion: str = "none", vp_store: tuple[float, float] | None = None,
                   data: tuple[bytes | None, bytes | None] = (None, None), ego_rows: int = 0,
                   unlabelled: bool = False) -> WarpedItem:
    """Warp + complete one item in memory (one pass per image/label, :mod:`vcprep.warp.completion`).
    ``data``: the image's and label's file bytes if already read (hashing reads them).
    ``unlabelled``: the label does not shape the completion (:attr:`WarpSettings.unlabelled_completion`).
    ``ego_rows``: the bottom rows showing the rig's own vehicle are cut off before anything else
    (an exact bottom crop: ``H`` holds as is for the remaining (w, h - ego_rows) image), so they
    never reach the store; the store pixels they would have covered are uncovered (completed or
    label ignore) like any other."""
    img = read_image(job.image, data=data[0])
    lab = None
    if job.label is not None:
        raw = read_image(job.label, label=True, data=data[1])
        if raw.size != img.size:
            raise InputError(f"label is {raw.size[0]}x{raw.size[1]} but its image is {img.size[0]}x{img.size[1]}",
                             job.label, "labels must have the size of their images")
        lab = decode_label(raw.array, fmt, job.label)
    return warp_arrays(img.array, lab, store_size, H, completion, vp_store, ego_rows, job.image, unlabelled)


def warp_arrays(image: np.ndarray, label: np.ndarray | None, store_size: tuple[int, int], H: np.ndarray,
                completion: str = "none", vp_store: tuple[float, float] | None = None, ego_rows: int = 0,
                file: Path | None = None, unlabelled: bool = False) -> WarpedItem:
    """:func:`warp_item_full` on arrays already in memory (a decoded video frame; ``label``: the
    decoded label or None); ``file`` names the source in errors; ``unlabelled``: the completion
    is the one of the image alone (the label's border ignore does not shape it)."""
    src, lab, w, h = image, label, image.shape[1], image.shape[0] - int(ego_rows)
    if ego_rows:
        if h < 1:
            raise InputError(f"ego_rows {ego_rows} leaves nothing of the {w}x{image.shape[0]} image", file,
                             "ego_rows must be less than the image height")
        src = src[:h]
        lab = lab[:h] if lab is not None else None
    maps = item_maps(H, (w, h), store_size, completion, vp_store, None if unlabelled else border_ignore(lab))
    warped = warp_image(src, maps)
    label = warp_label(lab, maps, border_value=maps.label_border) if lab is not None else None
    return WarpedItem(warped, label, maps.valid, maps)


def warp_item(job: Job, camera: Camera, store_size: tuple[int, int], H: np.ndarray, fmt: LabelFormat | None,
              completion: str = "none", vp_store: tuple[float, float] | None = None):
    """Warp one item in memory: returns (image, label or None, valid). ``camera`` is the camera
    at this image's size (its ``ego_rows`` are cut off)."""
    item = warp_item_full(job, store_size, H, fmt, completion, vp_store, ego_rows=camera.ego_rows)
    return item.image, item.label, item.valid


@dataclass(frozen=True)
class ItemResult:
    """What one item's build returned: 'built' (files written; ``record`` is new) or
    'up_to_date' (``record`` is the stored one, or it with its input paths re-recorded when
    ``rerecorded``: a record of an older version, relative paths); ``note`` is a remark for the
    user or None."""

    id: str
    status: str
    record: dict[str, Any]
    note: str | None = None
    off_vp: str | None = None  # VP outside the covered region: 'fine' or 'check' (off_vp_note)
    rerecorded: bool = False  # up to date, but the record changed: save it (no file is written)


@dataclass(frozen=True)
class _WarpContext:
    """Everything :func:`build_item` needs besides the item (shared by all items; sent once
    to each worker)."""

    root: Path
    camera: Camera | FrameCameras
    virtual_scaled: Camera
    params: dict[str, Any]
    fmt: LabelFormat | None
    completion: str
    unlabelled: bool = False  # WarpSettings.unlabelled_completion
    written: dict[str, str] = field(default_factory=dict, compare=False, repr=False)  # see write_item


@dataclass(frozen=True)
class _WarpTask:
    job: Job
    pose: ItemPose | None
    old: dict[str, Any] | None  # the item's current record, if any


def files_present(root: Path, rec: dict[str, Any]) -> bool:
    return all((root / rec[k]).is_file() for k in ("image", "label", "valid") if rec.get(k))


def write_item(root: Path, rec: ItemRecord, item: WarpedItem, written: dict[str, str]) -> dict[str, str]:
    """Write the item's PNGs (atomically); returns their SHA-256. The valid mask is shared by
    path (:func:`valid_path`): ``written`` (path -> SHA-256, one per build and process) holds the
    ones this process wrote in this build, which are not encoded again. A failed write (a full
    disk) raises :class:`StoreError` naming the file."""
    try:
        sums = {"image": write_png(root / rec.image, item.image, kind="store")}
        if item.label is not None and rec.label:
            sums["label"] = write_png(root / rec.label, item.label, kind="mask")
        sha = written.get(rec.valid)
        if sha is None:
            sha = written[rec.valid] = write_png(root / rec.valid, item.valid, kind="mask")
    except OSError as e:
        raise StoreError(f"cannot write: {e.strerror or e}", e.filename,
                         "free disk space (or check permissions) and run the same command again; finished items "
                         "are kept") from None
    sums["valid"] = sha
    return sums


def _item_pose(cam: Camera, pose: ItemPose | None, per_frame: bool) -> tuple[float, float, tuple[float, float], str]:
    """(pan, tilt, VP in source pixels, vp_status) of one item: its own VP pose (within-camera
    correction), else the camera's (per-frame calibration: that frame's, 'calibrated')."""
    if pose is not None:
        pan, tilt = pose_from_vp(cam, pose.vp)
        return pan, tilt, (float(pose.vp[0]), float(pose.vp[1])), pose.status
    return cam.pan, cam.tilt, vp_from_pose(cam, cam.pan, cam.tilt), "calibrated" if per_frame else "camera"


def build_item(ctx: _WarpContext, task: _WarpTask) -> ItemResult:
    """One item of :func:`warp_dataset`: hash the inputs, compute H and the item key; if the
    stored record has that key and its files, it is up to date; else warp + complete and write
    the PNGs (atomically) and return the new record. Raises :class:`VCError` on bad input."""
    job, old, camera, fmt = task.job, task.old, ctx.camera, ctx.fmt
    store_size = (int(ctx.params["store_size"][0]), int(ctx.params["store_size"][1]))
    src_hash, data = sha256_file(job.image, "image")
    if old is not None and not same_source(old.get("source"), job.image, old.get("source_sha256"), src_hash):
        raise InputError(f"store item '{job.id}' already holds another source ({old.get('source')})", job.image,
                         "use --id-prefix to keep datasets apart, or another --out")
    size = image_size_from_header(data)
    if size is None:
        size = read_image(job.image).size
    per_frame = isinstance(camera, FrameCameras)
    cam = camera_of_image(camera, job.image, size)  # per-frame: this frame's own calibration file
    pan, tilt, vp, vp_status = _item_pose(cam, task.pose, per_frame)
    cam, H = item_geometry(cam, size, ctx.virtual_scaled, job.image, pan, tilt)
    vp_store = tuple(apply_homography(H, [vp])[0])  # = the virtual principal point (H maps VP -> pp)
    lab_hash, lab_data = sha256_file(job.label, "label") if job.label is not None else (None, None)
    rec = ItemRecord(
        id=job.id, source=source_path(job.image), source_sha256=src_hash,
        label_source=source_path(job.label) if job.label else None, label_sha256=lab_hash,
        label_format=fmt.name if fmt and job.label else None, camera=camera.name, camera_params=cam.to_dict(),
        camera_file=source_path(camera.file_for(job.image)) if per_frame else None, size=list(cam.size),
        ego_rows=int(cam.ego_rows or 0), vp=[float(vp[0]), float(vp[1])], vp_status=vp_status,
        vp_rule=dict(task.pose.rule) if task.pose is not None and task.pose.rule else None, pan_deg=pan,
        tilt_deg=tilt, H=H.ravel().tolist(), image=f"images/{job.id}.png",
        label=f"labels/{job.id}.png" if job.label is not None else None,
        valid=valid_path(H, cam.visible_size, store_size), store_size=list(store_size), completion=ctx.completion,
        completion_unlabelled=ctx.unlabelled and job.label is not None,
    ).keyed(ctx.params)
    if old is not None and old.get("key") == rec.key and files_present(ctx.root, old):
        paths = {k: getattr(rec, k) for k in ("source", "label_source", "camera_file") if old.get(k) is not None}
        if all(old[k] == v for k, v in paths.items()):
            return ItemResult(job.id, "up_to_date", old)
        return ItemResult(job.id, "up_to_date", {**old, **paths}, rerecorded=True)  # an older version's relative paths
    item = warp_item_full(job, store_size=store_size, H=H, fmt=fmt, completion=ctx.completion, vp_store=vp_store,
                          data=(data, lab_data), ego_rows=cam.ego_rows, unlabelled=rec.completion_unlabelled)
    rec = replace(rec, **completion_fields(item.maps))
    rec = replace(rec, files_sha256=write_item(ctx.root, rec, item, ctx.written))
    return ItemResult(job.id, "built", rec.to_dict(), *off_vp_note(job.id, item.maps, vp_store, ctx.root))


@dataclass(frozen=True)
class LoopStep:
    """What :func:`build_loop` runs on each task: ``fn(ctx, task)`` -> :class:`ItemResult` (``ctx``
    is sent once to each worker), shown as ``desc`` on the progress bar."""

    fn: Callable[[Any, Any], ItemResult]
    ctx: Any
    desc: str


def build_loop(store: Store, step: LoopStep, tasks: list, ids: list[str], settings: Any) -> BuildSummary:
    """The loop :func:`warp_dataset` and :func:`vcprep.store.complete.complete_store` share: run
    ``step`` over the tasks (item ``ids``; :func:`vcprep.store.parallel.run_items`), record each built
    item as it arrives, count, and fold the records into the manifest at the end (also after an
    error or Ctrl-C). ``settings``: ``workers``, ``progress``, ``keep_going`` as in :class:`WarpSettings`.

    A bad item stops the build (after the items in flight) and its error is raised, unless
    ``settings.keep_going``: then it is counted in ``failed`` / ``errors`` and skipped."""
    summary = BuildSummary(total=len(tasks))
    t0 = time.perf_counter()
    if store.shard is None:
        for tmp in temp_files(store.root):  # left by a killed build (no other writer runs now)
            tmp.unlink(missing_ok=True)
    id_of = dict(zip(map(id, tasks), ids))
    first_error: list[VCError] = []
    rerecorded = 0

    def on_result(task, res) -> bool:
        nonlocal rerecorded
        if isinstance(res, ItemError):
            summary.failed.append(id_of[id(task)])
            summary.errors.append(str(res.error))
            if settings.keep_going:
                return True
            if not first_error:
                first_error.append(res.error)
            return False
        if res.status == "built" or res.rerecorded:
            store.record(res.record)
            rerecorded += res.rerecorded
        summary.count(res)
        return True

    try:
        run_items(step.fn, step.ctx, tasks, on_result, jobs=settings.workers, progress=settings.progress,
                  desc=step.desc)
    finally:
        summary.seconds = time.perf_counter() - t0
        summary.notes.sort()
        if summary.built or rerecorded or (store.shard is None and store.parts):  # (folds a killed build's journal)
            store.save()  # (and rewrites content.stamp if the content changed)
        elif not (store.root / STAMP).exists():  # a store of an older version: its first stamp
            store.write_stamp()
        if store.shard is None:
            store.prune_orphans()
    if first_error:
        raise first_error[0]
    return summary


def warp_dataset(jobs: list[Job], out: str | Path, settings: WarpSettings) -> tuple[Store, BuildSummary]:
    """Warp ``jobs`` from ``settings.camera`` into ``settings.virtual`` at ``settings.scale`` into
    the store ``out``.

    ``settings.camera``: one :class:`Camera` for every image, or :class:`FrameCameras` (per-frame
    calibration: each image its own camera and pose, ``vp_status`` 'calibrated', the file in the
    record's ``camera_file``; an image without a file fails as a bad item).

    ``settings.poses`` maps item ids to a per-image VP pose (within-camera correction); items
    without one use the camera's average pose (``vp_status`` 'camera'). ``settings.completion``
    names the method that fills uncovered store pixels ('none': left 0 / label 255).
    Items whose inputs and parameters are unchanged (same key, files present) are skipped.

    ``settings.workers`` processes build items in parallel (results byte-identical to 1);
    ``settings.shard`` builds only that shard's items and records them in its own part file. On a
    bad input the store keeps every item finished so far and the error propagates; with
    ``settings.keep_going`` bad items are skipped and listed in the summary instead.
    """
    check_method(settings.completion)
    params = store_params(settings.virtual, settings.scale)
    shard = settings.shard
    if shard is not None:
        jobs = [j for j in jobs if shard.contains(j.id)]
    poses = settings.poses or {}
    # the store is read after the lock is held: a writer that finished meanwhile is seen
    with store_lock(out, shared=shard is not None, on_wait=say_on_stderr if settings.progress else None):
        store = Store.open_or_create(out, params, shard=shard)
        ctx = _WarpContext(store.root, settings.camera, store.virtual, store.params, settings.label_format,
                           settings.completion, settings.unlabelled_completion)
        tasks = [_WarpTask(j, poses.get(j.id), store.items.get(j.id)) for j in jobs]
        held = (len(store.items), sorted({camera_words(r) for r in store.items.values()}))
        summary = build_loop(store, LoopStep(build_item, ctx, "warp"), tasks, [j.id for j in jobs], settings)
    summary.held, summary.held_cameras = held
    summary.cameras = sorted({camera_words(store.items[j.id]) for j in jobs if j.id in store.items})
    return store, summary


def say_on_stderr(msg: str) -> None:
    """Chatter of a library step for the person at the terminal (a store lock wait)."""
    print(msg, file=sys.stderr, flush=True)
