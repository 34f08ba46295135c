"""Camera-rate prediction (issue 69): decode, network and writing on three threads
(vctrain.predict.pipeline), the network's engine (vctrain.deploy.engine) and the int8 graph
(vctrain.deploy.quantize).

Oracles: the sequential path (each decoded frame through :meth:`Predictor.road_probability`, one
after the other, in this thread) for the threaded video and folder runs; PyTorch for the onnx
engine; the float graph for the int8 graph; items of known order and a failure at a known place
for the threads themselves.
"""
from __future__ import annotations

import json
import random
import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

from vcprep.camera import PRESETS
from vcprep.io import read_image
from vcprep.synthetic import RoadScene, render_road

from conftest import assert_one_error_line, run_cli
from test_video import _decode

from vctrain.predict import PredictOptions, Predictor, predict_inputs
from vctrain.predict.pipeline import Prefetch, Writer

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "models/road-multicamera/road.pt"
EXAMPLES = ROOT / "examples/camvid/images"  # 3 real CamVid frames, 480x360
torch.set_num_threads(1)


# -- the threads: order, completeness, errors --------------------------------------------------------

def _slow(items, fail_at=None):
    for i in items:
        time.sleep(random.random() * 0.002)
        if i == fail_at:
            raise ValueError(f"item {i}")
        yield i


def test_prefetch_yields_every_item_in_order_and_raises_where_it_failed():
    random.seed(0)
    with Prefetch(_slow(range(200)), depth=3) as items:
        assert list(items) == list(range(200))
    seen = []
    with pytest.raises(ValueError, match="item 57"):
        with Prefetch(_slow(range(200), fail_at=57), depth=3) as items:
            for i in items:
                seen.append(i)
    assert seen == list(range(57))  # every item before the failure, none after
    with Prefetch(_slow(range(10_000)), depth=2) as items:  # left early: the thread stops
        next(iter(items))
    assert not any(t.name == "decode" and t.is_alive() for t in threading.enumerate())


def test_writer_runs_every_call_in_order_and_raises_the_first_error():
    random.seed(1)
    done = []
    w = Writer(depth=2)
    for i in range(300):
        w.submit(lambda i: (time.sleep(random.random() * 0.0005), done.append(i)), i)
    w.close()
    assert done == list(range(300))

    done.clear()

    def write(i):
        if i == 20:
            raise OSError(28, "No space left on device", f"f{i}.png")
        done.append(i)
    w = Writer(depth=2)
    with pytest.raises(OSError, match="No space left"):
        for i in range(100):
            w.submit(write, i)
        w.close()
    assert done == list(range(20))  # nothing after the failed write is written
    w.abort()
    w = Writer(depth=2)
    w.submit(time.sleep, 0.05)
    for i in range(5):
        w.submit(done.append, 1000 + i)
    w.abort()  # Ctrl-C: the write running finishes, the waiting ones are dropped
    assert 1004 not in done


# -- the threaded road against the sequential path -------------------------------------------------

