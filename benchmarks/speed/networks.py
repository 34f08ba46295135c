"""The networks' cost side by side (issues 53, 59): ``lite0fpn`` (EfficientNet-Lite0 encoder) against ``resfpn``,
and the larger ``lite1fpn``/``lite2fpn``.

    .venv/bin/python benchmarks/speed/networks.py [--repeats 7] [--train-steps 6] [--models resfpn,lite0fpn]

Both networks with RANDOM weights (seed 0: time does not depend on them), set up exactly as
benchmarks/speed/deploy.py sets up resfpn (a virtual-camera model on crossval's designed virtual camera at
its store size, and its resize twin at 480x360), measured in one process, the models interleaved in
every repeat so that a load change on this shared machine hits both alike:

  predict_ms_t1      vctrain.predict.frames.FramePredictor.predict on the BDD100K 1280x720 frame (the
                     folder's assumed camera), 1 thread: warp + completion, network, back-projection
                     (what ``vctrain predict`` does per frame); ``resize_predict_ms_t1`` for the resize twin
  net_ms_t1          the network alone at the virtual model's working size, 1 thread
  train_img_per_s    training images per second at 2 threads: forward, cross-entropy, backward and
                     an AdamW step on batches of 8 random 4/9-width windows of the 480x360 working image
                     (the cpu recipe's study crop), after one warm-up step

Reported: median and min..max over ``--repeats`` (timings in ms) or ``--train-steps`` (one figure per
step), and each network's medians over the first's (``--models``' baseline; the targets: issue 53's
lite0fpn / resfpn predict at 1 thread <= 2x, issue 59's shipped model at most 1.5x today's). Results: benchmarks/speed/results/networks.{md,json}; the last stdout line is one JSON object.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
import torch
from torch.nn import functional as F

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.speed.deploy import RESIZE_SIZE, checkpoints, frames
from benchmarks.measure.report import machine, results_dir, today, write_json
from vctrain.training import DEFAULT_RECIPE, RECIPES, TRAIN_WINDOW, to_input
from vctrain.networks import build_model, model_args_for
from vctrain.predict import FramePredictor, Predictor

CROP = (round(RESIZE_SIZE[0] * TRAIN_WINDOW[0]), round(RESIZE_SIZE[1] * TRAIN_WINDOW[1]))  # the recipe's training window
BATCH = RECIPES[DEFAULT_RECIPE]["batch_size"]  # the recipe's batch


def _stat(v: list[float]) -> dict:
    return {"median": round(statistics.median(v), 2), "min": round(min(v), 2), "max": round(max(v), 2)}


def _train_step(model: torch.nn.Module, opt: torch.optim.Optimizer, x: torch.Tensor, y: torch.Tensor) -> float:
    t0 = time.perf_counter()
    opt.zero_grad(set_to_none=True)
    F.cross_entropy(model(x), y, ignore_index=255).backward()
    opt.step()
    return BATCH / (time.perf_counter() - t0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--train-steps", type=int, default=6)
    ap.add_argument("--models", default="resfpn,lite0fpn")
    a = ap.parse_args()
    models = a.models.split(",")
    name, (frame, cam, where) = "bdd", frames()["bdd"]
    h, w = frame.shape[:2]
    tmp = Path(tempfile.mkdtemp(prefix="networks-"))
    fps, nets, trains = {}, {}, {}
    for m in models:
        vc, rs, sp = checkpoints(tmp, m)
        p = Predictor(vc, "cpu")
        fps[m] = (FramePredictor(p, cam, (w, h)), FramePredictor(Predictor(rs, "cpu"), cam, (w, h)))
        work = p.working_size(fps[m][0].store_size)
        nets[m] = (p.model, p.network_input(to_input(cv2.resize(frame, tuple(work)))))
        torch.manual_seed(0)
        net = build_model(model_args_for(m)).train()
        g = torch.Generator().manual_seed(0)
        x = torch.rand(BATCH, 3, CROP[1], CROP[0], generator=g) * 2 - 1
        y = (torch.rand(BATCH, CROP[1], CROP[0], generator=g) > 0.5).long()
        trains[m] = (net, torch.optim.AdamW(net.parameters(), 1e-3), x, y)
    got = {m: {"predict_ms_t1": [], "resize_predict_ms_t1": [], "net_ms_t1": [], "train_img_per_s": []} for m in models}
    torch.set_num_threads(1)
    cv2.setNumThreads(1)
    for m in models:  # warm-up
        fps[m][0].predict(frame), fps[m][1].predict(frame)
    for _ in range(a.repeats):
        for m in models:
            for key, fn in (("predict_ms_t1", lambda: fps[m][0].predict(frame)),
                            ("resize_predict_ms_t1", lambda: fps[m][1].predict(frame))):
                t0 = time.perf_counter()
                fn()
                got[m][key].append(1000 * (time.perf_counter() - t0))
            net, x = nets[m]
            with torch.no_grad():
                t0 = time.perf_counter()
                net(x)
                got[m]["net_ms_t1"].append(1000 * (time.perf_counter() - t0))
    torch.set_num_threads(2)
    for m in models:
        _train_step(*trains[m])  # warm-up
    for _ in range(a.train_steps):
        for m in models:
            got[m]["train_img_per_s"].append(_train_step(*trains[m]))
    res = {m: {k: _stat(v) for k, v in d.items()} for m, d in got.items()}
    head = {f"{k}_{m}": res[m][k]["median"] for m in models for k in res[m]}
    base, others = models[0], models[1:]  # every other network over the first (the baseline of the run)
    for n in others:
        for k in res[base]:
            head[f"{k}_{n}_over_{base}"] = round(res[n][k]["median"] / res[base][k]["median"], 2)
    lines = [f"Networks on {where} ({w}x{h}); predict and network at 1 thread ({a.repeats} repeats), training at "
             f"2 threads (batch {BATCH} of {CROP[0]}x{CROP[1]} windows, {a.train_steps} steps); median (min..max).",
             "", "| figure | " + " | ".join(models) + "".join(f" | {n} / {base}" for n in others) + " |",
             "|---|" + "---|" * (2 * len(models) - 1)]
    for k in got[base]:
        cells = [f"{res[m][k]['median']} ({res[m][k]['min']}..{res[m][k]['max']})" for m in models]
        lines.append(f"| {k} | " + " | ".join(cells + [str(head[f"{k}_{n}_over_{base}"]) for n in others]) + " |")
    table = "\n".join(lines) + "\n"
    print(table)
    out = results_dir(__file__)
    (out / "networks.md").write_text(table)
    write_json(out / "networks.json", {"headline": head, "figures": res, "frame": where, "frame_size": [w, h],
                                       "train_window": list(CROP), "batch": BATCH, "repeats": a.repeats,
                                       "train_steps": a.train_steps, "machine": machine(), "date": today(),
                                       "command": f"benchmarks/speed/networks.py --repeats {a.repeats} "
                                                  f"--train-steps {a.train_steps} --models {a.models}"})
    print(json.dumps(head))
    sys.stdout.flush()


if __name__ == "__main__":
    main()
