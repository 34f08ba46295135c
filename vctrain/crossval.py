"""Leave-one-dataset-out cross-camera study (paper Tables 4 and 7).

Given N named datasets, each taken with its own camera, train on N-1 and test on the held-out
one, for every held-out dataset and every *condition*:

==========  ==========================================================================
resize      the baseline: original images simply resized to the working size
between     virtual camera, each dataset's average pose (between-camera correction)
within      virtual camera, each image's pose from its ESTIMATED road VP (within-camera)
within-gt   as within, with the GIVEN VPs of the study file (where every dataset has them)
zero        as within, uncovered virtual pixels zero-padded instead of projective completion
==========  ==========================================================================

Everything runs through the real tools: stores are built with :func:`vcprep.build.warp_dataset`
(one per dataset, split and geometry, shared by all folds), models with :func:`vctrain.train.fit`,
and the held-out test images are predicted in the model's own domain and scored in their ORIGINAL
camera (back-projected probabilities, threshold 0.5) against their original labels: road IoU =
ΣTP / Σ(TP+FP+FN) over the held-out test images, ignore pixels excluded.

Estimated VPs (``within``, ``zero``) are searched for and accepted only inside the pose range the
virtual camera is designed to hold (``pan_range``, ``tilt_range`` of the study; rejected images fall
back to the mean accepted VP, see :mod:`vcprep.vanishing_point`).

Nothing is tuned on the held-out camera: the checkpoint kept is the best on a validation share of
the TRAINING datasets. The virtual camera is designed from all the study's cameras (as in the
paper, whose virtual camera covers all five), which uses the held-out camera's calibration but
none of its images.

Layout under OUT: ``stores/<dataset>/<split>/<geometry>/`` (vcprep stores), ``vps/<dataset>-<split>.csv``
(the estimated VPs), ``runs/<heldout>/<condition>/`` (checkpoint, training log, ``result.json``),
``results.jsonl``, ``table.md``, ``table.csv``, ``summary.json``. A run whose ``result.json`` exists
is not redone, so an interrupted study resumes where it stopped; a run finished with other
settings (training, virtual camera, datasets) is redone.
"""
from __future__ import annotations

import hashlib
import json
import re
import time
from dataclasses import astuple, dataclass, field, fields
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from vcprep.build import ItemPose, Job, list_dataset, warp_dataset
from vcprep.camera import Camera, load_camera
from vcprep.errors import InputError
from vcprep.imageio import image_size_from_header, read_image, read_text, write_bytes_atomic
from vcprep.labels import decode_label, get_label_format
from vcprep.store import Store

__all__ = ["CONDITIONS", "GEOMETRIES", "Split", "Dataset", "Study", "load_study", "run_study", "format_table",
           "summary_of"]

# geometry name -> (VP source, completion); one store per dataset, split and geometry
GEOMETRIES: dict[str, tuple[str, str]] = {
    "between": ("none", "projective"),
    "within": ("estimate", "projective"),
    "within-gt": ("given", "projective"),
    "zero": ("estimate", "zero"),
}
# condition -> (geometry of its stores, training baseline)
CONDITIONS: dict[str, tuple[str, str]] = {
    "resize": ("between", "resize"),  # the resize baseline reads the original images the store records
    "between": ("between", "none"),
    "within": ("within", "none"),
    "within-gt": ("within-gt", "none"),
    "zero": ("zero", "none"),
}
# the study file's `train:` section may set these TrainConfig fields
TRAIN_KEYS = ("epochs", "arch", "base_width", "batch_size", "lr", "momentum", "weight_decay", "schedule", "seed",
              "val_fraction", "class_weights", "hflip", "greyscale", "device", "workers", "max_steps")
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


@dataclass(frozen=True)
class Split:
    images: Path
    labels: Path
    vps: Path | None = None


@dataclass(frozen=True)
class Dataset:
    name: str
    camera: str
    label_format: str
    train: Split
    test: Split


