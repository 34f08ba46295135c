"""Cross-camera study: leave one dataset out (paper Tables 4 and 7), and test-only datasets.

Given a study (:mod:`vctrain.study`: named datasets, each taken with its own camera, and the
conditions to compare), for every *condition*:

* each dataset of role ``both`` (the default) is held out in turn: train on every other dataset
  that may be trained on (role ``train`` or ``both``), test on the held-out one;
* when there are datasets of role ``test`` (never trained on, e.g. a new camera's labelled frames:
  "will my model work on camera X?"), one more model per condition is trained on ALL trainable
  datasets and tested on every test-role dataset.

This module is the run plan (:func:`plan_runs`) and its execution (:func:`run_study`): the stores
each run needs, the trainings, the adapted models and the scores; the conditions are defined in
:mod:`vctrain.study` and the tables written by :mod:`vctrain.report`.

Everything runs through the real tools: stores are built with :func:`vcprep.build.warp_dataset`
(one per dataset, split and geometry, shared by all folds), models with :func:`vctrain.train.fit`,
and the held-out test images are predicted in the model's own domain and scored in their ORIGINAL
camera (back-projected probabilities, threshold 0.5) against their original labels: road IoU =
ΣTP / Σ(TP+FP+FN) over the held-out test images, ignore pixels excluded.

A dataset's ``camera:`` may be a folder of per-frame calibration files (KITTI ``calib/``,
Cityscapes ``camera/<split>/``; :class:`vcprep.camera.FrameCameras`): then every frame has its
own camera and exact pose, in every geometry (nothing is estimated for it), and its first frame's
camera stands for it in the virtual camera's design.

Estimated VPs (``within``, ``zero``) are searched for and accepted only inside the pose range the
virtual camera is designed to hold (``pan_range``, ``tilt_range`` of the study; rejected images fall
back to the mean accepted VP, see :mod:`vcprep.vanishing_point`).

Nothing is tuned on an evaluated camera: the checkpoint kept is the best on a validation share of
the TRAINING datasets. The virtual camera is designed from all the study's cameras (as in the
paper, whose virtual camera covers all five), which uses the evaluated cameras' calibration but
none of their images. Training settings not given in the study are :class:`vctrain.train.TrainConfig`'s
defaults (the project's current recipe).

Layout under OUT: ``stores/<dataset>/<split>/<geometry>/`` (vcprep stores), ``vps/<dataset>-<split>.csv``
(the estimated VPs), ``runs/<heldout>/<condition>/`` (checkpoint, training log, ``train.json``,
``result.json``) and, with test-role datasets, ``runs/_all/<condition>/`` (one model,
``result-<dataset>.json`` per test-role dataset), ``results.jsonl`` (one row per evaluated dataset and
condition), ``table.md``, ``table.csv``, ``summary.json`` (:mod:`vctrain.report`). A finished result is
not redone, and a finished training is not repeated for a missing evaluation, so an interrupted study
resumes where it stopped; a run finished with other settings (effective training config, virtual
camera, datasets) is redone.
"""
from __future__ import annotations

import hashlib
import json
import math
import shutil
import time
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any, Callable, Sequence

from vcprep.build import ItemPose, Job, WarpSettings, list_dataset, warp_dataset
from vcprep.camera import PRESET_PREFIX, Camera, FrameCameras, load_camera, load_cameras
from vcprep.errors import InputError
from vcprep.imageio import image_size, read_image, write_bytes_atomic
from vcprep.labels import decode_label, get_label_format
from vcprep.store import Store

from .report import write_json, write_tables
from .study import (ADAPT_COMBINE, CONDITIONS, DEFAULT_CANVAS, DEFAULT_STORE_PIXELS, DEFAULT_TRAIN, GEOMETRIES,
                    RUN_KEYS, Dataset, Split, Study, check_conditions, evaluated_datasets)

__all__ = ["plan_runs", "training_settings", "run_study", "evaluate_heldout", "score_store"]

ESTIMATE_VERSION = 2  # bump when vcprep.camera_estimate changes what it estimates (cached estimates are redone)
ALL_RUN = "_all"  # runs/_all/<condition>/: trained on every trainable dataset, scored on the test-role ones


