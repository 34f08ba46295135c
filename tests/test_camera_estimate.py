"""Estimating a camera from its own frames (vcprep.camera.estimate; issue 25).

Oracle: synthetic roads rendered through cameras whose K, height and pose we choose, so the true
tilt, pan and horizon row are known exactly (:func:`vcprep.warp.homography.vp_from_pose`)."""
from __future__ import annotations

import json
import math
import struct

import cv2
import numpy as np
import pytest

from conftest import run_here, assert_one_error_line, run_cli
from vcprep.camera import Camera, read_camera_yaml
from vcprep.camera import ASSUMED_HFOV, ROAD_WIDTH, estimate_camera, exif_focal_35mm, road_widths
from vcprep.errors import InputError
from vcprep.warp import virt_H_src, vp_from_pose
from vcprep.labels import get_label_format
from vcprep.synthetic import RoadScene, render_road
from vcprep.vp import read_vp_csv



PANS = [0.0, 1.5, -1.0, 2.0, -2.0, 0.5]   # per-frame heading of the road relative to the camera


def _frames(folder, cam: Camera, n: int = 6, ext: str = ".png"):
    folder.mkdir(parents=True, exist_ok=True)
    files = []
    for i in range(n):
        img, _ = render_road(cam, RoadScene(texture_seed=i, offset=0.4 * (i % 3) - 0.4), pan=cam.pan + PANS[i],
                             supersample=1)
        files.append(folder / f"seq_{i:04d}{ext}")
        cv2.imwrite(str(files[-1]), img)
    return files


@pytest.mark.parametrize("focal, tilt", [(0.5, -6.0), (1.0, 3.0), (2.0, 8.0)])
def test_tilt_pan_and_horizon_of_a_known_camera(tmp_path, focal, tilt):
    """fx from 0.5x to 2x a 60-degree lens, tilt from -6 to +8 degrees: the median road VP gives the
    camera's tilt and pan (the frames' road headings average 0.17 deg) and the horizon row."""
    w, h = 320, 240
    f = focal * (w / 2) / math.tan(math.radians(30))
    cam = Camera("true", (w, h), f, f, 161.0, 117.0, 1.4, tilt=tilt, pan=0.0)
    est = estimate_camera(_frames(tmp_path / "f", cam), fx=f, pixel_aspect=1.0)
    v = est.values
    assert est.accepted == 6
    # the camera's cx, cy are not the image centre: the estimate assumes the centre, so the true
    # pose of the estimated camera is the one that puts the road VP where the true camera does
    u_true, v_true = vp_from_pose(cam, pan=float(np.median(PANS)))
    assert v["horizon_row"].value == pytest.approx(v_true, abs=0.005 * h)
    vp_est = vp_from_pose(est.camera)
    assert vp_est[1] == pytest.approx(v_true, abs=0.005 * h)
    assert vp_est[0] == pytest.approx(u_true, abs=0.005 * w)
    assert abs(est.camera.tilt - math.degrees(math.atan((est.camera.cy - v_true) / f))) < 0.3
    assert v["tilt"].source == "estimated" and v["tilt"].sure is not None
    assert v["fx"].source == "given" and est.camera.fx == f
    assert not [x for x in est.warnings if x.startswith("fx")]


def test_an_unknown_focal_length_is_assumed_and_said_the_horizon_still_holds(tmp_path):
    cam = Camera("true", (320, 240), 450.0, 450.0, 159.5, 119.5, 1.4, tilt=4.0)
    est = estimate_camera(_frames(tmp_path / "f", cam))
    fx = est.values["fx"]
    assert fx.source == "assumed" and "--fx" in fx.how and "--hfov" in fx.how
    assert fx.value == pytest.approx(160 / math.tan(math.radians(ASSUMED_HFOV / 2)), abs=1e-3)
    assert any(w.startswith("fx") for w in est.warnings) and any(w.startswith("height") for w in est.warnings)
    # the horizon row is measured in pixels: right whatever the focal length
    _, v_true = vp_from_pose(cam, pan=float(np.median(PANS)))
    assert est.values["horizon_row"].value == pytest.approx(v_true, abs=1.2)
    assert est.values["height"].source == "assumed" and est.camera.height == 1.4