@dataclass
class Study:
    """A parsed study file (schema in the README, section 'Cross-camera study')."""

    path: Path
    datasets: list[Dataset]
    conditions: list[str] = field(default_factory=lambda: list(CONDITIONS))
    virtual: str = "design"         # 'design' (from the datasets' cameras), a preset or a camera file
    pan_range: float = 10.0         # pose variation the designed virtual camera must hold (degrees)
    tilt_range: float = 5.0
    store_width: int = 320          # working width (px) of the virtual stores; resize uses the same size
    train: dict[str, Any] = field(default_factory=dict)  # TrainConfig overrides

    def dataset(self, name: str) -> Dataset:
        for d in self.datasets:
            if d.name == name:
                return d
        raise InputError(f"no dataset named '{name}'", self.path, f"use one of {', '.join(d.name for d in self.datasets)}")


# -- the study file ------------------------------------------------------------------------------
def _mapping(v: Any, what: str, path: Path) -> dict:
    if not isinstance(v, dict):
        raise InputError(f"{what} must be a mapping", path, "see the study schema in the README")
    return v


def _keys(d: dict, allowed: Sequence[str], required: Sequence[str], what: str, path: Path) -> None:
    unknown = sorted(set(map(str, d)) - set(allowed))
    if unknown:
        raise InputError(f"unknown key '{unknown[0]}' in {what}", path, f"allowed keys: {', '.join(allowed)}")
    for k in required:
        if k not in d:
            raise InputError(f"missing key '{k}' in {what}", path, "see the study schema in the README")


def _split(d: Any, what: str, path: Path) -> Split:
    d = _mapping(d, what, path)
    _keys(d, ("images", "labels", "vps"), ("images", "labels"), what, path)
    base = path.parent

    def p(key: str) -> Path:
        v = d[key]
        if not isinstance(v, str) or not v:
            raise InputError(f"'{key}' in {what} must be a path", path, "write a folder path (relative to the study file)")
        q = base / v
        if not q.exists():
            raise InputError(f"'{key}' of {what} not found: {q}", path, "check the path (relative to the study file)")
        return q

    return Split(p("images"), p("labels"), p("vps") if d.get("vps") is not None else None)


def load_study(path: str | Path) -> Study:
    """Read and check a study YAML file; paths in it are relative to the file."""
    import yaml

    path = Path(path)
    text = read_text(path, "study file", "give the study YAML file")
    try:
        d = yaml.safe_load(text)
    except yaml.YAMLError:
        raise InputError("not valid YAML", path, "fix the syntax; see the study schema in the README") from None
    d = _mapping(d, "the study file", path)
    _keys(d, ("datasets", "conditions", "virtual", "pan_range", "tilt_range", "store_width", "train"), ("datasets",),
          "the study file", path)
    raw = d["datasets"]
    if not isinstance(raw, list) or len(raw) < 2:
        raise InputError("'datasets' must list at least two datasets", path, "leave-one-out needs N >= 2 datasets")
    datasets: list[Dataset] = []
    for i, r in enumerate(raw):
        r = _mapping(r, f"dataset #{i + 1}", path)
        _keys(r, ("name", "camera", "label_format", "train", "test"), ("name", "camera", "label_format", "train"),
              f"dataset #{i + 1}", path)
        name = r["name"]
        if not isinstance(name, str) or not _NAME.match(name):
            raise InputError(f"dataset #{i + 1} has a bad name {name!r}", path, "use letters, digits, '_', '-', '.'")
        if any(x.name == name for x in datasets):
            raise InputError(f"two datasets named '{name}'", path, "give each dataset its own name")
        try:
            get_label_format(str(r["label_format"]))
        except InputError as e:
            raise InputError(f"dataset '{name}': {e.problem}", path, e.fix) from None
        cam = str(r["camera"])
        if not cam.isidentifier() or (path.parent / cam).exists():
            cam = str(path.parent / cam)
        train = _split(r["train"], f"dataset '{name}' train", path)
        test = _split(r["test"], f"dataset '{name}' test", path) if r.get("test") is not None else train
        datasets.append(Dataset(name, cam, str(r["label_format"]), train, test))
    study = Study(path, datasets)
    if "conditions" in d:
        conds = d["conditions"]
        if not isinstance(conds, list) or not conds:
            raise InputError("'conditions' must be a list", path, f"choose from {', '.join(CONDITIONS)}")
        study.conditions = check_conditions([str(c) for c in conds], path)
    if "virtual" in d:
        study.virtual = str(d["virtual"])
        if study.virtual != "design" and (path.parent / study.virtual).exists():
            study.virtual = str(path.parent / study.virtual)
    for key in ("pan_range", "tilt_range"):
        if key in d:
            v = d[key]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v < 60:
                raise InputError(f"'{key}' must be degrees in [0, 60), got {v!r}", path, "e.g. pan_range: 10")
            setattr(study, key, float(v))
    if "store_width" in d:
        v = d["store_width"]
        if isinstance(v, bool) or not isinstance(v, int) or not 64 <= v <= 8192:
            raise InputError(f"'store_width' must be a whole number of pixels in 64..8192, got {v!r}", path,
                             "e.g. store_width: 320")
        study.store_width = v
    if "train" in d:
        t = _mapping(d["train"], "'train'", path)
        _keys(t, TRAIN_KEYS, (), "'train'", path)
        study.train = dict(t)
    return study


