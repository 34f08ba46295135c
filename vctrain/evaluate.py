"""Evaluating a folder of predictions against a folder of labels (file layer over metrics.py).

Predictions are ``<stem>_mask.png`` (0 / nonzero = road) and optionally ``<stem>_prob.png``
(0-255), as written by ``vctrain predict``; ``<stem>`` is the image's file stem (a tree whose frames
repeat names: its path, ``drive1/000123``, and the label of that name in the same folders), and its label is
found in the label folder or its subfolders by the label format's naming rule (e.g. KITTI
``um_000000`` -> ``um_road_000000.png``; IDD ``<drive>_<id>`` -> ``<drive>/<id>_label.png``). A stem with only a probability map is thresholded at 128 (P >= 0.5).
KITTI metrics are computed when every evaluated stem has a probability map.

A folder knows which model wrote which masks: ``vctrain predict`` keeps ``predict.json`` in it
(:func:`record_predictions`: the model file, its SHA-256 and the frames its runs wrote; a run of
another model starts the list anew), and eval scores those frames alone, naming any other masks it
leaves out (an earlier run of another model into the same folder).
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any, Callable

import numpy as np
from tqdm import tqdm

from vcprep.bev import to_bev
from vcprep.dataset import find_images
from vcprep.errors import InputError
from vcprep.io import read_image, write_bytes_atomic
from vcprep.labels import LabelFormat, RoadShare, decode_label, label_stem_for

from .metrics import KittiMetrics, RoadMetrics

BevMapsOf = Callable[[str, tuple[int, int]], Any]  # a frame's stem and size (w, h) -> its BEV maps

__all__ = ["BevMapsOf", "RECORD", "record_predictions", "recorded_frames", "prediction_stems", "evaluate_folder"]

RECORD = "predict.json"  # in a prediction folder: which model's runs wrote which frames


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def record_predictions(out: Path, model: Path, masks: list[Path], engine: str = "") -> None:
    """Note in ``out/predict.json`` that ``model`` wrote ``masks`` (``<id>_mask.png`` in ``out``, an id
    with folders for a tree's frames: ``drive1/000123``) through ``engine`` (what ran its network,
    given: ``engine``): a run of the same model (the same file content) adds its frames to the
    record, a run of another model replaces it."""
    stems = [m.relative_to(out).as_posix()[: -len("_mask.png")] for m in masks if m.name.endswith("_mask.png")]
    sha = _sha256(model)
    old = recorded_frames(out)
    if old is not None and old[1] == sha:
        stems = old[2] + [s for s in stems if s not in set(old[2])]
    doc = {"model": str(model), "model_sha256": sha, **({"engine": engine} if engine else {}), "frames": stems}
    write_bytes_atomic(out / RECORD, (json.dumps(doc, indent=1) + "\n").encode())


def recorded_frames(pred_dir: Path) -> tuple[str, str, list[str]] | None:
    """(model, its SHA-256, the frames its runs wrote) from ``pred_dir/predict.json``; None where the
    folder has none (predictions of an older vctrain or of another tool)."""
    path = pred_dir / RECORD
    if not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text())
        return str(doc["model"]), str(doc["model_sha256"]), [str(s) for s in doc["frames"]]
    except (ValueError, KeyError, TypeError):
        raise InputError("not a prediction record of 'vctrain predict'", path,
                         "delete it (eval then scores every mask in the folder)") from None


def prediction_stems(pred_dir: Path) -> dict[str, dict[str, Path]]:
    """stem -> {'mask': path, 'prob': path} (either may be absent)."""
    out: dict[str, dict[str, Path]] = {}
    for f in sorted(pred_dir.glob("*.png")):
        for kind in ("mask", "prob"):
            if f.stem.endswith("_" + kind):
                out.setdefault(f.stem[: -len(kind) - 1], {})[kind] = f
    return out


def _recorded_stems(pred_dir: Path, stems: dict[str, dict[str, Path]],
                    notes: list[str] | None) -> dict[str, dict[str, Path]]:
    """``stems`` less the frames ``predict.json`` does not list (all of them without a record)."""
    record = recorded_frames(pred_dir)
    if record is None:
        return stems
    model, _, frames = record
    kept = {s: f for s, f in stems.items() if s in set(frames)}
    for frame in (f for f in frames if "/" in f):  # a tree's frames, in its folders
        files = {kind: pred_dir / f"{frame}_{kind}.png" for kind in ("mask", "prob")}
        files = {kind: f for kind, f in files.items() if f.is_file()}
        if files:
            kept[frame] = files
    if len(kept) < len(stems) and notes is not None:
        n = len(stems) - len(kept)
        notes.append(f"{pred_dir}: {n} of its {len(stems)} masks were not written by the model of its last "
                     f"predict run ({model}), left out (predict into a fresh --out to keep runs apart)")
    return kept


def _label_files(labels: Path, fmt: LabelFormat) -> dict[str, list[Path]]:
    """label stem -> its files in the tree ``labels`` (IDD: also by item id <drive>_<stem>)."""
    label_files: dict[str, list[Path]] = {}
    for p in find_images(labels, "label"):  # recursively: nested trees (Cityscapes gtFine/<split>/<city>/)
        if p.suffix.lower() == ".png":
            label_files.setdefault(p.stem, []).append(p)
            if fmt.drive_in_id:  # IDD: predictions named by item id <drive>_<stem> (crossval) or by file stem
                label_files.setdefault(f"{p.parent.name}_{p.stem}", []).append(p)
    return label_files


def _label_of(stem: str, files: dict[str, Path], label_files: dict[str, list[Path]], labels: Path,
              fmt: LabelFormat) -> Path:
    """The one label file of the prediction ``stem``."""
    folders, _, base = stem.rpartition("/")  # a tree's frame: its label in the same folders of the label tree
    lstem = label_stem_for(Path(base + ".png"), fmt)
    found = label_files.get(lstem, [])
    if folders and len(found) > 1:
        parts = tuple(folders.split("/"))
        found = [f for f in found if f.parent.relative_to(labels).parts[-len(parts):] == parts]
    if not found:
        raise InputError(f"no label '{lstem}.png' in {labels}", files.get("mask") or files.get("prob"),
                         "check --labels and --label-format")
    if len(found) > 1:
        raise InputError(f"two labels '{lstem}.png' in {labels} ({found[0]}, {found[1]})",
                         files.get("mask") or files.get("prob"), "evaluate one split at a time")
    return found[0]


def _predictions(files: dict[str, Path], label: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """(mask, probability map or None) of one frame, checked against its label's size."""
    prob = None
    if "prob" in files:
        prob = read_image(files["prob"], label=True).array
        if prob.ndim != 2 or prob.dtype != np.uint8:
            raise InputError("probability map is not a single-channel 8-bit PNG", files["prob"],
                             "give the _prob.png written by 'vctrain predict'")
    if "mask" in files:
        mask = read_image(files["mask"], label=True).array
        if mask.ndim != 2:
            raise InputError("mask is not a single-channel PNG", files["mask"], "give 0/255 road masks")
    else:
        mask = prob >= 128
    for what, arr, f in (("mask", mask, files.get("mask")), ("probability map", prob, files.get("prob"))):
        if arr is not None and arr.shape != label.shape:
            raise InputError(f"{what} is {arr.shape[1]}x{arr.shape[0]} but its label is "
                             f"{label.shape[1]}x{label.shape[0]}", f, "predict at the original image size")
    return mask, prob


