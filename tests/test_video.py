"""Video in, masks and overlay videos out (vctrain.predict.video), and the in-memory frame predictor it
runs on (vctrain.predict.frames). The oracle is the folder path of ``vctrain predict`` (warp into a
temporary store, infer, back-project) on the same frames as PNG files: the in-memory path must
give the same numbers, and a video the same masks as its decoded frames."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from typer.testing import CliRunner

from conftest import assert_one_error_line, run_cli
from vcprep.camera import PRESETS, camera_to_yaml
from vcprep.errors import InputError
from vcprep.warp import pose_from_vp, vp_from_pose
from vcprep.io import read_image, write_png
from vcprep.synthetic import RoadScene, render_road
from vcprep.vp import estimate_files
from vctrain.cli import app
from vctrain.predict import FramePredictor, StreamingVPs
from vctrain.predict import Predictor, predict_images

runner = CliRunner()
torch.set_num_threads(1)
N_FRAMES = 8


@pytest.fixture(scope="module")
def model(tiny_vc_model) -> Path:
    """The suite's tiny virtual-camera model (conftest: a width-8 network, 3 epochs, 110x56): every
    test here compares two paths through the same network."""
    return tiny_vc_model


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    """A short synthetic drive (240x180, the road drifting sideways, the camera panning a little),
    its camera with 12 own-vehicle rows as YAML, and the frames written as an mp4v video."""
    root = tmp_path_factory.mktemp("drive")
    cam = replace(PRESETS["camvid"].resized(0.25), ego_rows=12)
    frames = [render_road(cam, RoadScene(offset=0.25 * i, texture_seed=1), pan=1.5 * np.sin(i / 2), supersample=1)[0]
              for i in range(N_FRAMES)]
    (root / "cam.yaml").write_text(camera_to_yaml(cam))
    video = root / "drive.mp4"
    w = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, cam.size)
    for f in frames:
        w.write(f)
    w.release()
    return root, cam, frames, video


def _decode(path: Path) -> list[np.ndarray]:
    cap, out = cv2.VideoCapture(str(path)), []
    while True:
        ok, f = cap.read()
        if not ok:
            return out
        out.append(f)


def _p8(prob: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(prob * 255.0), 0, 255).astype(np.uint8)


def test_frame_predictor_equals_the_store_path(model, drive, tmp_path):
    """Fixed pose and per-frame VPs: the in-memory warp is the store's PNG bit for bit, and the
    probability equals what predict_images writes (own-vehicle rows cut off in both)."""
    _, cam, frames, _ = drive
    (tmp_path / "imgs").mkdir()
    for i, f in enumerate(frames[:3]):
        write_png(tmp_path / "imgs" / f"d_{i}.png", f)
    pred = Predictor(model, "cpu")
    # fixed pose (the camera's)
    predict_images(pred, [tmp_path / "imgs"], tmp_path / "fixed", cam, progress=False, within="none",
                   keep_store=tmp_path / "kept_fixed")
    fp = FramePredictor(pred, cam, cam.size)
    for i, f in enumerate(frames[:3]):
        warped, rec = fp.warp(f)
        assert np.array_equal(warped, read_image(tmp_path / "kept_fixed/images" / f"d_{i}.png").array)
        assert np.array_equal(_p8(fp.predict(f)), read_image(tmp_path / "fixed" / f"d_{i}_prob.png").array)
    assert fp.times.frames == 3 and fp.times.warp > 0 and fp.times.network > 0 and fp.times.backproject > 0
    # per-frame VPs (given), the virtual rectangle extended for all of them in advance as the folder path does
    vps = [vp_from_pose(cam, 3.0 * (i - 1), 1.0 - i) for i in range(3)]
    (tmp_path / "vps.csv").write_text("id,u,v\n" + "".join(f"d_{i},{u},{v}\n" for i, (u, v) in enumerate(vps)))
    predict_images(pred, [tmp_path / "imgs"], tmp_path / "own", cam, progress=False, within=str(tmp_path / "vps.csv"),
                   keep_store=tmp_path / "kept_own")
    fp = FramePredictor(pred, cam, cam.size, poses=[pose_from_vp(cam, vp) for vp in vps])
    for i, (f, vp) in enumerate(zip(frames, vps)):
        warped, rec = fp.warp(f, vp)
        assert np.array_equal(warped, read_image(tmp_path / "kept_own/images" / f"d_{i}.png").array)
        assert np.array_equal(_p8(fp.predict(f, vp)), read_image(tmp_path / "own" / f"d_{i}_prob.png").array)


def test_video_masks_equal_the_folder_path_on_its_decoded_frames(model, drive, tmp_path):
    root, cam, _, video = drive
    decoded = _decode(video)
    assert len(decoded) == N_FRAMES  # mp4v round-trips in opencv-python-headless
    r = runner.invoke(app, ["predict", str(model), "--camera", str(root / "cam.yaml"), str(video), "--overlay",
                            "--out", str(tmp_path / "out"), "--quiet"])
    assert r.exit_code == 0, r.output
    masks = sorted((tmp_path / "out/drive").glob("*_mask.png"))
    assert [m.name for m in masks] == [f"drive_{i:06d}_mask.png" for i in range(N_FRAMES)]
    assert r.stdout.split() == [str(m) for m in masks] + [str(tmp_path / "out/drive_overlay.mp4")]
    (tmp_path / "frames").mkdir()
    for i, f in enumerate(decoded):
        write_png(tmp_path / "frames" / f"drive_{i:06d}.png", f)
    r2 = runner.invoke(app, ["predict", str(model), "--camera", str(root / "cam.yaml"), str(tmp_path / "frames"),
                             "--out", str(tmp_path / "folder"), "--quiet"])
    assert r2.exit_code == 0, r2.output
    for m in masks:
        a = read_image(m, label=True).array
        assert a.shape == (180, 240)
        assert np.array_equal(a, read_image(tmp_path / "folder" / m.name, label=True).array)
        p = m.with_name(m.name.replace("_mask", "_prob"))
        assert np.array_equal(read_image(p, label=True).array,
                              read_image(tmp_path / "folder" / p.name, label=True).array)
    over = _decode(tmp_path / "out/drive_overlay.mp4")
    assert len(over) == N_FRAMES and over[0].shape == (180, 240, 3)
    assert not list((tmp_path / "out").glob(".*"))  # no temporary file left
    # --mask-video: the same masks, losslessly, as one video
    r3 = runner.invoke(app, ["predict", str(model), "--camera", str(root / "cam.yaml"), str(video), "--mask-video",
                             "--out", str(tmp_path / "mv"), "--quiet"])
    assert r3.exit_code == 0, r3.output
    mv = _decode(tmp_path / "mv/drive_mask.mkv")
    assert len(mv) == N_FRAMES
    for m, f in zip(masks, mv):
        assert np.array_equal(f[..., 0], read_image(m, label=True).array)


def test_streaming_vps_equal_the_whole_sequence_rule(drive, tmp_path):
    """VPs estimated as the frames stream by, smoothed over 2 frames either side, equal the
    whole-drive rule (estimate, reliability, smoothing over the sequence) on the frames as files,
    and lie near the rendered pose's VP."""
    _, cam, frames, _ = drive
    files = []
    for i, f in enumerate(frames):
        files.append(tmp_path / f"drive_{i:06d}.png")
        write_png(files[-1], f)
    whole = estimate_files(files, cam, smooth=2)
    # (one frame has too few lines: it takes its accepted neighbours' median in both)
    assert sum(r.status == "accepted" for r in whole) >= N_FRAMES - 2
    sv = StreamingVPs(cam, window=2)
    got = []
    for i, f in enumerate(frames):
        got += sv.push(i, f)
        assert [k for k, _ in got] == list(range(max(0, i - 1)))  # a frame is final 2 frames later
    got += sv.flush()
    assert [k for k, _ in got] == list(range(N_FRAMES))
    for (_, r), w in zip(got, whole):
        assert r.vp == pytest.approx(w.vp, abs=1e-9) and r.status == w.status
    for i, (_, r) in enumerate(got):  # near the truth (2 % of the width: frame 0 takes its panned neighbours)
        assert np.hypot(*np.subtract(r.vp, vp_from_pose(cam, 1.5 * np.sin(i / 2), cam.tilt))) < 5.0