def check_conditions(conds: Sequence[str], file: Path | None = None) -> list[str]:
    for c in conds:
        if c not in CONDITIONS:
            raise InputError(f"unknown condition '{c}'", file, f"choose from {', '.join(CONDITIONS)}")
    return list(dict.fromkeys(conds))


# -- stores --------------------------------------------------------------------------------------
class _Builder:
    """Builds (or finds up to date) the stores a study needs, each once."""

    def __init__(self, study: Study, out: Path, progress: bool, jobs: int, say: Callable[[str], None]):
        self.study, self.out, self.progress, self.jobs, self.say = study, out, progress, jobs, say
        self._cams: dict[str, Camera] = {}
        self._items: dict[tuple[str, str], list[Job]] = {}
        self._vps: dict[tuple[str, str], dict[str, ItemPose]] = {}
        self._virtual: Camera | None = None

    def split(self, ds: Dataset, split: str) -> Split:
        return ds.train if split == "train" else ds.test

    def items(self, ds: Dataset, split: str) -> list[Job]:
        key = (ds.name, split)
        if key not in self._items:
            s = self.split(ds, split)
            self._items[key] = list_dataset(s.images, s.labels, get_label_format(ds.label_format))
        return self._items[key]

    def camera(self, ds: Dataset) -> Camera:
        if ds.name not in self._cams:
            size = None
            first = self.items(ds, "train")[0].image
            if Path(ds.camera).suffix.lower() in (".txt", ".json"):
                size = image_size_from_header(first.read_bytes()[:65536])
            self._cams[ds.name] = load_camera(ds.camera, image_size=size)
        return self._cams[ds.name]

    def virtual(self) -> Camera:
        if self._virtual is None:
            if self.study.virtual == "design":
                from vcprep.virtual_camera import design_virtual_camera

                design = design_virtual_camera([self.camera(d) for d in self.study.datasets], self.study.pan_range,
                                               self.study.tilt_range, name="study-virtual")
                self._virtual = design.camera
            else:
                self._virtual = load_camera(self.study.virtual)
        return self._virtual

    def scale(self) -> float:
        return self.study.store_width / self.virtual().size[0]

    def has_given_vps(self, ds: Dataset, split: str) -> bool:
        return self.split(ds, split).vps is not None

    def poses(self, ds: Dataset, split: str, source: str) -> dict[str, ItemPose] | None:
        if source == "none":
            return None
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

    def store(self, ds: Dataset, split: str, geometry: str) -> Path:
        """The store of ``ds``'s ``split`` in ``geometry`` (built or brought up to date)."""
        source, completion = GEOMETRIES[geometry]
        root = self.out / "stores" / ds.name / split / geometry
        jobs = self.items(ds, split)
        poses = self.poses(ds, split, source)
        warp_dataset(jobs, self.camera(ds), self.virtual(), self.scale(), root, get_label_format(ds.label_format),
                     progress=self.progress, poses=poses, completion=completion, workers=self.jobs)
        return root


