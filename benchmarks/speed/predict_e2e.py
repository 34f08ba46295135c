"""End-to-end ``vctrain predict`` at camera sizes: frames/s of the whole run (decode, network, masks,
overlay) beside the network-only time of the same engine, measured in the same run (issue 69).

    .venv/bin/python benchmarks/speed/predict_e2e.py [--frames 60] [--threads 2] [--sizes 1280x720,960x720]
                                                     [--engines torch,onnx,openvino,graph,graph-ov,int8,int8-ov] [--quality]
                                                     [--only inprocess|whole] [--whole-frames 60,240]

Model (``--model``, a shipped model's name or a .pt): ``shipped`` (models/road-all/road.pt since issue 82, road-street before it;
figures before them: models/road-multicamera/road.pt, the same network: lite0fpn, resize, 480x360 working size).
Frames: the first ``--frames`` CamVid val frames (../shared/data/camvid/val, 480x360, real), enlarged
2x to 960x720, and to 1280x960 with its middle 720 rows kept for 1280x720; each size as an mp4v video
(what a dashcam gives) and as a folder of PNGs.

Engines (``vctrain predict`` in this process, :func:`vctrain.predict.inputs.predict_inputs`):
  torch     road.pt --engine torch: PyTorch (BN folded, channels last)
  onnx      road.pt --engine onnx: the network exported in memory, in onnxruntime
  openvino  road.pt --engine openvino (``auto`` where installed): the same in OpenVINO (float32)
  graph     the float graph of ``vctrain export road.pt --size WxH`` (resize, network, resize back
            inside), ``--engine onnx``: in onnxruntime; ``graph-ov``: in OpenVINO (the default)
  int8      the same with ``--int8`` (calibrated on the shipped examples); ``int8-ov``: in OpenVINO
Network only (``net_ms``), beside each: the engine's own call on one decoded frame in memory with
nothing read or written: torch / onnx the network on the 480x360 input (no resizes), graph / int8
the graph on the frame (its resizes included); beside it ``frame_ms``, the engine's whole call on the
frame in memory (torch / onnx: resize, normalisation, network, softmax, resize back); medians of 10
calls after one, measured just before that engine's runs. End-to-end (``e2e_ms`` per frame, ``fps``): the wall time of the whole
``predict_inputs`` run over the frames (PNG masks and probabilities; with ``overlay`` the video's
``_overlay.mp4`` or the folder's ``_overlay.png``), engine load excluded (every run is given the engine
loaded once, ``load_s``: the checkpoint read, the graph's session or OpenVINO compile, not a per-frame
cost on a camera stream; before this, each run's own load was timed). ``ratio`` = e2e_ms /
net_ms (target <= 1.3); beside it ``ratio_floor_video_overlay``, the lowest ratio the video with
overlay could reach on this machine's cores: (the engine's CPU a frame + the CPU a frame costs outside
it, ``side_cpu_ms``: decoding the mp4v video, the mask and probability PNGs, the tint, the mp4v
encoding; each measured alone) / (cores x net_ms), since the wall time is at least the CPU time
spread over every core. Targets (issue 69): the README's video command on the 1280x720 video with
overlay >= 30 frames/s with the int8 graph, >= 20 with a float engine.

Threads: torch, OpenCV and onnxruntime pinned to ``--threads`` (2: the machine's cores); the decoding
and writing threads come on top. The machine is shared: the load average is recorded, and the
ratios, not the absolute times, are the result.

``--quality``: the int8 graph against the float model on held-out frames the shipped model never
trained on (models/road-multicamera/README.md): CamVid val (101 frames, 480x360), the KITTI road
frame (1242x375), Cityscapes cs_25xx-cs_29xx (43 frames, 256x256); each split predicted by road.pt
(PyTorch: the card's numbers), its float graph and its int8 graph at the split's size; road IoU
(vctrain eval) and the share of pixels whose mask is the float graph's.

The whole command (issue 81; ``--only whole`` runs just this part): ``vctrain predict MODEL VIDEO --out
DIR [--overlay] [--engine E]`` as a user types it, a fresh process per run (imports, model load, the
OpenVINO compile, the video decoded, every mask PNG and the overlay video written), timed by its wall
clock at two video lengths (``--whole-frames``, default 60 and 240 frames: the same frames cycled).
The difference gives the steady-state rate, ``fps_steady`` = (n2 - n1) / (t2 - t1), with everything
paid once counted once; the rest is the start-up, ``startup_s`` = t1 - n1 / fps_steady (imports,
model load, graph compilation, first frames), reported apart, and ``fps_whole`` = n2 / t2 is what
the longer run gave a user. Sizes (``--whole-sizes``): 1280x720 (CamVid val, enlarged, as above) and
KITTI's 1242x375 (``../shared/data/kitti_semantics/images``, 98 frames); each with and without
``--overlay``; engines (``--whole-engines``): ``default`` (no ``--engine``: the command as the README
prints it; OpenVINO, else onnxruntime, where installed), ``torch`` (``--engine torch``: PyTorch, a
study's masks bit for bit) and ``int8`` (the int8 graph of ``vctrain export --int8 --size WxH``,
exported once per size, its export not timed), run in turn at each length so that they share the
load; beside the fitted start-up, the one the longer run said (predict.json: ``load_s``, the model
read; ``compile_s``, the network exported and compiled); threads: the command's own defaults (what
a user gets); the load average before and after is recorded, a loaded machine says so there.

Results: benchmarks/speed/results/predict_e2e.json (in process) and predict_e2e.whole.json (the whole
command); the last stdout line is one JSON object (both headlines).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import DATA, KITTI, ROOT  # noqa: E402
from benchmarks.measure.report import machine, results_dir, today, write_json  # noqa: E402

MODEL = ROOT / "models" / "road-multicamera" / "road.pt"  # (main() sets the --model given; default: shipped)
ENGINES = ("torch", "onnx", "openvino", "graph", "graph-ov", "int8", "int8-ov")
CITYSCAPES = DATA.parent / "cityscapes_pix2pix"


def frames_at(n: int, size: tuple[int, int]) -> list[np.ndarray]:
    """The first ``n`` CamVid val frames at ``size``: 960x720 (2x), 1280x720 (1280x960, middle rows)."""
    out = []
    for f in sorted((DATA / "val").glob("*.png"))[:n]:
        img = cv2.imread(str(f))
        w, h = size
        s = w / img.shape[1]
        big = cv2.resize(img, (w, int(round(img.shape[0] * s))), interpolation=cv2.INTER_LINEAR)
        y0 = (big.shape[0] - h) // 2
        out.append(np.ascontiguousarray(big[y0:y0 + h]))
    return out


def write_inputs(frames: list[np.ndarray], wd: Path, tag: str) -> tuple[Path, Path]:
    """(an mp4v video at 30 frames/s, a folder of PNGs) of ``frames``."""
    video, folder = wd / f"drive_{tag}.mp4", wd / f"frames_{tag}"
    folder.mkdir(parents=True, exist_ok=True)
    h, w = frames[0].shape[:2]
    vw = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (w, h))
    for i, f in enumerate(frames):
        vw.write(f)
        cv2.imwrite(str(folder / f"f{i:04d}.png"), f)
    vw.release()
    return video, folder


def cpu_ms(fn, n: int = 10) -> float:
    """CPU milliseconds (every thread of this process) one call of ``fn`` costs, the mean of ``n``."""
    fn()
    t0 = time.process_time()
    for _ in range(n):
        fn()
    return 1000 * (time.process_time() - t0) / n


def side_cpu_ms(video: Path, frames: list[np.ndarray], wd: Path) -> dict[str, float]:
    """The CPU a frame costs outside the engine, per stage, as the video road spends it: decoding the
    mp4v video, and the writing thread's work (the mask and probability PNGs, the overlay's tint and
    its mp4v encoding) on a P(road) of the frame's size."""
    from vctrain.predict import write_prediction
    from vctrain.predict.written import road_mask, tint_road

    def decode():
        cap = cv2.VideoCapture(str(video))
        while cap.read()[0]:
            pass
        cap.release()
    h, w = frames[0].shape[:2]
    prob = cv2.resize(cv2.GaussianBlur(np.random.default_rng(0).random((h // 8, w // 8), dtype=np.float32), (0, 0), 3),
                      (w, h))
    prob = (prob - prob.min()) / (prob.max() - prob.min())
    writer = cv2.VideoWriter(str(wd / "side.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (w, h))
    mask = road_mask(prob)
    out = {"decode": cpu_ms(decode, 3) / len(frames),
           "pngs": cpu_ms(lambda: write_prediction(wd, "side", prob, mask=road_mask(prob))),
           "tint": cpu_ms(lambda: tint_road(frames[0], mask)),
           "mp4v": cpu_ms(lambda: writer.write(frames[0]))}
    writer.release()
    return out


def median_ms(fn, n: int = 10) -> float:
    fn()
    ts = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return 1000 * statistics.median(ts)


def engine_model(engine: str, graphs: dict[str, Path]):
    """(the path predict is given, its --engine, a network-only call on a frame, the engine's call
    on a frame: P(road) at its size, resizes included)."""
    from vctrain.deploy import OnnxPredictor
    from vctrain.predict import Predictor
    from vctrain.training import to_input

    t0 = time.perf_counter()
    if engine in ("torch", "onnx", "openvino"):
        p = Predictor(MODEL, "cpu", engine)

        def net(frame):
            x = to_input(cv2.resize(frame, p.size, interpolation=cv2.INTER_LINEAR))
            return lambda: p.logits(x)
        return MODEL, engine, net, lambda frame: (lambda: p.road_probability(frame)), p, time.perf_counter() - t0
    graph, runtime = engine.removesuffix("-ov"), "openvino" if engine.endswith("-ov") else "onnx"
    g = OnnxPredictor(graphs[graph], runtime=runtime)
    call = lambda frame: (lambda: g.road_probability(frame))  # noqa: E731
    return graphs[graph], runtime, call, call, g, time.perf_counter() - t0


def e2e(path: Path, engine: str, src: Path, out: Path, overlay: bool, predictor=None) -> tuple[float, str]:
    """(seconds, engine said) of one ``vctrain predict`` run on ``src`` (a video or a folder);
    ``predictor`` (given): the engine already loaded, so its load (an OpenVINO compile, an in-memory
    export) is not timed, for any engine alike."""
    import shutil

    from vctrain.predict import PredictOptions, predict_inputs

    shutil.rmtree(out, ignore_errors=True)
    t0 = time.perf_counter()
    r = predict_inputs(PredictOptions(path, (src,), out, overlay=overlay, progress=False, engine=engine),
                       predictor=predictor)
    return time.perf_counter() - t0, r.engine


def speed(args, wd: Path) -> list[dict]:
    from vctrain.deploy import export_onnx

    rows = []
    for size in args.sizes:
        tag = f"{size[0]}x{size[1]}"
        frames = frames_at(args.frames, size)
        video, folder = write_inputs(frames, wd, tag)
        graphs = {}
        if {"graph", "graph-ov"} & set(args.engines):
            graphs["graph"] = wd / f"road_{tag}.onnx"
            export_onnx(MODEL, None, graphs["graph"], size=size)
        if {"int8", "int8-ov"} & set(args.engines):
            graphs["int8"] = wd / f"road_{tag}_int8.onnx"
            export_onnx(MODEL, None, graphs["int8"], size=size, int8=True)
        side = side_cpu_ms(video, frames, wd)
        print(f"{tag}: CPU ms a frame outside the engine: " + ", ".join(f"{k} {v:.1f}" for k, v in side.items()),
              file=sys.stderr)
        for engine in args.engines:
            path, flag, net, call, loaded, load_s = engine_model(engine, graphs)
            e2e(path, flag, folder, wd / "warm", False, loaded)  # the in-memory export made, caches warm
            net_ms, frame_ms = median_ms(net(frames[0])), median_ms(call(frames[0]))
            frame_cpu = cpu_ms(call(frames[0]))
            # e2e >= all the CPU a frame costs / the cores: the lowest ratio the video with overlay can reach
            floor = (frame_cpu + sum(side.values())) / (os.cpu_count() * net_ms)
            for kind, src in (("video", video), ("folder", folder)):
                for overlay in (False, True):
                    secs, said = e2e(path, flag, src, wd / "out", overlay, loaded)
                    ms = 1000 * secs / len(frames)
                    rows.append({"size": tag, "engine": engine, "input": kind, "overlay": overlay, "net_ms": net_ms,
                                 "load_s": load_s, "frame_ms": frame_ms, "frame_cpu_ms": frame_cpu,
                                 "side_cpu_ms": side, "ratio_floor_video_overlay": floor, "e2e_ms": ms, "fps": 1000 / ms, "ratio": ms / net_ms, "engine_said": said})
                    r = rows[-1]
                    print(f"{tag} {engine:5s} {kind:6s} overlay={overlay!s:5s} net {net_ms:6.1f} ms frame {frame_ms:6.1f} "
                          f"ms  e2e {ms:6.1f} ms "
                          f"{r['fps']:5.1f} fps  ratio {r['ratio']:.2f}", file=sys.stderr)
    return rows


WHOLE_ENGINES = ("default", "torch", "int8")


def whole_frames(n: int, size: tuple[int, int]) -> list[np.ndarray]:
    """Frames for a ``size`` video: KITTI's (kitti_semantics) at 1242x375, else CamVid's (:func:`frames_at`)."""
    kitti = sorted((DATA.parent / "kitti_semantics" / "images").glob("*.jpg"))
    if size == (1242, 375) and kitti:
        return [cv2.resize(cv2.imread(str(f)), size, interpolation=cv2.INTER_AREA) for f in kitti[:n]]
    return frames_at(n, size)


def write_video(frames: list[np.ndarray], n: int, path: Path) -> tuple[Path, tuple[int, int]]:
    """An mp4v video at 30 frames/s of ``n`` frames (``frames`` cycled), and its frame size as
    decoded: mp4v keeps even sizes only, so KITTI's 1242x375 comes back 1242x374."""
    h, w = frames[0].shape[:2]
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (w, h))
    for i in range(n):
        vw.write(frames[i % len(frames)])
    vw.release()
    cap = cv2.VideoCapture(str(path))
    ok, first = cap.read()
    cap.release()
    return path, ((first.shape[1], first.shape[0]) if ok else (w, h))


def run_predict(model: Path, video: Path, out: Path, overlay: bool, engine: str | None) -> tuple[float, dict]:
    """(wall seconds, the start-up it said: predict.json's ``load_s`` and ``compile_s``) of one
    ``vctrain predict`` in a fresh process (the console script beside this Python; ``engine`` None: no
    ``--engine``, the command's default)."""
    import shutil
    import subprocess

    shutil.rmtree(out, ignore_errors=True)
    exe = Path(sys.executable).with_name("vctrain")
    cmd = [str(exe) if exe.exists() else "vctrain", "predict", str(model), str(video), "--out", str(out)]
    cmd += (["--overlay"] if overlay else []) + (["--engine", engine] if engine else [])
    t0 = time.perf_counter()
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_NUM_THREADS", "MKL_NUM_THREADS")}  # its defaults
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    secs = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{proc.stderr[-2000:]}")
    record = json.loads((out / "predict.json").read_text())
    return secs, {**record["runs"][-1].get("startup", {}), "engine": record.get("engine", "")}


def whole_command(args, wd: Path) -> list[dict]:
    """The rows of the whole-command part (module docstring): per size, engine and overlay, the
    wall time at both lengths (the fastest of ``--whole-repeats`` runs each; the engines run in
    turn at each length, so that they share the machine's load), the steady-state rate and the
    start-up (fitted, and as the command said it)."""
    from vctrain.deploy import export_onnx

    n1, n2 = args.whole_frames
    rows = []
    for size in args.whole_sizes:
        tag = f"{size[0]}x{size[1]}"
        frames = whole_frames(max(n1, 1), size)
        written = {n: write_video(frames, n, wd / f"whole_{tag}_{n}.mp4") for n in (n1, n2)}
        videos, decoded = {n: v for n, (v, _) in written.items()}, written[n1][1]
        models = {}
        for engine in args.whole_engines:  # (path, --engine): the default runs with none
            models[engine] = (MODEL, None if engine == "default" else engine)
            if engine == "int8":  # the graph for the frames as decoded (1242x374 for KITTI's 1242x375)
                models[engine] = (wd / f"road_{decoded[0]}x{decoded[1]}_int8.onnx", None)
                if not models[engine][0].exists():
                    export_onnx(MODEL, None, models[engine][0], size=decoded, int8=True)
        for overlay in (False, True):
            t, said = {}, {}
            for n in (n1, n2):
                for _ in range(args.whole_repeats):
                    for engine, (model, flag) in models.items():
                        secs, said[engine, n] = run_predict(model, videos[n], wd / "whole_out", overlay, flag)
                        t[engine, n] = min(t.get((engine, n), secs), secs)
            for engine in models:
                rows.append(whole_row(tag, decoded, engine, overlay, (n1, n2), (t[engine, n1], t[engine, n2]),
                                      said[engine, n2]))
    return rows


def whole_row(tag: str, decoded: tuple, engine: str, overlay: bool, n: tuple, t: tuple, said: dict) -> dict:
    """One row: the steady-state rate from the two lengths, the fitted start-up, and the start-up
    the longer run said (its load and export/compile seconds)."""
    # the longer run no slower than the shorter: load swamped the difference, no rate
    fps = (n[1] - n[0]) / (t[1] - t[0]) if t[1] > t[0] else None
    row = {"size": tag, "decoded": f"{decoded[0]}x{decoded[1]}", "engine": engine, "engine_said": said.get("engine"),
           "overlay": overlay, "frames": list(n), "wall_s": list(t), "fps_steady": fps,
           "startup_s": None if fps is None else t[0] - n[0] / fps, "fps_whole": n[1] / t[1],
           "load_s": said.get("load_s"), "compile_s": said.get("compile_s")}
    print(f"whole {tag} {engine:7s} overlay={overlay!s:5s} {n[0]} frames {t[0]:6.1f} s, {n[1]} frames {t[1]:6.1f} s: "
          f"steady {fps or float('nan'):5.1f} frames/s, start-up {row['startup_s'] or float('nan'):5.1f} s (said: "
          f"load {row['load_s'] or 0:.1f} s, export/compile {row['compile_s'] or 0:.1f} s), whole "
          f"{row['fps_whole']:5.1f} frames/s", file=sys.stderr)
    return row


def whole_headline(rows: list[dict]) -> dict:
    head = {}
    for r in rows:
        key = f"{r['size']}_{r['engine']}{'_overlay' if r['overlay'] else ''}"
        head[f"fps_steady_{key}"] = None if r["fps_steady"] is None else round(r["fps_steady"], 1)
        head[f"startup_s_{key}"] = None if r["startup_s"] is None else round(r["startup_s"], 1)
        head[f"fps_whole_{key}"] = round(r["fps_whole"], 1)
        for k in ("load_s", "compile_s"):
            if r.get(k) is not None:
                head[f"{k}_{key}"] = round(r[k], 1)
    return head


def run_whole(args) -> dict:
    """The whole-command part: rows, predict_e2e.whole.json, its headline."""
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="predict_e2e_whole-") as tmp:
        rows = whole_command(args, args.workdir or Path(tmp))
    head = whole_headline(rows)
    write_json(results_dir(__file__) / "predict_e2e.whole.json",
               {"command": "python " + " ".join(["benchmarks/speed/predict_e2e.py"] + sys.argv[1:]), "date": today(), "model": MODEL.parent.name,
                "machine": machine(), "threads": "the command's defaults", "load_average": [load0, os.getloadavg()[0]],
                "cv2": cv2.__version__, "numpy": np.__version__,
                "data": "1280x720: CamVid val (../shared/data/camvid/val), enlarged; 1242x375: "
                        "../shared/data/kitti_semantics/images; frames cycled to each length",
                "headline": head, "rows": rows})
    return head


def main() -> None:
    from vctrain.threads import use_threads

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--model", default="shipped", help="a shipped model's name or a .pt (default: shipped)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--sizes", default="1280x720,960x720")
    ap.add_argument("--engines", default=",".join(ENGINES))
    ap.add_argument("--quality", action="store_true", help="also the int8 graph's IoU on held-out splits")
    ap.add_argument("--workdir", type=Path, default=None)
    ap.add_argument("--only", choices=("inprocess", "whole"), default=None, help="run one part (default: both)")
    ap.add_argument("--whole-frames", default="60,240", help="the whole command's two video lengths")
    ap.add_argument("--whole-sizes", default="1280x720,1242x375")
    ap.add_argument("--whole-engines", default=",".join(WHOLE_ENGINES))
    ap.add_argument("--whole-repeats", type=int, default=1, help="runs per length (the fastest is kept)")
    args = ap.parse_args()
    global MODEL
    from vctrain.shipped import resolve_model

    MODEL = resolve_model(args.model)
    args.sizes = [tuple(int(v) for v in s.split("x")) for s in args.sizes.split(",")]
    args.engines = args.engines.split(",")
    args.whole_frames = tuple(int(v) for v in args.whole_frames.split(","))
    args.whole_sizes = [tuple(int(v) for v in s.split("x")) for s in args.whole_sizes.split(",")]
    args.whole_engines = args.whole_engines.split(",")
    whole = run_whole(args) if args.only in (None, "whole") else {}
    if args.only == "whole":
        print(json.dumps(whole))
        return
    use_threads(args.threads)
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="predict_e2e-") as tmp:
        wd = args.workdir or Path(tmp)
        wd.mkdir(parents=True, exist_ok=True)
        rows = speed(args, wd)
        quality = None
        if args.quality:
            from benchmarks.speed.int8_quality import held_out_quality

            quality = held_out_quality(MODEL, wd / "quality")
    load1 = os.getloadavg()[0]
    print("size | engine | input | overlay | network only ms | engine on a frame ms | end-to-end ms | frames/s | "
          "end-to-end / network")
    for r in rows:
        print(f"{r['size']} | {r['engine']} | {r['input']} | {'yes' if r['overlay'] else 'no'} | {r['net_ms']:.1f} | "
              f"{r['frame_ms']:.1f} | {r['e2e_ms']:.1f} | {r['fps']:.1f} | {r['ratio']:.2f}")
    pick = {(r["size"], r["engine"], r["input"], r["overlay"]): r for r in rows}
    headline = {}
    for e in args.engines:
        r = pick.get(("1280x720", e, "video", True))
        if r:
            headline[f"fps_1280x720_video_overlay_{e}"] = round(r["fps"], 1)
            headline[f"ratio_1280x720_video_overlay_{e}"] = round(r["ratio"], 2)
            headline[f"ratio_floor_1280x720_video_overlay_{e}"] = round(r["ratio_floor_video_overlay"], 2)
    if rows:
        headline["worst_ratio"] = round(max(r["ratio"] for r in rows), 2)
    if quality:
        headline.update(quality["headline"])
    fps = lambda engines: max((headline[k] for e in engines if (k := f"fps_1280x720_video_overlay_{e}") in headline),
                              default=None)
    int8, flt = fps(("int8", "int8-ov")), fps(("torch", "onnx", "openvino", "graph", "graph-ov"))
    targets = {"int8 video 1280x720 overlay >= 30 fps": None if int8 is None else int8 >= 30,
               "float video 1280x720 overlay >= 20 fps": None if flt is None else flt >= 20,
               "end-to-end <= 1.3 x network only (every row)": all(r["ratio"] <= 1.3 for r in rows)}
    write_json(results_dir(__file__) / "predict_e2e.json",
               {"command": "python " + " ".join(["benchmarks/speed/predict_e2e.py"] + sys.argv[1:]), "date": today(), "model": MODEL.parent.name,
                "machine": machine(), "threads": args.threads, "load_average": [load0, load1],
                "frames": args.frames, "data": "CamVid val (../shared/data/camvid/val), first frames, enlarged",
                "headline": headline, "targets": targets, "rows": rows, "quality": quality})
    print(json.dumps({**headline, **whole}))


if __name__ == "__main__":
    main()
