"""The cross-camera study file (``vctrain crossval``): its schema, checked as it is read.

A study names datasets, each taken with its own camera, and the *conditions* to compare. A
dataset's ``role`` says what it is for (:data:`ROLES`): ``both`` (the default; held out in turn,
trained on otherwise), ``train`` (only trained on) or ``test`` (never trained on, e.g. a new
camera's labelled frames: "will my model work on camera X?"). Its ``camera:`` is a preset, a
camera file, ``estimate`` (estimated from its own frames) or a folder of per-frame calibration
files; ``ego:`` its own-vehicle rows. Splits (``train:``, ``test:``, ``unlabelled:``) name image and
label folders, optional given VPs and include/exclude globs on file stems.

Conditions (:data:`CONDITIONS`; each names the geometry of its stores, :data:`GEOMETRIES`):

==========  ==========================================================================
resize      the baseline: original images simply resized to the working size
between     virtual camera, each dataset's average pose (between-camera correction)
within      virtual camera, each image's pose from its ESTIMATED road VP (within-camera)
within-gt   as within, with the GIVEN VPs of the study file (where every dataset has them)
zero        as within, uncovered virtual pixels zero-padded instead of projective completion
prior       no training: the geometric prior p_g of the training datasets' ``within`` stores
            (their mean road label in the virtual camera), segmentation p_g >= 0.5 (Table 5
            "Geo-Prior"); ``runs/<run>/prior/prior.npy`` (+ its description) is the prior
adapt       the ``within`` model (the within run's own checkpoint, never a second training)
            fine-tuned by :func:`vctrain.adapt.adapt` on the evaluated dataset's UNLABELLED images
            (its ``unlabelled:`` split, else its test images without their labels) with
            surrogate labels from the training datasets' prior; one adapted model per evaluated
            dataset (``runs/<heldout>/adapt/`` or ``runs/_all/adapt/<dataset>/``); the
            surrogate labels are the prior's tri-mask alone (paper §4.5)
adapt-fuse  as adapt, the surrogate labels from the prior FUSED with the within model's own
            prediction on each image (``vctrain adapt --combine fuse``, GeoSeg-like: a
            confident network decides where the prior is unsure, and vice versa)
adapt-self  as adapt, the surrogate labels from the within model's own prediction alone
            (``--combine self``: self-training, the control for what the prior adds)
average     no training of its own: P(road) = the mean of the ``within`` and ``resize`` models'
            probabilities (those runs' own checkpoints, trained once and shared with those
            conditions), each in the evaluated camera's own pixels
mixed       ONE network trained on both views of every training frame (its ``within`` store
            item and its original image resized as ``resize`` does; batches of one view, the
            steps of one view's run); P(road) = the mean of its two views' probabilities in
            the evaluated camera's own pixels (issue 53's mixed-view candidate)
resize-rays resize plus two input channels, each pixel's signed ray angles beside and below
            its frame's own estimated road VP from the camera file's focal length (CAM-Convs;
            zero weight at the start in the first convolution)
==========  ==========================================================================

A study's default conditions are the first five (:data:`DEFAULT_CONDITIONS`); ``prior``,
``adapt``, ``adapt-fuse``, ``adapt-self``, ``average``, ``resize-vp``, ``mixed`` and ``resize-rays`` run when asked for (study ``conditions:`` or ``--conditions``).
Training settings the study's ``train:`` does not give are :class:`vctrain.training.TrainConfig`'s
defaults. How a study runs: :mod:`vctrain.study.execute`; its tables: :mod:`vctrain.report`.
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass, field, fields
from fnmatch import fnmatchcase
from pathlib import Path
from typing import Any, Sequence

from vcprep.camera import (DESIGN_ABOVE, DESIGN_PAN_RANGE, DESIGN_TILT_RANGE, PRESET_PREFIX, PRESETS, STORE_PIXELS,
                           preset_name)
from vcprep.errors import InputError, one_of
from vcprep.io import read_text
from vcprep.labels import get_label_format

from ..training.config import TRAIN_WINDOW, TrainConfig

__all__ = ["CONDITIONS", "CONDITION_TRAIN", "DEFAULT_CONDITIONS", "DEFAULT_STORE_PIXELS", "DEFAULT_ABOVE", "DEFAULT_TRAIN", "CANVASES",
           "DEFAULT_CANVAS", "GEOMETRIES", "ROLES", "ADAPT_COMBINE", "RUN_KEYS", "TRAIN_KEYS", "Split", "Dataset",
           "Study", "load_study", "check_conditions", "evaluated_datasets"]

# geometry name -> (VP source, completion); one store per dataset, split and geometry
GEOMETRIES: dict[str, tuple[str, str]] = {
    "between": ("none", "projective"),
    "within": ("estimate", "projective"),
    "within-gt": ("given", "projective"),
    "zero": ("estimate", "zero"),
}
# condition -> (geometry of its stores, how its predictor comes about): a `vctrain fit` baseline
# ('none': virtual camera, 'resize'), 'prior' (no training: the training stores' prior p_g) or
# 'adapt' (the within run's model adapted to the evaluated dataset's unlabelled images)
CONDITIONS: dict[str, tuple[str, str]] = {
    "resize": ("between", "resize"),  # the resize baseline reads the original images the store records
    "between": ("between", "none"),
    "within": ("within", "none"),
    "within-gt": ("within-gt", "none"),
    "zero": ("zero", "none"),
    "prior": ("within", "prior"),
    "adapt": ("within", "adapt"),
    "adapt-fuse": ("within", "adapt"),
    "adapt-self": ("within", "adapt"),
    "average": ("within", "average"),  # scored on the within test stores; resize reads their records' sources
    "resize-vp": ("within", "resize"),  # resize + the VP channel: each frame's own (within-estimated) road VP
    "mixed": ("within", "mixed"),  # one network on both views (within items + resized sources), the two averaged
    "resize-rays": ("within", "resize"),  # resize + each pixel's ray angles from its VP and focal length
}
# condition -> the training settings it sets on top of the study's (and in its models' keys)
CONDITION_TRAIN: dict[str, dict[str, Any]] = {"resize-vp": {"vp_channel": True}, "resize-rays": {"ray_channels": True}}
# adaptation condition -> how its surrogate labels are made (vctrain.adapt.COMBINE): the prior's
# tri-mask alone (paper §4.5), or the prior fused with the within model's own prediction (GeoSeg-like)
ADAPT_COMBINE = {"adapt": "prior", "adapt-fuse": "fuse", "adapt-self": "self"}
DEFAULT_CONDITIONS = ("resize", "between", "within", "within-gt", "zero")  # a study without 'conditions:'
# The measured best design (benchmarks/archive/other_cameras/real_cameras.py --dev and issue 24's real cameras: 56.7 vs 55.7
# road IoU on four real other cameras, 81.1 vs 75.5 on CamVid's unseen rig, against store_width 320,
# no crop above the horizon and whole-image training): the defaults of a study that sets nothing.
# (one source of truth with `vcprep warp`'s defaults: vcprep.camera.virtual, vctrain.training.config.TRAIN_WINDOW)
DEFAULT_STORE_PIXELS = STORE_PIXELS    # the pixels of 480x360 per virtual store image
DEFAULT_ABOVE = DESIGN_ABOVE           # degrees of the designed virtual camera kept above the horizon
# How the designed virtual camera's rectangle is sized per store (vctrain.study.resolve.Resolution.virtual_for):
# 'shared' -- one rectangle holding every dataset's camera (the paper's rule); 'footprint' -- the same
# virtual camera (focal length, height, level pose, top edge), its rectangle holding only the trainable
# datasets' cameras for their stores, and also the dataset's own camera for a test-only dataset's
# stores; the pixel budget sizes the training rectangle, so a wide or steep test camera no longer
# shrinks the training images (the network, fully convolutional, runs on the larger test rectangle at
# the training's pixels per degree).
# Measured (benchmarks/other_cameras/as_shipped.py, CamVid -> five real other cameras, 3 seeds): 'footprint' gives the
# CamVid content 1.75x the linear resolution of 'shared' at the same budget (the shared rectangle is
# sized by the widest and steepest test cameras, KITTI and LUMS) -- see docs/studies.md for the numbers.
CANVASES = ("shared", "footprint")
DEFAULT_CANVAS = "footprint"
DEFAULT_TRAIN = {"crop": TRAIN_WINDOW}  # full-height training windows of 4/9 of the width (76800 px a step)
# the study file's `train:` section may set any TrainConfig field except these, which the study sets per run
RUN_KEYS = ("stores", "out", "baseline", "images", "labels", "label_format", "size", "val_stores", "resume", "log",
            "progress")
TRAIN_KEYS = tuple(f.name for f in fields(TrainConfig) if f.name not in RUN_KEYS)
# role -> (trained on, evaluated); 'both' = held out in turn (leave one out)
ROLES: dict[str, tuple[bool, bool]] = {"both": (True, True), "train": (True, False), "test": (False, True)}
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


@dataclass(frozen=True)
class Split:
    images: Path
    labels: Path | None         # None: an unlabelled split (adaptation images)
    vps: Path | None = None
    include: tuple[str, ...] = ()  # keep only items whose id (file stem) matches one of these globs (empty: all)
    exclude: tuple[str, ...] = ()  # then drop items whose id matches one of these globs

    def selects(self, item_id: str) -> bool:
        """Whether the item ``item_id`` belongs to this split (globs are case-sensitive, fnmatch)."""
        return ((not self.include or any(fnmatchcase(item_id, g) for g in self.include))
                and not any(fnmatchcase(item_id, g) for g in self.exclude))


@dataclass(frozen=True)
class Dataset:
    name: str
    camera: str
    label_format: str
    train: Split | None      # None for role 'test'
    test: Split | None       # None for role 'train'
    role: str = "both"
    unlabelled: Split | None = None  # images without labels to adapt to (condition adapt; default: test images)
    ego: str | int = "auto"  # own-vehicle rows: 'auto' (found from the labels, vcprep.camera.ego), 'none' or a row count

    @property
    def trained(self) -> bool:
        return ROLES[self.role][0]

    @property
    def evaluated(self) -> bool:
        return ROLES[self.role][1]

    @property
    def first_split(self) -> str:
        """The split whose first image stands for the camera's image size."""
        return "train" if self.train is not None else "test"


