"""Pinhole camera models: the :class:`Camera` record, the preset table, and readers for
camera YAML files, KITTI calibration files and Cityscapes ``camera/*.json``.

Conventions (``../shared/docs/method.md``):

* pixel (u, v): u right, v down, origin at the CENTRE of the top-left pixel;
* camera frame x right, y down, z forward; ``K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``;
* ``height`` in metres above the road; ``tilt`` (beta) in degrees, positive = optical axis
  pitched DOWN; ``pan`` (alpha) in degrees, rotation about the vertical axis after the tilt.

Per-frame calibration (:class:`FrameCameras`): a folder of calibration files, one per image,
matched by file stem (KITTI road ``calib/um_000000.txt`` for ``image_2/um_000000.png``;
Cityscapes ``camera/.../X_camera.json`` for ``leftImg8bit/.../X_leftImg8bit.png``).

Resizing an image by ``s`` maps pixel centres as ``u' = s*(u + 0.5) - 0.5``, so K scales as
``fx' = s*fx`` and ``cx' = s*(cx + 0.5) - 0.5`` (see :func:`scale_matrix`).

Ego-vehicle rows (``ego_rows``): the bottom rows of every image that show the rig's own vehicle
(a bonnet). Everything that warps an image treats them as cut off by an exact bottom crop: same
K and pose, source size ``visible_size`` = (w, h - ego_rows) (:meth:`Camera.without_ego`).
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .errors import InputError
from .imageio import read_text

__all__ = [
    "Camera",
    "PRESETS",
    "PRESET_PREFIX",
    "preset_name",
    "scale_matrix",
    "load_camera",
    "camera_from_dict",
    "read_camera_yaml",
    "read_kitti_calib",
    "read_cityscapes_camera",
    "camera_to_yaml",
    "FrameCameras",
    "load_cameras",
    "camera_of_image",
]

MAX_ABS_TILT_DEG = 80.0
MAX_ABS_PAN_DEG = 80.0
MAX_HEIGHT_M = 50.0


def scale_matrix(sx: float, sy: float | None = None) -> np.ndarray:
    """3x3 matrix taking pixel coordinates of an image to those of the same image resized by
    (sx, sy), pixel centres at integers: ``u' = sx*(u + 0.5) - 0.5``."""
    sy = sx if sy is None else sy
    return np.array([[sx, 0.0, 0.5 * (sx - 1.0)], [0.0, sy, 0.5 * (sy - 1.0)], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class Camera:
    """A pinhole camera above a flat road.

    ``size`` is (width, height) in pixels of the images K refers to; ``height`` is the
    mounting height in metres; ``tilt``/``pan`` are the average pose in degrees; the bottom
    ``ego_rows`` rows of every image (at ``size``) show the rig's own vehicle and are never
    warped (an exact bottom crop: K unchanged, see :meth:`without_ego`).
    """

    name: str
    size: tuple[int, int]
    fx: float
    fy: float
    cx: float
    cy: float
    height: float
    tilt: float = 0.0
    pan: float = 0.0
    ego_rows: int = 0

    @property
    def K(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def width(self) -> int:
        return self.size[0]

    @property
    def rows(self) -> int:
        return self.size[1]

    @property
    def visible_size(self) -> tuple[int, int]:
        """(w, h - ego_rows): the size of the image once the ego-vehicle rows are cut off."""
        return self.size[0], self.size[1] - self.ego_rows

    def without_ego(self) -> "Camera":
        """The camera of the image with its bottom ``ego_rows`` rows cut off: a bottom crop is
        exact, so K and the pose are unchanged and only the height shrinks (``ego_rows`` 0)."""
        if not self.ego_rows:
            return self
        return replace(self, size=self.visible_size, ego_rows=0)

    def fov_deg(self) -> tuple[float, float]:
        """Horizontal and vertical field of view (degrees), measured to the outer pixel edges."""
        w, h = self.size
        hfov = math.atan((self.cx + 0.5) / self.fx) + math.atan((w - 0.5 - self.cx) / self.fx)
        vfov = math.atan((self.cy + 0.5) / self.fy) + math.atan((h - 0.5 - self.cy) / self.fy)
        return math.degrees(hfov), math.degrees(vfov)

    def resized(self, sx: float, sy: float | None = None, size: tuple[int, int] | None = None) -> "Camera":
        """The same camera for images resized by (sx, sy); K follows the pixel-centre rule."""
        sy = sx if sy is None else sy
        K = scale_matrix(sx, sy) @ self.K
        if size is None:
            size = (int(round(self.size[0] * sx)), int(round(self.size[1] * sy)))
        return replace(self, size=(int(size[0]), int(size[1])), fx=float(K[0, 0]), fy=float(K[1, 1]),
                       cx=float(K[0, 2]), cy=float(K[1, 2]), ego_rows=self._ego_rows_at(sy, int(size[1])))

    def _ego_rows_at(self, sy: float, rows: int) -> int:
        """``ego_rows`` for the image resized by ``sy`` to ``rows`` rows: every new row that
        reaches below the top edge of the ego-vehicle rows (pixel edge ``sy*(h - ego_rows)``), i.e.
        rounded up so that the whole vehicle stays excluded; at least 1, at most ``rows - 1``."""
        if not self.ego_rows:
            return 0
        n = math.ceil(rows - sy * (self.size[1] - self.ego_rows) - 1e-9)
        return int(min(max(n, 1), rows - 1))

    def for_image_size(self, size: tuple[int, int], file: str | Path | None = None) -> "Camera":
        """This camera for images of ``size`` (w, h).

        Equal size: unchanged. A uniform rescale of the calibrated size (each side within one
        pixel of the same factor): K is scaled exactly per axis by the true size ratios. Anything
        else raises :class:`InputError`.
        """
        w, h = int(size[0]), int(size[1])
        W, H = self.size
        if (w, h) == (W, H):
            return self
        sx, sy = w / W, h / H
        # uniform: one factor s that, rounded either way, gives both sides (|s*W - w| <= 1, |s*H - h| <= 1)
        if max((w - 1) / W, (h - 1) / H) <= min((w + 1) / W, (h + 1) / H):
            return self.resized(sx, sy, size=(w, h))
        raise InputError(
            f"image is {w}x{h} but camera '{self.name}' is calibrated for {W}x{H}, "
            "which is not a uniform rescale of it",
            file,
            "use a camera file calibrated for this image size, or crop/resize the images uniformly",
        )

    def with_pose(self, pan: float | None = None, tilt: float | None = None) -> "Camera":
        return replace(self, pan=self.pan if pan is None else float(pan), tilt=self.tilt if tilt is None else float(tilt))

    def to_dict(self) -> dict[str, Any]:
        """The YAML schema's keys; ``ego_rows`` only when non-zero (so that the records, keys and
        store parameters of cameras without an ego-vehicle are what they were before it existed)."""
        d = {"name": self.name, "image_size": list(self.size), "fx": self.fx, "fy": self.fy, "cx": self.cx,
             "cy": self.cy, "height": self.height, "tilt": self.tilt, "pan": self.pan}
        if self.ego_rows:
            d["ego_rows"] = int(self.ego_rows)
        return d


# --- presets: the one table of built-in cameras (paper Table 1; virtual fx = 2262, see method.md)
_PRESET_ROWS = [
    # name          w     h     cx    cy    fx    fy   height  tilt
    ("camvid",      960,  720,  485,  365,  862,  1141, 1.21, 0.0),
    ("cityscapes",  2048, 1024, 1082, 514,  2262, 2252, 1.21, 2.4),
    ("kitti",       1242, 375,  610,  173,  721,  721,  1.65, 0.0),
    ("qian",        2048, 1536, 1024, 768,  1845, 1845, 1.50, 0.0),
    ("toronto2020", 1024, 576,  508,  328,  776,  701,  1.35, 0.0),
    ("virtual",     5500, 2800, 2750, 1400, 2262, 2262, 1.38, 0.0),
]
PRESETS: dict[str, Camera] = {
    r[0]: Camera(name=r[0], size=(r[1], r[2]), cx=float(r[3]), cy=float(r[4]), fx=float(r[5]), fy=float(r[6]),
                 height=r[7], tilt=r[8])
    for r in _PRESET_ROWS
}

_REQUIRED = ("image_size", "fx", "fy", "cx", "cy", "height")
_OPTIONAL = ("name", "tilt", "pan", "ego_rows")


def _number(d: dict, key: str, file, default=None) -> float:
    if key not in d:
        if default is not None:
            return default
        raise InputError(f"missing key '{key}'", file, f"add '{key}:' (see the camera schema in docs/cameras.md)")
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InputError(f"key '{key}' must be a number, got {v!r}", file, "write a plain number")
    v = float(v)
    if not math.isfinite(v):
        raise InputError(f"key '{key}' is {v}", file, "write a finite number")
    return v


def camera_from_dict(d: Any, file: str | Path | None = None, default_name: str = "camera") -> Camera:
    """Build and validate a :class:`Camera` from a parsed YAML/JSON mapping (schema in README)."""
    if not isinstance(d, dict):
        raise InputError("camera file must be a mapping of keys to values", file, "see the camera schema in docs/cameras.md")
    unknown = sorted(set(map(str, d)) - set(_REQUIRED) - set(_OPTIONAL))
    if unknown:
        raise InputError(f"unknown key '{unknown[0]}'", file,
                         f"allowed keys: {', '.join(_REQUIRED + _OPTIONAL)}")
    if "image_size" not in d:
        raise InputError("missing key 'image_size'", file, "add 'image_size: [width, height]' in pixels")
    size = d["image_size"]
    if (not isinstance(size, (list, tuple)) or len(size) != 2
            or not all(isinstance(s, int) and not isinstance(s, bool) for s in size)):
        raise InputError(f"key 'image_size' must be [width, height] in whole pixels, got {size!r}", file,
                         "write e.g. 'image_size: [960, 720]'")
    w, h = size
    if not (0 < w <= 100_000 and 0 < h <= 100_000):
        raise InputError(f"key 'image_size' {size} is out of range", file, "width and height must be 1..100000")
    fx, fy = _number(d, "fx", file), _number(d, "fy", file)
    cx, cy = _number(d, "cx", file), _number(d, "cy", file)
    height = _number(d, "height", file)
    tilt, pan = _number(d, "tilt", file, 0.0), _number(d, "pan", file, 0.0)
    for key, v in (("fx", fx), ("fy", fy)):
        if v <= 0:
            raise InputError(f"key '{key}' must be a positive focal length in pixels, got {v:g}", file,
                             "take fx, fy from the calibration's K matrix")
    if height <= 0:
        raise InputError(f"key 'height' must be a positive camera height in metres, got {height:g}", file,
                         "measure the lens height above the road")
    if height > MAX_HEIGHT_M:
        raise InputError(f"key 'height' is {height:g} m, not a road camera height", file,
                         "'height' is the mounting height in metres, not the image height (that is image_size)")
    if not (-0.5 <= cx <= w - 0.5 and -0.5 <= cy <= h - 0.5):
        raise InputError(f"principal point ({cx:g}, {cy:g}) lies outside the {w}x{h} image", file,
                         "check cx, cy (pixels, origin at the centre of the top-left pixel) and image_size")
    if abs(tilt) >= MAX_ABS_TILT_DEG:
        raise InputError(f"key 'tilt' is {tilt:g} degrees; the road plane would be (nearly) edge-on", file,
                         f"tilt is in degrees, positive = pitched down, |tilt| < {MAX_ABS_TILT_DEG:g}")
    if abs(pan) >= MAX_ABS_PAN_DEG:
        raise InputError(f"key 'pan' is {pan:g} degrees", file, f"pan is in degrees, |pan| < {MAX_ABS_PAN_DEG:g}")
    ego = d.get("ego_rows", 0)
    if isinstance(ego, bool) or not isinstance(ego, int) or ego < 0:
        raise InputError(f"key 'ego_rows' must be a whole number of rows >= 0, got {ego!r}", file,
                         "write the number of bottom image rows that show your own vehicle, e.g. 'ego_rows: 36'")
    if ego >= h:
        raise InputError(f"key 'ego_rows' is {ego} but the image has only {h} rows", file,
                         "ego_rows counts the bottom rows (at image_size) that show your own vehicle; "
                         "it must be less than the image height")
    name = d.get("name", default_name)
    if not isinstance(name, str) or not name:
        raise InputError(f"key 'name' must be a non-empty string, got {name!r}", file, "write e.g. 'name: mycam'")
    return Camera(name=name, size=(int(w), int(h)), fx=fx, fy=fy, cx=cx, cy=cy, height=height, tilt=tilt, pan=pan,
                  ego_rows=int(ego))


def read_camera_yaml(path: str | Path) -> Camera:
    """Read a camera YAML file (schema in README); every problem raises :class:`InputError`."""
    import yaml

    path = Path(path)
    text = read_text(path, "camera file", "give the camera file itself")
    try:
        d = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        raise InputError(f"not valid YAML{where}", path, "fix the syntax; see the camera schema in docs/cameras.md") from None
    except (ValueError, RecursionError, OverflowError):
        raise InputError("not valid YAML", path, "fix the syntax; see the camera schema in docs/cameras.md") from None
    return camera_from_dict(d, path, default_name=path.stem)


def yaml_name(name: str) -> str:
    """``name`` as a YAML scalar that reads back as this string (quoted where YAML would read a
    bool, number or null: a camera named 'true' or '1.5')."""
    import yaml

    try:
        if yaml.safe_load(name) == name and "#" not in name and ": " not in name:
            return name
    except yaml.YAMLError:
        pass
    return json.dumps(name)


def camera_to_yaml(cam: Camera) -> str:
    d = cam.to_dict()
    lines = [
        "# vcprep camera (pixels: origin at the centre of the top-left pixel)",
        f"name: {yaml_name(d['name'])}",
        f"image_size: [{d['image_size'][0]}, {d['image_size'][1]}]   # width, height in pixels",
        f"fx: {d['fx']:.10g}   # focal lengths in pixels",
        f"fy: {d['fy']:.10g}",
        f"cx: {d['cx']:.10g}   # principal point in pixels",
        f"cy: {d['cy']:.10g}",
        f"height: {d['height']:.10g}   # mounting height above the road, metres",
        f"tilt: {d['tilt']:.10g}   # degrees, positive = pitched down",
        f"pan: {d['pan']:.10g}   # degrees",
    ]
    if cam.ego_rows:
        lines.append(f"ego_rows: {cam.ego_rows}   # bottom rows (at image_size) showing the rig's own vehicle")
    return "\n".join(lines) + "\n"


def read_kitti_calib(path: str | Path, image_size: tuple[int, int] = (1242, 375)) -> Camera:
    """A KITTI calibration file: ``P2`` gives K; ``Tr_cam_to_road`` (KITTI road) gives this
    frame's camera height and tilt. Without ``Tr_cam_to_road`` the kitti preset's height and
    zero tilt are used. KITTI files carry no image size: ``image_size`` is that of the frames."""
    path = Path(path)
    text = read_text(path, "camera file", "give the camera file itself")
    entries: dict[str, np.ndarray] = {}
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        key, sep, rest = line.partition(":")
        if not sep:
            raise InputError(f"line {n} is not 'KEY: values'", path, "this should be a KITTI calib_*.txt file")
        try:
            vals = np.array([float(x) for x in rest.split()], dtype=float)
        except ValueError:
            raise InputError(f"line {n} ('{key.strip()}') has a value that is not a number", path,
                             "this should be a KITTI calibration file") from None
        if not np.all(np.isfinite(vals)):
            raise InputError(f"line {n} ('{key.strip()}') has a non-finite value", path, "fix the calibration file")
        entries[key.strip()] = vals
    if "P2" not in entries:
        raise InputError("no 'P2' line (the left colour camera's projection matrix)", path,
                         "use the calib file of the image_2 camera from the KITTI release")
    P2 = entries["P2"]
    if P2.size != 12:
        raise InputError(f"'P2' has {P2.size} values, expected 12 (3x4 row-major)", path, "fix the calibration file")
    P = P2.reshape(3, 4)
    fx, fy, cx, cy = P[0, 0], P[1, 1], P[0, 2], P[1, 2]
    height, tilt = PRESETS["kitti"].height, 0.0
    if "Tr_cam_to_road" in entries:
        T = entries["Tr_cam_to_road"]
        if T.size != 12:
            raise InputError(f"'Tr_cam_to_road' has {T.size} values, expected 12", path, "fix the calibration file")
        T = T.reshape(3, 4)
        # road frame: Y down, road plane Y = 0; the camera centre sits at road coords T[:, 3].
        height = -float(T[1, 3])
        n = T[1, :3]  # road 'down' axis expressed in camera coordinates (our R2)
        # R2 = (sin a sin b, cos b, cos a sin b); with pan 0: tilt b = atan2(R2_z, R2_y)
        tilt = math.degrees(math.atan2(n[2], n[1]))
    d = {"name": path.stem, "image_size": list(image_size), "fx": float(fx), "fy": float(fy),
         "cx": float(cx), "cy": float(cy), "height": height, "tilt": tilt}
    return camera_from_dict(d, path)


def read_cityscapes_camera(path: str | Path, image_size: tuple[int, int] = (2048, 1024)) -> Camera:
    """A Cityscapes ``camera/*.json``: ``intrinsic {fx, fy, u0, v0}``, ``extrinsic {pitch, yaw, z}``
    (radians, metres). Cityscapes pitch > 0 is pitched down = our tilt; yaw > 0 (turned left)
    puts the road VP right of the principal point = our pan > 0."""
    path = Path(path)
    text = read_text(path, "camera file", "give the camera file itself")
    try:
        d = json.loads(text)
    except (json.JSONDecodeError, RecursionError):
        raise InputError("not valid JSON", path, "this should be a Cityscapes camera/*.json file") from None
    if not isinstance(d, dict):
        raise InputError("expected a JSON object with 'intrinsic' and 'extrinsic'", path, "use a Cityscapes camera file")
    for section, keys in (("intrinsic", ("fx", "fy", "u0", "v0")), ("extrinsic", ("pitch", "z"))):
        sec = d.get(section)
        if not isinstance(sec, dict):
            raise InputError(f"missing object '{section}'", path, "use a Cityscapes camera/*.json file")
        for k in keys:
            if k not in sec:
                raise InputError(f"missing key '{section}.{k}'", path, "use a complete Cityscapes camera file")
    intr, extr = d["intrinsic"], d["extrinsic"]
    try:
        pitch = _number(extr, "pitch", path)
        yaw = _number(extr, "yaw", path, 0.0)
    except InputError as e:
        raise InputError(e.problem.replace("key '", "key 'extrinsic."), path, e.fix) from None
    cam = {"name": path.stem, "image_size": list(image_size), "fx": intr["fx"], "fy": intr["fy"],
           "cx": intr["u0"], "cy": intr["v0"], "height": extr["z"],
           "tilt": math.degrees(pitch), "pan": math.degrees(yaw)}
    return camera_from_dict(cam, path)


PRESET_PREFIX = "preset:"


def preset_name(spec: str | Path) -> str | None:
    """The one rule for a camera spec that may be a preset or a path: ``preset:NAME`` is the
    preset; a bare preset name is the preset unless a file or folder of that name exists where
    it is read (the current folder; a study: the study file's folder) -- then it is ambiguous, an
    error naming both readings; a name with a path separator (``./kitti``, ``cams/kitti``) or any
    other name is a path. Returns the preset's name, or None for a path."""
    if isinstance(spec, Path):
        return None
    s = str(spec)
    if s.startswith(PRESET_PREFIX):
        name = s[len(PRESET_PREFIX):]
        if name not in PRESETS:
            raise InputError(f"unknown camera preset '{name}'", s, f"use one of {', '.join(PRESETS)}")
        return name
    if s in PRESETS:
        if os.path.lexists(s):
            kind = "folder" if os.path.isdir(s) else "file"
            raise InputError(f"'{s}' is both the camera preset {s} and the {kind} ./{s}", s,
                             f"write preset:{s} for the preset, or ./{s} for the {kind}")
        return s
    return None


def load_camera(spec: str | Path, image_size: tuple[int, int] | None = None) -> Camera:
    """A preset (see :func:`preset_name`), or a file: ``.yaml``/``.yml`` (our schema), ``.txt``
    (KITTI calibration), ``.json`` (Cityscapes camera). ``image_size`` is used for calibration
    files, which carry none."""
    s = str(spec)
    preset = preset_name(spec)
    if preset is not None:
        return PRESETS[preset]
    path = Path(s)
    if not path.exists():
        raise InputError("not a camera preset and no such file", s,
                         f"use one of {', '.join(PRESETS)} or a camera YAML file")
    suffix = path.suffix.lower()
    if suffix in (".yaml", ".yml"):
        return read_camera_yaml(path)
    if suffix == ".txt":
        return read_kitti_calib(path, image_size or (1242, 375))
    if suffix == ".json":
        return read_cityscapes_camera(path, image_size or (2048, 1024))
    raise InputError(f"unknown camera file type '{suffix}'", path,
                     "use .yaml (camera schema), .txt (KITTI calib) or .json (Cityscapes camera)")


# --- per-frame calibration ------------------------------------------------------------------------
# calibration file suffix -> what its stem carries after the image's key (Cityscapes: X_camera.json)
CALIB_FILES = {".txt": "", ".json": "_camera", ".yaml": "", ".yml": ""}
IMAGE_KEY_SUFFIXES = ("_leftImg8bit",)  # image stem suffixes its calibration file's name drops (Cityscapes)


def _calib_key(path: Path) -> str:
    tail = CALIB_FILES[path.suffix.lower()]
    stem = path.stem
    return stem[: -len(tail)] if tail and stem.endswith(tail) else stem


def _image_keys(image: Path) -> list[str]:
    stem = Path(image).stem
    return [stem] + [stem[: -len(s)] for s in IMAGE_KEY_SUFFIXES if stem.endswith(s) and len(stem) > len(s)]


@dataclass(frozen=True)
class FrameCameras:
    """Per-frame calibration: every image has its own camera file in ``folder`` (searched
    recursively), matched by stem: ``<stem>.txt`` (KITTI: ``P2`` and this frame's
    ``Tr_cam_to_road``), ``<stem>.yaml`` (our schema), or ``<key>_camera.json`` (Cityscapes, for
    the image ``<key>_leftImg8bit.png``). ``files`` maps each key to its file."""

    folder: Path
    files: Mapping[str, Path]

    @property
    def name(self) -> str:
        """What store records call the camera: the folder's name (``calib``, ``camera``)."""
        return Path(os.path.abspath(self.folder)).name

    @classmethod
    def from_folder(cls, folder: str | Path) -> "FrameCameras":
        folder = Path(folder)
        files: dict[str, Path] = {}
        for top, dirs, names in os.walk(folder, followlinks=True):
            dirs[:] = sorted(d for d in dirs if not d.startswith("."))
            for n in sorted(names):
                p = Path(top) / n
                if n.startswith(".") or p.suffix.lower() not in CALIB_FILES:
                    continue
                key = _calib_key(p)
                if key in files:
                    raise InputError(f"two calibration files for frame '{key}' (also {files[key]})", p,
                                     "keep one calibration file per frame in the folder")
                files[key] = p
        if not files:
            raise InputError("folder holds no calibration files (.txt KITTI, .json Cityscapes, .yaml)", folder,
                             "give the folder of per-frame calibration files, or one camera file or preset")
        return cls(folder, files)

    def file_for(self, image: str | Path) -> Path:
        """The calibration file of ``image``; none is an :class:`InputError` naming the image."""
        keys = _image_keys(Path(image))
        for k in keys:
            if k in self.files:
                return self.files[k]
        raise InputError(f"no calibration file for this image in {self.folder} (looked for "
                         f"{keys[-1]}.txt, {keys[-1]}_camera.json or {keys[-1]}.yaml)", image,
                         "add the frame's calibration file, or remove the image")

    def for_image(self, image: str | Path, size: tuple[int, int]) -> Camera:
        """The camera of ``image`` (of ``size`` (w, h)) from its own calibration file."""
        return load_camera(self.file_for(image), image_size=size).for_image_size(size, image)


def camera_of_image(camera: "Camera | FrameCameras", image: str | Path, size: tuple[int, int]) -> Camera:
    """The camera of one image of ``size``: ``camera`` at that size, or its own calibration file."""
    if isinstance(camera, FrameCameras):
        return camera.for_image(image, size)
    return camera.for_image_size(size, image)


def load_cameras(spec: str | Path, sample_image: str | Path | None = None,
                 per_frame: bool = True) -> "Camera | FrameCameras":
    """``--camera``: a preset, a camera file (KITTI and Cityscapes files carry no image size: the
    size of ``sample_image`` is used), or, with ``per_frame``, a folder of per-frame calibration
    files (:class:`FrameCameras`)."""
    s = str(spec)
    if preset_name(spec) is not None:
        return load_camera(spec)
    if Path(s).is_dir():
        if not per_frame:
            raise InputError("is a folder of per-frame calibration files; this command needs one camera", s,
                             "give one camera file or preset (per-frame folders work in warp, predict and crossval)")
        return FrameCameras.from_folder(s)
    size = None
    if sample_image is not None and Path(s).suffix.lower() in (".txt", ".json"):
        from .imageio import image_size_from_header

        try:
            with open(sample_image, "rb") as f:
                size = image_size_from_header(f.read(262144))
        except OSError:
            size = None
    return load_camera(s, image_size=size)