def test_video_with_per_frame_vps_and_a_broken_frame(model, drive, tmp_path):
    """An MJPG video whose frame 3 cannot be decoded: said on stderr with its number, every other
    frame predicted (with per-frame VPs), the overlay keeps the input's length; a truncated
    copy says where it ends."""
    root, _, frames, _ = drive
    video = tmp_path / "bad.avi"
    w = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (240, 180))
    for f in frames:
        w.write(f)
    w.release()
    data = bytearray(video.read_bytes())
    starts = [k for k in range(len(data) - 2) if data[k:k + 3] == b"\xff\xd8\xff"]
    assert len(starts) == N_FRAMES
    data[starts[3]:starts[3] + 600] = bytes(600)  # frame 3's JPEG header is gone
    video.write_bytes(bytes(data))
    r = runner.invoke(app, ["predict", str(model), "--camera", str(root / "cam.yaml"), str(video), "--within",
                            "estimate", "--overlay", "--out", str(tmp_path / "out")])
    assert r.exit_code == 0, r.output
    assert "frame 3 cannot be decoded" in r.stderr
    masks = sorted(p.name for p in (tmp_path / "out/bad").glob("*_mask.png"))
    assert masks == [f"bad_{i:06d}_mask.png" for i in range(N_FRAMES) if i != 3]
    assert len(_decode(tmp_path / "out/bad_overlay.mp4")) == N_FRAMES
    short = tmp_path / "short.avi"
    short.write_bytes(bytes(data[:starts[6] + 100]))
    r = runner.invoke(app, ["predict", str(model), "--camera", str(root / "cam.yaml"), str(short), "--mask-video",
                            "--out", str(tmp_path / "o2"), "--quiet"])
    assert r.exit_code == 0, r.output
    assert "frame 3 cannot be decoded" in r.stderr and f"ends after 6 of the {N_FRAMES} frames" in r.stderr
    assert len(_decode(tmp_path / "o2/short_mask.mkv")) == 6


