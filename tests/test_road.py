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

from conftest import run_cli
from test_video import model  # noqa: F401  (the module's small virtual-camera model)
from vcprep.camera import load_cameras
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