@dataclass
class Study:
    """A parsed study file (schema: docs/studies.md, 'The study file')."""

    path: Path
    datasets: list[Dataset]
    conditions: list[str] = field(default_factory=lambda: list(DEFAULT_CONDITIONS))
    virtual: str = "design"         # 'design' (from the datasets' cameras), a preset or a camera file
    pan_range: float = DESIGN_PAN_RANGE  # pose variation the designed virtual camera must hold (degrees)
    tilt_range: float = DESIGN_TILT_RANGE
    store_width: int | None = None   # working width (px) of the virtual stores (unless store_pixels)
    store_pixels: int | None = None  # pixel budget of the virtual stores (wins over store_width); neither
                                     # given: DEFAULT_STORE_PIXELS
    above: float | None = DEFAULT_ABOVE  # designed virtual camera cropped to this many degrees above the horizon
                                     # (None: not cropped)
    canvas: str | None = None        # 'shared': one designed rectangle for every store; 'footprint': the
                                     # training stores hold the trainable datasets' cameras, a test-only
                                     # dataset's stores also its own (CANVASES); None: DEFAULT_CANVAS, or
                                     # 'shared' for conditions prior/adapt (vctrain.study.run_study)
    extent: str = "max"              # the designed rectangle holds every camera ('max') or reaches as far as
                                     # the median camera ('median'; every test split's stores extended to
                                     # hold their own camera: vctrain.study.resolve.Resolution.virtual_for)
    train: dict[str, Any] = field(default_factory=dict)  # TrainConfig overrides

    def dataset(self, name: str) -> Dataset:
        for d in self.datasets:
            if d.name == name:
                return d
        raise InputError(f"no dataset named '{name}'", self.path, one_of(name, [d.name for d in self.datasets]))


