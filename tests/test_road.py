"""The one road for a frame (vctrain.predict.road): image folders go through the in-memory frame
pipeline. The oracle is the store path (the frames warped into a store with vcprep's build, read
back and predicted: ``predict_images(..., keep_store=...)``), which was the folder path until the
road replaced it: on the shipped examples, for a virtual-camera model and a resize model, the
probability PNGs must be bit-identical."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from conftest import assert_one_error_line, run_cli
from test_video import model  # noqa: F401  (the module's small virtual-camera model)
from vcprep.camera import camera_to_yaml, load_cameras
from vcprep.errors import InputError
from vcprep.io import read_image, write_png
from vctrain.predict import Predictor, predict_images, run_road

torch.set_num_threads(1)
ROOT = Path(__file__).resolve().parent.parent
CAMVID = ROOT / "examples/camvid/images"
KITTI = ROOT / "examples/kitti/image_2"
SHIPPED = ROOT / "models/road-multicamera/road.pt"


def _camera(folder: Path):
    if folder == CAMVID:
        return load_cameras("camvid")
    return load_cameras(ROOT / "examples/kitti/calib", next(folder.iterdir()), per_frame=True)  # per-frame files


def _probs(out: Path) -> dict[str, np.ndarray]:
    return {p.name: read_image(p).array for p in sorted(out.glob("*_prob.png"))}


@pytest.mark.parametrize("which", ["virtual", "resize"])
@pytest.mark.parametrize("folder,within", [(CAMVID, "estimate"), (CAMVID, "none"), (KITTI, "auto")],
                         ids=["camvid-own-vps", "camvid-mount-pose", "kitti-calib-folder"])
def test_folder_road_equals_the_store_path(model, which, folder, within, tmp_path):  # noqa: F811
    pred = Predictor(model if which == "virtual" else SHIPPED, "cpu")
    assert pred.mode == which
    cam = _camera(folder)
    road = predict_images(pred, [folder], tmp_path / "road", cam, progress=False, within=within)
    stored = predict_images(pred, [folder], tmp_path / "store", cam, progress=False, within=within,
                            keep_store=tmp_path / "kept")
    assert [p.name for p in road] == [p.name for p in stored]
    a, b = _probs(tmp_path / "road"), _probs(tmp_path / "store")
    assert len(a) == len(list(folder.iterdir())) and a.keys() == b.keys()
    for name in a:
        assert np.array_equal(a[name], b[name]), name
    assert (tmp_path / "kept/manifest.jsonl").exists() == (which == "virtual")


def _folder_with_a_bad_frame(tmp_path: Path) -> Path:
    folder = tmp_path / "frames"
    folder.mkdir()
    for p in sorted(CAMVID.iterdir())[:2]:
        write_png(folder / p.name, read_image(p).array)
    good = (folder / sorted(CAMVID.iterdir())[0].name).read_bytes()
    (folder / "broken.png").write_bytes(good[: len(good) // 3])  # a truncated file
    return folder


@pytest.mark.parametrize("within", ["estimate", "none"])
def test_a_bad_frame_is_named_and_the_others_predicted(model, within, tmp_path):  # noqa: F811
    folder = _folder_with_a_bad_frame(tmp_path)
    run = run_road(Predictor(model, "cpu"), [folder], tmp_path / "out", load_cameras("camvid"), progress=False,
                   within=within, overlay=True)
    assert [p.name for p in run.written] == ["0001TP_007170_mask.png", "0006R0_f02400_mask.png"]
    assert [Path(f).name for f, _ in run.failed] == ["broken.png"]
    assert sorted(p.name for p in (tmp_path / "out").iterdir() if p.name.startswith("broken")) == []
    with pytest.raises(InputError):  # the library call raises the frame's error, after the others
        predict_images(Predictor(model, "cpu"), [folder], tmp_path / "out2", load_cameras("camvid"), progress=False,
                       within=within)
    assert len(list((tmp_path / "out2").glob("*_mask.png"))) == 2


def test_predict_cli_names_a_bad_frame_and_exits_1(tmp_path):
    folder = _folder_with_a_bad_frame(tmp_path)
    proc = run_cli("predict", SHIPPED, folder, "--out", tmp_path / "out", prog="vctrain")
    assert proc.returncode == 1
    assert [Path(x).name for x in proc.stdout.split()] == ["0001TP_007170_mask.png", "0006R0_f02400_mask.png"]
    skipped = [ln for ln in proc.stderr.splitlines() if ln.startswith("skipped: ")]
    assert len(skipped) == 1 and "broken.png" in skipped[0]
    error = [ln for ln in proc.stderr.splitlines() if ln.startswith("Error: ")]
    assert len(error) == 1 and "broken.png" in error[0] and "the other 2 frames are written" in error[0]
    assert not list((tmp_path / "out").glob("broken*"))


# --- the paths around the road: cameras checked, estimated from a video, graphs on videos and other sizes

from test_video import drive  # noqa: E402,F401  (a synthetic 240x180 drive as frames and an mp4)


@pytest.mark.parametrize("spec", ["camvdi", "mycam.yaml"])
def test_camera_is_checked_even_where_the_model_needs_none(spec, tmp_path):
    """The shipped model reads frames as they are, but a mistyped or missing camera is still an error."""
    proc = run_cli("predict", SHIPPED, "--camera", spec, CAMVID, "--out", tmp_path / "o", prog="vctrain")
    assert_one_error_line(proc, spec, "not a camera preset and no such file")
    assert not (tmp_path / "o").exists() or not list((tmp_path / "o").iterdir())


def test_camera_estimate_works_on_a_video(model, drive, tmp_path):  # noqa: F811
    root, cam, frames, video = drive
    proc = run_cli("predict", model, "--camera", "estimate", video, "--out", tmp_path / "o", prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    assert f"{len(frames)} frames sampled from drive.mp4" in proc.stderr
    assert len(list((tmp_path / "o/drive").glob("*_mask.png"))) == len(frames)
    proc = run_cli("camera", "estimate", video, "-o", tmp_path / "est.yaml")
    assert proc.returncode == 0, proc.stderr
    assert f"of {len(frames)} frames with a road VP" in proc.stderr
    est = load_cameras(tmp_path / "est.yaml")
    assert abs(est.tilt - cam.tilt) < 2.0 and est.size == cam.size  # the rendered camera's own tilt


def test_a_graph_predicts_a_video_and_the_model_without_a_camera(drive, tmp_path):  # noqa: F811
    """The shipped (resize) model exported without --camera, for the drive's frame size: the graph
    takes the video as the .pt does, and their masks agree."""
    root, cam, frames, video = drive
    proc = run_cli("export", SHIPPED, "--size", f"{cam.size[0]}x{cam.size[1]}", "-o", tmp_path / "road.onnx",
                   prog="vctrain")
    assert proc.returncode == 0, proc.stderr
    for model_file, out in ((tmp_path / "road.onnx", "g"), (SHIPPED, "pt")):
        proc = run_cli("predict", model_file, video, "--out", tmp_path / out, prog="vctrain")
        assert proc.returncode == 0, proc.stderr
    for i in range(len(frames)):
        a = read_image(tmp_path / f"g/drive/drive_{i:06d}_mask.png").array
        b = read_image(tmp_path / f"pt/drive/drive_{i:06d}_mask.png").array
        assert (a == b).mean() > 0.999  # onnxruntime vs torch: 1e-6 apart, a pixel at P = 0.5 may flip
    assert_one_error_line(run_cli("export", SHIPPED, "-o", tmp_path / "x.onnx", prog="vctrain"), "--frame", "--size")


def _masks(folder: Path) -> dict[str, np.ndarray]:
    return {p.relative_to(folder).as_posix(): read_image(p).array for p in sorted(folder.rglob("*_mask.png"))}


@pytest.mark.parametrize("which", ["virtual", "resize"])
def test_a_graph_refuses_its_camera_at_another_resolution_and_says_the_export(model, drive, which, tmp_path):  # noqa: F811
    """A graph exported for the drive's camera at 480x360 refuses its 240x180 frames (a folder and a
    video: no silent resize, issue 69) with one line naming both sizes and the export that fits; that
    export, run, gives the .pt model's masks on the same frames (but for float rounding at the
    road's edge)."""
    import shlex

    root, cam, frames, video = drive
    (tmp_path / "big.yaml").write_text(camera_to_yaml(cam.resized(2.0)))  # the same camera at 480x360
    (tmp_path / "frames").mkdir()
    for i, f in enumerate(frames[:4]):
        write_png(tmp_path / f"frames/f{i}.png", f)
    ckpt = model if which == "virtual" else SHIPPED
    assert run_cli("export", ckpt, "--camera", tmp_path / "big.yaml", "-o", tmp_path / "big.onnx",
                   prog="vctrain").returncode == 0
    for src in (tmp_path / "frames", video):
        g = run_cli("predict", tmp_path / "big.onnx", src, "--out", tmp_path / "g", prog="vctrain")
        assert_one_error_line(g, "240x180", "480x360", "vctrain export")
        assert not (tmp_path / "g").exists()
    fix = g.stderr.strip().rsplit("(", 1)[1].rstrip(")")  # 'export a graph for 240x180: vctrain export ...'
    argv = shlex.split(fix.split(": ", 1)[1])
    assert argv[:2] == ["vctrain", "export"] and "--frame" in argv
    argv[argv.index("--frame") + 1] = str(tmp_path / "frames/f0.png")
    argv[argv.index("-o") + 1] = str(tmp_path / "small.onnx")
    assert run_cli(*argv[1:], prog="vctrain").returncode == 0
    g = run_cli("predict", tmp_path / "small.onnx", tmp_path / "frames", "--out", tmp_path / "g", prog="vctrain")
    assert g.returncode == 0, g.stderr
    pt = run_cli("predict", ckpt, "--camera", tmp_path / "big.yaml", tmp_path / "frames", "--out", tmp_path / "pt",
                 "--ego", "none", prog="vctrain")
    assert pt.returncode == 0, pt.stderr
    a, b = _masks(tmp_path / "g"), _masks(tmp_path / "pt")
    assert a.keys() == b.keys() and len(a) == 4
    for name in a:
        assert a[name].shape == (180, 240), name
        assert (a[name] == b[name]).mean() > 0.99, (name, (a[name] == b[name]).mean())
        assert 0.02 < (a[name] > 0).mean() < 0.98, name  # road and not road: a real mask, not an empty one


