"""What a study's finished work depends on, as short hashes (one way of hashing for all of it).

A model, result, adapted model or camera estimate is redone when its key changes and never when
it does not: an interrupted study resumes where it stopped, and a run finished with other
settings (effective training config, virtual camera, datasets) is redone.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

from vcprep.camera import PRESET_PREFIX, Camera

from ..training.config import ADAPT_EPOCHS, ADAPT_LR_FACTOR, AdaptSettings
from .hashing import settings_sha
from .spec import ADAPT_COMBINE, CONDITION_TRAIN, Dataset

if TYPE_CHECKING:
    from .resolve import Resolution
    from .runs import Run

__all__ = ["adapt_settings", "Keys", "TEST_WARP"]


# how a test split is warped and scored: as `vctrain predict` does the same frames for the model (its VP rule,
# own vehicle, rectangle extended for every frame at its pose; frame pixels beyond the training rectangle by
# the rays from the road VP: `--beyond hybrid`, issue 60; "as-predict-1": the network's own values there); a
# result scored by an earlier rule is scored again
# "as-predict-2": before the working size followed the frames' pixel density (Predictor.density_scale, issue 73)
TEST_WARP = "as-predict-3"


def _median_test_canvas(res: "Resolution", d: Dataset) -> dict[str, Any]:
    """``extent: median``'s test rectangle as the keys knew it before test splits were warped as
    ``vctrain predict`` warps them (the training rectangle extended for the camera at every pose of
    the ranges): kept in the keys so that the models of such a study are found, not trained again."""
    from vcprep.camera import extend_canvas

    base, st = res.training_virtual(), res.study
    if st.virtual != "design":
        return base.to_dict()
    cam = res.nominal_camera(d)
    views = [(cam, cam.pan + a * st.pan_range, cam.tilt + b * st.tilt_range) for a in (-1, 0, 1) for b in (-1, 0, 1)]
    return extend_canvas(base, views).to_dict()


def adapt_settings(condition: str = "adapt") -> dict[str, Any]:
    """What an adapted model depends on besides the study's settings (vctrain.adapt's defaults)."""
    default = AdaptSettings()
    return {"epochs": ADAPT_EPOCHS, "lr_factor": ADAPT_LR_FACTOR, "lo": default.lo, "hi": default.hi,
            "combine": ADAPT_COMBINE[condition]}


class Keys:
    """The keys of a study's models and results.

    * ``full``: every setting of the study (``settings_sha`` of the results of condition prior,
      the base of the adapted models' keys, and of every row written before the split below,
      still accepted);
    * ``model(run)``: the training settings, the training stores' virtual camera and scale, the
      pose ranges and the run's training datasets (their cameras, labels, splits, own vehicle,
      estimates) -- so a test-only dataset added or changed retrains nothing (canvas: footprint;
      with ``canvas: shared`` its camera shapes the one virtual camera, which is in the key);
    * ``result(run, ds)``: the model's key, the test store's (``ds``'s camera, canvas, splits) and
      the rule test splits are warped by (:data:`TEST_WARP`);
    * ``adapted(run, ds)``: the study's settings, the adaptation's and the images adapted to."""

    def __init__(self, res: "Resolution", virt: Camera, training: dict[str, Any]):
        study = res.study
        self.res = res
        self.common = {"virtual": virt.to_dict(), "scale": res.scale(), "pan_range": study.pan_range,
                       "tilt_range": study.tilt_range, "train": training,
                       "resize_size": "source aspect, store pixels"}
        self.entry = {d.name: self._entry(d) for d in study.datasets}
        settings = {**self.common, "datasets": [self.entry[d.name]["dataset"] for d in study.datasets]}
        canvases = {d.name: self.entry[d.name]["canvas"] for d in study.datasets}
        if study.extent != "max":
            settings["extent"] = study.extent
            canvases.update({d.name + ":test": self.entry[d.name]["test_canvas"] for d in study.datasets})
        if any(c != virt.to_dict() for c in canvases.values()):  # (every store in the shared rectangle: as before)
            settings["canvas"] = canvases
        ego = {n: e["ego_rows"] for n, e in self.entry.items() if e.get("ego_rows")}
        if ego:  # only when a camera sees its own vehicle: the settings of studies without one are as before
            settings["ego_rows"] = ego
        if res.estimated:  # a changed estimate redoes what depends on it
            settings["cameras_estimated"] = {k: v["camera"] for k, v in res.estimated.items()}
        self.full = settings_sha(settings)

    def _entry(self, d: Dataset) -> dict[str, Any]:
        res = self.res
        # (a preset is written preset:NAME since the one naming rule; bare, as before, in the settings)
        e = {"dataset": [d.name, d.role, d.camera.removeprefix(PRESET_PREFIX), d.label_format, repr(d.train),
                         repr(d.test)], "canvas": res.training_virtual().to_dict(),
             **({"test_canvas": _median_test_canvas(res, d)} if res.study.extent != "max" else {}),
             "camera_params": res.nominal_camera(d).to_dict()}  # (the file's contents, not only its name)
        cam = res.camera(d)
        if isinstance(cam, Camera) and cam.ego_rows:
            e["ego_rows"] = cam.ego_rows
        if d.name in res.estimated:
            e["camera_estimated"] = res.estimated[d.name]["camera"]
        return e

    def model(self, run: "Run") -> str:
        own = CONDITION_TRAIN.get(run.condition)  # (a condition's own settings: only where it has some)
        return settings_sha({**self.common, "train_datasets": [self.entry[d.name] for d in run.train],
                             **({"condition_train": own} if own else {})})

    def result(self, run: "Run", ds: Dataset) -> str:
        return settings_sha({"model": self.model(run), "test": self.entry[ds.name], "test_warp": TEST_WARP})

    def adapted(self, run: "Run", ds: Dataset) -> str:
        return settings_sha({"study": self.full, "adapt": adapt_settings(run.condition),
                             "target": self.res.adapt_split(ds), "unlabelled": repr(ds.unlabelled)})