# -- the study file ------------------------------------------------------------------------------
def _mapping(v: Any, what: str, path: Path) -> dict:
    if not isinstance(v, dict):
        raise InputError(f"{what} must be a mapping", path, "see the study schema in docs/studies.md")
    return v


def _keys(d: dict, allowed: Sequence[str], required: Sequence[str], what: str, path: Path) -> None:
    unknown = sorted(set(map(str, d)) - set(allowed))
    if unknown:
        raise InputError(f"unknown key '{unknown[0]}' in {what}", path, one_of(unknown[0], allowed, what="allowed keys:"))
    for k in required:
        if k not in d:
            raise InputError(f"missing key '{k}' in {what}", path, "see the study schema in docs/studies.md")


def _globs(v: Any, key: str, what: str, path: Path) -> tuple[str, ...]:
    if v is None:
        return ()
    globs = [v] if isinstance(v, str) else v
    if not isinstance(globs, list) or not globs or not all(isinstance(g, str) and g for g in globs):
        raise InputError(f"'{key}' in {what} must be a glob or a list of globs on file stems", path,
                         f"e.g. {key}: ['0016E5_*', '0006R0_*']")
    return tuple(globs)


def _split(d: Any, what: str, path: Path, labelled: bool = True) -> Split:
    """A split's mapping; ``labelled=False``: images only (an ``unlabelled:`` split)."""
    d = _mapping(d, what, path)
    if labelled:
        _keys(d, ("images", "labels", "vps", "include", "exclude"), ("images", "labels"), what, path)
    else:
        _keys(d, ("images", "include", "exclude"), ("images",), what, path)
    base = path.parent

    def p(key: str) -> Path:
        v = d[key]
        if not isinstance(v, str) or not v:
            raise InputError(f"'{key}' in {what} must be a path", path, "write a folder path (relative to the study file)")
        q = base / v
        if not q.exists():
            raise InputError(f"'{key}' of {what} not found: {q}", path, "check the path (relative to the study file)")
        return q

    return Split(p("images"), p("labels") if labelled else None, p("vps") if d.get("vps") is not None else None,
                 _globs(d.get("include"), "include", what, path), _globs(d.get("exclude"), "exclude", what, path))