# -- one run -------------------------------------------------------------------------------------
def _train_config(study: Study, stores: list[Path], out: Path, baseline: str, size: tuple[int, int],
                  progress: bool, overrides: dict[str, Any]):
    from .train import TrainConfig

    cfg = TrainConfig(stores=[str(s) for s in stores], out=str(out / "model.pt"), baseline=baseline, size=size,
                      progress=progress)
    names = {f.name for f in fields(TrainConfig)}
    for k, v in {**study.train, **overrides}.items():
        if k in names and v is not None:
            setattr(cfg, k, v)
    return cfg


def evaluate_heldout(checkpoint: Path, store_dir: Path, progress: bool = False) -> dict[str, Any]:
    """Road metrics of ``checkpoint`` on every labelled item of a held-out test store, scored in the
    item's ORIGINAL camera against its original label (P(road) >= 0.5)."""
    from tqdm import tqdm

    from .metrics import RoadMetrics
    from .predict import Predictor

    predictor = Predictor(checkpoint, device="cpu")
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


def _atomic_json(path: Path, obj: Any) -> None:
    write_bytes_atomic(path, (json.dumps(obj, indent=1, sort_keys=True) + "\n").encode())


def run_study(study: Study, out: str | Path, conditions: Sequence[str] | None = None,
              heldout: Sequence[str] | None = None, progress: bool = True, jobs: int = 1,
              train_overrides: dict[str, Any] | None = None,
              say: Callable[[str], None] = lambda s: None) -> list[dict[str, Any]]:
    """Run (or resume) every (held-out dataset, condition) of ``study`` into ``out``; returns all
    result rows (finished earlier or now), in table order. Writes the tables (:func:`write_tables`)."""
    from .train import fit

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    conditions = check_conditions(conditions or study.conditions)
    held = [study.dataset(h).name for h in heldout] if heldout else [d.name for d in study.datasets]
    overrides = dict(train_overrides or {})
    b = _Builder(study, out, progress, jobs, say)
    virt = b.virtual()
    _atomic_json(out / "study.json", {"study": str(study.path), "virtual": virt.to_dict(), "scale": b.scale(),
                                      "conditions": conditions, "datasets": [d.name for d in study.datasets],
                                      "train": {**study.train, **overrides}})
    # what a run's result depends on (besides its held-out dataset and condition): a finished run
    # with other settings is redone, never silently reused
    settings = {"virtual": virt.to_dict(), "scale": b.scale(), "pan_range": study.pan_range,
                "tilt_range": study.tilt_range, "train": {**study.train, **overrides},
                "datasets": [[d.name, d.camera, d.label_format, *(str(x) for x in (*astuple(d.train), *astuple(d.test)))]
                             for d in study.datasets]}
    settings_sha = hashlib.sha256(json.dumps(settings, sort_keys=True, default=str).encode()).hexdigest()[:16]
    plan = [(h, c) for h in held for c in conditions]
    rows: list[dict[str, Any]] = []
    for k, (h, c) in enumerate(plan, 1):
        run_dir = out / "runs" / h / c
        done = run_dir / "result.json"
        if done.exists():
            prev = json.loads(done.read_text())
            if prev.get("settings_sha") == settings_sha:
                rows.append(prev)
                say(f"[{k}/{len(plan)}] held out {h}, {c}: done earlier (IoU {prev['iou']:.3f})")
                continue
            say(f"[{k}/{len(plan)}] held out {h}, {c}: the study's settings changed since it ran; redoing it")
            for old in (done, run_dir / "model.pt", run_dir / "model.last.pt", run_dir / "model.log.jsonl"):
                old.unlink(missing_ok=True)
        geometry, baseline = CONDITIONS[c]
        train_sets = [d for d in study.datasets if d.name != h]
        test_set = study.dataset(h)
        if GEOMETRIES[geometry][0] == "given":
            missing = [d.name for d in train_sets if not b.has_given_vps(d, "train")]
            if not b.has_given_vps(test_set, "test"):
                missing.append(test_set.name)
            if missing:
                say(f"[{k}/{len(plan)}] held out {h}, {c}: skipped (no given VPs for {', '.join(missing)})")
                continue
        say(f"[{k}/{len(plan)}] held out {h}, {c}: stores")
        stores = [b.store(d, "train", geometry) for d in train_sets]
        test_store = b.store(test_set, "test", geometry)
        size = Store.open(stores[0]).store_size
        run_dir.mkdir(parents=True, exist_ok=True)
        cfg = _train_config(study, stores, run_dir, baseline, size, progress, overrides)
        say(f"[{k}/{len(plan)}] held out {h}, {c}: training on {', '.join(d.name for d in train_sets)} "
            f"({cfg.epochs} epochs at {size[0]}x{size[1]})")
        t0 = time.perf_counter()
        summary = fit(cfg)
        t_train = time.perf_counter() - t0
        metrics = evaluate_heldout(Path(cfg.out), test_store, progress)
        row = {"heldout": h, "condition": c, **metrics, "train_datasets": [d.name for d in train_sets],
               "train_items": summary["data"]["train_items"], "val_items": summary["data"]["val_items"],
               "best_epoch": summary["best_epoch"], "best_val_iou": summary["best_val_iou"], "epochs": cfg.epochs,
               "input_size": list(size), "train_seconds": round(t_train, 1),
               "total_seconds": round(time.perf_counter() - t0, 1), "settings_sha": settings_sha}
        _atomic_json(done, row)
        rows.append(row)
        say(f"[{k}/{len(plan)}] held out {h}, {c}: road IoU {row['iou']:.3f} ({row['total_seconds']:.0f} s)")
    write_tables(out, rows, held, conditions)
    return rows