def test_given_values_and_non_square_pixels(tmp_path):
    cam = Camera("true", (256, 256), 283.0, 566.0, 127.5, 127.5, 1.22, tilt=2.4)
    est = estimate_camera(_frames(tmp_path / "f", cam), hfov=2 * math.degrees(math.atan(128 / 283.0)),
                          source_size=(2048, 1024), height=1.22)
    assert est.camera.fx == pytest.approx(283.0, abs=0.01) and est.camera.fy == pytest.approx(566.0, abs=0.02)
    assert est.camera.height == 1.22 and est.values["height"].source == "given"
    assert est.camera.tilt == pytest.approx(2.4 + 0.0, abs=0.3)


def _labelled_frames(folder, cam: Camera, width: float, n: int = 6):
    """Frames and 0/1 road labels of a road ``width`` metres wide (format values:road=1;max=1)."""
    (folder / "labels").mkdir(parents=True, exist_ok=True)
    images, labels = [], []
    for i in range(n):
        img, lab = render_road(cam, RoadScene(width=width, texture_seed=i, offset=0.4 * (i % 3) - 0.4),
                               pan=cam.pan + PANS[i], supersample=1)
        images.append(folder / f"seq_{i:04d}.png")
        labels.append(folder / "labels" / f"seq_{i:04d}.png")
        cv2.imwrite(str(images[-1]), img)
        cv2.imwrite(str(labels[-1]), lab)
    return images, labels


BINARY = "values:road=1;max=1"


@pytest.mark.parametrize("width_factor", [1.0, 0.6])
def test_road_widths_measure_the_road_in_camera_heights(tmp_path, width_factor):
    """A road W metres wide seen from h metres measures W / h in every frame, whatever the focal
    length; the estimated height makes it ROAD_WIDTH metres wide."""
    width = ROAD_WIDTH * width_factor
    cam = Camera("true", (320, 240), 400.0, 400.0, 159.5, 119.5, 1.4, tilt=3.0)
    images, labels = _labelled_frames(tmp_path, cam, width)
    w = road_widths(labels, get_label_format(BINARY), cam)
    assert len(w) == 6
    # the frames' headings (PANS) widen the road's cut across the rows by 1/cos(pan): under 0.1 %
    assert np.median(w) == pytest.approx(width / 1.4, rel=0.03)
    est = estimate_camera(images, fx=400.0, labels=labels, label_format=get_label_format(BINARY))
    assert est.values["height"].source == "estimated" and "road footprint" in est.values["height"].how
    assert est.camera.height == pytest.approx(1.4 / width_factor, rel=0.04)
    assert not [x for x in est.warnings if x.startswith("height")]


def test_a_road_footprint_height_absorbs_an_unknown_pixel_aspect(tmp_path):
    """Frames squashed 2:1 (the Cityscapes pix2pix case: fy = 2 fx) estimated with square pixels:
    the road-footprint height makes up for it, so the estimated camera maps the road plane into
    the virtual camera where the true camera does."""
    true = Camera("true", (256, 256), 283.0, 566.0, 127.5, 127.5, 1.22, tilt=0.0)
    images, labels = _labelled_frames(tmp_path, true, ROAD_WIDTH)
    est = estimate_camera(images, fx=283.0, labels=labels, label_format=get_label_format(BINARY))
    assert est.camera.fy == pytest.approx(283.0) and est.values["fy"].source == "assumed"
    assert est.camera.height == pytest.approx(2 * 1.22, rel=0.04)
    virt = Camera("virtual", (400, 200), 300.0, 300.0, 199.5, 20.0, 1.2)
    ys, xs = np.mgrid[150:256:5, 0:256:5]
    pts = np.stack([xs.ravel(), ys.ravel(), np.ones(xs.size)]).astype(float)

    def below_horizon(cam):  # each point's virtual row, counted from the virtual horizon
        p = virt_H_src(cam, virt) @ pts
        return p[1] / p[2] - virt.cy

    ratio = below_horizon(est.camera) / below_horizon(true)
    assert np.median(ratio) == pytest.approx(1.0, abs=0.04) and np.percentile(np.abs(ratio - 1), 90) < 0.08
    # square pixels and the assumed 1.4 m without labels: the same road lands about 1.6x as far below
    plain = estimate_camera(images, fx=283.0)
    assert np.median(below_horizon(plain.camera) / below_horizon(true)) > 1.5