@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    """12 rendered 240x180 CamVid-camera frames as an mp4v video and as a folder of PNGs."""
    root = tmp_path_factory.mktemp("pipeline")
    cam = PRESETS["camvid"].resized(0.25)
    frames = [render_road(cam, RoadScene(offset=0.3 * i - 1.5, texture_seed=i), pan=2 * np.sin(i), supersample=1)[0]
              for i in range(12)]
    (root / "frames").mkdir()
    w = cv2.VideoWriter(str(root / "drive.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, cam.size)
    for i, f in enumerate(frames):
        w.write(f)
        cv2.imwrite(str(root / "frames" / f"f{i:02d}.png"), f)
    w.release()
    return root


def test_threaded_video_and_folder_give_the_sequential_masks_in_order(drive, tmp_path):
    """Every frame, in order, with the masks the sequential path gives (same engine: PyTorch), and
    the overlay video has every frame."""
    p = Predictor(SHIPPED, "cpu", "torch")
    frames = _decode(drive / "drive.mp4")
    ref = [np.where(p.road_probability(f) >= 0.5, 255, 0).astype(np.uint8) for f in frames]
    r = predict_inputs(PredictOptions(SHIPPED, (drive / "drive.mp4",), tmp_path / "v", overlay=True, progress=False,
                                      engine="torch"))
    masks = [m for m in r.written if m.name.endswith("_mask.png")]
    assert [m.name for m in masks] == [f"drive_{i:06d}_mask.png" for i in range(len(frames))]
    for m, want in zip(masks, ref):
        assert np.array_equal(read_image(m).array, want), m.name
    assert len(_decode(tmp_path / "v/drive_overlay.mp4")) == len(frames)
    files = sorted((drive / "frames").iterdir())
    ref = [np.where(p.road_probability(read_image(f).array) >= 0.5, 255, 0).astype(np.uint8) for f in files]
    r = predict_inputs(PredictOptions(SHIPPED, (drive / "frames",), tmp_path / "f", overlay=True, progress=False,
                                      engine="torch"))
    assert [m.name for m in r.written] == [f"{f.stem}_mask.png" for f in files]
    for m, want in zip(r.written, ref):
        assert np.array_equal(read_image(m).array, want), m.name
    from vcprep.figures import overlay_label  # the folder's overlay: overlay_label's numbers, through a table

    want = overlay_label(read_image(files[3]).array, (ref[3] > 0).astype(np.uint8))
    assert np.array_equal(read_image(tmp_path / f"f/{files[3].stem}_overlay.png").array, want)


def test_a_failing_write_ends_the_run_with_its_error_and_no_partial_video(drive, tmp_path):
    """Frame 5's write fails (a folder stands where its probability PNG goes): the run ends with that
    error, the frames before it are written, none after it, and the overlay video's temporary file
    is removed (no video left)."""
    out = tmp_path / "o"
    (out / "drive/drive_000005_prob.png").mkdir(parents=True)
    with pytest.raises(OSError) as e:
        predict_inputs(PredictOptions(SHIPPED, (drive / "drive.mp4",), out, overlay=True, progress=False, engine="torch"))
    assert "drive_000005_prob.png" in str(e.value)
    assert sorted(p.name for p in out.iterdir()) == ["drive"]  # no overlay video, finished or temporary
    assert sorted(p.name for p in (out / "drive").glob("*_mask.png")) == [f"drive_{i:06d}_mask.png" for i in range(5)]


# -- the engine -------------------------------------------------------------------------------------

@pytest.mark.parametrize("engine,said", [("onnx", "onnxruntime "), ("openvino", "OpenVINO ")])
def test_exported_engines_give_pytorchs_masks_and_both_are_recorded(engine, said, tmp_path):
    """--engine onnx / openvino (the network exported in memory) against --engine torch on the CamVid
    examples: P(road) within float rounding, the masks identical; each run says its engine in
    predict.json and on stderr."""
    pytest.importorskip("onnxruntime" if engine == "onnx" else "openvino")
    runs = {}
    for engine in ("torch", engine):
        r = run_cli("predict", SHIPPED, EXAMPLES, "--out", tmp_path / engine, "--engine", engine, "--threads", "1",
                    prog="vctrain")
        assert r.returncode == 0, r.stderr
        runs[engine] = json.loads((tmp_path / engine / "predict.json").read_text())["engine"]
        assert runs[engine] in r.stderr
    assert runs["torch"].startswith("PyTorch ") and runs[engine].startswith(said)
    assert "exported in memory" in runs[engine]
    for f in sorted(EXAMPLES.iterdir()):
        a, b = (read_image(tmp_path / e / f"{f.stem}_mask.png").array for e in ("torch", engine))
        assert np.array_equal(a, b), f.name
        pa, pb = (read_image(tmp_path / e / f"{f.stem}_prob.png").array.astype(int) for e in ("torch", engine))
        assert np.abs(pa - pb).max() <= 1  # 0-255: a rounding step at most
    assert_one_error_line(run_cli("predict", SHIPPED, EXAMPLES, "--out", tmp_path / "x", "--engine", "tensorrt",
                                  prog="vctrain"), "unknown --engine 'tensorrt'")


def test_the_default_engine_is_the_fastest_installed_and_its_start_up_is_said_apart(tmp_path, monkeypatch):
    """`vctrain predict` with no --engine runs the network exported in memory in OpenVINO (else
    onnxruntime) on the CPU, says one start-up line (load and export/compile seconds, the engine)
    and records them in predict.json; where neither runtime is installed it runs PyTorch and says why,
    once (not per frame); a GPU's auto is PyTorch."""
    from vctrain.deploy import engine as eng
    from vctrain.predict import DEFAULT_ENGINE

    assert DEFAULT_ENGINE == "auto" and eng.choose_engine("auto", "cuda:0") == "torch"
    assert eng.engine_note("auto", "cuda:0") == "" and eng.engine_note("torch", "cpu") == ""
    runtime = next((r for r in ("openvino", "onnxruntime") if eng.installed(r)), None)
    if runtime is None:
        pytest.skip("neither OpenVINO nor onnxruntime is installed (the deploy extra)")
    r = run_cli("predict", SHIPPED, EXAMPLES, "--out", tmp_path / "fast", "--threads", "1", prog="vctrain")
    assert r.returncode == 0, r.stderr
    record = json.loads((tmp_path / "fast" / "predict.json").read_text())
    assert record["engine"].startswith({"openvino": "OpenVINO ", "onnxruntime": "onnxruntime "}[runtime])
    startup = record["runs"][-1]["startup"]
    assert startup["load_s"] > 0 and startup["compile_s"] > 0
    lines = [line for line in r.stderr.splitlines() if "start-up:" in line]
    assert len(lines) == 1 and "the network exported and compiled in" in lines[0], r.stderr
    assert record["engine"] in lines[0] and "start-up:" in r.stderr.splitlines()[-2]  # (said with the summary)
    monkeypatch.setattr(eng, "installed", lambda module: False)  # no deploy extra
    r = run_cli("predict", SHIPPED, EXAMPLES, "--out", tmp_path / "torch", "--threads", "1", prog="vctrain")
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "torch" / "predict.json").read_text())["engine"].startswith("PyTorch ")
    assert r.stderr.count("neither OpenVINO nor onnxruntime is installed: PyTorch runs the network") == 1, r.stderr
    for f in sorted(EXAMPLES.iterdir()):  # the same masks either way (tests above: P(road) within rounding)
        a, b = (read_image(tmp_path / e / f"{f.stem}_mask.png").array for e in ("torch", "fast"))
        assert np.array_equal(a, b), f.name


