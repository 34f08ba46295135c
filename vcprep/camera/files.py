"""Camera files: our camera YAML schema (read, validate, write), KITTI calibration files and
Cityscapes ``camera/*.json``. Each reader returns a validated :class:`~vcprep.camera.pinhole.Camera`;
every problem raises :class:`InputError` naming the file."""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..io.images import read_text
from .pinhole import PRESETS, Camera

__all__ = ["camera_from_dict", "read_camera_yaml", "yaml_name", "camera_to_yaml", "read_kitti_calib",
           "read_kitti_entries",
           "read_cityscapes_camera"]

MAX_ABS_TILT_DEG = 80.0
MAX_ABS_PAN_DEG = 80.0
MAX_HEIGHT_M = 50.0
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
                  ego_rows=int(ego), ego_stated="ego_rows" in d)


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
    elif cam.ego_stated:
        lines.append("ego_rows: 0   # the frames show no own vehicle (none is searched for)")
    return "\n".join(lines) + "\n"


def read_kitti_entries(path: str | Path) -> dict[str, np.ndarray]:
    """Every ``KEY: numbers`` line of a KITTI calibration file, as flat float arrays (``P2``: 12
    values, ``R0_rect``: 9, ``Tr_cam_to_road``: 12, ...); a malformed line raises :class:`InputError`."""
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
    return entries


def read_kitti_calib(path: str | Path, image_size: tuple[int, int] = (1242, 375)) -> Camera:
    """A KITTI calibration file: ``P2`` gives K; ``Tr_cam_to_road`` (KITTI road) gives this
    frame's camera height and tilt. Without ``Tr_cam_to_road`` the kitti preset's height and
    zero tilt are used. KITTI files carry no image size: ``image_size`` is that of the frames."""
    path = Path(path)
    entries = read_kitti_entries(path)
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
         "cx": float(cx), "cy": float(cy), "height": height, "tilt": tilt,
         "ego_rows": 0}  # KITTI's rectified frames (a roof-mounted rig) show no own vehicle: stated, not searched
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
