"""Would OpenVINO pay as a third engine? (issue 69 item 1: "OpenVINO if it measures faster on this
CPU ... add one only if it pays"). OpenVINO is not a dependency: run this with it importable, e.g.

    pip install --target /tmp/ovlib openvino && rm -rf /tmp/ovlib/numpy*
    PYTHONPATH=/tmp/ovlib .venv/bin/python benchmarks/speed/openvino_trial.py [--frames 24] [--reps 3]

Model: the shipped one's graphs for 1280x720 frames (``vctrain export road.pt --size 1280x720``, float
and ``--int8``). For each graph, interleaved ``--reps`` times in one run:

* network only: the graph on one frame in memory, median of 5 calls (onnxruntime as ``vctrain
  predict`` runs it, :func:`vctrain.deploy.runtime._session`; OpenVINO 'CPU', LATENCY, float32
  precision: on a CPU with bf16 units it would otherwise run bf16, which this run also times, with its
  share of mask pixels equal to onnxruntime's float graph);
* end to end: the README's video command (``vctrain predict GRAPH drive.mp4 --overlay``, the
  three-thread pipeline) on a 1280x720 mp4v video of the first ``--frames`` CamVid val frames, with the
  graph run in onnxruntime, and in OpenVINO (the predictor's call swapped for a compiled OpenVINO
  model: the same frames, pipeline and writes).

It pays if its end to end beats onnxruntime's. Results: benchmarks/speed/results/openvino_trial.json;
the last stdout line is one JSON object.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.report import machine, results_dir, today, write_json  # noqa: E402
from benchmarks.speed.predict_e2e import MODEL, frames_at, write_inputs  # noqa: E402


def openvino_call(path: Path, threads: int, precision: str = "f32"):
    """frame -> P(road) of the graph at ``path`` compiled by OpenVINO for the CPU."""
    import openvino as ov

    core = ov.Core()
    net = core.compile_model(core.read_model(str(path)), "CPU", {
        "INFERENCE_NUM_THREADS": threads, "PERFORMANCE_HINT": "LATENCY", "INFERENCE_PRECISION_HINT": precision})
    req, out = net.create_infer_request(), net.outputs[0]
    return lambda frame: req.infer({"frame": frame})[out]


def median_ms(fn, n: int = 5) -> float:
    fn()
    ts = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return 1000 * statistics.median(ts)


def e2e_fps(graph: Path, video: Path, out: Path, frames: int, ov_call=None) -> float:
    """frames/s of ``vctrain predict GRAPH VIDEO --overlay`` (``ov_call``: the graph run by OpenVINO)."""
    from vctrain.deploy import runtime
    from vctrain.predict import predict_inputs

    orig = runtime.OnnxPredictor._run
    if ov_call is not None:
        runtime.OnnxPredictor._run = lambda self, frame, vp: ov_call(np.ascontiguousarray(frame))
    try:
        shutil.rmtree(out, ignore_errors=True)
        t0 = time.perf_counter()
        predict_inputs(graph, [video], out, None, overlay=True, progress=False)
        return frames / (time.perf_counter() - t0)
    finally:
        runtime.OnnxPredictor._run = orig


def trial(args, wd: Path) -> dict:
    from vctrain.deploy import OnnxPredictor, export_onnx

    frames = frames_at(args.frames, (1280, 720))
    video, _ = write_inputs(frames, wd, "1280x720")
    graphs = {"float": wd / "f.onnx", "int8": wd / "q.onnx"}
    export_onnx(MODEL, None, graphs["float"], size=(1280, 720))
    export_onnx(MODEL, None, graphs["int8"], size=(1280, 720), int8=True)
    ort = {k: OnnxPredictor(p, threads=args.threads) for k, p in graphs.items()}
    ov = {k: openvino_call(p, args.threads) for k, p in graphs.items()}
    bf16 = openvino_call(graphs["float"], args.threads, "bf16")
    ref = ort["float"].road_probability(frames[0]) >= 0.5
    same = {f"{k}_{r}": float(np.mean((f(frames[0]) >= 0.5) == ref)) * 100
            for k, r, f in [(k, "openvino", ov[k]) for k in graphs] + [(k, "onnxruntime", ort[k].road_probability)
                                                                       for k in graphs] + [("float", "openvino_bf16", bf16)]}
    cells: dict[str, list[float]] = {}
    for _ in range(args.reps):
        for k in graphs:
            cells.setdefault(f"net_ms_{k}_onnxruntime", []).append(median_ms(lambda: ort[k].road_probability(frames[0])))
            cells.setdefault(f"net_ms_{k}_openvino", []).append(median_ms(lambda: ov[k](frames[0])))
            cells.setdefault(f"fps_{k}_onnxruntime", []).append(e2e_fps(graphs[k], video, wd / "o", len(frames)))
            cells.setdefault(f"fps_{k}_openvino", []).append(e2e_fps(graphs[k], video, wd / "o", len(frames), ov[k]))
        cells.setdefault("net_ms_float_openvino_bf16", []).append(median_ms(lambda: bf16(frames[0])))
    head = {k: round(statistics.median(v), 1) for k, v in cells.items()}
    head.update({f"mask_same_pct_{k}": round(v, 3) for k, v in same.items()})
    pays = {k: head[f"fps_{k}_openvino"] > head[f"fps_{k}_onnxruntime"] for k in graphs}
    return {"headline": head, "cells": cells, "openvino_pays_end_to_end": pays}


def main() -> None:
    from vctrain.threads import use_threads

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    try:
        import openvino
    except ImportError:
        raise SystemExit("openvino is not importable: see this script's docstring") from None
    use_threads(args.threads)
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="openvino_trial-") as tmp:
        res = trial(args, Path(tmp))
    for k, v in res["headline"].items():
        print(f"{k}: {v}")
    write_json(results_dir(__file__) / "openvino_trial.json",
               {"command": "python " + " ".join(["benchmarks/speed/openvino_trial.py"] + sys.argv[1:]), "date": today(),
                "machine": machine(), "threads": args.threads, "load_average": [load0, os.getloadavg()[0]],
                "openvino": openvino.__version__, "frames": args.frames, **res})
    print(json.dumps({**res["headline"], "pays": res["openvino_pays_end_to_end"]}))


if __name__ == "__main__":
    main()
