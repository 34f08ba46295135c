"""Camera model: presets, YAML schema and its errors, resizing with the pixel-centre rule, and the
KITTI / Cityscapes readers."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from vcprep.camera import PRESETS, Camera, camera_to_yaml, load_camera, read_camera_yaml, read_cityscapes_camera, \
    read_kitti_calib
from vcprep.errors import InputError

from conftest import EXAMPLES, run_here



GOOD = """name: mycam
image_size: [960, 720]
fx: 862
fy: 1141
cx: 485
cy: 365
height: 1.21
tilt: 0
"""


def test_presets_match_paper_table():
    assert set(PRESETS) == {"camvid", "cityscapes", "kitti", "qian", "toronto2020", "virtual"}
    v = PRESETS["virtual"]
    assert v.size == (5500, 2800) and v.fx == v.fy == 2262 and v.height == 1.38
    hf, vf = v.fov_deg()
    assert hf == pytest.approx(101.1, abs=0.1) and vf == pytest.approx(63.5, abs=0.1)  # paper Table 1
    assert PRESETS["cityscapes"].tilt == 2.4


def test_yaml_round_trip(tmp_path):
    p = tmp_path / "cam.yaml"
    p.write_text(GOOD)
    cam = read_camera_yaml(p)
    assert cam == Camera("mycam", (960, 720), 862, 1141, 485, 365, 1.21)
    p2 = tmp_path / "again.yaml"
    p2.write_text(camera_to_yaml(cam))
    assert read_camera_yaml(p2) == cam
    assert load_camera(p) == cam and load_camera("camvid") is PRESETS["camvid"]


@pytest.mark.parametrize("edit, needle", [
    (lambda t: t + "focal: 3\n", "unknown key 'focal'"),
    (lambda t: t.replace("fx: 862\n", ""), "missing key 'fx'"),
    (lambda t: t.replace("fx: 862", "fx: -862"), "'fx' must be a positive"),
    (lambda t: t.replace("fy: 1141", "fy: 0"), "'fy' must be a positive"),
    (lambda t: t.replace("height: 1.21", "height: -1"), "'height' must be a positive"),
    (lambda t: t.replace("height: 1.21", "height: .nan"), "'height' is nan"),
    (lambda t: t.replace("cx: 485", "cx: 2000"), "principal point"),
    (lambda t: t.replace("tilt: 0", "tilt: 89.5"), "'tilt'"),
    (lambda t: t.replace("height: 1.21", "height: 720"), "not a road camera height"),
    (lambda t: t.replace("image_size: [960, 720]", "image_size: [960]"), "image_size"),
    (lambda t: t.replace("fx: 862", "fx: abc"), "'fx' must be a number"),
    (lambda t: "fx: [", "not valid YAML"),
    (lambda t: "", "must be a mapping"),
])
def test_yaml_errors_name_file_and_key(tmp_path, edit, needle):
    p = tmp_path / "bad.yaml"
    p.write_text(edit(GOOD))
    with pytest.raises(InputError) as e:
        read_camera_yaml(p)
    assert needle in str(e.value) and str(p) in str(e.value)


def test_resize_follows_pixel_centre_rule():
    cam = PRESETS["camvid"]
    half = cam.for_image_size((480, 360))
    # u' = s (u + 0.5) - 0.5 for pixel centres at integers
    assert half.fx == 431 and half.fy == 570.5
    assert half.cx == pytest.approx(0.5 * (485 + 0.5) - 0.5) and half.cy == pytest.approx(0.5 * (365 + 0.5) - 0.5)
    # a 3D point projects to the same place in the resized image as resizing its projection
    P = np.array([1.3, 0.7, 9.0])
    u_full = cam.K @ P
    u_full = u_full[:2] / u_full[2]
    u_half = half.K @ P
    u_half = u_half[:2] / u_half[2]
    assert np.allclose(u_half, 0.5 * (u_full + 0.5) - 0.5)
    assert cam.for_image_size((960, 720)) is cam


def test_non_uniform_size_is_an_error():
    with pytest.raises(InputError, match="not a uniform rescale"):
        PRESETS["camvid"].for_image_size((480, 300), "x.png")


@pytest.mark.parametrize("size", [(1224, 370), (1226, 370), (1238, 374), (1241, 376)])
def test_kittis_cropped_frames_are_not_rescales(size):
    """KITTI's rectified frames come in several sizes cut from one sensor (crops: same fx, cx and cy
    shifted); against the 1242x375 preset none is a uniform rescale, and the error names both sizes
    and the camera file to write."""
    with pytest.raises(InputError) as e:
        PRESETS["kitti"].for_image_size(size, "000000.png")
    msg = str(e.value)
    assert f"{size[0]}x{size[1]}" in msg and "1242x375" in msg and "not a uniform rescale" in msg
    assert "000000.png" in msg and (f"image_size [{size[0]}, {size[1]}]" in msg or "calibrated for" in msg)


@pytest.mark.parametrize("name,factor", [("camvid", 0.5), ("kitti", 0.5), ("kitti", 1 / 3), ("kitti", 0.25),
                                         ("cityscapes", 0.125), ("toronto2020", 0.1), ("camvid", 2.0),
                                         ("kitti", 0.9), ("qian", 0.3)])
def test_true_rescales_are_taken(name, factor):
    """Every size cv2.resize gives for a factor (rounded per side) is a rescale; K follows the sides'
    true ratios (the oracle: the pixel-centre rule on each axis)."""
    cam = PRESETS[name]
    size = (int(round(cam.size[0] * factor)), int(round(cam.size[1] * factor)))
    got = cam.for_image_size(size)
    sx, sy = size[0] / cam.size[0], size[1] / cam.size[1]
    assert got.size == size and got.fx == pytest.approx(cam.fx * sx) and got.fy == pytest.approx(cam.fy * sy)
    assert got.cx == pytest.approx(sx * (cam.cx + 0.5) - 0.5) and got.cy == pytest.approx(sy * (cam.cy + 0.5) - 0.5)


def test_one_pixel_off_the_rounding_is_not_a_rescale():
    """480x361 is no rounding of any factor of 960x720 (the old one-pixel tolerance took it)."""
    with pytest.raises(InputError, match="not a uniform rescale"):
        PRESETS["camvid"].for_image_size((480, 361))
    with pytest.raises(InputError, match="not a uniform rescale"):
        PRESETS["kitti"].for_image_size((622, 187))


def test_kitti_calib_reader():
    cam = read_kitti_calib(EXAMPLES / "kitti" / "calib" / "um_000000.txt")
    assert cam.fx == pytest.approx(721.5377) and cam.cx == pytest.approx(609.5593) and cam.cy == pytest.approx(172.854)
    assert cam.height == pytest.approx(1.597, abs=1e-3)  # from Tr_cam_to_road
    # road normal in camera coords is (0.0054, 0.9999, -0.0111): optical axis pitched slightly UP
    assert cam.tilt == pytest.approx(math.degrees(math.atan2(-1.111504746388e-02, 9.999234779341e-01)), abs=1e-6)
    assert cam.tilt < 0


def test_kitti_calib_without_p2(tmp_path):
    p = tmp_path / "calib.txt"
    p.write_text("P0: 1 0 0 0 0 1 0 0 0 0 1 0\n")
    with pytest.raises(InputError, match="no 'P2' line"):
        read_kitti_calib(p)


def test_cityscapes_camera_reader(tmp_path):
    d = {"extrinsic": {"baseline": 0.21, "pitch": 0.038, "roll": 0.0, "yaw": -0.0195, "x": 1.7, "y": 0.1, "z": 1.22},
         "intrinsic": {"fx": 2262.52, "fy": 2265.3, "u0": 1096.98, "v0": 513.137}}
    p = tmp_path / "aachen_000000_000019_camera.json"
    p.write_text(json.dumps(d))
    cam = read_cityscapes_camera(p)
    assert cam.tilt == pytest.approx(math.degrees(0.038)) and cam.height == 1.22 and cam.size == (2048, 1024)
    assert cam.pan == pytest.approx(math.degrees(-0.0195))
    del d["intrinsic"]["v0"]
    p.write_text(json.dumps(d))
    with pytest.raises(InputError, match="intrinsic.v0"):
        read_cityscapes_camera(p)


def test_unknown_camera_spec():
    with pytest.raises(InputError, match="not a camera preset"):
        load_camera("camvidd")


def test_shipped_camera_template_is_valid():
    cam = read_camera_yaml(EXAMPLES / "camera_template.yaml")
    assert cam.name == "mycam" and cam.size == (1280, 720) and cam.cx == 639.5


@pytest.mark.parametrize("name", ["true", "no", "1.5", "null", "cam #2", "a: b", "mycam"])
def test_camera_names_that_yaml_would_misread_round_trip(tmp_path, name):
    from dataclasses import replace as _replace

    from vcprep.camera import PRESETS, camera_to_yaml, read_camera_yaml

    cam = _replace(PRESETS["camvid"], name=name)
    (tmp_path / "c.yaml").write_text(camera_to_yaml(cam))
    assert read_camera_yaml(tmp_path / "c.yaml") == cam


def test_a_name_that_is_both_a_preset_and_a_path_is_an_error_naming_both(tmp_path):
    """One rule (issue 26.5): preset:NAME is the preset, ./NAME the path, a bare NAME that is both
    an error naming both readings; a bare preset name with no such path is the preset."""
    from conftest import assert_one_error_line
    from vcprep.camera import PRESETS, camera_to_yaml

    assert run_here("camera", "show", "kitti", "--json", cwd=tmp_path).returncode == 0    # no ./kitti: the preset
    (tmp_path / "kitti").mkdir()
    assert_one_error_line(run_here("camera", "show", "kitti", cwd=tmp_path), "both the camera preset kitti and the "
                          "folder ./kitti", "preset:kitti", "./kitti")
    proc = run_here("camera", "show", "preset:kitti", "--json", cwd=tmp_path)
    assert proc.returncode == 0 and json.loads(proc.stdout)["fx"] == PRESETS["kitti"].fx
    (tmp_path / "camvid").write_text(camera_to_yaml(PRESETS["kitti"]))   # a file named like another preset
    assert_one_error_line(run_here("camera", "show", "camvid", cwd=tmp_path), "file ./camvid", "preset:camvid")
    assert_one_error_line(run_here("camera", "show", "preset:nope", cwd=tmp_path), "unknown camera preset 'nope'")
    # a per-frame folder: ./kitti is the folder, kitti ambiguous, in every command that takes one
    import cv2
    import numpy as np

    (tmp_path / "img").mkdir()
    cv2.imwrite(str(tmp_path / "img" / "a.png"), np.zeros((375, 1242, 3), np.uint8))
    assert_one_error_line(run_here("vp", "--camera", "kitti", "img", cwd=tmp_path), "both the camera preset")