def test_a_file_that_is_no_video_is_one_error_line(model, tmp_path):
    (tmp_path / "notes.mp4").write_text("not a video\n")
    proc = run_cli("predict", model, "--camera", "camvid", tmp_path / "notes.mp4", "--out", tmp_path / "o",
                   prog="vctrain")
    assert_one_error_line(proc, "notes.mp4", "cannot read as a video")
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").rglob("*.png"))


# -- the own vehicle found from the video's own frames (issue 35) -----------------------------------
# Oracle: tests/test_ego.py's rendered drive (offset, pan, tilt, texture and traffic vary) with a
# bonnet painted at the same place in every frame, whose top we choose; and the folder path with a
# camera that states the rows.

BONNET = 25


@pytest.fixture(scope="module")
def ego_drive(tmp_path_factory):
    """36 distinct 240x180 frames with and without a painted bonnet, as mp4v videos, and the
    CamVid camera at that size stating no ego_rows."""
    from test_ego import _drive, _paint_bonnet

    root = tmp_path_factory.mktemp("ego_drive")
    frames = _drive()
    cam = PRESETS["camvid"].for_image_size((240, 180))
    (root / "cam.yaml").write_text(camera_to_yaml(cam))
    for name, fs in (("bonnet", [_paint_bonnet(f, BONNET) for f in frames]), ("plain", frames)):
        w = cv2.VideoWriter(str(root / f"{name}.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (240, 180))
        for f in fs:
            w.write(f)
        w.release()
    return root, cam


def test_video_finds_its_own_vehicle_and_predicts_with_it(model, ego_drive, tmp_path):
    """No ego_rows in the camera: the rows are found from the video's frames (said on stderr), and
    every mask is the folder path's with a camera that states them; --ego none warps the bonnet."""
    import re

    root, cam = ego_drive
    r = runner.invoke(app, ["predict", str(model), "--camera", str(root / "cam.yaml"), str(root / "bonnet.mp4"),
                            "--out", str(tmp_path / "auto")])
    assert r.exit_code == 0, r.output
    m = re.search(r"own vehicle: (\d+) rows found from the frames \((.*)\); set ego_rows in the camera file", r.stderr)
    assert m, r.stderr
    rows = int(m.group(1))
    assert abs(rows - BONNET) <= 2
    decoded = _decode(root / "bonnet.mp4")
    (tmp_path / "frames").mkdir()
    for i, f in enumerate(decoded):
        write_png(tmp_path / "frames" / f"bonnet_{i:06d}.png", f)
    (tmp_path / "ego.yaml").write_text(camera_to_yaml(replace(cam, ego_rows=rows)))
    r2 = runner.invoke(app, ["predict", str(model), "--camera", str(tmp_path / "ego.yaml"), str(tmp_path / "frames"),
                             "--out", str(tmp_path / "folder"), "--quiet"])
    assert r2.exit_code == 0, r2.output
    probs = sorted((tmp_path / "auto/bonnet").glob("*_prob.png"))
    assert len(probs) == len(decoded) == 36
    for p in probs:
        assert np.array_equal(read_image(p, label=True).array, read_image(tmp_path / "folder" / p.name, label=True).array)
    # --ego none: no search, the bonnet is warped as road surface (other numbers), nothing said
    r3 = runner.invoke(app, ["predict", str(model), "--camera", str(root / "cam.yaml"), str(root / "bonnet.mp4"),
                             "--out", str(tmp_path / "none"), "--ego", "none"])
    assert r3.exit_code == 0, r3.output
    assert "own vehicle" not in r3.stderr
    assert any(not np.array_equal(read_image(p, label=True).array,
                                  read_image(tmp_path / "none/bonnet" / p.name, label=True).array) for p in probs)


def test_video_without_own_vehicle_finds_none(ego_drive, drive):
    from vcprep.io import open_video
    from vctrain.predict import ego_camera

    root, cam = ego_drive
    said: list[str] = []
    cap, info = open_video(root / "plain.mp4")
    cap.release()
    got = ego_camera(cam, info, "auto", said.append)
    assert got.ego_rows == 0 and len(said) == 1 and said[0].startswith("own vehicle: none found from the frames")
    assert ego_camera(cam, info, "7").ego_rows == 7 and ego_camera(cam, info, "none").ego_rows == 0
    with pytest.raises(InputError, match="--ego"):
        ego_camera(cam, info, "180")
    # 8 frames are too few to tell a fixed vehicle from a scene: not looked for, and said
    vroot, vcam, _, video = drive
    cap, info = open_video(video)
    cap.release()
    said.clear()
    assert ego_camera(replace(vcam, ego_rows=0), info, "auto", said.append).ego_rows == 0
    assert len(said) == 1 and "not looked for" in said[0] and "too few" in said[0]
    assert ego_camera(vcam, info, "auto", said.append).ego_rows == 12 and len(said) == 1  # stated: kept, no search


def test_a_cut_off_mp4_is_said_to_be_cut_off_not_blamed_on_the_codec(model, drive, tmp_path):
    """An mp4 copied or recorded only in part has no index ('moov' box, written last): the error says
    so, where it used to blame a missing codec; a file that is no video at all still gets the codec
    advice."""
    root, cam, frames, video = drive
    data = video.read_bytes()
    (tmp_path / "cut.mp4").write_bytes(data[: len(data) // 2])
    proc = run_cli("predict", model, "--camera", root / "cam.yaml", tmp_path / "cut.mp4", "--out", tmp_path / "o",
                   prog="vctrain")
    assert_one_error_line(proc, "cut.mp4", "without its index", "cut off")
    (tmp_path / "text.mp4").write_text("not a video\n")
    proc = run_cli("predict", model, "--camera", root / "cam.yaml", tmp_path / "text.mp4", "--out", tmp_path / "o",
                   prog="vctrain")
    assert_one_error_line(proc, "text.mp4", "codec")


def test_a_folder_of_one_camera_finds_its_own_vehicle_as_a_video_does(model, ego_drive, tmp_path):
    """A folder's frames with a camera that states no ego_rows: the rows are found from the frames (said
    on stderr) and the masks are those of a camera that states them; a camera that states them is
    not searched; --ego none warps the bonnet."""
    import re
    from test_ego import _drive, _paint_bonnet

    root, cam = ego_drive
    (tmp_path / "frames").mkdir()
    for i, f in enumerate(_drive()):
        write_png(tmp_path / "frames" / f"b_{i:03d}.png", _paint_bonnet(f, BONNET))
    r = runner.invoke(app, ["predict", str(model), "--camera", str(root / "cam.yaml"), str(tmp_path / "frames"),
                            "--out", str(tmp_path / "auto")])
    assert r.exit_code == 0, r.output
    m = re.search(r"own vehicle: (\d+) rows found from the frames", r.stderr)
    assert m and abs(int(m.group(1)) - BONNET) <= 2, r.stderr
    (tmp_path / "ego.yaml").write_text(camera_to_yaml(replace(cam, ego_rows=int(m.group(1)))))
    r2 = runner.invoke(app, ["predict", str(model), "--camera", str(tmp_path / "ego.yaml"), str(tmp_path / "frames"),
                             "--out", str(tmp_path / "stated")])
    assert r2.exit_code == 0 and "found from the frames" not in r2.stderr, r2.output  # not searched
    assert "(the camera's ego_rows)" in r2.stderr  # (stderr says where the rows come from)
    probs = sorted((tmp_path / "auto").glob("*_prob.png"))
    assert len(probs) == 36
    for p in probs:
        assert np.array_equal(read_image(p).array, read_image(tmp_path / "stated" / p.name).array)
    r3 = runner.invoke(app, ["predict", str(model), "--camera", str(root / "cam.yaml"), str(tmp_path / "frames"),
                             "--out", str(tmp_path / "none"), "--ego", "none"])
    assert r3.exit_code == 0 and "found from the frames" not in r3.stderr and "own vehicle: none" in r3.stderr
    assert any(not np.array_equal(read_image(p).array, read_image(tmp_path / "none" / p.name).array) for p in probs)