# -- stores --------------------------------------------------------------------------------------
class _Builder:
    """Builds (or finds up to date) the stores a study needs, each once."""

    def __init__(self, study: Study, out: Path, progress: bool, jobs: int, say: Callable[[str], None]):
        self.study, self.out, self.progress, self.jobs, self.say = study, out, progress, jobs, say
        self._cams: dict[str, Camera] = {}
        self.ego_found: dict[str, dict] = {}  # dataset -> what the own-vehicle search found (ego: auto)
        self.estimated: dict[str, Any] = {}   # dataset -> its CameraEstimate (camera: estimate)
        self._items: dict[tuple[str, str], list[Job]] = {}
        self._vps: dict[tuple[str, str], dict[str, ItemPose]] = {}
        self._virtual: Camera | None = None
        self._canvas: dict[str, Camera] = {}  # virtual_for: the canvases of canvas: footprint
        self.canvas = study.canvas or DEFAULT_CANVAS  # the rectangle rule (run_study may choose 'shared')

    def split(self, ds: Dataset, split: str) -> Split:
        return {"train": ds.train, "test": ds.test, "unlabelled": ds.unlabelled}[split]

    @staticmethod
    def adapt_split(ds: Dataset) -> str:
        """The split condition adapt adapts to: 'unlabelled' where the study gives one, else 'test'
        (its images only: their labels are never read for adaptation)."""
        return "unlabelled" if ds.unlabelled is not None else "test"

    def items(self, ds: Dataset, split: str) -> list[Job]:
        """The split's items: every image of its folder that its include/exclude globs select
        (with their labels, except for an unlabelled split)."""
        key = (ds.name, split)
        if key not in self._items:
            s = self.split(ds, split)
            fmt = get_label_format(ds.label_format) if s.labels is not None else None
            try:
                jobs = [j for j in list_dataset(s.images, s.labels, fmt) if s.selects(j.id)]
            except InputError as e:
                raise InputError(f"dataset '{ds.name}' {split}: {e.problem}{f' ({e.file})' if e.file else ''}",
                                 self.study.path, "check the split's folders in the study file") from None
            if not jobs:
                raise InputError(f"dataset '{ds.name}' {split}: no image of {s.images} is selected", self.study.path,
                                 "check the folder and the split's include/exclude globs (on file stems)")
            self._items[key] = jobs
        return self._items[key]

    def camera(self, ds: Dataset) -> Camera | FrameCameras:
        """The dataset's camera, or its per-frame calibration when ``camera:`` is a folder; with
        its own-vehicle rows (``ego``) when the camera file does not state them."""
        if ds.name not in self._cams:
            if ds.camera == "estimate":
                cam = self._estimate(ds)
            else:
                cam = load_cameras(ds.camera, self.items(ds, ds.first_split)[0].image)
            if isinstance(cam, Camera) and not cam.ego_rows and ds.ego != "none" and ds.camera != "estimate":
                cam = replace(cam, ego_rows=self._ego_rows(ds, cam))
            self._cams[ds.name] = cam
        return self._cams[ds.name]

    def _labelled_splits(self, ds: Dataset) -> list[str]:
        return [s for s in ("train", "test") if self.split(ds, s) is not None and self.split(ds, s).labels is not None]

    def _estimate(self, ds: Dataset) -> Camera:
        """``camera: estimate``: the camera estimated from the dataset's own frames (every split's
        images; the own vehicle from its labels unless ``ego: none``/``N``, the height from its labels'
        road footprint), once: kept in
        ``OUT/cameras/<dataset>.yaml`` with the frames it came from, reused while they are the same."""
        from vcprep.camera import read_camera_yaml
        from vcprep.camera_estimate import estimate_camera, estimate_to_yaml

        jobs = {j.image: j for split in ("train", "test") if self.split(ds, split) is not None
                for j in self.items(ds, split)}
        images = sorted(jobs)
        from vcprep.ego import MIN_FRAMES as EGO_MIN_FRAMES

        labels = sorted({jobs[i].label for i in images if jobs[i].label is not None})
        labels = labels if len(labels) >= EGO_MIN_FRAMES else []
        key = hashlib.sha256(json.dumps([ESTIMATE_VERSION, [str(i) for i in images], [str(x) for x in labels],
                                         ds.label_format, ds.ego == "auto"]).encode()).hexdigest()[:16]
        path = self.out / "cameras" / f"{ds.name}.yaml"
        record = path.with_suffix(".json")
        rec, cam = None, None
        if path.exists() and record.exists():
            try:
                rec = json.loads(record.read_text())
                cam = read_camera_yaml(path) if rec.get("key") == key else None
            except (OSError, ValueError, AttributeError, InputError):
                cam = None  # unreadable: estimated again
        if cam is None:
            self.say(f"{ds.name}: estimating its camera from {len(images)} frames")
            est = estimate_camera(images, name=f"{ds.name}-estimated", ids=[jobs[i].id for i in images],
                                  labels=labels or None, label_format=get_label_format(ds.label_format),
                                  find_ego=ds.ego == "auto")
            # written at once, and the camera taken as its YAML reads back: the first run and every
            # resumed one design the same virtual camera (so finished stores stay finished)
            path.parent.mkdir(parents=True, exist_ok=True)
            write_bytes_atomic(path, estimate_to_yaml(est).encode())
            rec, cam = {"key": key, **est.to_dict()}, read_camera_yaml(path)
        if isinstance(ds.ego, int):
            cam = replace(cam, ego_rows=ds.ego)
        rec["camera"] = cam.to_dict()
        write_json(record, rec)
        self.estimated[ds.name] = rec
        return cam

    def write_estimates(self) -> None:
        """Each estimated camera beside the study's stores (OUT/cameras/), and one line saying so."""
        for name, rec in self.estimated.items():
            path = self.out / "cameras" / f"{name}.yaml"
            v = rec["values"]
            self.say(f"{name}: camera ESTIMATED from its frames ({path.relative_to(self.out)}): tilt {v['tilt']['value']} "
                     f"deg, pan {v['pan']['value']} deg from {rec['accepted_vps']} of {rec['frames']} road VPs; "
                     f"fx {v['fx']['source']}, height {v['height']['source']}, ego_rows {rec['camera'].get('ego_rows', 0)}")

    def _ego_rows(self, ds: Dataset, cam: Camera) -> int:
        """``ego: N`` as given; ``ego: auto``: the own vehicle found from the dataset's labels
        (every labelled split; :mod:`vcprep.ego`), at the camera's image size. Too few labelled
        frames: none. What was found is in ``ego_found`` (said by :meth:`say_ego`)."""
        if isinstance(ds.ego, int):
            return ds.ego
        from vcprep.ego import ego_rows_from_label_files, rows_at_height
        labels = sorted({j.label for split in self._labelled_splits(ds) for j in self.items(ds, split)})
        try:
            est = ego_rows_from_label_files(labels, get_label_format(ds.label_format), self.study.path)
        except InputError as e:
            self.ego_found[ds.name] = {"ego_rows": 0, "not_searched": e.problem}
            return 0
        rows = rows_at_height(est, cam.size[1])
        self.ego_found[ds.name] = {**est.to_dict(), "ego_rows_at_camera_size": rows, "describe": est.describe()}
        return rows

    def say_ego(self) -> None:
        """One line per dataset whose own vehicle was found, or could not be searched for."""
        for name, f in self.ego_found.items():
            if f.get("not_searched"):
                self.say(f"{name}: own vehicle not searched for ({f['not_searched']}); write ego: N in the study if "
                         "its frames show it")
            elif f["ego_rows"]:
                self.say(f"{name}: {f['describe']}; the camera's ego_rows: {f['ego_rows_at_camera_size']} (write "
                         "ego: none in the study to warp them)")

    def nominal_camera(self, ds: Dataset) -> Camera:
        """One camera standing for the dataset (the virtual camera's design): per-frame
        calibration is represented by its first frame's camera."""
        cam = self.camera(ds)
        if isinstance(cam, FrameCameras):
            first = self.items(ds, ds.first_split)[0].image
            cam = cam.for_image(first, image_size(first))
        return cam

    def virtual(self) -> Camera:
        if self._virtual is None:
            if self.study.virtual == "design":
                from vcprep.virtual_camera import design_virtual_camera

                design = design_virtual_camera([self.nominal_camera(d) for d in self.study.datasets], self.study.pan_range,
                                               self.study.tilt_range, name="study-virtual", above=self.study.above)
                self._virtual = design.camera
            else:
                self._virtual = load_camera(self.study.virtual)
        return self._virtual

    def virtual_for(self, ds: Dataset) -> Camera:
        """The virtual camera of ``ds``'s stores. ``canvas: shared`` (or a given virtual camera):
        :meth:`virtual` for every dataset. ``canvas: footprint``: the virtual camera designed from
        the trainable datasets' cameras alone (focal length, height, level pose, top edge, and the
        rectangle that holds them: every trainable dataset's stores, so a model's training images
        share one size and no test camera shapes the training), and for a test-only dataset that
        camera's rectangle extended to its own camera (the network runs on it at the training's
        pixels per degree)."""
        if self.study.virtual != "design" or self.canvas == "shared":
            return self.virtual()
        key = "\0train" if ds.role != "test" else ds.name
        if key not in self._canvas:
            from vcprep.virtual_camera import design_virtual_camera

            cams = [self.nominal_camera(d) for d in self.study.datasets if d.role != "test"]
            if ds.role == "test":
                ref = self.virtual_for(next(d for d in self.study.datasets if d.role != "test"))
                cams.append(self.nominal_camera(ds))
                f, height = ref.fx, ref.height
            else:
                f = height = None
            self._canvas[key] = design_virtual_camera(cams, self.study.pan_range, self.study.tilt_range,
                                                      name="study-virtual", above=self.study.above, f=f,
                                                      height=height).camera
        return self._canvas[key]

    def training_virtual(self) -> Camera:
        """The virtual camera of every trainable dataset's stores (what the pixel budget sizes)."""
        trainable = [d for d in self.study.datasets if d.role != "test"]
        return self.virtual_for(trainable[0]) if trainable else self.virtual()

    def scale(self) -> float:
        w, h = self.training_virtual().size
        if self.study.store_width and not self.study.store_pixels:
            return self.study.store_width / w
        return math.sqrt((self.study.store_pixels or DEFAULT_STORE_PIXELS) / (w * h))

    def resize_size(self, datasets: Sequence[Dataset], store_size: tuple[int, int]) -> tuple[int, int]:
        """The resize baseline's working size: the virtual store's pixel count at the aspect of
        the first training dataset's images (same pixel budget, no squashing of the source)."""
        first = self.items(datasets[0], "train")[0].image
        w0, h0 = image_size(first)
        n = store_size[0] * store_size[1]
        return max(32, int(round(math.sqrt(n * w0 / h0)))), max(32, int(round(math.sqrt(n * h0 / w0))))

    def has_given_vps(self, ds: Dataset, split: str) -> bool:
        return self.split(ds, split).vps is not None

    def poses(self, ds: Dataset, split: str, source: str) -> dict[str, ItemPose] | None:
        if source == "none" or (source == "estimate" and isinstance(self.camera(ds), FrameCameras)):
            return None  # (per-frame calibration: every frame's exact pose, nothing to estimate)
        from vcprep.vanishing_point import vps_for_items, write_vp_csv

        key = (ds.name, split, source)
        if key not in self._vps:
            jobs = self.items(ds, split)
            images, ids = [j.image for j in jobs], [j.id for j in jobs]
            if source == "given":
                vps = self.split(ds, split).vps
                if vps is None:
                    raise InputError(f"dataset '{ds.name}' {split} has no 'vps' file", self.study.path,
                                     "add 'vps:' to the split, or drop the within-gt condition")
                res = vps_for_items(images, ids, self.camera(ds), str(vps))
            else:
                from vcprep.vanishing_point import VPConfig

                # search and accept VPs only within the pose range the virtual camera is designed
                # to hold: a pose outside it would push the image out of the virtual frame
                cfg = VPConfig(pan_range=self.study.pan_range, tilt_range=self.study.tilt_range)
                self.say(f"estimating road VPs of {ds.name}/{split} ({len(jobs)} images)")
                res = vps_for_items(images, ids, self.camera(ds), "estimate", cfg=cfg)
                (self.out / "vps").mkdir(parents=True, exist_ok=True)
                write_vp_csv(self.out / "vps" / f"{ds.name}-{split}.csv", ids, res)
            self._vps[key] = {i: ItemPose((r.vp[0], r.vp[1]), r.status) for i, r in zip(ids, res)}
        return self._vps[key]

    def _drop_if_other_virtual(self, root: Path, virtual: Camera) -> None:
        """The study's stores are its own derived data: one built for another virtual camera or
        scale (the study's datasets or settings changed since) is removed, to be built afresh."""
        if not (root / "store.json").exists():
            return
        from vcprep.build import store_params

        want = store_params(virtual, self.scale())
        have = Store.open(root).params
        if any(have.get(k) != want[k] for k in ("virtual", "scale", "store_size")):
            self.say(f"{root.relative_to(self.out)}: built for another virtual camera or scale; building it afresh")
            shutil.rmtree(root)

    def warp_settings(self, ds: Dataset, split: str, geometry: str) -> WarpSettings:
        """How the store of ``ds``'s ``split`` in ``geometry`` is built: the dataset's camera into
        the study's virtual camera and scale, with the geometry's poses and completion."""
        source, completion = GEOMETRIES[geometry]
        return WarpSettings(camera=self.camera(ds), virtual=self.virtual_for(ds), scale=self.scale(),
                            label_format=get_label_format(ds.label_format), completion=completion,
                            poses=self.poses(ds, split, source), workers=self.jobs, progress=self.progress)

    def store(self, ds: Dataset, split: str, geometry: str) -> Path:
        """The store of ``ds``'s ``split`` in ``geometry`` (built or brought up to date)."""
        root = self.out / "stores" / ds.name / split / geometry
        jobs = self.items(ds, split)
        settings = self.warp_settings(ds, split, geometry)
        self._drop_if_other_virtual(root, settings.virtual)
        warp_dataset(jobs, root, settings)
        return root


