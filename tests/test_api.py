"""The Python face: ``vctrain.load(...).segment(frame, camera)`` and its kin (vctrain.predict.model).

The oracle is ``vctrain predict`` run on the same frames as files, each with its default engine: the
in-memory masks must equal its ``_mask.png`` bit for bit (and P(road) its ``_prob.png``), for the shipped model and for a
virtual-camera model with a camera; ``bev=True`` must give the road in metres that ``predict
--bev`` prints. Bad input raises the project's own error."""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

import vctrain
from conftest import EXAMPLES, run_cli
from vcprep.camera import PRESETS, camera_to_yaml
from vcprep.errors import InputError, VCError
from vcprep.synthetic import RoadScene, render_road

torch.set_num_threads(1)
CAMVID = sorted((EXAMPLES / "camvid" / "images").glob("*.png"))
KITTI_FRAME = EXAMPLES / "kitti" / "image_2" / "um_000000.png"
KITTI_CALIB = EXAMPLES / "kitti" / "calib" / "um_000000.txt"


@pytest.fixture(scope="module")
def shipped():
    return vctrain.load("shipped")  # the default engine, as predict's (_predict)


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    """Five frames of a short synthetic drive (240x180, the road drifting, the camera panning) as
    PNG files of one sequence and as an mp4v video; their camera (12 own-vehicle rows) as YAML."""
    root = tmp_path_factory.mktemp("api_drive")
    cam = replace(PRESETS["camvid"].resized(0.25), ego_rows=12)
    (root / "cam.yaml").write_text(camera_to_yaml(cam))
    (root / "frames").mkdir()
    video = cv2.VideoWriter(str(root / "drive.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, cam.size)
    for i in range(5):
        img = render_road(cam, RoadScene(offset=0.25 * i, texture_seed=1), pan=1.5 * np.sin(i / 2), supersample=1)[0]
        cv2.imwrite(str(root / "frames" / f"d_{i:06d}.png"), img)
        video.write(img)
    video.release()
    return root


def _predict(tmp_path: Path, *args) -> tuple[Path, str]:
    out = tmp_path / "out"
    proc = run_cli("predict", *args, "--out", out, "--threads", "1", "--quiet", prog="vctrain")  # its default engine
    assert proc.returncode == 0, proc.stderr
    return out, proc.stdout


def _same_as_written(result, out: Path, stem: str) -> None:
    """``result``'s mask and P(road) against the PNGs ``vctrain predict`` wrote for the frame."""
    mask = cv2.imread(str(out / f"{stem}_mask.png"), cv2.IMREAD_UNCHANGED)
    prob = cv2.imread(str(out / f"{stem}_prob.png"), cv2.IMREAD_UNCHANGED)
    assert result.mask.dtype == bool and result.prob.dtype == np.float32
    assert result.mask.shape == result.prob.shape == mask.shape
    assert np.array_equal(result.mask, mask == 255), f"{stem}: {np.mean(result.mask != (mask == 255)):.2e} differ"
    assert np.array_equal(np.clip(np.rint(result.prob * 255.0), 0, 255).astype(np.uint8), prob)


def test_shipped_model_by_name_gives_predicts_masks(shipped, tmp_path):
    """``vctrain.load("shipped")`` and ``vctrain predict shipped``, no engine given either: the same
    engine (the fastest installed, vctrain.predict.settings.DEFAULT_ENGINE), the same masks."""
    out, _ = _predict(tmp_path, "shipped", EXAMPLES / "camvid" / "images")
    assert shipped.engine == json.loads((out / "predict.json").read_text())["engine"]
    assert shipped.kind == "resize" and not shipped.needs_camera
    for f in CAMVID:
        _same_as_written(shipped.segment(cv2.imread(str(f))), out, f.stem)
    files = list(shipped.segment_files([EXAMPLES / "camvid" / "images"]))
    assert [Path(r.source).name for r in files] == [f.name for f in CAMVID]
    for f, r in zip(CAMVID, files):
        _same_as_written(r, out, f.stem)


@pytest.mark.parametrize("camera, within", [("cam.yaml", "none"), ("cam.yaml", "estimate"), ("camvid", "auto")])
def test_virtual_model_with_camera_gives_predicts_masks(tiny_vc_model, drive, tmp_path, camera, within):
    """A folder's frames together (VPs estimated as one sequence, one rectangle; the preset states no
    own vehicle: it is looked for in the frames) and one frame alone."""
    model = vctrain.load(tiny_vc_model)
    assert model.kind == "virtual" and model.needs_camera
    camera = str(drive / camera) if camera.endswith(".yaml") else camera
    frames = sorted((drive / "frames").glob("*.png"))
    out, _ = _predict(tmp_path, tiny_vc_model, drive / "frames", "--camera", camera, "--within", within)
    results = model.segment_frames([cv2.imread(str(f)) for f in frames], camera, within=within)
    for f, r in zip(frames, results):
        _same_as_written(r, out, f.stem)
    for f, r in zip(frames, model.segment_files([drive / "frames"], camera, within=within)):
        _same_as_written(r, out, f.stem)
    assert all((r.vp_status in ("accepted", "fallback")) == (within == "estimate") for r in results)
    assert all(r.pose is not None and r.camera is not None for r in results)
    one = tmp_path / "one"
    one.mkdir()
    cv2.imwrite(str(one / frames[2].name), cv2.imread(str(frames[2])))
    out1 = _predict(tmp_path / "o1", tiny_vc_model, one, "--camera", camera, "--within", within)[0]
    _same_as_written(model.segment(cv2.imread(str(frames[2])), camera, within=within), out1, frames[2].stem)


def test_a_video_frame_by_frame_gives_predicts_masks(tiny_vc_model, drive, tmp_path):
    model = vctrain.load(tiny_vc_model)
    out, _ = _predict(tmp_path, tiny_vc_model, drive / "drive.mp4", "--camera", drive / "cam.yaml", "--within",
                      "estimate")
    results = list(model.segment_video(drive / "drive.mp4", drive / "cam.yaml", within="estimate"))
    assert [r.index for r in results] == list(range(5))
    for r in results:
        _same_as_written(r, out / "drive", f"drive_{r.index:06d}")
    assert all(r.vp is not None and r.pose is not None for r in results)


def test_bev_gives_the_metres_predict_prints(shipped, tmp_path):
    """One KITTI frame with its calibration, and the CamVid frames together with a preset (each
    frame's pose from its road VP)."""
    _, stdout = _predict(tmp_path / "k", "shipped", KITTI_FRAME, "--camera", KITTI_CALIB, "--bev")
    printed = json.loads(stdout.splitlines()[0])
    got = shipped.segment(cv2.imread(str(KITTI_FRAME)), KITTI_CALIB, bev=True)  # (a Path as a str)
    assert got.metres["free_m"] == printed["free_m"] and got.metres == {k: printed[k] for k in got.metres}
    assert got.bev.mask.shape == got.bev.prob.shape and set(np.unique(got.bev.mask)) <= {0, 1, 255}
    _, stdout = _predict(tmp_path / "c", "shipped", EXAMPLES / "camvid" / "images", "--camera", "camvid", "--bev")
    printed = {d["id"]: d for d in map(json.loads, stdout.splitlines())}
    results = shipped.segment_frames([cv2.imread(str(f)) for f in CAMVID], "camvid", bev=True)
    assert [r.metres["free_m"] for r in results] == [printed[f.stem]["free_m"] for f in CAMVID]
    assert [r.metres["pose"] for r in results] == [printed[f.stem]["pose"] for f in CAMVID]


def test_a_virtual_camera_model_without_camera_is_refused(tiny_vc_model, drive):
    model = vctrain.load(tiny_vc_model)
    with pytest.raises(InputError, match="camera") as e:
        model.segment(cv2.imread(str(sorted((drive / "frames").glob("*.png"))[0])))
    assert "camera=" in e.value.fix and e.value.file == str(tiny_vc_model)


@pytest.mark.parametrize("frame, said", [(np.full((10, 10), 128, np.uint8), "(10, 10)"),
                                         (np.zeros((40, 40, 3), np.float32), "float32"),
                                         (np.zeros((40, 40, 4), np.uint8), "(40, 40, 4)"),
                                         ("frame.png", "str")])
def test_anything_but_a_bgr_uint8_frame_is_refused(shipped, frame, said):
    with pytest.raises(VCError) as e:
        shipped.segment(frame)
    assert isinstance(e.value, InputError) and said in e.value.problem and "H x W x 3 uint8" in e.value.problem


def test_metres_without_bev_and_an_unknown_model_are_refused(shipped):
    r = shipped.segment(cv2.imread(str(CAMVID[0])))
    with pytest.raises(InputError, match="bev=True"):
        r.metres
    with pytest.raises(InputError, match="not found") as e:
        vctrain.load("no-such-model.pt")
    assert "shipped" in e.value.fix


def _page_commands(page: Path) -> list[list[str]]:
    """The command lines of ``page``'s fenced sh blocks, in order."""
    import re
    import shlex

    blocks = re.findall(r"```sh\n(.*?)```", page.read_text(), flags=re.S)
    return [shlex.split(line) for block in blocks for line in block.splitlines() if line.strip()]


def test_the_api_page_runs_as_a_doctest(tmp_path, monkeypatch):
    """docs/api.md: its fenced commands (the fine-tuning) run first, then its Python examples as a
    doctest, in a folder holding the shipped examples (the model by name from any folder)."""
    import doctest

    page = Path(__file__).resolve().parent.parent / "docs" / "api.md"
    (tmp_path / "examples").symlink_to(EXAMPLES)
    commands = _page_commands(page)
    assert [c[:2] for c in commands] == [["vctrain", "fit"]]
    for argv in commands:
        proc = run_cli(*argv[1:], prog=argv[0], cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr
    monkeypatch.chdir(tmp_path)
    # a fence line ends an example's expected output, as a blank line does
    text = "\n".join("" if line.startswith("```") else line for line in page.read_text().splitlines())
    test = doctest.DocTestParser().get_doctest(text, {}, "api.md", str(page), 0)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0 and result.attempted >= 25, result


def test_help_and_docstrings_take_the_defaults_from_the_settings():
    """``--engine``'s and ``--beyond``'s help say the defaults vctrain.predict.settings declares, and no
    docstring of the predict package calls another rule the default (issue 79: they said extend)."""
    from vctrain.predict import BEYOND, DEFAULT_BEYOND, DEFAULT_ENGINE, GRAPH_ENGINE

    proc = run_cli("predict", "--help", prog="vctrain")
    text = " ".join(proc.stdout.split())
    assert f"default {DEFAULT_ENGINE}. A graph (.onnx): openvino, onnx or auto; default {GRAPH_ENGINE}." in text
    assert f"; default {DEFAULT_BEYOND} " in text
    sources = " ".join(" ".join(p.read_text().split()) for p in (Path(vctrain.__file__).parent / "predict").glob("*.py"))
    assert f"``{DEFAULT_BEYOND}`` (the default" in sources
    assert [r for r in BEYOND if r != DEFAULT_BEYOND and f"``{r}`` (the default" in sources] == []
    assert [r for r in BEYOND if r != DEFAULT_BEYOND and f"None: the default, {r}" in sources] == []
