"""The stores a study needs, each built once (or found up to date) with :func:`vcprep.store.build.warp_dataset`:
``OUT/stores/<dataset>/<split>/<geometry>/``, one per dataset, split and geometry, shared by all
runs, and the road VPs they are warped with (``OUT/vps/<dataset>-<split>.csv``).

Estimated VPs (``within``, ``zero``) are searched for and accepted only inside the pose range the
virtual camera is designed to hold (``pan_range``, ``tilt_range`` of the study; rejected images fall
back to the mean accepted VP, see :mod:`vcprep.vp`); the stores record that rule, so
``vctrain predict`` estimates a study model's VPs with it. A test split's stores are warped as
``vctrain predict`` warps its frames (:meth:`Stores.warp_settings`).
"""
from __future__ import annotations

import shutil
from pathlib import Path
from typing import Sequence

from vcprep.store import WarpSettings, warp_dataset
from vcprep.camera import Camera, FrameCameras
from vcprep.errors import InputError
from vcprep.io import image_size
from vcprep.labels import get_label_format
from vcprep.store import Store
from vcprep.vp import ItemPose, frame_poses

from .resolve import Resolution
from .spec import GEOMETRIES, Dataset

__all__ = ["Stores"]


class Stores:
    """The stores of a study whose files ``res`` resolves (``jobs`` worker processes; ``progress`` bars)."""

    def __init__(self, res: Resolution, progress: bool = False, jobs: int = 1):
        self.res, self.progress, self.jobs = res, progress, jobs
        self.out, self.say = res.out, res.say
        self._vps: dict[tuple[str, str, str], dict[str, ItemPose] | None] = {}

    def resize_size(self, datasets: Sequence[Dataset], store_size: tuple[int, int]) -> tuple[int, int]:
        """The resize baseline's working size: the virtual store's pixel count at the aspect of
        the first training dataset's images (same pixel budget, no squashing of the source)."""
        from ..training.parts import resize_working_size

        return resize_working_size(store_size, image_size(self.res.items(datasets[0], "train")[0].image))

    def has_given_vps(self, ds: Dataset, split: str) -> bool:
        return self.res.split(ds, split).vps is not None

    def poses(self, ds: Dataset, split: str, source: str) -> dict[str, ItemPose] | None:
        """The split's frames' poses (:func:`vcprep.vp.frame_poses`, as ``vctrain predict``
        finds them): ``source`` 'none', 'estimate' (:meth:`Resolution.vp_rule`, over the split's frames
        together; written to ``vps/<dataset>-<split>.csv``) or 'given' (the split's ``vps`` file)."""
        if source == "none" or (source == "estimate" and isinstance(self.res.camera(ds), FrameCameras)):
            return None  # (per-frame calibration: every frame's exact pose, nothing to estimate)
        from vcprep.vp import write_vp_csv

        key = (ds.name, split, source)
        if key not in self._vps:
            jobs = self.res.items(ds, split)
            if source == "given":
                vps = self.res.split(ds, split).vps
                if vps is None:
                    raise InputError(f"dataset '{ds.name}' {split} has no 'vps' file", self.res.study.path,
                                     "add 'vps:' to the split, or drop the within-gt condition")
                self._vps[key] = frame_poses(jobs, self.res.camera(ds), str(vps))[0]
            else:
                self.say(f"estimating road VPs of {ds.name}/{split} ({len(jobs)} images)")
                self._vps[key], found = frame_poses(jobs, self.res.camera(ds), "estimate", self.res.vp_rule(ds))
                (self.out / "vps").mkdir(parents=True, exist_ok=True)
                write_vp_csv(self.out / "vps" / f"{ds.name}-{split}.csv", [j.id for j in jobs], found)
        return self._vps[key]

    def _drop_if_other_virtual(self, root: Path, virtual: Camera) -> None:
        """The study's stores are its own derived data: one built for another virtual camera or
        scale (the study's datasets or settings changed since) is removed, to be built afresh."""
        if not (root / "store.json").exists():
            return
        from vcprep.store import store_params

        want = store_params(virtual, self.res.scale())
        have = Store.open(root).params
        if any(have.get(k) != want[k] for k in ("virtual", "scale", "store_size")):
            self.say(f"{root.relative_to(self.out)}: built for another virtual camera or scale; building it afresh")
            shutil.rmtree(root)

    def warp_settings(self, ds: Dataset, split: str, geometry: str, fixed: bool = False) -> WarpSettings:
        """How the store of ``ds``'s ``split`` in ``geometry`` is built: the dataset's camera into
        the study's virtual camera and scale, with the geometry's poses and completion. A test
        split is warped as ``vctrain predict`` warps the same frames for a model of the study (the
        same poses, own vehicle and rectangle, so the study's number is the number a user gets): its
        labels never shape the completion (they are scored in the original camera), and the
        training rectangle is extended to hold every frame at its pose
        (:func:`vctrain.predict.frames_canvas`); ``fixed``: the training rectangle as it is (the
        geometric prior is an image of it: ``vctrain predict --prior`` warps into it)."""
        source, completion = GEOMETRIES[geometry]
        poses = self.poses(ds, split, source)
        virtual = self.res.training_virtual()
        if split == "test" and not fixed:
            from ..predict.road import frames_canvas

            virtual = frames_canvas(virtual, self.res.items(ds, split), self.res.camera(ds), poses)
        return WarpSettings(camera=self.res.camera(ds), virtual=virtual, scale=self.res.scale(),
                            label_format=get_label_format(ds.label_format), completion=completion, poses=poses,
                            unlabelled_completion=split == "test", workers=self.jobs, progress=self.progress)

    def store(self, ds: Dataset, split: str, geometry: str, fixed: bool = False) -> Path:
        """The store of ``ds``'s ``split`` in ``geometry`` (built or brought up to date); ``fixed``
        (a test split for the prior): in the training rectangle, ``<geometry>-fixed/`` where the
        test split's own rectangle differs from it."""
        root = self.out / "stores" / ds.name / split / geometry
        jobs = self.res.items(ds, split)
        settings = self.warp_settings(ds, split, geometry, fixed)
        if fixed and settings.virtual != self.warp_settings(ds, split, geometry).virtual:
            root = root.with_name(f"{geometry}-fixed")
        self._drop_if_other_virtual(root, settings.virtual)
        warp_dataset(jobs, root, settings)
        return root