# -- one run -------------------------------------------------------------------------------------
def _train_config(study: Study, stores: list[Path], out: Path, baseline: str, size: tuple[int, int] | None,
                  progress: bool, overrides: dict[str, Any]):
    """The study's ``train:``, then ``overrides``, then for every setting left unset the recipe's
    default exactly as ``vctrain fit`` resolves it (so a study follows the project's recipe)."""
    from .train import TrainConfig, resolve_recipe

    cfg = TrainConfig(stores=[str(s) for s in stores], out=str(out / "model.pt"), baseline=baseline, size=size,
                      progress=progress)
    names = {f.name for f in fields(TrainConfig)}
    for k, v in {**DEFAULT_TRAIN, **study.train, **overrides}.items():
        if k in names and v is not None:
            setattr(cfg, k, v)
    try:
        return resolve_recipe(cfg)
    except InputError as e:
        raise InputError(f"'train': {e.problem}", study.path, e.fix) from None


def training_settings(study: Study, overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """The training settings every run of ``study`` shares (the effective config, defaults included)."""
    cfg = _train_config(study, [], Path("."), "none", None, False, dict(overrides or {}))
    return {k: v for k, v in cfg.to_dict().items() if k not in RUN_KEYS and k != "workers"}


def evaluate_heldout(checkpoint: Path, store_dir: Path, progress: bool = False) -> dict[str, Any]:
    """Road metrics of ``checkpoint`` on every labelled item of a held-out test store, scored in the
    item's ORIGINAL camera against its original label (P(road) >= 0.5)."""
    from .predict import Predictor

    return score_store(Predictor(checkpoint, device="cpu"), store_dir, progress)


def score_store(predictor, store_dir: Path, progress: bool = False) -> dict[str, Any]:
    """Road metrics of ``predictor`` (a :class:`vctrain.predict.Predictor` or
    :class:`vctrain.adapt.PriorPredictor`: anything with ``store_item``) on every labelled item of
    a test store, each scored in its ORIGINAL camera against its original label (P(road) >= 0.5)."""
    from tqdm import tqdm

    from .metrics import RoadMetrics

    store = Store.open(store_dir)
    m = RoadMetrics()
    n = 0
    for rec in tqdm(list(store), desc="test", unit="img", disable=None if progress else True, leave=False):
        if not rec.get("label_source"):
            continue
        prob = predictor.store_item(store, rec)
        raw = read_image(rec["label_source"], label=True).array
        label = decode_label(raw, get_label_format(rec["label_format"]), rec["label_source"])
        m.add(prob >= 0.5, label)
        n += 1
    return {**m.result(), "test_items": n}


@dataclass(frozen=True)
class _Run:
    """One model: ``condition`` trained on ``train``, scored on each dataset of ``tests``."""

    name: str                   # runs/<name>/<condition>/: the held-out dataset, or ALL_RUN
    condition: str
    train: tuple[Dataset, ...]
    tests: tuple[Dataset, ...]

    def result_file(self, run_dir: Path, ds: Dataset) -> Path:
        return run_dir / ("result.json" if ds.name == self.name else f"result-{ds.name}.json")


class _Keys:
    """What a finished model and a finished result depend on, as short hashes: a model or result
    of other settings is redone, never silently reused, and one of the same is never redone.

    * ``full``: every setting of the study (``settings_sha`` of the results of conditions prior
      and adapt, and of every row written before the split below, still accepted);
    * ``model(run)``: the training settings, the training stores' virtual camera and scale, the
      pose ranges and the run's training datasets (their cameras, labels, splits, own vehicle,
      estimates) -- so a test-only dataset added or changed retrains nothing (canvas: footprint;
      with ``canvas: shared`` its camera shapes the one virtual camera, which is in the key);
    * ``result(run, ds)``: the model's key and the test store's (``ds``'s camera, canvas, splits)."""

    def __init__(self, b: "_Builder", virt: Camera, training: dict[str, Any]):
        study = b.study
        self.b = b
        self.common = {"virtual": virt.to_dict(), "scale": b.scale(), "pan_range": study.pan_range,
                       "tilt_range": study.tilt_range, "train": training,
                       "resize_size": "source aspect, store pixels"}
        self.entry = {d.name: self._entry(d) for d in study.datasets}
        settings = {**self.common, "datasets": [self.entry[d.name]["dataset"] for d in study.datasets]}
        canvases = {d.name: b.virtual_for(d).to_dict() for d in study.datasets}
        if any(c != virt.to_dict() for c in canvases.values()):  # (every store in the shared rectangle: as before)
            settings["canvas"] = canvases
        ego = {n: e["ego_rows"] for n, e in self.entry.items() if e.get("ego_rows")}
        if ego:  # only when a camera sees its own vehicle: the settings of studies without one are as before
            settings["ego_rows"] = ego
        if b.estimated:  # a changed estimate redoes what depends on it
            settings["cameras_estimated"] = {k: v["camera"] for k, v in b.estimated.items()}
        self.full = _sha(settings)

    def _entry(self, d: Dataset) -> dict[str, Any]:
        b = self.b
        # (a preset is written preset:NAME since the one naming rule; bare, as before, in the settings)
        e = {"dataset": [d.name, d.role, d.camera.removeprefix(PRESET_PREFIX), d.label_format, repr(d.train),
                         repr(d.test)], "canvas": b.virtual_for(d).to_dict(),
             "camera_params": b.nominal_camera(d).to_dict()}  # (the file's contents, not only its name)
        cam = b.camera(d)
        if isinstance(cam, Camera) and cam.ego_rows:
            e["ego_rows"] = cam.ego_rows
        if d.name in b.estimated:
            e["camera_estimated"] = b.estimated[d.name]["camera"]
        return e

    def model(self, run: "_Run") -> str:
        return _sha({**self.common, "train_datasets": [self.entry[d.name] for d in run.train]})

    def result(self, run: "_Run", ds: Dataset) -> str:
        return _sha({"model": self.model(run), "test": self.entry[ds.name]})


def _sha(obj: Any) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:16]