def test_a_graph_refuses_another_aspect_and_leaves_no_folder(drive, tmp_path):  # noqa: F811
    root, cam, frames, video = drive
    assert run_cli("export", SHIPPED, "--camera", root / "cam.yaml", "-o", tmp_path / "g.onnx",
                   prog="vctrain").returncode == 0
    (tmp_path / "frames").mkdir()
    write_png(tmp_path / "frames/wide.png", frames[0][:150])  # 240x150: another aspect (a crop)
    proc = run_cli("predict", tmp_path / "g.onnx", tmp_path / "frames", "--out", tmp_path / "o", prog="vctrain")
    assert proc.returncode == 1
    error = [ln for ln in proc.stderr.splitlines() if ln.startswith("Error: ")]
    assert len(error) == 1 and "wide.png" in error[0] and "240x150" in error[0] and "240x180" in error[0]
    assert "not a uniform rescale" in error[0] and "vctrain export" in error[0] and "--frame" in error[0]
    assert not (tmp_path / "o").exists()


def _folder_with_an_odd_frame_first(tmp_path: Path) -> Path:
    """The shipped CamVid frames, a truncated one and, first in order, one of another aspect (a crop)."""
    folder = _folder_with_a_bad_frame(tmp_path)
    write_png(folder / "0000_odd.png", read_image(sorted(CAMVID.iterdir())[0]).array[:250, :400])
    return folder