def _with_exif_focal35(jpeg: bytes, f35: int) -> bytes:
    """A JPEG with an APP1 EXIF segment holding FocalLengthIn35mmFilm (little-endian TIFF)."""
    ifd0 = struct.pack("<H", 1) + struct.pack("<HHII", 0x8769, 4, 1, 26) + struct.pack("<I", 0)
    exif = struct.pack("<H", 1) + struct.pack("<HHIHH", 0xA405, 3, 1, f35, 0) + struct.pack("<I", 0)
    tiff = b"II*\x00" + struct.pack("<I", 8) + ifd0 + exif
    body = b"Exif\x00\x00" + tiff
    return jpeg[:2] + b"\xff\xe1" + struct.pack(">H", len(body) + 2) + body + jpeg[2:]


def test_the_exif_focal_length_is_read(tmp_path):
    cam = Camera("true", (320, 240), 300.0, 300.0, 159.5, 119.5, 1.4, tilt=2.0)
    files = _frames(tmp_path / "f", cam, ext=".jpg")
    for p in files:
        p.write_bytes(_with_exif_focal35(p.read_bytes(), 28))
    assert exif_focal_35mm(files[0]) == 28.0 and cv2.imread(str(files[0])) is not None
    est = estimate_camera(files)
    assert est.values["fx"].source == "exif"
    assert est.camera.fx == pytest.approx(28 * math.hypot(320, 240) / math.hypot(36, 24), abs=1e-2)
    png = tmp_path / "x.png"
    cv2.imwrite(str(png), np.zeros((4, 4), np.uint8))
    assert exif_focal_35mm(png) is None and exif_focal_35mm(tmp_path / "missing.jpg") is None


def test_what_cannot_be_estimated_is_refused(tmp_path):
    cam = Camera("true", (320, 240), 300.0, 300.0, 159.5, 119.5, 1.4)
    files = _frames(tmp_path / "f", cam)
    with pytest.raises(InputError, match="too few"):
        estimate_camera(files[:4])
    blank = tmp_path / "blank"
    blank.mkdir()
    for i in range(6):
        cv2.imwrite(str(blank / f"b{i}.png"), np.full((240, 320, 3), 90, np.uint8))
    with pytest.raises(InputError, match="road vanishing point was found in 0 of 6"):
        estimate_camera(sorted(blank.iterdir()))
    cv2.imwrite(str(tmp_path / "f" / "seq_0009.png"), np.zeros((120, 160, 3), np.uint8))
    with pytest.raises(InputError, match="more than one size"):
        estimate_camera(sorted((tmp_path / "f").iterdir()))


def test_vcprep_camera_estimate_writes_a_camera_the_tools_read(tmp_path):
    cam = Camera("true", (320, 240), 300.0, 300.0, 159.5, 119.5, 1.4, tilt=3.0)
    _frames(tmp_path / "f", cam)
    labels = tmp_path / "labels"
    labels.mkdir()
    for i in range(6):  # labels ignoring the bottom 20 rows of every frame: the own vehicle
        lab = np.zeros((240, 320), np.uint8)
        lab[-20:] = 11
        cv2.imwrite(str(labels / f"seq_{i:04d}.png"), lab)
    out, vps = tmp_path / "cams" / "est.yaml", tmp_path / "vps.csv"
    proc = run_here("camera", "estimate", tmp_path / "f", "-o", out, "--fx", "300", "--vps", vps, "--labels", labels,
                 "-f", "camvid", "--json")
    assert proc.returncode == 0, proc.stderr
    rep = json.loads(proc.stdout)
    got = read_camera_yaml(out)
    assert got.fx == 300.0 and got.ego_rows == 20 and got.tilt == pytest.approx(3.0, abs=0.3)
    assert rep["values"]["tilt"]["source"] == "estimated" and rep["values"]["ego_rows"]["value"] == 20
    text = out.read_text()
    assert "tilt: " in text and "# ESTIMATED: median road VP of 6 of 6 frames" in text
    assert "height: 1.4   # ASSUMED" in text and "fx: 300   # GIVEN" in text
    assert sorted(read_vp_csv(vps)) == [f"seq_{i:04d}" for i in range(6)]
    # the estimate is a camera every command takes
    proc = run_cli("warp", "--camera", out, "--images", tmp_path / "f", "--within", vps, "--out", tmp_path / "store",
                   "--scale", "0.05", "-q")
    assert proc.returncode == 0, proc.stderr
    # errors: one line, naming what is missing
    assert_one_error_line(run_here("camera", "estimate", tmp_path / "f", "-o", out, "--fx", "300", "--hfov", "60"),
                          "--fx and --hfov")
    assert_one_error_line(run_here("camera", "estimate", tmp_path / "f" / "seq_0000.png", "-o", out), "too few")