def plan_runs(study: Study, conditions: Sequence[str], evaluated: Sequence[str]) -> list[_Run]:
    """Leave-one-out runs for the evaluated 'both' datasets, then (with test-role datasets) one run
    per condition on every trainable dataset, scored on each evaluated test-role dataset."""
    trainable = tuple(d for d in study.datasets if d.trained)
    chosen = [study.dataset(n) for n in evaluated]
    runs = [_Run(d.name, c, tuple(t for t in trainable if t.name != d.name), (d,))
            for d in chosen if d.role == "both" for c in conditions]
    tests = tuple(d for d in chosen if d.role == "test")
    return runs + [_Run(ALL_RUN, c, trainable, tests) for c in conditions] if tests else runs


def _what(run: _Run, ds: Dataset, tag: str) -> str:
    return f"{tag} {'held out' if ds.role == 'both' else 'tested on'} {ds.name}, {run.condition}"


def _pending(run: _Run, b: _Builder, key: Callable[[Dataset], str], tag: str,
             legacy: str | None = None) -> tuple[list[dict[str, Any]], list[Dataset]]:
    """(results finished earlier with settings ``key(ds)`` -- or ``legacy``, every setting of the
    study, as rows were keyed before :class:`_Keys` --, datasets still to score); a result of
    other settings is removed."""
    run_dir = b.out / "runs" / run.name / run.condition
    rows, todo = [], []
    for ds in run.tests:
        f = run.result_file(run_dir, ds)
        prev = json.loads(f.read_text()) if f.exists() else None
        if prev is not None and prev.get("settings_sha") in (key(ds), legacy):
            rows.append(prev)
            b.say(f"{_what(run, ds, tag)}: done earlier (IoU {prev['iou']:.3f})")
            continue
        if prev is not None:
            b.say(f"{_what(run, ds, tag)}: the study's settings changed since it ran; redoing it")
            f.unlink()
        todo.append(ds)
    return rows, todo