# -- tables --------------------------------------------------------------------------------------
def summary_of(rows: Sequence[dict[str, Any]], conditions: Sequence[str]) -> dict[str, float]:
    """Condition -> mean road IoU over the held-out datasets that have a result for it."""
    out = {}
    for c in conditions:
        v = [r["iou"] for r in rows if r["condition"] == c]
        if v:
            out[c] = float(np.mean(v))
    return out


def format_table(rows: Sequence[dict[str, Any]], heldout: Sequence[str], conditions: Sequence[str],
                 fmt: str = "md") -> str:
    """Rows: held-out dataset + mean; columns: conditions; cells: road IoU x 100 ('-' = no run)."""
    cell = {(r["heldout"], r["condition"]): r["iou"] for r in rows}
    mean = summary_of(rows, conditions)
    body = [[h] + [f"{100 * cell[h, c]:.1f}" if (h, c) in cell else "-" for c in conditions] for h in heldout]
    body.append(["mean"] + [f"{100 * mean[c]:.1f}" if c in mean else "-" for c in conditions])
    header = ["held out"] + list(conditions)
    if fmt == "csv":
        return "\n".join(",".join(r) for r in [header] + body) + "\n"
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in body]
    return "\n".join(lines) + "\n"


def write_tables(out: Path, rows: Sequence[dict[str, Any]], heldout: Sequence[str], conditions: Sequence[str]) -> None:
    write_bytes_atomic(out / "results.jsonl", "".join(json.dumps(r, sort_keys=True) + "\n" for r in rows).encode())
    write_bytes_atomic(out / "table.md", ("Road IoU (%) on the held-out dataset's test images, scored in its own "
                                          "camera.\n\n" + format_table(rows, heldout, conditions)).encode())
    write_bytes_atomic(out / "table.csv", format_table(rows, heldout, conditions, "csv").encode())
    _atomic_json(out / "summary.json", summary_of(rows, conditions))
