"""Deployment speed: the exported ONNX graph (``vctrain export``) against the torch path, per frame.

    .venv/bin/python benchmarks/speed/deploy.py [--repeats 7] [--threads 1,2,default]

Model: the cpu recipe's default architecture (resfpn, base width 16) with RANDOM weights (seed 0:
timing does not depend on them; agreement is checked on them) at its default working size, the
store size; the virtual camera designed as ``vctrain crossval``'s defaults do it (CamVid's camera,
pan/tilt range 10/5 degrees, 8 degrees above the horizon, stores of 172800 pixels), a
projective-completion model, and its resize twin (the same network on 480x360, 172800 pixels).
Frames: the KITTI road frame (1242x375, its own calibration) and a BDD100K frame (1280x720, the
folder's assumed camera) from ../shared/data; the virtual rectangle extended to each camera as
``vctrain predict`` does. Threads: cv2, torch and onnxruntime (intra-op) pinned to each of
``--threads`` in turn; 'default' is what ``vctrain predict`` takes without ``--threads``
(:func:`vctrain.threads.default_threads` when the script starts: the cores no other process is
running on; its count is recorded). Median and spread (min..max) over ``--repeats`` calls after
one warm-up.

Measured per frame (ms):
  net_torch / net_ort      the network alone (input at the working size, logits out) in torch / onnxruntime
  torch_path               vctrain.predict.frames.FramePredictor.predict: warp + completion (cv2.remap, cached
                           maps), the network (+ softmax), back-projection (cv2.warpPerspective); its
                           per-stage split from FramePredictor.times
  onnx_fixed / onnx_vp     the exported graph (frame -> P(road)) in onnxruntime: mount pose built in /
                           ``--vp-input`` (homography and completion built in the graph from the VP)
  torch_path_vp            the torch path with a VP per frame (what ``vctrain predict --within`` does),
                           on the --vp-input graph's rectangle; like onnx_vp, every call a new VP (a pose
                           within 90 % of the pose range), so no map is reused
  resize_torch / resize_onnx   the resize twin: FramePredictor (resize, network, resize back) / its graph
  folder road / store path     ``vctrain predict`` on a folder of 6 copies of the frame (per frame, at the
                           first thread count): the one road for a frame (vctrain.predict.road, in memory)
                           against the store path it replaced (warped into a store, read back); the
                           probabilities must be identical (issue 46)
Ratios (issue 35): geometry share = (warp + back-projection) / network, of the torch path
(target <= 0.15) and of the graph ((onnx_fixed - net_ort) / net_ort); onnx_over_torch =
onnx_fixed / torch_path (target <= 1) and onnx_vp / torch_path_vp; agreement of the graph with the
torch path: max |dP| (<= 1e-3) and the share of pixels whose mask (P >= 0.5) agrees (>= 0.999), for
the --vp-input graph the worst of the mount VP and 5 per-frame VPs. Results:
benchmarks/speed/results/deploy.json; the last stdout line is one JSON object of headline figures.
"""
from __future__ import annotations

import argparse
import io
import json
import math
import os
import platform
import statistics
import sys
import tempfile
import time
import warnings
from datetime import date
from pathlib import Path

import cv2
import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import SHARED_DATA
from benchmarks.measure.report import results_dir, write_json
from vcprep.store import store_params
from vcprep.camera import PRESETS, load_camera
from vcprep.warp import vp_from_pose
from vcprep.camera import design_virtual_camera
from vctrain.training import save_checkpoint, to_input
from vctrain.deploy import POSE_RANGE, OnnxPredictor, export_onnx  # (POSE_RANGE: vctrain export's default for --vp-input)
from vctrain.predict import FramePredictor, StageTimes
from vctrain.networks import build_model, model_args_for
from vctrain.predict import Predictor
from vctrain.threads import default_threads
from vctrain.study import DEFAULT_ABOVE, DEFAULT_STORE_PIXELS

DATA = SHARED_DATA
RESIZE_SIZE = (480, 360)  # the resize twin's working size: the same 172800 pixels