_INFO = ("train_datasets", "train_items", "val_items", "best_epoch", "best_val_iou", "epochs", "input_size",
         "train_seconds", "train_images_per_s")  # what each result row repeats of its model's training


def _execute(run: _Run, b: _Builder, keys: _Keys, overrides: dict[str, Any], tag: str) -> list[dict[str, Any]]:
    """Train (unless trained earlier with these settings) and score the results still missing."""
    kind = CONDITIONS[run.condition][1]
    if kind == "prior":
        return _execute_prior(run, b, keys.full, tag)
    if kind == "adapt":
        return _execute_adapt(run, b, keys, overrides, tag)
    rows, todo = _pending(run, b, lambda ds: keys.result(run, ds), tag, keys.full)
    if not todo:
        return rows
    say, c = b.say, run.condition
    geometry = CONDITIONS[c][0]
    if GEOMETRIES[geometry][0] == "given":
        no_train = [d.name for d in run.train if not b.has_given_vps(d, "train")]
        for ds in list(todo):
            missing = no_train + ([ds.name] if not b.has_given_vps(ds, "test") else [])
            if missing:
                say(f"{_what(run, ds, tag)}: skipped (no given VPs for {', '.join(missing)})")
                todo.remove(ds)
        if not todo:
            return rows
    say(f"{tag} {run.name}, {c}: stores")
    test_stores = {ds.name: b.store(ds, "test", geometry) for ds in todo}
    cfg, info = _trained(run, b, keys, overrides, tag)
    for ds in todo:
        t0 = time.perf_counter()
        metrics = evaluate_heldout(Path(cfg.out), test_stores[ds.name], b.progress)
        rows.append(_result(run, b, ds, metrics, info, info["train_seconds"] + time.perf_counter() - t0,
                            keys.result(run, ds), tag))
    return rows


