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
from .study.hashing import file_sha256

BevMapsOf = Callable[[str, tuple[int, int]], Any]  # a frame's stem and size (w, h) -> its BEV maps

__all__ = ["BevMapsOf", "RECORD", "record_predictions", "recorded_frames", "recorded_runs", "recorded_poses",
           "prediction_stems", "evaluate_folder"]

RECORD = "predict.json"  # in a prediction folder: which model's runs wrote which frames


def record_predictions(out: Path, model: Path, masks: list[Path], engine: str = "",
                       inputs: list[str] | None = None, poses: dict[str, dict] | None = None,
                       startup: dict | None = None, output: str = "road") -> None:
    """Note in ``out/predict.json`` that ``model`` wrote ``masks`` (``<id>_mask.png`` in ``out``, an id
    with folders for a tree's frames: ``drive1/000123``) through ``engine`` (what ran its network,
    given: ``engine``): a run of the same model (the same file content) adds its frames to the
    record, a run of another model replaces it. Each run is kept apart under ``runs`` (``inputs``:
    what it was given; its ``frames``; a later run of the same inputs replaces it, a frame belongs to
    the last run that wrote it); ``poses`` (given: ``predict --bev``'s, stem -> the frame's BEV pose)
    are kept under ``bev_poses``; ``startup`` (given: what the run paid once, ``load_s`` and
    ``compile_s``) under its run. ``output``: the model output the masks are of (a two-output model's
    ``drivable``: recorded, and masks of another output of the same model are another model's: they
    replace the record; road, every one-output model's, is not written)."""
    stems = [m.relative_to(out).as_posix()[: -len("_mask.png")] for m in masks if m.name.endswith("_mask.png")]
    sha = file_sha256(model)
    old = _read_record(out)
    same = old is not None and old.get("model_sha256") == sha and old.get("output", "road") == output
    runs = old.get("runs", []) if same else []
    bev_poses = dict(old.get("bev_poses", {})) if runs else {}
    new = set(stems)
    runs = [{**r, "frames": [f for f in r["frames"] if f not in new]} for r in runs
            if inputs is None or r.get("inputs") != list(inputs)]
    runs = [r for r in runs if r["frames"]] + [{"inputs": list(inputs or []), "frames": stems,
                                                  **({"startup": startup} if startup else {})}]
    bev_poses.update(poses or {})
    frames = [f for r in runs for f in r["frames"]]
    doc = {"model": str(model), "model_sha256": sha, **({"output": output} if output != "road" else {}),
           **({"engine": engine} if engine else {}), "frames": frames,
           "runs": runs, **({"bev_poses": bev_poses} if bev_poses else {})}
    write_bytes_atomic(out / RECORD, (json.dumps(doc, indent=1) + "\n").encode())


def _read_record(pred_dir: Path) -> dict | None:
    """``pred_dir/predict.json`` as written (an older one without ``runs``: its frames as one run)."""
    path = pred_dir / RECORD
    if not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text())
        doc["frames"] = [str(s) for s in doc["frames"]]
        for key in ("model", "model_sha256"):
            doc[key] = str(doc[key])
        doc.setdefault("runs", [{"inputs": [], "frames": doc["frames"]}])
        return doc
    except (ValueError, KeyError, TypeError):
        raise InputError("not a prediction record of 'vctrain predict'", path,
                         "delete it (eval then scores every mask in the folder)") from None


def recorded_frames(pred_dir: Path) -> tuple[str, str, list[str]] | None:
    """(model, its SHA-256, the frames its runs wrote) from ``pred_dir/predict.json``; None where the
    folder has none (predictions of an older vctrain or of another tool)."""
    doc = _read_record(pred_dir)
    return None if doc is None else (str(doc["model"]), str(doc["model_sha256"]), doc["frames"])


def recorded_runs(pred_dir: Path) -> list[dict[str, Any]]:
    """The runs ``pred_dir/predict.json`` keeps apart (``inputs``, ``frames``); [] without a record."""
    doc = _read_record(pred_dir)
    return [] if doc is None else list(doc["runs"])


def recorded_poses(pred_dir: Path) -> dict[str, dict[str, Any]]:
    """stem -> the BEV pose ``predict --bev`` gave the frame (:meth:`vcprep.bev.GroundView.pose_dict`); {} without."""
    doc = _read_record(pred_dir)
    return {} if doc is None else dict(doc.get("bev_poses", {}))


def prediction_stems(pred_dir: Path) -> dict[str, dict[str, Path]]:
    """stem -> {'mask': path, 'prob': path} (either may be absent): the perspective masks; a
    ``<stem>_bev_mask.png`` / ``_bev_prob.png`` beside ``<stem>``'s own (``predict --bev``'s) is none."""
    out: dict[str, dict[str, Path]] = {}
    for f in sorted(pred_dir.glob("*.png")):
        for kind in ("mask", "prob"):
            if f.stem.endswith("_" + kind):
                out.setdefault(f.stem[: -len(kind) - 1], {})[kind] = f
    for stem in [s for s in out if s.endswith("_bev")]:
        base = stem[: -len("_bev")]
        if base in out or any((pred_dir / f"{base}_{k}.png").is_file() for k in ("mask", "prob")):
            del out[stem]
    return out