class _Scores:
    """Road and KITTI metrics accumulated frame by frame (``with_prob``: the KITTI ones too)."""

    def __init__(self, with_prob: bool):
        self.road, self.kitti, self.with_prob = RoadMetrics(), KittiMetrics(), with_prob

    def add(self, mask: np.ndarray, prob: np.ndarray | None, label: np.ndarray) -> None:
        self.road.add(mask, label)
        if self.with_prob:
            self.kitti.add(prob, label)

    def result(self) -> dict[str, float]:
        result: dict[str, float] = self.road.result()
        if self.with_prob:
            k = self.kitti.result()
            result.update({"maxf": k["maxf"], "ap": k["ap"]})
            result.update({f"kitti_{key}": k[key] for key in ("precision", "recall", "fpr", "fnr", "threshold")})
        return result


def evaluate_folder(pred_dir: str | Path, labels: str | Path, fmt: LabelFormat,
                    progress: bool = True, road_share: RoadShare | None = None,
                    notes: list[str] | None = None, bev: BevMapsOf | None = None) -> tuple[dict[str, Any], int]:
    """Road metrics (and KITTI metrics from probability maps) of ``pred_dir`` against ``labels``,
    and the number of images. Keys: iou, mean_image_iou, precision, recall, f1; with probability
    maps also maxf, ap, kitti_precision, kitti_recall, kitti_fpr, kitti_fnr, kitti_threshold (the
    operating point of MaxF). Every value is in [0, 1].

    ``bev`` (given: a frame's stem and size -> its :func:`vcprep.bev.bev_maps`): the metrics again
    in the bird's-eye view of the road, under the key ``bev``: with probability maps the KITTI road
    benchmark's (``maxf``, ``ap``, ``precision``, ``recall``, ``fpr``, ``fnr``, ``threshold``) and
    the masks' ``iou``, ``mean_image_iou``; without, the masks' (iou ... f1). Labels and masks go
    onto the grid by nearest neighbour (unseen cells ignored), probability maps as the devkit's
    ``transform2BEV`` for a KITTI calibration (its pixel), bilinearly for other cameras.

    Every prediction must have its label (the reverse is not required: evaluate a subset by
    predicting a subset). Raises :class:`InputError` on a missing label or a size mismatch.
    ``road_share`` (given) gets every decoded label (:class:`vcprep.labels.RoadShare`: where road
    lies, and whether that makes sense). Where the folder records its predictions (``predict.json``)
    only the recorded frames are scored; ``notes`` (given) gets a line naming those left out."""
    pred_dir, labels = Path(pred_dir), Path(labels)
    if not pred_dir.is_dir():
        raise InputError("prediction folder not found", pred_dir, "give the --out folder of 'vctrain predict'")
    if not labels.is_dir():
        raise InputError("label folder not found", labels, "check --labels")
    stems = _recorded_stems(pred_dir, prediction_stems(pred_dir), notes)
    if not stems:
        raise InputError("no <stem>_mask.png or <stem>_prob.png in folder", pred_dir,
                         "give the --out folder of 'vctrain predict'")
    label_files = _label_files(labels, fmt)
    with_prob = all("prob" in v for v in stems.values())
    scores, bev_scores = _Scores(with_prob), _Scores(with_prob)
    for stem, files in tqdm(stems.items(), desc="eval", unit="img", disable=None if progress else True, leave=False):
        lf = _label_of(stem, files, label_files, labels, fmt)
        label = decode_label(read_image(lf, label=True).array, fmt, lf)
        if road_share is not None:
            road_share.add(label)
        mask, prob = _predictions(files, label)
        scores.add(mask, prob, label)
        if bev is not None:
            maps = bev(stem, (label.shape[1], label.shape[0]))
            bev_scores.add(to_bev((mask != 0).astype(np.uint8), maps, "label"),
                           None if prob is None else to_bev(prob, maps, "prob"), to_bev(label, maps, "label"))
    result: dict[str, Any] = scores.result()
    if bev is not None:
        b = bev_scores.result()  # with probability maps the KITTI benchmark's names; the masks' IoU beside them
        kitti = {k.removeprefix("kitti_"): v for k, v in b.items() if k.startswith(("kitti_", "maxf", "ap"))}
        result["bev"] = {**kitti, "iou": b["iou"], "mean_image_iou": b["mean_image_iou"]} if kitti else b
    return result, len(stems)