def _check_train_keys(t: dict, path: Path) -> None:
    """Keys of the study's ``train:`` section: TrainConfig fields the study does not set per run."""
    bad = sorted(set(map(str, t)) - set(TRAIN_KEYS))
    if bad:
        raise InputError(f"unknown key '{bad[0]}' in 'train'", path, one_of(bad[0], TRAIN_KEYS, what="allowed keys:"))


def camera_spec(spec: str, path: Path, what: str) -> str:
    """A camera named in the study file ``path``, by the one rule of :func:`vcprep.camera.preset_name`
    read from the study file's folder: ``preset:NAME`` -> the preset; a bare preset name -> the
    preset, or an error naming both readings when a file or folder of that name is next to the
    study file; anything else -> a path relative to the study file."""
    if spec.startswith(PRESET_PREFIX):
        try:
            preset_name(spec)
        except InputError as e:
            raise InputError(f"{what}: {e.problem}", path, e.fix) from None
        return spec
    if spec in PRESETS:
        beside = path.parent / spec
        if os.path.lexists(beside):
            kind = "folder" if beside.is_dir() else "file"
            raise InputError(f"{what} '{spec}' is both the camera preset {spec} and the {kind} {beside}", path,
                             f"write '{PRESET_PREFIX}{spec}' for the preset, or './{spec}' for the {kind}")
        return PRESET_PREFIX + spec
    return str(path.parent / spec)