def frames() -> dict[str, tuple[np.ndarray, object, str]]:
    """name -> (BGR frame, its camera, where it came from)."""
    out = {}
    kitti = DATA / "kitti_road" / "training"
    if (kitti / "image_2" / "um_000000.png").is_file():
        out["kitti"] = (cv2.imread(str(kitti / "image_2" / "um_000000.png")),
                        load_camera(kitti / "calib" / "um_000000.txt"), "KITTI road um_000000 (its calibration)")
    bdd = DATA / "bdd100k_drivable"
    files = sorted((bdd / "images").glob("*.jpg")) if bdd.is_dir() else []
    if files:
        out["bdd"] = (cv2.imread(str(files[0])), load_camera(bdd / "camera.yaml"),
                      f"BDD100K {files[0].name} (the folder's assumed camera)")
    if not out:
        raise SystemExit(f"no frames: {DATA} holds neither kitti_road nor bdd100k_drivable")
    return out


def checkpoints(folder: Path, arch: str = "resfpn") -> tuple[Path, Path, dict]:
    """A virtual-camera checkpoint and its resize twin with random weights (module docstring); ``arch``
    their network (benchmarks/speed/networks.py compares them)."""
    virt = design_virtual_camera([PRESETS["camvid"]], 10.0, 5.0, name="study-virtual", above=DEFAULT_ABOVE).camera
    sp = store_params(virt, math.sqrt(DEFAULT_STORE_PIXELS / (virt.size[0] * virt.size[1])))
    torch.manual_seed(0)
    args = model_args_for(arch, 3).to_dict()
    ck = {"model": build_model(args).state_dict(), "model_args": args, "config": {"recipe": "cpu"},
          "data": {"mode": "virtual", "input_size": sp["store_size"], "store_params": sp,
                   "completion": "projective", "vp_channel": False, "greyscale": 0.0}}
    save_checkpoint(folder / f"vc-{arch}.pt" if arch != "resfpn" else folder / "vc.pt", ck)
    ck["data"] = {"mode": "resize", "input_size": list(RESIZE_SIZE), "store_params": None, "completion": "none",
                  "vp_channel": False, "greyscale": 0.0}
    names = ("vc.pt", "rs.pt") if arch == "resfpn" else (f"vc-{arch}.pt", f"rs-{arch}.pt")
    save_checkpoint(folder / names[1], ck)
    return folder / names[0], folder / names[1], sp


def timed(fn, repeats: int) -> list[float]:
    fn()
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        ts.append((time.perf_counter() - t0) * 1000)
    return ts


def stat(ts: list[float]) -> dict:
    return {"median": statistics.median(ts), "min": min(ts), "max": max(ts)}


def network_graph(model: torch.nn.Module, size: tuple[int, int]) -> bytes:
    """The network alone as ONNX (input (1, 3, h, w) float, logits out)."""
    buf = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(model, (torch.zeros(1, 3, size[1], size[0]),), buf, dynamo=False, opset_version=17,
                          input_names=["x"], output_names=["logits"])
    return buf.getvalue()


def ort_session(model, threads: int):
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = threads
    so.inter_op_num_threads = 1
    so.log_severity_level = 3
    return ort.InferenceSession(model, so, providers=["CPUExecutionProvider"])


def agreement(got: np.ndarray, ref: np.ndarray) -> dict:
    return {"max_abs_diff": float(np.abs(got - ref).max()), "mask_agreement": float(((got >= 0.5) == (ref >= 0.5)).mean())}