def test_warp_with_camera_estimate_equals_warp_with_the_estimated_camera(tmp_path):
    cam = Camera("true", (320, 240), 277.128, 277.128, 159.5, 119.5, 1.4, tilt=2.0)
    _frames(tmp_path / "f", cam)
    proc = run_cli("warp", "--camera", "estimate", "--images", tmp_path / "f", "--out", tmp_path / "a",
                   "--scale", "0.05", "--jobs", "1")
    assert proc.returncode == 0, proc.stderr
    assert "camera ESTIMATED from the frames" in proc.stderr and "assumed fx" in proc.stderr
    est = tmp_path / "a" / "camera.estimated.yaml"
    assert read_camera_yaml(est).tilt == pytest.approx(2.0, abs=0.3)
    proc = run_cli("warp", "--camera", est, "--images", tmp_path / "f", "--out", tmp_path / "b", "--scale", "0.05",
                   "--jobs", "1", "-q")
    assert proc.returncode == 0, proc.stderr
    for name in sorted((tmp_path / "a" / "images").iterdir()):
        assert name.read_bytes() == (tmp_path / "b" / "images" / name.name).read_bytes()


def test_figure_camera_draws_the_horizon_where_the_camera_puts_it(tmp_path):
    cam = Camera("true", (320, 240), 300.0, 300.0, 159.5, 119.5, 1.4, tilt=5.0, ego_rows=20)
    files = _frames(tmp_path / "f", cam, n=2)
    (tmp_path / "cam.yaml").write_text(__import__("vcprep.camera", fromlist=["camera_to_yaml"]).camera_to_yaml(cam))
    out = tmp_path / "fig" / "cam.png"
    proc = run_here("figure", "camera", tmp_path / "cam.yaml", *files, "-o", out, "--width", "640", "--samples", "2")
    assert proc.returncode == 0, proc.stderr
    fig = cv2.imread(str(proc.stdout.strip()))
    assert fig.shape[1] == 640
    s = 320 / 320  # two columns of 320 px: frames at their own scale
    row = 56 + round((vp_from_pose(cam)[1] + 0.5) * s - 0.5)       # under the 56-px caption
    cyan = (fig[:, :, 0] > 200) & (fig[:, :, 1] > 200) & (fig[:, :, 2] < 80)
    assert cyan[row].mean() > 0.9                                    # the horizon, across both frames
    assert cyan[row - 3].mean() < 0.1 and cyan[row + 3].mean() < 0.1   # and nowhere near it
    ego = fig[56 + 240 - 10, :, 2].astype(int) - fig[56 + 240 - 10, :, 0]   # the ego band is tinted red
    top = fig[56 + 10, :, 2].astype(int) - fig[56 + 10, :, 0]
    assert ego.mean() > top.mean() + 40


def test_camera_estimate_wherever_frames_are_given(tmp_path):
    """vcprep vp --camera estimate gives the VPs of the estimated camera; a command without frames
    to estimate from says what to do instead."""
    cam = Camera("true", (320, 240), 277.128, 277.128, 159.5, 119.5, 1.4, tilt=2.0)
    _frames(tmp_path / "f", cam)
    a = run_here("vp", "--camera", "estimate", tmp_path / "f")
    assert a.returncode == 0, a.stderr
    assert "camera ESTIMATED from 6 frames" in a.stderr
    assert run_here("camera", "estimate", tmp_path / "f", "-o", tmp_path / "c.yaml", "-q").returncode == 0
    b = run_here("vp", "--camera", tmp_path / "c.yaml", tmp_path / "f")
    assert a.stdout == b.stdout
    assert_one_error_line(run_here("camera", "show", "estimate"), "not a camera preset")