def load_study(path: str | Path) -> Study:
    """Read and check a study YAML file; paths in it are relative to the file."""
    import yaml

    path = Path(path)
    text = read_text(path, "study file", "give the study YAML file")
    try:
        d = yaml.safe_load(text)
    except yaml.YAMLError:
        raise InputError("not valid YAML", path, "fix the syntax; see the study schema in docs/studies.md") from None
    d = _mapping(d, "the study file", path)
    _keys(d, ("datasets", "conditions", "virtual", "pan_range", "tilt_range", "store_width", "store_pixels", "above",
              "canvas", "extent", "train"), ("datasets",),
          "the study file", path)
    raw = d["datasets"]
    if not isinstance(raw, list) or len(raw) < 2:
        raise InputError("'datasets' must list at least two datasets", path,
                         "a study trains on some datasets and tests on others")
    datasets: list[Dataset] = []
    for i, r in enumerate(raw):
        datasets.append(_dataset(r, i, path, datasets))
    _check_roles(datasets, path)
    study = Study(path, datasets)
    _read_settings(d, study)
    return study


def _dataset(r: Any, i: int, path: Path, before: Sequence[Dataset]) -> Dataset:
    """Dataset #``i + 1`` of the study file ``path`` (``before``: the datasets read so far)."""
    r = _mapping(r, f"dataset #{i + 1}", path)
    _keys(r, ("name", "camera", "label_format", "role", "train", "test", "unlabelled", "ego"),
          ("name", "camera", "label_format"),
          f"dataset #{i + 1}", path)
    name = r["name"]
    if not isinstance(name, str) or not _NAME.match(name):
        raise InputError(f"dataset #{i + 1} has a bad name {name!r}", path, "use letters, digits, '_', '-', '.'")
    role = r.get("role", "both")
    if role not in ROLES:
        raise InputError(f"dataset '{name}' has an unknown role {role!r}", path, one_of(str(role), ROLES))
    # a test-role dataset is never trained on (only 'test:'); a train-role one never tested ('train:')
    need, unused = {"both": ("train", None), "train": ("train", "test"), "test": ("test", "train")}[role]
    if r.get(need) is None:
        raise InputError(f"missing key '{need}' in dataset '{name}' (role {role})", path,
                         f"add '{need}: {{images: ..., labels: ...}}'")
    if unused is not None and r.get(unused) is not None:
        raise InputError(f"dataset '{name}' has role {role}, so its '{unused}' split would never be used", path,
                         f"remove '{unused}:', or use role: both")
    if any(x.name == name for x in before):
        raise InputError(f"two datasets named '{name}'", path, "give each dataset its own name")
    try:
        get_label_format(str(r["label_format"]))
    except InputError as e:
        raise InputError(f"dataset '{name}': {e.problem}", path, e.fix) from None
    cam = str(r["camera"])
    if cam != "estimate":
        cam = camera_spec(cam, path, f"dataset '{name}' camera")
    train = _split(r["train"], f"dataset '{name}' train", path) if role != "test" else None
    test = _split(r["test"], f"dataset '{name}' test", path) if r.get("test") is not None else train
    if role == "train" and r.get("unlabelled") is not None:
        raise InputError(f"dataset '{name}' has role train, so its 'unlabelled' split would never be used", path,
                         "remove 'unlabelled:' (it is what condition adapt adapts to on an evaluated dataset)")
    unlabelled = (_split(r["unlabelled"], f"dataset '{name}' unlabelled", path, labelled=False)
                  if r.get("unlabelled") is not None else None)
    ego = r.get("ego", "auto")
    if not (ego in ("auto", "none") or (isinstance(ego, int) and not isinstance(ego, bool) and ego >= 0)):
        raise InputError(f"dataset '{name}' has ego {ego!r}", path,
                         "write ego: auto (found from the labels), none, or the number of bottom rows that show "
                         "your own vehicle")
    return Dataset(name, cam, str(r["label_format"]), train, test if role != "train" else None, role, unlabelled, ego)