def _result(run: _Run, b: _Builder, ds: Dataset, metrics: dict[str, Any], info: dict[str, Any], seconds: float,
            sha: str, tag: str, **extra: Any) -> dict[str, Any]:
    """Write and return the result row of ``ds`` in ``run``."""
    row = {"heldout": ds.name, "condition": run.condition, "role": ds.role, "run": run.name, **metrics,
           **{k: info[k] for k in _INFO}, **extra, "total_seconds": round(seconds, 1), "settings_sha": sha}
    write_json(run.result_file(b.out / "runs" / run.name / run.condition, ds), row)
    b.say(f"{_what(run, ds, tag)}: road IoU {row['iou']:.3f} ({row['total_seconds']:.0f} s)")
    return row


def _trained(run: _Run, b: _Builder, keys: _Keys, overrides: dict[str, Any], tag: str):
    """``(config, train.json)`` of ``run``'s model: trained now, or found trained earlier with
    the settings it depends on (``keys.model(run)``; ``runs/<run>/<condition>/train.json``), so a
    model is never trained twice."""
    from .train import fit

    say, c = b.say, run.condition
    run_dir = b.out / "runs" / run.name / c
    geometry, baseline = CONDITIONS[c]
    stores = [b.store(d, "train", geometry) for d in run.train]
    size = Store.open(stores[0]).store_size
    if baseline == "resize":
        size = b.resize_size(run.train, size)
    run_dir.mkdir(parents=True, exist_ok=True)
    cfg = _train_config(b.study, stores, run_dir, baseline, size, b.progress, overrides)
    trained = run_dir / "train.json"
    info = json.loads(trained.read_text()) if trained.exists() else None
    model_sha = keys.model(run)
    if (info is not None and model_sha in (info.get("model_sha"), info.get("settings_sha") == keys.full and model_sha)
            and Path(cfg.out).exists()):
        say(f"{tag} {run.name}, {c}: model trained earlier")
        if info.get("model_sha") != model_sha:  # (keyed by every setting of the study before _Keys)
            info["model_sha"] = model_sha
            write_json(trained, info)
    else:  # a training of other settings, or one that was interrupted: start afresh
        for old in (trained, Path(cfg.out), run_dir / "model.last.pt", run_dir / "model.log.jsonl"):
            old.unlink(missing_ok=True)
        say(f"{tag} {run.name}, {c}: training on {', '.join(d.name for d in run.train)} "
            f"({cfg.epochs} epochs at {size[0]}x{size[1]})")
        t0 = time.perf_counter()
        summary = fit(cfg)
        info = {"train_datasets": [d.name for d in run.train], "train_items": summary["data"]["train_items"],
                "val_items": summary["data"]["val_items"], "best_epoch": summary["best_epoch"],
                "best_val_iou": summary["best_val_iou"], "epochs": cfg.epochs, "input_size": list(size),
                "train_seconds": round(time.perf_counter() - t0, 1),
                "train_images_per_s": summary["train_images_per_s"], "model_args": summary["model_args"],
                "settings_sha": keys.full, "model_sha": model_sha}
        write_json(trained, info)
    return cfg, info