def measure(name: str, frame: np.ndarray, cam, vc: Path, rs: Path, tmp: Path, threads: list[tuple[str, int]],
            repeats: int) -> dict:
    """Every figure of one frame at each (label, count) of ``threads``."""
    h, w = frame.shape[:2]
    p, prs = Predictor(vc, "cpu"), Predictor(rs, "cpu")
    fp = FramePredictor(p, cam, (w, h))
    fp_rs = FramePredictor(prs, cam, (w, h))
    work = p.working_size(fp.store_size)
    export_onnx(vc, cam, tmp / f"{name}.onnx")
    export_onnx(vc, cam, tmp / f"{name}_vp.onnx", vp_input=True, pose_range=POSE_RANGE)
    export_onnx(rs, cam, tmp / f"{name}_rs.onnx")
    vp = vp_from_pose(cam.for_image_size((w, h)))
    # the --vp-input graph's rectangle holds every pose in the range: the torch path with the same one
    poses = [(cam.pan + a * POSE_RANGE[0], cam.tilt + b * POSE_RANGE[1]) for a in (-1, 0, 1) for b in (-1, 0, 1)]
    fp_vp = FramePredictor(p, cam, (w, h), poses)
    c = cam.for_image_size((w, h))

    def frame_vps(seed: int, k: int) -> list[np.ndarray]:
        """Per-frame VPs (float32) of poses drawn within 90 % of the range: every timed call gets
        a VP no earlier call had (the torch path reuses no map)."""
        poses = np.random.default_rng(seed).uniform(-0.9, 0.9, (k, 2))
        return [np.array(vp_from_pose(c, c.pan + a * POSE_RANGE[0], c.tilt + b * POSE_RANGE[1]), np.float32)
                for a, b in poses]
    d = {"frame_size": [w, h], "store_size": list(fp.store_size), "working_size": list(work),
         "resize_working_size": list(RESIZE_SIZE), "vp_store_size": list(fp_vp.store_size),
         "graph_mb": {k: os.path.getsize(tmp / f"{name}{k}.onnx") / 1e6 for k in ("", "_vp", "_rs")}}
    with torch.no_grad():
        d["agreement_fixed"] = agreement(OnnxPredictor(tmp / f"{name}.onnx", 1).road_probability(frame), fp.predict(frame))
        g = OnnxPredictor(tmp / f"{name}_vp.onnx", 1)
        each = [agreement(g.road_probability(frame, v), fp_vp.predict(frame, v.astype(np.float64)))
                for v in [np.array(vp, np.float32)] + frame_vps(100, 5)]
        d["agreement_vp"] = {"max_abs_diff": max(a["max_abs_diff"] for a in each),
                             "mask_agreement": min(a["mask_agreement"] for a in each), "vps": len(each)}
        d["agreement_resize"] = agreement(OnnxPredictor(tmp / f"{name}_rs.onnx", 1).road_probability(frame),
                                          fp_rs.predict(frame))
    img, _ = fp.warp(frame)
    x = p.network_input(to_input(cv2.resize(img, work) if tuple(work) != fp.store_size else img))
    xr = p.network_input(to_input(cv2.resize(frame, RESIZE_SIZE)))
    net_vc, net_rs = network_graph(p.model, work), network_graph(p.model, RESIZE_SIZE)
    d["threads"] = {}
    for label, t in threads:
        cv2.setNumThreads(t)
        torch.set_num_threads(t)
        r: dict = {"threads": t}
        with torch.no_grad():
            r["net_torch"] = stat(timed(lambda: p.model(x), repeats))
            r["resize_net_torch"] = stat(timed(lambda: p.model(xr), repeats))
            fp.predict(frame)
            fp.times = StageTimes()
            r["torch_path"] = stat(timed(lambda: fp.predict(frame), repeats))
            r["torch_stages"] = fp.times.per_frame_ms()
            r["resize_torch"] = stat(timed(lambda: fp_rs.predict(frame), repeats))
            vps = iter(frame_vps(2 * t, repeats + 1))
            r["torch_path_vp"] = stat(timed(lambda: fp_vp.predict(frame, next(vps).astype(np.float64)), repeats))
        s = ort_session(net_vc, t)
        r["net_ort"] = stat(timed(lambda: s.run(None, {"x": x.numpy()}), repeats))
        s = ort_session(net_rs, t)
        r["resize_net_ort"] = stat(timed(lambda: s.run(None, {"x": xr.numpy()}), repeats))
        g = OnnxPredictor(tmp / f"{name}.onnx", t)
        r["onnx_fixed"] = stat(timed(lambda: g.road_probability(frame), repeats))
        g = OnnxPredictor(tmp / f"{name}_vp.onnx", t)
        vps = iter(frame_vps(2 * t + 1, repeats + 1))
        r["onnx_vp"] = stat(timed(lambda: g.road_probability(frame, next(vps)), repeats))
        g = OnnxPredictor(tmp / f"{name}_rs.onnx", t)
        r["resize_onnx"] = stat(timed(lambda: g.road_probability(frame), repeats))
        st = r["torch_stages"]
        r["geometry_share_torch"] = (st["warp"] + st["backproject"]) / st["network"]
        r["geometry_share_graph"] = (r["onnx_fixed"]["median"] - r["net_ort"]["median"]) / r["net_ort"]["median"]
        r["onnx_over_torch"] = r["onnx_fixed"]["median"] / r["torch_path"]["median"]
        r["onnx_vp_over_torch"] = r["onnx_vp"]["median"] / r["torch_path"]["median"]
        r["onnx_vp_over_torch_vp"] = r["onnx_vp"]["median"] / r["torch_path_vp"]["median"]
        r["resize_onnx_over_torch"] = r["resize_onnx"]["median"] / r["resize_torch"]["median"]
        d["threads"][label] = r
        if "folder" not in d:  # at the first thread count
            d["folder"] = folder_paths(name, frame, cam, vc, tmp, repeats)
    return d


