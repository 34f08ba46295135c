"""Property-based tests: the camera readers raise nothing but the project's own error type.

The default run uses a small number of examples; `make fuzz` runs >= 10^4 per reader
(HYPOTHESIS_PROFILE=fuzz)."""
from __future__ import annotations

import json
import os

import numpy as np
import yaml
from hypothesis import HealthCheck, given, settings, strategies as st

from vcprep.camera import Camera, camera_from_dict, read_camera_yaml, read_cityscapes_camera, read_kitti_calib
from vcprep.errors import VCError

settings.register_profile("default", max_examples=60, deadline=None,
                          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
settings.register_profile("fuzz", max_examples=10_000, deadline=None,
                          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))

KEYS = ["name", "image_size", "fx", "fy", "cx", "cy", "height", "tilt", "pan", "focal", "K", ""]
scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6), st.floats(allow_nan=True),
                    st.text(max_size=8))
values = st.recursive(scalars, lambda c: st.one_of(st.lists(c, max_size=3), st.dictionaries(st.text(max_size=4), c,
                                                                                            max_size=3)),
                      max_leaves=6)
GOOD = {"image_size": [960, 720], "fx": 862, "fy": 1141, "cx": 485, "cy": 365, "height": 1.21}


def _accepts(fn, *args):
    try:
        cam = fn(*args)
    except VCError:
        return
    assert isinstance(cam, Camera)
    assert cam.fx > 0 and cam.fy > 0 and cam.height > 0


@given(st.dictionaries(st.sampled_from(KEYS), values, max_size=9))
def test_camera_dict_random(d):
    _accepts(camera_from_dict, d, "x.yaml")


@given(st.sampled_from(list(GOOD)), values)
def test_camera_dict_one_bad_value(key, value):
    d = dict(GOOD)
    d[key] = value
    _accepts(camera_from_dict, d, "x.yaml")


@given(st.text(max_size=200))
def test_camera_yaml_text(tmp_path_factory, text):
    p = tmp_path_factory.mktemp("y") / "cam.yaml"
    p.write_text(text)
    _accepts(read_camera_yaml, p)


@given(st.dictionaries(st.sampled_from(KEYS), values, max_size=9))
def test_camera_yaml_structured(tmp_path_factory, d):
    p = tmp_path_factory.mktemp("y") / "cam.yaml"
    try:
        p.write_text(yaml.safe_dump(d))
    except yaml.YAMLError:
        return
    _accepts(read_camera_yaml, p)


calib_line = st.tuples(st.sampled_from(["P0", "P2", "Tr_cam_to_road", "R0_rect", "X", ""]),
                       st.lists(st.one_of(st.floats(allow_nan=True, width=32), st.integers(-10, 2000)),
                                max_size=14), st.sampled_from([":", " ", ": "]))


@given(st.lists(calib_line, max_size=5), st.text(max_size=20))
def test_kitti_calib(tmp_path_factory, lines, junk):
    text = "\n".join(f"{k}{sep}{' '.join(map(str, vals))}" for k, vals, sep in lines) + "\n" + junk
    p = tmp_path_factory.mktemp("k") / "calib.txt"
    p.write_text(text)
    _accepts(read_kitti_calib, p)


@given(st.one_of(values, st.fixed_dictionaries({
    "intrinsic": st.dictionaries(st.sampled_from(["fx", "fy", "u0", "v0", "x"]), values, max_size=5),
    "extrinsic": st.dictionaries(st.sampled_from(["pitch", "yaw", "z", "roll"]), values, max_size=4)})))
def test_cityscapes_json(tmp_path_factory, d):
    p = tmp_path_factory.mktemp("c") / "camera.json"
    try:
        p.write_text(json.dumps(d))
    except ValueError:
        return
    _accepts(read_cityscapes_camera, p)


@given(st.binary(max_size=300))
def test_cityscapes_json_bytes(tmp_path_factory, data):
    p = tmp_path_factory.mktemp("c") / "camera.json"
    p.write_bytes(data)
    _accepts(read_cityscapes_camera, p)


from vcprep.vp import read_vp_csv  # noqa: E402

csv_cell = st.one_of(st.text(alphabet="0123456789.-eE+nai,f #\"", max_size=8), st.floats(allow_nan=True),
                     st.integers(-10**9, 10**9))


@given(st.lists(st.lists(csv_cell, max_size=5), max_size=6), st.booleans())
def test_vp_csv(tmp_path_factory, rows, header):
    text = ("id,u,v\n" if header else "") + "\n".join(",".join(map(str, r)) for r in rows)
    p = tmp_path_factory.mktemp("v") / "vps.csv"
    p.write_text(text)
    try:
        table = read_vp_csv(p)
    except VCError:
        return
    for k, (u, v) in table.items():
        assert isinstance(k, str) and np.isfinite(u) and np.isfinite(v)


@given(st.binary(max_size=200))
def test_vp_csv_bytes(tmp_path_factory, data):
    p = tmp_path_factory.mktemp("v") / "vps.csv"
    p.write_bytes(data)
    try:
        read_vp_csv(p)
    except VCError:
        pass