def _write_prior(run: _Run, b: _Builder, run_dir: Path) -> tuple[Path, dict[str, Any], float]:
    """The geometric prior p_g of ``run``'s training datasets (their ``within`` training stores,
    :func:`vcprep.prior.compute_prior`), written as ``run_dir/prior.npy`` with its description
    (usable by ``vctrain predict --prior``); returns (path, description, seconds)."""
    from vcprep.prior import compute_prior, prior_meta, write_prior

    stores = [b.store(d, "train", CONDITIONS["prior"][0]) for d in run.train]
    t0 = time.perf_counter()
    prior, n_unlabelled = compute_prior(stores)
    meta = prior_meta(stores, n_unlabelled)
    run_dir.mkdir(parents=True, exist_ok=True)
    path = write_prior(run_dir / "prior.npy", prior, meta)
    return path, meta, time.perf_counter() - t0


def _execute_prior(run: _Run, b: _Builder, sha: str, tag: str) -> list[dict[str, Any]]:
    """Condition prior: no model; P(road) = the training datasets' p_g back-projected to each test
    image (:class:`vctrain.adapt.PriorPredictor`), scored like every other condition."""
    from .adapt import PriorPredictor

    rows, todo = _pending(run, b, lambda ds: sha, tag)
    if not todo:
        return rows
    run_dir = b.out / "runs" / run.name / run.condition
    b.say(f"{tag} {run.name}, prior: stores and the prior of {', '.join(d.name for d in run.train)}")
    path, meta, seconds = _write_prior(run, b, run_dir)
    predictor = PriorPredictor(path)
    info = {"train_datasets": [d.name for d in run.train], "train_items": meta["items"], "val_items": 0,
            "best_epoch": None, "best_val_iou": None, "epochs": 0, "input_size": list(predictor.prior.shape[::-1]),
            "train_seconds": round(seconds, 1), "train_images_per_s": None}
    for ds in todo:
        store = b.store(ds, "test", CONDITIONS["prior"][0])
        t0 = time.perf_counter()
        metrics = score_store(predictor, store, b.progress)
        rows.append(_result(run, b, ds, metrics, info, seconds + time.perf_counter() - t0, sha, tag,
                            prior_unlabelled_pixels=meta["unlabelled_pixels"]))
    return rows


def _adapt_settings(condition: str = "adapt") -> dict[str, Any]:
    """What an adapted model depends on besides the study's settings (vctrain.adapt's defaults)."""
    from .adapt import ADAPT_EPOCHS, ADAPT_LR_FACTOR

    return {"epochs": ADAPT_EPOCHS, "lr_factor": ADAPT_LR_FACTOR, "lo": 0.25, "hi": 0.75,
            "combine": ADAPT_COMBINE[condition]}


def _execute_adapt(run: _Run, b: _Builder, keys: _Keys, overrides: dict[str, Any], tag: str) -> list[dict[str, Any]]:
    """Condition adapt: the within run's model (trained once, shared with condition within)
    adapted to each evaluated dataset's unlabelled images with the training datasets' prior
    (:func:`vctrain.adapt.adapt`), then scored on its test images like every other condition."""
    from .adapt import adapt

    # a result depends on the study's settings, the adaptation's and the images adapted to
    def adapt_sha(ds: Dataset) -> str:
        key = {"study": keys.full, "adapt": _adapt_settings(run.condition), "target": b.adapt_split(ds),
               "unlabelled": repr(ds.unlabelled)}
        return hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:16]

    rows, todo = [], []
    for ds in run.tests:  # each evaluated dataset has its own adapted model and settings
        r, t = _pending(_Run(run.name, run.condition, run.train, (ds,)), b, adapt_sha, tag)
        rows, todo = rows + r, todo + t
    if not todo:
        return rows
    say = b.say
    run_dir = b.out / "runs" / run.name / run.condition
    within = _Run(run.name, "within", run.train, run.tests)
    cfg, info = _trained(within, b, keys, overrides, tag)
    source = Path(cfg.out)
    source_sha = hashlib.sha256(source.read_bytes()).hexdigest()
    prior_path, _, _ = _write_prior(run, b, run_dir)
    for ds in todo:
        asha = adapt_sha(ds)
        split = b.adapt_split(ds)
        adir = run_dir if ds.name == run.name else run_dir / ds.name
        adir.mkdir(parents=True, exist_ok=True)
        model, record = adir / "model.pt", adir / "adapt.json"
        done = json.loads(record.read_text()) if record.exists() else None
        if (done is not None and done.get("settings_sha") == asha and done.get("from_sha256") == source_sha
                and model.exists()):
            say(f"{_what(run, ds, tag)}: adapted earlier")
        else:  # adapted with other settings or from another model, or interrupted: afresh
            for old in (record, model, adir / "model.last.pt", adir / "model.log.jsonl"):
                old.unlink(missing_ok=True)
            shutil.rmtree(adir / "target.store", ignore_errors=True)  # never train on another run's items
            jobs = b.items(ds, split)
            if isinstance(b.camera(ds), FrameCameras):
                poses = "none"  # per-frame calibration: every frame's exact pose, as in the test store
            else:
                b.poses(ds, split, "estimate")  # the study's VP estimates (its pose range), as the test store's
                poses = str(b.out / "vps" / f"{ds.name}-{split}.csv")
            say(f"{_what(run, ds, tag)}: adapting the within model to {len(jobs)} unlabelled {split} images")
            t0 = time.perf_counter()
            # images only: adapt never sees a label of the evaluated dataset (its labels are surrogates from the prior)
            summary = adapt(source, [j.image for j in jobs], b.camera(ds), prior_path, model,
                            store=adir / "target.store", within=poses, combine=ADAPT_COMBINE[run.condition],
                            device=cfg.device, seed=cfg.seed,
                            max_steps=cfg.max_steps, progress=b.progress)
            done = {"settings_sha": asha, "from": str(source), "from_sha256": source_sha, "target": split,
                    "target_items": len(jobs), "adapt_seconds": round(time.perf_counter() - t0, 1),
                    "label_shares": summary["adapted"]["label_shares"], "epochs": summary["adapted"]["epochs"],
                    "lr": summary["adapted"]["lr"]}
            write_json(record, done)
        t0 = time.perf_counter()
        metrics = evaluate_heldout(model, b.store(ds, "test", CONDITIONS["adapt"][0]), b.progress)
        rows.append(_result(run, b, ds, metrics, info,
                            info["train_seconds"] + done["adapt_seconds"] + time.perf_counter() - t0, asha, tag,
                            adapt_target=split, adapt_items=done["target_items"],
                            adapt_seconds=done["adapt_seconds"], adapt_label_shares=done["label_shares"]))
    return rows