FOLDER_FRAMES = 6  # frames of the folder-path timing (copies of the frame)


def folder_paths(name: str, frame: np.ndarray, cam, vc: Path, tmp: Path, repeats: int) -> dict:
    """``vctrain predict MODEL --camera CAM FOLDER`` per frame: the one road for a frame (in memory,
    vctrain.predict.road: "after") against the store path it replaced (the folder warped into a store,
    read back and predicted: "before", what ``--keep-store`` still does); the same masks (checked)."""
    from vctrain.predict import predict_frames

    folder = tmp / f"{name}_folder"
    folder.mkdir()
    for k in range(FOLDER_FRAMES):
        cv2.imwrite(str(folder / f"f{k}.png"), frame)
    p, runs = Predictor(vc, "cpu"), iter(range(10 ** 6))

    def road():
        return predict_frames(p, [folder], tmp / f"{name}_road{next(runs)}", cam, progress=False, within="none")

    def store():
        k = next(runs)
        return predict_frames(p, [folder], tmp / f"{name}_store{k}", cam, progress=False, within="none",
                              keep_store=tmp / f"{name}_kept{k}")

    a, b = road().written, store().written  # (also the warm-up)
    same = all(np.array_equal(cv2.imread(str(x.with_name(x.name.replace("_mask", "_prob"))), cv2.IMREAD_UNCHANGED),
                              cv2.imread(str(y.with_name(y.name.replace("_mask", "_prob"))), cv2.IMREAD_UNCHANGED))
               for x, y in zip(a, b))
    after, before = stat(timed(road, repeats)), stat(timed(store, repeats))
    per = {k: v / FOLDER_FRAMES for k, v in after.items()}, {k: v / FOLDER_FRAMES for k, v in before.items()}
    return {"frames": FOLDER_FRAMES, "road_ms": per[0], "store_path_ms": per[1], "same_probabilities": same,
            "road_over_store": per[0]["median"] / per[1]["median"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--threads", default="1,2,default", help="comma-separated thread counts (cv2, torch, "
                    "onnxruntime); 'default': vctrain predict's default on this machine now")
    args = ap.parse_args()
    threads = [(t, default_threads() if t == "default" else int(t)) for t in args.threads.split(",")]
    sets = frames()
    machine = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores"
    print(f"model: resfpn width 16, random weights; threads {threads}; {machine}; "
          f"load average {os.getloadavg()[0]:.1f} at start", file=sys.stderr)
    detail = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        vc, rs, sp = checkpoints(tmp)
        for name, (frame, cam, _) in sets.items():
            print(f"{name}: measuring ...", file=sys.stderr)
            detail[name] = measure(name, frame, cam, vc, rs, tmp, threads, args.repeats)
    cols = ["frames", "thr", "net torch", "net ort", "torch path (warp/net/back)", "onnx fixed", "torch path vp",
            "onnx vp", "resize torch", "resize onnx", "geom/net torch", "geom/net graph", "onnx/torch", "vp: onnx/torch"]
    print(" | ".join(cols))
    for name, d in detail.items():
        for t, r in d["threads"].items():
            st = r["torch_stages"]
            print(" | ".join([f"{name} {d['frame_size'][0]}x{d['frame_size'][1]}",
                              t if t != "default" else f"default ({r['threads']})",
                              *(f"{r[k]['median']:.1f}" for k in ("net_torch", "net_ort")),
                              f"{r['torch_path']['median']:.1f} ({st['warp']:.1f}/{st['network']:.1f}/{st['backproject']:.1f})",
                              *(f"{r[k]['median']:.1f}" for k in ("onnx_fixed", "torch_path_vp", "onnx_vp",
                                                                   "resize_torch", "resize_onnx")),
                              f"{r['geometry_share_torch']:.3f}", f"{r['geometry_share_graph']:.3f}",
                              f"{r['onnx_over_torch']:.2f}", f"{r['onnx_vp_over_torch_vp']:.2f}"]))
        a = d["agreement_fixed"]
        print(f"  {name}: store {d['store_size'][0]}x{d['store_size'][1]} (vp graph {d['vp_store_size'][0]}x"
              f"{d['vp_store_size'][1]}); graph vs torch path: max |dP| {a['max_abs_diff']:.2e}, masks agree "
              f"{100 * a['mask_agreement']:.3f} %; --vp-input graph ({d['agreement_vp']['vps']} VPs): max |dP| "
              f"{d['agreement_vp']['max_abs_diff']:.2e}, masks agree {100 * d['agreement_vp']['mask_agreement']:.3f} %; "
              f"graphs {d['graph_mb']['']:.1f} MB (vp {d['graph_mb']['_vp']:.1f})")
    for name, d in detail.items():
        f = d["folder"]
        print(f"  {name}: a folder of {f['frames']} frames, ms per frame: the one road {f['road_ms']['median']:.1f}, "
              f"the store path it replaced {f['store_path_ms']['median']:.1f} ({f['road_over_store']:.2f}x); "
              f"probabilities {'identical' if f['same_probabilities'] else 'DIFFERENT'}")
    headline = {}
    for name, d in detail.items():
        r = d["threads"][threads[0][0]]
        headline.update({f"geometry_share_of_network_{name}": round(r["geometry_share_torch"], 3),
                         f"graph_geometry_share_of_network_{name}": round(r["geometry_share_graph"], 3),
                         f"onnx_over_torch_{name}": round(r["onnx_over_torch"], 3),
                         f"onnx_vp_over_torch_{name}": round(r["onnx_vp_over_torch"], 3),
                         f"onnx_vp_over_torch_vp_{name}": round(r["onnx_vp_over_torch_vp"], 3),
                         f"vp_max_abs_diff_{name}": float(f"{d['agreement_vp']['max_abs_diff']:.3g}"),
                         f"vp_mask_agreement_{name}": round(d["agreement_vp"]["mask_agreement"], 5),
                         f"resize_onnx_over_torch_{name}": round(r["resize_onnx_over_torch"], 3),
                         f"max_abs_diff_{name}": float(f"{d['agreement_fixed']['max_abs_diff']:.3g}"),
                         f"mask_agreement_{name}": round(d["agreement_fixed"]["mask_agreement"], 5),
                         f"graph_mb_{name}": round(d["graph_mb"][""], 1),
                         f"folder_road_ms_{name}": round(d["folder"]["road_ms"]["median"], 1),
                         f"folder_store_path_ms_{name}": round(d["folder"]["store_path_ms"]["median"], 1),
                         f"folder_road_over_store_{name}": round(d["folder"]["road_over_store"], 3),
                         f"folder_same_probabilities_{name}": d["folder"]["same_probabilities"]})
    headline["threads"] = threads[0][1]
    out = {"command": "python " + " ".join(["benchmarks/speed/deploy.py"] + sys.argv[1:]), "date": date.today().isoformat(),
           "machine": machine, "threads": [label for label, _ in threads],
           "default_threads": dict(threads).get("default"), "load_average_start": os.getloadavg()[0],
           "data": "; ".join(s[2] for s in sets.values()) + "; resfpn width 16 with random weights",
           "store_params": {"store_size": sp["store_size"], "scale": sp["scale"]},
           "headline": headline, "detail": detail}
    write_json(results_dir(__file__) / "deploy.json", out, indent=2)
    print(json.dumps(headline))


if __name__ == "__main__":
    main()
