"""Label formats: the one table that says how each dataset encodes road / not road / ignore,
and how its label files are named. Everything else derives from :data:`LABEL_FORMATS`.

Decoded labels are uint8 with ``ROAD = 1``, ``NOT_ROAD = 0``, ``IGNORE = 255``. What "road" means is
the format's ``definition`` (:data:`DEFINITIONS`): ``road`` (CamVid, Cityscapes, KITTI: the carriageway) or
``drivable`` (IDD's and BDD100K's drivable area: the road and, in IDD, parking and dirt shoulders too); a
model with two outputs (``vctrain fit --outputs road,drivable``) learns each from the datasets that label it.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from .errors import InputError, one_of

__all__ = ["ROAD", "NOT_ROAD", "IGNORE", "DEFINITIONS", "LabelFormat", "LABEL_FORMATS", "LABEL_FORMAT_HELP", "get_label_format", "decode_label",
           "label_stem_for", "RoadShare"]

NOT_ROAD, ROAD, IGNORE = 0, 1, 255
# what a label's ROAD means: 'road' (the carriageway) or 'drivable' (drivable area: road, and in IDD parking and
# dirt shoulders); a format's ``definition``, and the outputs of a two-output model (vctrain.training.outputs)
DEFINITIONS = ("road", "drivable")


@dataclass(frozen=True)
class LabelFormat:
    """How one dataset encodes road in its label files.

    ``kind`` is ``ids`` (single-channel class ids) or ``channels`` (colour images read channel by channel, as the KITTI road devkit reads its ground truth:
    ``valid_channel`` set = labelled, then ``road_channel`` set = road; ``valid_channel`` clear = ignore).
    ``max_value`` bounds valid ids (None: any value; unlisted values are not road).
    ``image_suffix``/``label_suffix``: an image ``<stem><image_suffix>.<ext>`` has the label
    ``<stem><label_suffix>.png``; ``kitti_naming`` inserts ``_road`` after the category.
    ``drive_in_id``: the image's folder (a drive) prefixes its id, ``<folder>_<stem>``, for
    trees whose file names repeat from drive to drive (IDD); the drive is then the id's sequence.
    ``definition``: what its road is (:data:`DEFINITIONS`): ``road`` or ``drivable`` (drivable area).
    """

    name: str
    kind: str
    road: tuple = ()
    ignore: tuple = ()
    not_road: tuple = ()
    max_value: int | None = None
    image_suffix: str = ""
    label_suffix: str = ""
    kitti_naming: bool = False
    drive_in_id: bool = False
    road_channel: int | None = None   # ``channels``: the BGR channel whose non-zero pixels are road
    valid_channel: int | None = None  # ``channels``: the BGR channel whose zero pixels are ignore
    description: str = ""
    definition: str = "road"
    extra: dict = field(default_factory=dict)


# KITTI gt_image_2 (magenta road, red not road, black outside the evaluated area) is read as the devkit
# reads it (evaluateRoad.py on cv2's BGR image): road = blue channel > 0, evaluated area = red channel > 0,
# so a stray colour (a few pure blue pixels in 21 of the 289 training labels) is simply outside the area.
LABEL_FORMATS: dict[str, LabelFormat] = {
    f.name: f
    for f in [
        LabelFormat("camvid", "ids", road=(3,), ignore=(11,), max_value=11,
                    description="SegNet CamVid ids: 3 road, 11 unlabelled (ego bonnet) = ignore, 0..11"),
        LabelFormat("kitti", "channels", road_channel=0, valid_channel=2, kitti_naming=True,
                    description="KITTI road gt_image_2, read as the devkit: red set = evaluated (blue set: road, "
                                "magenta; clear: not road, red), red clear = ignore"),
        LabelFormat("cityscapes", "ids", road=(7,), ignore=(1, 2, 3), max_value=33,
                    image_suffix="_leftImg8bit", label_suffix="_gtFine_labelIds",
                    description="Cityscapes labelIds: 7 road; 1 ego vehicle, 2 rectification border, 3 out of roi = ignore"),
        LabelFormat("bdd", "ids", road=(1, 2), max_value=2, label_suffix="_drivable_id", definition="drivable",
                    description="BDD100K drivable ids: 1 direct, 2 alternative = road, 0 background"),
        LabelFormat("idd", "ids", road=(0,), ignore=(255,), max_value=255, image_suffix="_image",
                    label_suffix="_label", drive_in_id=True, definition="drivable",
                    description="IDD / IDD-Lite level-1 ids: 0 drivable = road, 255 void = ignore; drive folders, "
                                "<id>_image.jpg <-> <id>_label.png, item id <drive>_<id>"),
    ]
}
# --label-format's help, for every command that takes one: the named formats and the generic one, quoted
# as it must be typed (a shell ends a command at an unquoted ;)
LABEL_FORMAT_HELP = (f"{', '.join(LABEL_FORMATS)} or 'values:road=3;ignore=11' (quoted; add ';definition=drivable' "
                     "where the labels' road is drivable area)")


def _parse_values(spec: str) -> LabelFormat:
    """``values:road=3,4;ignore=11[;max=11][;definition=drivable]`` -> a generic ids format."""
    body = spec[len("values:"):]
    road: list[int] = []
    ignore: list[int] = []
    max_value = None
    definition = "road"
    for part in filter(None, (p.strip() for p in body.split(";"))):
        key, sep, vals = part.partition("=")
        key = key.strip()
        if key == "definition":
            definition = vals.strip()
            if definition not in DEFINITIONS:
                raise InputError(f"unknown label definition '{definition}' in '{part}'", spec,
                                 f"write ;definition= one of {', '.join(DEFINITIONS)}")
            continue
        try:
            nums = [int(v) for v in vals.split(",") if v.strip()]
        except ValueError:
            nums = None
        if not sep or key not in ("road", "ignore", "max") or not nums or any(n < 0 or n > 65535 for n in nums):
            raise InputError(f"cannot parse label format part '{part}'", spec,
                             "write e.g. 'values:road=3;ignore=11' (comma-separated ids, optional ;max=N and "
                             ";definition=drivable; quoted: "
                             "a shell ends a command at ;)")
        if key == "road":
            road += nums
        elif key == "ignore":
            ignore += nums
        else:
            max_value = nums[0]
    if not road:
        raise InputError("generic label format names no road value", spec, "write e.g. 'values:road=3;ignore=11'")
    return LabelFormat(spec, "ids", road=tuple(road), ignore=tuple(ignore), max_value=max_value,
                       description="generic ids", definition=definition)


def get_label_format(name: str) -> LabelFormat:
    if name in LABEL_FORMATS:
        return LABEL_FORMATS[name]
    if name.startswith("values:"):
        return _parse_values(name)
    raise InputError(f"unknown label format '{name}'", None,
                     one_of(name, LABEL_FORMATS, "or values:road=ID[,ID];ignore=ID"))


def decode_label(raw: np.ndarray, fmt: LabelFormat, file: str | Path | None = None) -> np.ndarray:
    """Raw label image -> uint8 (h, w) with 0 not road, 1 road, 255 ignore.

    Values outside the format (an id above ``max_value``; for ``channels``, a grey picture) raise
    :class:`InputError` naming the first offending value.
    """
    if fmt.kind == "channels":
        return _decode_channels(raw, fmt, file)
    if raw.ndim == 3:
        if raw.shape[2] >= 3 and np.array_equal(raw[..., 0], raw[..., 1]) and np.array_equal(raw[..., 0], raw[..., 2]):
            raw = raw[..., 0]
        else:
            raise InputError(f"label has {raw.shape[2]} channels, format '{fmt.name}' needs single-channel ids", file,
                             "give the id/label image, not a colour visualisation")
    if fmt.max_value is not None:
        mx = int(raw.max()) if raw.size else 0
        if mx > fmt.max_value:
            raise InputError(f"label value {mx} is outside format '{fmt.name}' (ids 0..{fmt.max_value})", file,
                             "check --label-format")
    if raw.dtype == np.uint8:  # one table lookup per pixel (ids 0..255)
        lut = np.zeros(256, dtype=np.uint8)
        lut[[v for v in fmt.road if 0 <= v < 256]] = ROAD
        if fmt.ignore:
            lut[[v for v in fmt.ignore if 0 <= v < 256]] = IGNORE
        return cv2.LUT(raw, lut)
    out = np.zeros(raw.shape, dtype=np.uint8)
    out[np.isin(raw, fmt.road)] = ROAD
    if fmt.ignore:
        out[np.isin(raw, fmt.ignore)] = IGNORE
    return out


def _decode_channels(raw: np.ndarray, fmt: LabelFormat, file: str | Path | None) -> np.ndarray:
    """A colour label read channel by channel (the KITTI devkit's rule): ``valid_channel`` clear -> ignore,
    else ``road_channel`` set -> road, clear -> not road. A grey picture (every channel equal: ids saved as
    an image, a mask) is not such a label and is refused, naming its first non-black pixel."""
    if raw.ndim != 3 or raw.shape[2] < 3:
        raise InputError(f"label has {1 if raw.ndim == 2 else raw.shape[2]} channel(s), format '{fmt.name}' "
                         "needs a colour image", file, "give the colour-coded gt_image_2 file")
    bgr = raw[..., :3]
    if np.array_equal(bgr[..., 0], bgr[..., 1]) and np.array_equal(bgr[..., 0], bgr[..., 2]) and bgr.any():
        y, x = np.argwhere(bgr[..., 0] > 0)[0]
        b, g, r = bgr[y, x]
        raise InputError(f"label colour (R,G,B)=({r},{g},{b}) at pixel ({x}, {y}) is not in format '{fmt.name}'",
                         file, "check --label-format (kitti expects magenta road, red not road, black ignore)")
    valid = bgr[..., fmt.valid_channel] > 0
    out = np.where(valid, NOT_ROAD, IGNORE).astype(np.uint8)
    out[valid & (bgr[..., fmt.road_channel] > 0)] = ROAD
    return out


_KITTI_RE = re.compile(r"^(?P<cat>[a-z]+)_(?P<num>\d+)$")


def image_id(image: Path, fmt: LabelFormat | None) -> str:
    """The item id of an image: its stem, minus the format's image suffix (``_leftImg8bit``);
    with ``drive_in_id`` (IDD) prefixed by its folder's name, the drive: ``<drive>_<stem>``."""
    stem = _file_id(image, fmt)
    if fmt is not None and fmt.drive_in_id:
        return f"{image.parent.name}_{stem}"
    return stem


def _file_id(image: Path, fmt: LabelFormat | None) -> str:
    stem = image.stem
    if fmt is not None and fmt.image_suffix and stem.endswith(fmt.image_suffix):
        stem = stem[: -len(fmt.image_suffix)]
    return stem


def label_stem_for(image: Path, fmt: LabelFormat) -> str:
    """File stem of the label that belongs to ``image`` under ``fmt``'s naming rule."""
    stem = _file_id(image, fmt)
    if fmt.kitti_naming:
        m = _KITTI_RE.match(stem)
        if m:
            return f"{m['cat']}_road_{m['num']}"
    return stem + fmt.label_suffix


# -- labels that make no sense under their format ---------------------------------------------------------
# Over a set of a road camera's labels, road covers a fair share of the labelled pixels (CamVid val 30 %,
# Cityscapes 36 %; from 13 % (the KITTI frame) to 49 % (LUMS) on the real sets here) and lies below the
# horizon. A parseable but wrong format breaks one of these: a road id that is not in the labels gives none,
# one that is every class's gives nearly all, and another class's id (CamVid's buildings, sky) puts most of
# "road" above the horizon. The horizon is each frame's road vanishing point row where the frame's VP is
# known (a store's items: the virtual camera's horizon is near the top of its image, not in the middle), the
# frame's middle row otherwise (frames of a camera with its horizon near the middle). Measured on the seven
# real label sets of ../shared/data with their right formats (issue 80): road above the VP row 0.0-1.8 %
# of it in stores of the designed and of a shared virtual camera, in the upper half of the raw frames
# 0.0-16 % (LUMS); CamVid's buildings (values:road=1): 70-84 % above the VP row in stores, 76-85 % in
# the frames' upper half (56 % in the worst 24 frames in a row), so the rule sits far from both.
NO_ROAD = 0.005       # road below this share of the labelled pixels over a set: none
ALL_ROAD = 0.95       # above this share: nearly all
UPPER_ROAD = 0.5      # more than this share of the road pixels above the horizon of their frames


class RoadShare:
    """Where road lies in a set of decoded labels (:meth:`add` each), and :meth:`warning`: one line
    when it makes no sense for a road camera (``vcprep warp`` and ``vctrain eval`` say it, ``vctrain
    fit`` refuses it)."""

    def __init__(self) -> None:
        self.frames = self.labelled = self.road = self.upper = 0
        self.with_horizon = 0  # frames whose horizon was given (their VP row), not their middle row

    def add(self, label: np.ndarray, horizon: float | None = None) -> None:
        """One decoded label (uint8 (h, w): ``ROAD``, ``NOT_ROAD``, ``IGNORE``); ``horizon``: the row
        (pixel centres at integers) of its road vanishing point, the horizon; None: the middle row."""
        road = label == ROAD
        h = label.shape[0]
        above = h // 2 if horizon is None else min(max(int(np.ceil(horizon)), 0), h)  # rows y < horizon
        self.frames += 1
        self.with_horizon += horizon is not None
        self.labelled += int((label != IGNORE).sum())
        self.road += int(road.sum())
        self.upper += int(road[:above].sum())

    def _above(self) -> str:
        """Where the road that makes no sense lies, in the words of the horizon used."""
        if self.with_horizon == self.frames:
            return "lie above the horizon (the row of each frame's road vanishing point)"
        if not self.with_horizon:
            return "lie in the frames' upper half"
        return "lie above the horizon (the row of each frame's road vanishing point, else the frame's upper half)"

    def problem(self) -> str | None:
        """What makes no sense (None: nothing, or no labelled pixel)."""
        if not self.labelled:
            return None
        share = self.road / self.labelled
        n = f"{self.frames} frame{'s' if self.frames != 1 else ''}"
        if not self.road:
            return f"no labelled pixel of {n} reads as road"
        if share < NO_ROAD or share > ALL_ROAD:
            return f"road covers {share:.2%} of the labelled pixels of {n}"
        if self.upper > UPPER_ROAD * self.road:
            return f"{self.upper / self.road:.0%} of the pixels read as road in {n} {self._above()}, where sky and " \
                   "buildings are, not road"
        return None

    def _said(self, fmt: "LabelFormat") -> tuple[str, str] | None:
        """(what makes no sense, the fix) under ``fmt``, or None."""
        problem = self.problem()
        if problem is None:
            return None
        road = ", ".join(str(v) for v in fmt.road) if fmt.kind == "ids" else f"BGR channel {fmt.road_channel} set"
        return (f"under label format '{fmt.name}' (road = {road}) {problem}: the format probably does not fit these "
                f"labels", "check --label-format: a named format such as camvid or cityscapes, or values:road=ID;"
                "ignore=ID with the ids these labels give road and ignore")

    def warning(self, fmt: "LabelFormat", where: str | Path) -> str | None:
        """'warning: <where>: under label format '<name>' (road = ...) <problem>: ... (<fix>)', or None."""
        said = self._said(fmt)
        return None if said is None else f"warning: {where}: {said[0]} ({said[1]})"

    def refuse(self, fmt: "LabelFormat", where: str | Path, override: str, then: str = "") -> None:
        """Raise :class:`InputError` with :meth:`warning`'s words when the labels make no sense under ``fmt``
        (``override``: the flag that goes on anyway, added to the fix; ``then``: what follows the right format,
        e.g. warping the store again)."""
        said = self._said(fmt)
        if said is not None:
            raise InputError(said[0], where, f"{said[1]}{then}; or {override} to train on them anyway")