def _check_adapt_targets(b: _Builder, evaluated: Sequence[str]) -> None:
    """Condition adapt needs, for every evaluated dataset, at least one image to adapt to."""
    for name in evaluated:
        ds = b.study.dataset(name)
        b.items(ds, b.adapt_split(ds))


def run_study(study: Study, out: str | Path, conditions: Sequence[str] | None = None,
              heldout: Sequence[str] | None = None, progress: bool = True, jobs: int = 1,
              train_overrides: dict[str, Any] | None = None,
              say: Callable[[str], None] = lambda s: None) -> list[dict[str, Any]]:
    """Run (or resume) every (evaluated dataset, condition) of ``study`` into ``out`` (``heldout``:
    only these evaluated datasets); returns all result rows (finished earlier or now), in table
    order. Writes the tables (:func:`write_tables`)."""
    out = Path(out)
    conditions = check_conditions(conditions or study.conditions)
    evaluated = evaluated_datasets(study, heldout)
    overrides = dict(train_overrides or {})
    training = training_settings(study, overrides)  # checks the training settings before anything is written
    b = _Builder(study, out, progress, jobs, say)
    if any(CONDITIONS[c][1] == "adapt" for c in conditions):
        _check_adapt_targets(b, evaluated)  # also before anything is written
    if any(CONDITIONS[c][1] in ("prior", "adapt") for c in conditions):
        # the prior is an image of the training rectangle: every store must share it
        if study.canvas == "footprint":
            raise InputError("conditions prior, adapt and adapt-fuse need every store in one rectangle", study.path,
                             "drop 'canvas: footprint' from the study, or those conditions")
        b.canvas = "shared"
    out.mkdir(parents=True, exist_ok=True)
    virt = b.training_virtual()  # (canvas: shared -- the one virtual camera of every store)
    for d in study.datasets:
        b.camera(d)  # every camera before anything is written: the own vehicle is searched for now
    b.say_ego()
    b.write_estimates()
    write_json(out / "study.json", {"study": str(study.path), "virtual": virt.to_dict(), "scale": b.scale(),
                                      "conditions": conditions, "datasets": [d.name for d in study.datasets],
                                      "roles": {d.name: d.role for d in study.datasets}, "train": training,
                                      "canvas": b.canvas,
                                      **({"canvases": {d.name: list(b.virtual_for(d).size) for d in study.datasets}}
                                         if b.canvas != "shared" else {}),
                                      **({"ego_found": b.ego_found} if b.ego_found else {}),
                                      **({"cameras_estimated": {k: v["camera"] for k, v in b.estimated.items()}}
                                         if b.estimated else {})})
    keys = _Keys(b, virt, training)
    runs = plan_runs(study, conditions, evaluated)
    rows: list[dict[str, Any]] = []
    for k, run in enumerate(runs, 1):
        rows += _execute(run, b, keys, overrides, f"[{k}/{len(runs)}]")
    order = {(h, c): i for i, (h, c) in enumerate((h, c) for h in evaluated for c in conditions)}
    rows.sort(key=lambda r: order[r["heldout"], r["condition"]])
    notes = [f"Camera of {k} ESTIMATED from its frames (cameras/{k}.yaml: what was estimated, given and assumed)."
             for k in b.estimated]
    write_tables(out, rows, evaluated, conditions, notes)
    return rows
