"""What a study's files resolve to: each split's items, each dataset's camera (given, per-frame
calibration or estimated from its frames) with its own-vehicle rows, and the virtual camera of
each dataset's stores with the study's scale. Each is found once and kept (:class:`Resolution`).

A dataset's ``camera:`` may be a folder of per-frame calibration files (KITTI ``calib/``,
Cityscapes ``camera/<split>/``; :class:`vcprep.camera.FrameCameras`): then every frame has its
own camera and exact pose, in every geometry (nothing is estimated for it), and its first frame's
camera stands for it in the virtual camera's design. ``camera: estimate`` is estimated from the
dataset's own frames once and kept in ``OUT/cameras/<dataset>.yaml`` (with ``.json``: what was
estimated, given and assumed). The virtual camera is designed from all the study's cameras (as in
the paper, whose virtual camera covers all five), which uses the evaluated cameras' calibration
but none of their images; ``canvas: footprint`` sizes the training stores' rectangle by the trainable
cameras alone (:meth:`Resolution.training_virtual`).
"""
from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any, Callable

from vcprep.dataset import Job, list_dataset
from vcprep.camera import Camera, FrameCameras, load_camera, load_cameras
from vcprep.errors import InputError
from vcprep.io import image_size, write_bytes_atomic
from vcprep.labels import get_label_format

from ..report import write_json
from .hashing import settings_sha
from .spec import DEFAULT_CANVAS, DEFAULT_STORE_PIXELS, Dataset, Split, Study

__all__ = ["Resolution", "ESTIMATE_VERSION"]

ESTIMATE_VERSION = 2  # bump when vcprep.camera.estimate changes what it estimates (cached estimates are redone)


class Resolution:
    """The items, cameras and virtual cameras of ``study`` (study folder ``out``; ``say``: chatter)."""

    def __init__(self, study: Study, out: Path, say: Callable[[str], None] = lambda s: None):
        self.study, self.out, self.say = study, Path(out), say
        self._cams: dict[str, Camera] = {}
        self.ego_found: dict[str, dict] = {}  # dataset -> what the own-vehicle search found (ego: auto)
        self.estimated: dict[str, Any] = {}   # dataset -> its CameraEstimate (camera: estimate)
        self._items: dict[tuple[str, str], list[Job]] = {}
        self._virtual: Camera | None = None
        self._train_canvas: Camera | None = None  # training_virtual of canvas: footprint
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
        from vcprep.camera import estimate_camera, estimate_to_yaml

        jobs = {j.image: j for split in ("train", "test") if self.split(ds, split) is not None
                for j in self.items(ds, split)}
        images = sorted(jobs)
        from vcprep.camera.ego import MIN_FRAMES as EGO_MIN_FRAMES

        labels = sorted({jobs[i].label for i in images if jobs[i].label is not None})
        labels = labels if len(labels) >= EGO_MIN_FRAMES else []
        key = settings_sha([ESTIMATE_VERSION, [str(i) for i in images], [str(x) for x in labels], ds.label_format,
                            ds.ego == "auto"])
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
        (every labelled split; :mod:`vcprep.camera.ego`), at the camera's image size. Too few labelled
        frames: none. What was found is in ``ego_found`` (said by :meth:`say_ego`)."""
        if isinstance(ds.ego, int):
            return ds.ego
        from vcprep.camera import ego_rows_from_label_files, rows_at_height
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
                from vcprep.camera import design_virtual_camera

                design = design_virtual_camera([self.nominal_camera(d) for d in self.study.datasets], self.study.pan_range,
                                               self.study.tilt_range, name="study-virtual", above=self.study.above,
                                               extent=self.study.extent)
                self._virtual = design.camera
            else:
                self._virtual = load_camera(self.study.virtual)
        return self._virtual

    def training_virtual(self) -> Camera:
        """The virtual camera of every training store (what the pixel budget sizes). ``canvas:
        shared`` (or a given virtual camera): :meth:`virtual`. ``canvas: footprint``: the virtual
        camera designed from the trainable datasets' cameras alone (focal length, height, level
        pose, top edge, and the rectangle that holds them; ``extent: median``: as far as the median
        camera reaches), so that no test camera shapes the training. A test split's stores hold this
        rectangle extended for their own frames at their poses, as ``vctrain predict`` extends a
        model's (:func:`vctrain.predict.frames_canvas`, :class:`vctrain.study.stores.Stores`)."""
        trainable = [d for d in self.study.datasets if d.role != "test"]
        if self.study.virtual != "design" or self.canvas == "shared" or not trainable:
            return self.virtual()
        if self._train_canvas is None:
            from vcprep.camera import design_virtual_camera

            st = self.study
            self._train_canvas = design_virtual_camera([self.nominal_camera(d) for d in trainable], st.pan_range,
                                                       st.tilt_range, name="study-virtual", above=st.above,
                                                       extent=st.extent).camera
        return self._train_canvas

    def vp_rule(self, ds: Dataset):
        """The rule of ``ds``'s estimated VPs (:class:`~vcprep.vp.VPRule`): searched and
        accepted only within the pose range the virtual camera is designed to hold (a pose outside it
        would push the image out of the virtual frame), no smoothing, sequences by file name (by
        folder for a label format whose ids name the drive: IDD). The stores record it, so ``vctrain
        predict`` estimates a study model's VPs with it (``--vp-sequences`` where a test set's differs)."""
        from vcprep.vp import VPRule

        drives = get_label_format(ds.label_format).drive_in_id
        return VPRule(self.study.pan_range, self.study.tilt_range, sequences="folder" if drives else "name")

    def scale(self) -> float:
        w, h = self.training_virtual().size
        if self.study.store_width and not self.study.store_pixels:
            return self.study.store_width / w
        return math.sqrt((self.study.store_pixels or DEFAULT_STORE_PIXELS) / (w * h))
