"""What ``vctrain predict --bev`` adds to predict's time a frame: the same frames predicted without and
with ``--bev``, interleaved in one run (issue 71: <= 10 %).

    .venv/bin/python benchmarks/speed/predict_bev.py [--frames 8] [--repeats 3] [--threads 2] [--engine auto]

Model: models/road-multicamera/road.pt (the shipped resize model; ``--engine``, default predict's
'auto'). Frames: the first ``--frames`` CamVid val frames enlarged 2x to 960x720 (the camvid preset's
size; benchmarks/speed/predict_e2e.py's frames), as an mp4v video (with ``--overlay``: the inset is
drawn) and as a folder of PNGs (no overlay). Camera: the camvid preset. Default grid (KITTI's,
400x800 cells of 0.05 m).

Columns (each the median over ``--repeats`` runs of the whole ``predict_inputs`` call, divided by the
frames; the three kinds of run take turns, so a change in the machine's load hits all three):
  off        predict without --bev
  nominal    --bev --within none: every frame at the camera's pose (the maps built once, cached)
  vp         --bev (default --within auto): each frame's own road VP, estimated by the model's rule
             (a resize model estimates none of its own: the VP is --bev's cost), maps built per frame
``ratio`` = column / off. Beside them, --bev's own work a frame timed alone in this thread (``stage``, the
median over repeats of the mean over the frames' probabilities of the last run): ``bev_ms`` (the two
remaps with cached maps, the PNGs, the metres; what the writing thread gets more), ``maps_ms`` (the maps
of a frame's own VP pose, built afresh) and ``vp_ms`` (the frame's road VP, vcprep.vp.frame_poses).
Threads: torch, OpenCV and onnxruntime pinned to ``--threads``; the
decoding and writing threads of the pipeline come on top. The load average is recorded: on a
shared machine the ratios, not the times, are the result.

Results: benchmarks/speed/results/predict_bev.json; the last stdout line is one JSON object.
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

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.report import machine, results_dir, today, write_json  # noqa: E402
from benchmarks.speed.predict_e2e import MODEL, frames_at, write_inputs  # noqa: E402

SIZE = (960, 720)
MODES = ("off", "nominal", "vp")


def run_once(src: Path, out: Path, mode: str, overlay: bool, engine: str) -> float:
    """Seconds of one ``vctrain predict`` (in this process) of ``src`` in ``mode``."""
    from vctrain.predict import PredictOptions, predict_inputs
    from vctrain.predict.bev import BevOptions

    shutil.rmtree(out, ignore_errors=True)
    bev = None if mode == "off" else BevOptions(emit=lambda record: None, spec="camvid")
    t0 = time.perf_counter()
    predict_inputs(PredictOptions(MODEL, (src,), out, "camvid", overlay=overlay, progress=False, engine=engine,
                                  within="none" if mode == "nominal" else "auto", bev=bev))
    return time.perf_counter() - t0


def stage(folder: Path, out: Path, repeats: int) -> dict[str, float]:
    """--bev's own work a frame, in this thread (module docstring), on ``out``'s ``_prob.png``."""
    import cv2

    from vcprep.bev import clear_cache
    from vcprep.camera import PRESETS
    from vcprep.dataset import collect_images
    from vcprep.vp import frame_poses
    from vctrain.predict.bev import BevOptions, BevRun

    jobs = collect_images([folder])
    probs = [cv2.imread(str(out / f"{j.id}_prob.png"), cv2.IMREAD_UNCHANGED) / 255.0 for j in jobs]
    cam, n = PRESETS["camvid"], len(jobs)
    nominal, own = (BevRun(BevOptions(spec="camvid"), cam, w) for w in ("none", "estimate"))
    t = {"bev_ms": [], "maps_ms": [], "vp_ms": []}
    with tempfile.TemporaryDirectory(prefix="predict_bev-stage-") as tmp:
        for _ in range(repeats):
            t0 = time.perf_counter()
            poses, _ = frame_poses(jobs, cam, "estimate")
            t["vp_ms"].append(1000 * (time.perf_counter() - t0) / n)
            t0 = time.perf_counter()
            for j, p in zip(jobs, probs):
                nominal.write(Path(tmp), j.id, p, j.image)
            t["bev_ms"].append(1000 * (time.perf_counter() - t0) / n)
            spent = 0.0
            for j, p in zip(jobs, probs):
                clear_cache()
                t0 = time.perf_counter()
                own.write(Path(tmp), j.id, p, j.image, poses[j.id].vp, poses[j.id].status)
                spent += time.perf_counter() - t0
            t["maps_ms"].append(1000 * spent / n - t["bev_ms"][-1])
    return {k: statistics.median(v) for k, v in t.items()}


def main() -> None:
    from vctrain.threads import use_threads

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--engine", default="auto")
    args = ap.parse_args()
    use_threads(args.threads)
    load0 = os.getloadavg()[0]
    rows = []
    with tempfile.TemporaryDirectory(prefix="predict_bev-") as tmp:
        wd = Path(tmp)
        video, folder = write_inputs(frames_at(args.frames, SIZE), wd, "960x720")
        for kind, src, overlay in (("video", video, True), ("folder", folder, False)):
            run_once(src, wd / "warm", "vp", overlay, args.engine)  # the engine loaded, caches warm
            times = {m: [] for m in MODES}
            for _ in range(args.repeats):
                for m in MODES:
                    times[m].append(1000 * run_once(src, wd / "out", m, overlay, args.engine) / args.frames)
            med = {m: statistics.median(times[m]) for m in MODES}
            if kind == "folder":
                costs = stage(folder, wd / "out", args.repeats)
            rows.append({"input": kind, "overlay": overlay, **{f"{m}_ms": med[m] for m in MODES},
                         **{f"ratio_{m}": med[m] / med["off"] for m in MODES[1:]}, "runs_ms": times})
            r = rows[-1]
            print(f"{kind}: off {med['off']:.1f} ms, nominal {med['nominal']:.1f} ms ({r['ratio_nominal']:.3f}x), "
                  f"vp {med['vp']:.1f} ms ({r['ratio_vp']:.3f}x)", file=sys.stderr)
    load1 = os.getloadavg()[0]
    costs["bev_over_off"] = costs["bev_ms"] / rows[-1]["off_ms"]
    costs["bev_maps_vp_over_off"] = (costs["bev_ms"] + costs["maps_ms"] + costs["vp_ms"]) / rows[-1]["off_ms"]
    print("input | overlay | off ms/frame | --bev --within none ms/frame | ratio | --bev (VP poses) ms/frame | ratio")
    for r in rows:
        print(f"{r['input']} | {'yes' if r['overlay'] else 'no'} | {r['off_ms']:.1f} | {r['nominal_ms']:.1f} | "
              f"{r['ratio_nominal']:.3f} | {r['vp_ms']:.1f} | {r['ratio_vp']:.3f}")
    print(f"--bev's own work a frame, alone: {costs['bev_ms']:.1f} ms (cached maps), + {costs['maps_ms']:.1f} ms "
          f"(its VP pose's maps), + {costs['vp_ms']:.1f} ms (its road VP); predict without --bev "
          f"{rows[-1]['off_ms']:.1f} ms: {costs['bev_over_off']:.3f} / {costs['bev_maps_vp_over_off']:.3f}")
    headline = {f"ratio_{m}_{r['input']}": round(r[f"ratio_{m}"], 3) for r in rows for m in MODES[1:]}
    headline.update({k: round(v, 3) for k, v in costs.items()})
    targets = {"--bev adds <= 10 % a frame (nominal pose)": all(r["ratio_nominal"] <= 1.10 for r in rows),
               "--bev adds <= 10 % a frame (VP poses)": all(r["ratio_vp"] <= 1.10 for r in rows)}
    write_json(results_dir(__file__) / "predict_bev.json",
               {"command": "python " + " ".join(["benchmarks/speed/predict_bev.py"] + sys.argv[1:]), "date": today(),
                "machine": machine(), "threads": args.threads, "engine": args.engine, "load_average": [load0, load1],
                "frames": args.frames, "repeats": args.repeats, "size": list(SIZE),
                "data": "CamVid val (../shared/data/camvid/val), first frames, enlarged 2x",
                "headline": headline, "targets": targets, "rows": rows, "stage": costs})
    print(json.dumps(headline))


if __name__ == "__main__":
    main()