def _check_roles(datasets: Sequence[Dataset], path: Path) -> None:
    """Some dataset is trained on, some tested on, and a held-out one leaves one to train on."""
    trainable = [x for x in datasets if x.trained]
    if not trainable:
        raise InputError("no dataset may be trained on (every role is 'test')", path,
                         "give at least one dataset role: train or both")
    if not any(x.evaluated for x in datasets):
        raise InputError("no dataset is tested on (every role is 'train')", path,
                         "give at least one dataset role: test or both")
    if len(trainable) == 1 and trainable[0].role == "both":
        raise InputError(f"dataset '{trainable[0].name}' is the only one that may be trained on, so it cannot be held "
                         "out", path, "give it role: train (trained on, never tested), or add a training dataset")


def _whole(d: dict, key: str, lo: int, hi: int, path: Path, fix: str) -> int:
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise InputError(f"'{key}' must be a whole number of pixels in {lo}..{hi}, got {v!r}", path, fix)
    return v


def _read_settings(d: dict, study: Study) -> None:
    """The study-wide settings of the file's mapping ``d`` into ``study`` (checked)."""
    path = study.path
    if "conditions" in d:
        conds = d["conditions"]
        if not isinstance(conds, list) or not conds:
            raise InputError("'conditions' must be a list", path, f"choose from {', '.join(CONDITIONS)}")
        study.conditions = check_conditions([str(c) for c in conds], path)
    if "virtual" in d:
        study.virtual = str(d["virtual"])
        if study.virtual != "design":
            study.virtual = camera_spec(study.virtual, path, "virtual")
    for key in ("pan_range", "tilt_range"):
        if key in d:
            v = d[key]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v < 60:
                raise InputError(f"'{key}' must be degrees in [0, 60), got {v!r}", path, "e.g. pan_range: 10")
            setattr(study, key, float(v))
    if "store_width" in d:
        study.store_width = _whole(d, "store_width", 64, 8192, path, "e.g. store_width: 320")
    if "store_pixels" in d:
        study.store_pixels = _whole(d, "store_pixels", 4096, 64_000_000, path,
                                    "e.g. store_pixels: 76800 (the pixels of 320x240)")
    if "above" in d:
        v = d["above"]
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v < 60):
            raise InputError(f"'above' must be degrees in [0, 60), got {v!r}", path, "e.g. above: 8")
        if v is not None and study.virtual != "design":
            raise InputError("'above' crops a designed virtual camera", path, "use it with virtual: design")
        study.above = None if v is None else float(v)
    if "canvas" in d:
        v = d["canvas"]
        if v not in CANVASES:
            raise InputError(f"'canvas' must be one of {', '.join(CANVASES)}, got {v!r}", path, "e.g. canvas: footprint")
        if v != "shared" and study.virtual != "design":
            raise InputError("'canvas' sizes a designed virtual camera", path, "use it with virtual: design")
        study.canvas = v
    if "extent" in d:
        from vcprep.camera import EXTENTS

        v = d["extent"]
        if v not in EXTENTS:
            raise InputError(f"'extent' must be one of {', '.join(EXTENTS)}, got {v!r}", path, "e.g. extent: median")
        if study.virtual != "design":
            raise InputError("'extent' sizes a designed virtual camera", path, "use it with virtual: design")
        study.extent = v
    if "train" in d:
        t = _mapping(d["train"], "'train'", path)
        _check_train_keys(t, path)
        study.train = dict(t)


def check_conditions(conds: Sequence[str], file: Path | None = None) -> list[str]:
    """``conds`` without repeats, in order; an unknown one raises (naming ``file``, the study file)."""
    for c in conds:
        if c not in CONDITIONS:
            raise InputError(f"unknown condition '{c}'", file, one_of(c, CONDITIONS, what="choose from"))
    return list(dict.fromkeys(conds))


def evaluated_datasets(study: Study, names: Sequence[str] | None = None) -> list[str]:
    """The datasets a study scores (role both or test; ``names`` picks some of them), in file order."""
    if not names:
        return [d.name for d in study.datasets if d.evaluated]
    chosen = [study.dataset(n) for n in names]
    for d in chosen:
        if not d.evaluated:
            raise InputError(f"dataset '{d.name}' has role train: it is never tested", study.path,
                             "pick datasets of role both or test")
    return [d.name for d in study.datasets if d in chosen]