@pytest.mark.parametrize("which", ["virtual", "resize", "graph"])
def test_every_model_skips_and_names_a_frame_it_cannot_predict(model, which, tmp_path):  # noqa: F811
    """A folder whose first frame is of another size and one of whose frames is truncated: every
    model kind names each frame it cannot predict ('skipped: <file>: ...'), writes the others and
    exits 1 (a resize model reads the other size as it is)."""
    folder = _folder_with_an_odd_frame_first(tmp_path)
    ckpt = {"virtual": model, "resize": SHIPPED, "graph": tmp_path / "g.onnx"}[which]
    if which == "graph":
        assert run_cli("export", SHIPPED, "--camera", "camvid", "--frame", CAMVID / "0001TP_007170.png", "-o", ckpt,
                       prog="vctrain").returncode == 0
    proc = run_cli("predict", ckpt, "--camera", "camvid", folder, "--out", tmp_path / "out", prog="vctrain")
    assert proc.returncode == 1
    skipped = sorted(Path(ln.split(": ")[1]).name for ln in proc.stderr.splitlines() if ln.startswith("skipped: "))
    odd_ok = which == "resize"
    assert skipped == (["broken.png"] if odd_ok else ["0000_odd.png", "broken.png"]), proc.stderr
    written = sorted(Path(x).name for x in proc.stdout.split())
    assert written == (["0000_odd_mask.png"] if odd_ok else []) + ["0001TP_007170_mask.png", "0006R0_f02400_mask.png"]
    for name in written:
        assert read_image(tmp_path / "out" / name).array.shape == ((250, 400) if "odd" in name else (360, 480))
    if not odd_ok:
        odd = [ln for ln in proc.stderr.splitlines() if "0000_odd.png" in ln and ln.startswith("skipped: ")][0]
        assert "400x250" in odd and "480x360" in odd and "not a uniform rescale" in odd