def _recorded_stems(pred_dir: Path, stems: dict[str, dict[str, Path]],
                    notes: list[str] | None, run: int | None = None) -> dict[str, dict[str, Path]]:
    """``stems`` less the frames ``predict.json`` does not list (all of them without a record);
    ``run`` (given, from 1): that recorded run's frames alone."""
    record = recorded_frames(pred_dir)
    if record is None:
        if run is not None:
            raise InputError("--run: the folder has no predict.json (no runs recorded)", pred_dir,
                             "drop --run, or predict into this folder again with 'vctrain predict'")
        return stems
    model, _, frames = record
    if run is not None:
        runs = recorded_runs(pred_dir)
        if not 1 <= run <= len(runs):
            raise InputError(f"--run {run}: the folder records {len(runs)} run(s)", pred_dir,
                             f"give --run 1 to {len(runs)} ({_runs_said(runs)})")
        frames = runs[run - 1]["frames"]
    kept = {s: f for s, f in stems.items() if s in set(frames)}
    for frame in (f for f in frames if "/" in f):  # a tree's frames, in its folders
        files = {kind: pred_dir / f"{frame}_{kind}.png" for kind in ("mask", "prob")}
        files = {kind: f for kind, f in files.items() if f.is_file()}
        if files:
            kept[frame] = files
    if run is None and len(kept) < len(stems) and notes is not None:
        n = len(stems) - len(kept)
        notes.append(f"{pred_dir}: {n} of its {len(stems)} masks were not written by the model of its last "
                     f"predict run ({model}), left out (predict into a fresh --out to keep runs apart)")
    return kept


def _runs_said(runs: list[dict[str, Any]]) -> str:
    """'run 1: 60 frames of a/image_2; run 2: 49 frames of b/image_2'."""
    def inputs(r):
        names = [str(p) for p in r.get("inputs", [])]
        return ", ".join(names[:2]) + (", ..." if len(names) > 2 else "") if names else "inputs not recorded"

    return "; ".join(f"run {i}: {len(r['frames'])} frame(s) of {inputs(r)}" for i, r in enumerate(runs, 1))


def _labels_of(pred_dir: Path, stems: dict[str, dict[str, Path]], labels: Path, fmt: LabelFormat,
               run: int | None) -> dict[str, Path]:
    """stem -> its label file. A folder that holds the frames of several predict runs, some of them
    without a label here, is named as such (its runs, and ``--run``); else the first missing label."""
    label_files = _label_files(labels, fmt)
    found, missing = {}, []
    for stem, files in stems.items():
        try:
            found[stem] = _label_of(stem, files, label_files, labels, fmt)
        except InputError as e:
            if "no label" not in e.problem:
                raise
            missing.append((stem, e))
    runs = recorded_runs(pred_dir) if run is None else []
    if missing and len(runs) > 1:
        names = ", ".join(m[0] for m in missing[:3]) + (", ..." if len(missing) > 3 else "")
        raise InputError(f"holds the frames of {len(runs)} predict runs of one model ({_runs_said(runs)}), and "
                         f"{len(missing)} of its frames ({names}) have no label in {labels}", pred_dir,
                         f"score one run with --run N (1 to {len(runs)}), or predict each frame set into its "
                         "own --out")
    if missing:
        raise missing[0][1]
    return found


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
                    notes: list[str] | None = None, bev: BevMapsOf | None = None,
                    run: int | None = None) -> tuple[dict[str, Any], int]:
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
    only the recorded frames are scored; ``notes`` (given) gets a line naming those left out; ``run``
    (given, from 1): the frames of that recorded run alone. A folder holding the frames of several
    runs of which some have no label is refused naming its runs."""
    pred_dir, labels = Path(pred_dir), Path(labels)
    if not pred_dir.is_dir():
        raise InputError("prediction folder not found", pred_dir, "give the --out folder of 'vctrain predict'")
    if not labels.is_dir():
        raise InputError("label folder not found", labels, "check --labels")
    stems = _recorded_stems(pred_dir, prediction_stems(pred_dir), notes, run)
    if not stems:
        raise InputError("no <stem>_mask.png or <stem>_prob.png in folder", pred_dir,
                         "give the --out folder of 'vctrain predict'")
    label_of = _labels_of(pred_dir, stems, labels, fmt, run)
    with_prob = all("prob" in v for v in stems.values())
    scores, bev_scores = _Scores(with_prob), _Scores(with_prob)
    for stem, files in tqdm(stems.items(), desc="eval", unit="img", disable=None if progress else True, leave=False):
        lf = label_of[stem]
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