# -- the int8 graph ---------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def float_graph(tmp_path_factory) -> Path:
    """The shipped model's float graph for 480x360 frames (export_onnx), exported once for the tests
    that read it (none writes it)."""
    pytest.importorskip("onnxruntime")
    from vctrain.deploy import export_onnx

    path = tmp_path_factory.mktemp("graph") / "f.onnx"
    export_onnx(SHIPPED, None, path, size=(480, 360))
    return path


def test_int8_graph_agrees_with_the_float_graph_and_refuses_another_size(float_graph, tmp_path):
    """`vctrain export --int8` of the shipped model for 480x360 frames, calibrated on the examples:
    its masks are the float graph's on >= 99 % of the examples' pixels (measured here with both
    graphs, and as the export reports it); predict says and records the int8 graph; a 240x180 frame is
    refused with one line naming both sizes and the export that fits."""
    from vctrain.deploy import OnnxPredictor

    r = run_cli("export", SHIPPED, "--size", "480x360", "--int8", "-o", tmp_path / "q.onnx", "--threads", "1",
                prog="vctrain")
    assert r.returncode == 0, r.stderr
    assert "int8 network, calibrated on" in r.stderr and "% of their pixels" in r.stderr
    f, q = OnnxPredictor(float_graph, threads=1), OnnxPredictor(tmp_path / "q.onnx", threads=1)
    same = total = 0
    for img in (read_image(p).array for p in sorted(EXAMPLES.iterdir())):
        a, b = f.road_probability(img) >= 0.5, q.road_probability(img) >= 0.5
        same, total = same + int((a == b).sum()), total + a.size
        assert 0.05 < a.mean() < 0.95  # a real road in view
    assert same / total >= 0.99
    assert abs(q.info["int8"]["mask_agreement"] - same / total) < 0.01  # (it also saw the KITTI frame, resized)
    assert (tmp_path / "q.onnx").stat().st_size < 0.5 * float_graph.stat().st_size
    import onnx  # the first convolution and the finest lateral keep float weights, every other conv int8

    graph = onnx.load(str(tmp_path / "q.onnx")).graph
    made_by, consts = {o: n.op_type for n in graph.node for o in n.output}, {i.name for i in graph.initializer}
    convs = {n.name: n.input[1] in consts or made_by.get(n.input[1]) != "DequantizeLinear"
             for n in graph.node if n.op_type == "Conv" and n.name.startswith("/model/")}
    assert [k for k, is_float in convs.items() if is_float] == ["/model/_conv_stem/Conv", "/model/lateral.0/Conv"]
    assert len(convs) > 40
    r = run_cli("predict", tmp_path / "q.onnx", EXAMPLES, "--out", tmp_path / "p", "--threads", "1", prog="vctrain")
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "p/predict.json").read_text())["engine"].endswith("the graph (int8)")
    small = tmp_path / "small"
    small.mkdir()
    cv2.imwrite(str(small / "s.png"), cv2.resize(read_image(sorted(EXAMPLES.iterdir())[0]).array, (240, 180)))
    assert_one_error_line(run_cli("predict", tmp_path / "q.onnx", small, "--out", tmp_path / "s", prog="vctrain"),
                          "frame is 240x180 but the graph was exported for 480x360 frames",
                          "vctrain export", "--frame")


