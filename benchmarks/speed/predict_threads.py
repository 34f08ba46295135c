"""Threads under load: `vctrain predict`'s time per frame at 1 thread, 2 threads and the default
(:func:`vctrain.threads.default_threads`) beside 0, 1 and 2 busy processes (issue 45).

    .venv/bin/python benchmarks/speed/predict_threads.py [--repeats 5] [--loads 0,1,2]

Model: the shipped road model ``models/road-multicamera/road.pt`` (the resize twin, 480x360).
Frames: the four shipped example frames (``examples/camvid/images``: three CamVid 960x720,
``examples/kitti/image_2``: one KITTI 1242x375). Measured in this process: the path ``vctrain
predict MODEL FRAMES --out OUT`` runs once its model is loaded (:func:`vctrain.predict.predict_images`:
read, resize, network, resize back, a mask and a probability PNG per frame), one warm-up pass, then
``--repeats`` passes, the three thread settings alternated pass by pass; ms per frame, median and
range over the passes. Load: N processes ``python -c
'while 1: pass'`` started before the three thread settings of that load and killed after them; the
default is chosen (:func:`vctrain.threads.default_threads`) with them running. Threads: torch and OpenCV pinned
to 1, 2 and the default in turn (:func:`vctrain.threads.use_threads`).

Baseline: 1 thread at the same load. Target (issue 45): with 2 busy processes, the default takes no
more than 1.5x the time of 1 thread. Other jobs on a shared machine load it too: the 1-minute load
average at the start and the processes running besides this one (``busy_cpus``) at each load are
recorded. Writes benchmarks/speed/results/predict_threads.json; prints the table, then one JSON line last.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import ROOT
from benchmarks.measure.report import machine, results_dir, today, write_json
from vctrain.predict import Predictor, predict_images
from vctrain.threads import available_cpus, busy_cpus, use_threads

MODEL = ROOT / "models" / "road-multicamera" / "road.pt"
FRAMES = [ROOT / "examples" / "camvid" / "images", ROOT / "examples" / "kitti" / "image_2"]


def one_pass_ms(predictor: Predictor, out: Path) -> float:
    """ms per frame of one pass over the example frames."""
    t0 = time.perf_counter()
    n = len(predict_images(predictor, FRAMES, out, None, progress=False))
    return (time.perf_counter() - t0) * 1000 / n


def at_load(predictor: Predictor, load: int, out: Path, repeats: int) -> dict:
    """The three thread settings beside ``load`` busy processes, alternated pass by pass (so that
    the machine's other jobs load each alike), each after one warm-up pass."""
    procs = [subprocess.Popen([sys.executable, "-c", "while 1: pass"]) for _ in range(load)]
    settings = {"1": 1, "2": 2, "default": None}
    try:
        time.sleep(0.5)  # running
        row: dict = {"busy_besides": busy_cpus()}
        chosen = {k: use_threads(v) for k, v in settings.items()}  # the default chosen beside the load
        ts: dict[str, list[float]] = {k: [] for k in settings}
        for r in range(repeats + 1):
            for k in settings:
                use_threads(chosen[k])
                t = one_pass_ms(predictor, out)
                if r:  # the first pass warms up
                    ts[k].append(t)
    finally:
        for p in procs:
            p.kill()
            p.wait()
    for k, v in ts.items():
        row[k] = {"threads": chosen[k], "median": statistics.median(v), "min": min(v), "max": max(v)}
    row["default_over_1"] = row["default"]["median"] / row["1"]["median"]
    row["2_over_1"] = row["2"]["median"] / row["1"]["median"]
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--loads", default="0,1,2", help="comma-separated numbers of busy processes")
    args = ap.parse_args()
    loads = [int(x) for x in args.loads.split(",")]
    load_avg = os.getloadavg()[0]
    print(f"{MODEL.relative_to(ROOT)} on the example frames; {machine()}, {available_cpus()} available; load "
          f"average {load_avg:.1f} at start", file=sys.stderr)
    predictor = Predictor(MODEL, "cpu")
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        for load in loads:
            print(f"{load} busy processes ...", file=sys.stderr)
            rows[str(load)] = at_load(predictor, load, Path(tmp), args.repeats)
    print("busy processes | running besides | 1 thread ms/frame | 2 threads | default (threads) | default / 1 | 2 / 1")
    for load, r in rows.items():
        cell = lambda k: f"{r[k]['median']:.0f} ({r[k]['min']:.0f}–{r[k]['max']:.0f})"  # noqa: E731
        print(f"{load} | {r['busy_besides']} | {cell('1')} | {cell('2')} | {cell('default')} ({r['default']['threads']}) "
              f"| {r['default_over_1']:.2f} | {r['2_over_1']:.2f}")
    headline = {f"default_over_1_load{k}": round(r["default_over_1"], 2) for k, r in rows.items()}
    headline.update({f"2_over_1_load{k}": round(r["2_over_1"], 2) for k, r in rows.items()})
    headline.update({f"default_threads_load{k}": r["default"]["threads"] for k, r in rows.items()})
    worst = rows.get("2")
    targets = {"load 2: default <= 1.5 x 1 thread": None if worst is None else worst["default_over_1"] <= 1.5}
    write_json(results_dir(__file__) / "predict_threads.json",
               {"command": "python " + " ".join(["benchmarks/speed/predict_threads.py"] + sys.argv[1:]), "date": today(),
                "machine": machine(), "load_average_start": load_avg, "repeats": args.repeats,
                "data": "models/road-multicamera/road.pt on examples/camvid/images (3) and examples/kitti/image_2 (1)",
                "headline": headline, "targets": targets, "loads": rows})
    print(json.dumps(headline))


if __name__ == "__main__":
    main()