def test_the_written_probabilities_and_masks_are_numpys_bit_for_bit():
    """prob_u8 and road_mask (OpenCV's SIMD conversions, for speed) give exactly the defining numpy
    expressions -- rint(prob x 255) clipped (half to even) and prob >= 0.5 -- on every rounding edge
    k/255, (k + 0.5)/255 and 0.5, one float step either side of each, and random frames; negative
    values (a bicubic resize's undershoot) and float64 take the numpy path."""
    from vctrain.predict.written import prob_u8, road_mask

    k = np.arange(256, dtype=np.float64)
    edges = np.concatenate([(k + 0.5) / 255, k / 255, [0.5]]).astype(np.float32)
    near = np.concatenate([np.nextafter(edges, np.float32(-1)), edges, np.nextafter(edges, np.float32(2))])
    rng = np.random.default_rng(0)
    cases = [np.clip(near, 0, 1).astype(np.float32).reshape(3, -1), rng.random((720, 1280), dtype=np.float32),
             rng.random((37, 53)) * 1.2 - 0.1, (rng.random((40, 60), dtype=np.float32) - 0.05)]
    for prob in cases:
        assert np.array_equal(prob_u8(prob), np.clip(np.rint(prob * 255.0), 0, 255).astype(np.uint8))
        assert np.array_equal(road_mask(prob), np.where(prob >= 0.5, 255, 0).astype(np.uint8))


def test_the_tint_is_overlay_labels_whatever_the_masks_extent():
    """tint_road (a table applied within the mask's bounding box) gives overlay_label's numbers bit for bit:
    scattered road touching every border, one pixel in a corner, an empty mask and a full one."""
    from vcprep.figures import overlay_label
    from vctrain.predict.written import tint_road

    rng = np.random.default_rng(1)
    frame = rng.integers(0, 256, (72, 128, 3), dtype=np.uint8)
    corner = np.zeros((72, 128), np.uint8)
    corner[71, 127] = 255
    blobs = np.where(rng.random((72, 128)) > 0.7, 255, 0).astype(np.uint8)
    blobs[:5], blobs[:, :3] = 0, 0  # road away from the top and left borders: a box smaller than the frame
    for mask in (corner, blobs, np.where(rng.random((72, 128)) > 0.5, 255, 0).astype(np.uint8),
                 np.zeros((72, 128), np.uint8), np.full((72, 128), 255, np.uint8)):
        assert np.array_equal(tint_road(frame, mask), overlay_label(frame, (mask > 0).astype(np.uint8)))
    grey = frame[..., 1]
    assert np.array_equal(tint_road(grey, blobs), overlay_label(grey, (blobs > 0).astype(np.uint8)))


def test_a_graph_runs_in_openvino_with_onnxruntimes_masks(float_graph, tmp_path):
    """The shipped model's 480x360 graph in OpenVINO (the default where installed: the faster runtime)
    and in onnxruntime (--engine onnx): P(road) within float rounding and the masks identical on the
    examples (OpenVINO in float32, not the bf16 it would pick on a CPU with bf16 units); predict says
    which ran; --engine torch on a graph is refused."""
    pytest.importorskip("openvino")
    from vctrain.deploy import OnnxPredictor

    ov, ort = (OnnxPredictor(float_graph, threads=1, runtime=r) for r in ("openvino", "onnxruntime"))
    assert OnnxPredictor(float_graph, threads=1).runtime == "openvino"
    for img in (read_image(p).array for p in sorted(EXAMPLES.iterdir())):
        a, b = ov.road_probability(img), ort.road_probability(img)
        assert a.dtype == b.dtype == np.float32 and np.abs(a - b).max() < 1e-4
        assert np.array_equal(a >= 0.5, b >= 0.5)
    for engine, said in ((None, "OpenVINO "), ("onnx", "onnxruntime ")):
        r = run_cli("predict", float_graph, EXAMPLES, "--out", tmp_path / str(engine), "--threads", "1",
                    *(["--engine", engine] if engine else []), prog="vctrain")
        assert r.returncode == 0, r.stderr
        assert json.loads((tmp_path / str(engine) / "predict.json").read_text())["engine"].startswith(said)
    assert_one_error_line(run_cli("predict", float_graph, EXAMPLES, "--out", tmp_path / "t", "--engine",
                                  "torch", prog="vctrain"), "not PyTorch")
