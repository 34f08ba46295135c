"""How well `vcprep camera estimate` recovers cameras whose calibration we know and hide (issue 25).

    .venv/bin/python benchmarks/camera_from_frames/camera_estimate.py [--frames 8] [--quick]

Threads: cv2.setNumThreads(1) (one core). Nothing here trains; the estimator has no parameter fitted
to these frames (its constants are in vcprep/camera/estimate.py and vcprep/vp/reliability.py).

Sets (truth -> what is compared):

* ``synthetic``: roads rendered (:mod:`vcprep.synthetic`) through 25 exactly known cameras at
  480x360: fx = 0.5, 0.71, 1, 1.41, 2 x a 60-degree lens, tilt -8, -4, 0, 4, 8 degrees, principal
  point off the centre by (+3, -4) px; ``--frames`` frames each, road headings within +/-2 deg
  (median 0). Exact truth for everything.
* ``camvid-sim``: CamVid val through ``vcprep simulate`` cameras (exact K' R K^-1 from the camvid
  preset at 480x360; a crop, so at most 33 deg wide at +/-8 deg): hfov 20 deg x tilt -3/0/+3 deg and 30 deg x -6/0/+6 deg
  relative to the CamVid rig. The truth
  is the simulated camera's nominal pose, which inherits the real rig's unknown mounting offset
  (CamVid val's own estimate: ``camvid-val`` below), so these errors include it.
* ``camvid-val`` (101 frames), ``camvid-0016E5`` / ``camvid-0006R0`` / ``camvid-0001TP`` (train
  sequences) against the camvid preset (tilt 0: the paper's nominal value, not a measurement), and
  ``cityscapes`` (400 frames, 256x256 squashed from 2048x1024; ``--source-size 2048x1024``) against
  its camera.yaml (typical Cityscapes intrinsics, tilt 2.4: typical extrinsics, not per frame).
  KITTI: the one frame in ../shared/data is below the estimator's minimum of 5 frames (listed).

Per camera, estimated twice: with the true fx and pixel aspect given (``--fx``, ``--source-size``:
what the frames alone say about the pose) and with nothing given but the labels of the real sets
(fx ASSUMED from a 60-degree FOV, square pixels ASSUMED, the height from the road footprint where
there are labels, ASSUMED 1.4 m elsewhere). Errors: horizon row (% of the height; independent of
fx), tilt and pan (degrees), fx (%; only where it was assumed), and the road plane's depth scale
``fy * height`` (%; the vertical stretch of the road in the virtual image is its inverse) with
the road-footprint height and with the height assumed. The road width the footprint height aims
at (``ROAD_WIDTH``) is measured beside: the median visible road width of CamVid train and of the
Cityscapes set under their true calibrations. Targets of
the issue: |tilt error| <= 1 deg, |horizon error| <= 2 % of the height, fx within 10 % (median over
cameras) -- the last is reported as the error of the assumption, since road frames do not fix fx
(vcprep/camera/estimate.py). Speed: seconds per 100 frames of the estimate outside VP detection
(total minus the time spent in ``estimate_vp``, measured in the same run), beside VP detection's own.
The last stdout line is one JSON object: ``tilt_abs_err_median``, ``tilt_abs_err_max``,
``horizon_err_pct_median``, ``horizon_err_pct_max`` (synthetic, fx given), the same with fx assumed
(``*_fx_assumed``), ``fx_err_pct_median_assumed``, ``real`` (per real set), ``s_per_100_frames_besides_vp``,
``s_per_100_frames_vp``, ``real_depth_scale_err_pct`` (and ``_height_assumed``), ``road_width_m``. Outputs: benchmarks/camera_from_frames/results/camera_estimate.{md,json}.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import BIN, CITYSCAPES, CS_FORMAT, DATA, ROOT, run
from benchmarks.measure.report import machine, results_dir, today, write_json
import vcprep.vp.reliability as vpmod
from vcprep.camera import PRESETS, Camera, load_camera
from vcprep.camera import ASSUMED_HEIGHT, ROAD_WIDTH, estimate_camera, road_widths
from vcprep.errors import InputError
from vcprep.warp import vp_from_pose
from vcprep.labels import get_label_format
from vcprep.synthetic import RoadScene, render_road

FOCALS = [0.5, 0.71, 1.0, 1.41, 2.0]
TILTS = [-8.0, -4.0, 0.0, 4.0, 8.0]
# simulate crops the 58-degree CamVid frame (<= 33 deg wide at +/-8 deg); the horizon stays in view
SIM = {f"hfov{hf}_tilt{t:+d}": (hf, t) for hf, ts in ((20, (-3, 0, 3)), (30, (-6, 0, 6))) for t in ts}


class _VPTimer:
    """Time spent inside estimate_vp (what the estimate costs besides VP detection)."""

    def __init__(self):
        self.seconds, self._orig = 0.0, vpmod.estimate_vp

    def __enter__(self):
        def timed(*a, **k):
            t = time.perf_counter()
            try:
                return self._orig(*a, **k)
            finally:
                self.seconds += time.perf_counter() - t
        vpmod.estimate_vp = timed
        return self

    def __exit__(self, *exc):
        vpmod.estimate_vp = self._orig


def _errors(est, truth: Camera, with_fx: bool) -> dict:
    """Horizon row error (% height) at the principal point's column, tilt/pan errors (deg), fx error (%)."""
    c = est.camera
    # the horizon (row of the average road VP) of the truth and of the estimate, in the same pixels
    v_true = vp_from_pose(truth)[1]
    v_est = vp_from_pose(c)[1]
    out = {"horizon_err_pct": 100 * (v_est - v_true) / truth.size[1],
           "tilt_err": c.tilt - truth.tilt, "pan_err": c.pan - truth.pan, "accepted": est.accepted,
           "frames": est.frames}
    if not with_fx:
        out["fx_err_pct"] = 100 * (c.fx / truth.fx - 1)
    return out


def _synthetic(wd: Path, frames: int) -> dict[str, tuple[list[Path], Camera, dict]]:
    sets = {}
    w, h = 480, 360
    heads = np.linspace(-2, 2, frames)
    for fk in FOCALS:
        for t in TILTS:
            f = fk * (w / 2) / math.tan(math.radians(30))
            cam = Camera("true", (w, h), f, f, (w - 1) / 2 + 3, (h - 1) / 2 - 4, 1.4, tilt=t, pan=0.0)
            d = wd / f"syn_f{fk}_t{t:+.0f}"
            d.mkdir(parents=True, exist_ok=True)
            files = []
            for i, dp in enumerate(heads):
                p = d / f"s_{i:03d}.png"
                if not p.exists():
                    img, _ = render_road(cam, RoadScene(texture_seed=i, offset=0.5 * ((i % 3) - 1)), pan=float(dp),
                                         supersample=1)
                    cv2.imwrite(str(p), img)
                files.append(p)
            sets[d.name] = (files, cam, {})
    return sets


def _camvid_sim(wd: Path, quick: bool) -> dict[str, tuple[list[Path], Camera, dict]]:
    from benchmarks.measure.data import native_camera

    native = native_camera(wd)
    images, labels = DATA / "val", DATA / "valannot"
    if quick:  # 8 frames
        images, labels = wd / "val_subset" / "images", wd / "val_subset" / "labels"
        for src, dst in ((DATA / "val", images), (DATA / "valannot", labels)):
            dst.mkdir(parents=True, exist_ok=True)
            for f in sorted(src.glob("*.png"))[:8]:
                (dst / f.name).symlink_to(f)
    sets = {}
    for name, (hf, t) in SIM.items():
        dst = wd / f"sim_{name}"
        if not (dst / "camera.yaml").exists():
            run(BIN / "vcprep", "simulate", "--camera", native, "--images", images, "--labels", labels,
                "--label-format", "camvid", "--out", dst, "--name", name, "--size", "400x300", "--hfov", hf,
                "--tilt", t, "--quiet")
        files = sorted((dst / "images").iterdir())
        sets[f"camvid-sim {name}"] = (files, load_camera(dst / "camera.yaml"), {})
    return sets


def _real(quick: bool) -> dict[str, tuple[list[Path], Camera, dict]]:
    """Real sets: (frames, true camera, {"source_size", "labels", "label_format"} as they apply)."""
    cv = PRESETS["camvid"].for_image_size((480, 360))
    lab = lambda files, folder: [folder / f.name for f in files]
    val = sorted((DATA / "val").glob("*.png"))
    sets = {"camvid-val": (val, cv, {"labels": lab(val, DATA / "valannot"), "label_format": "camvid"})}
    for seq in ("0016E5", "0006R0", "0001TP"):
        files = sorted((DATA / "train").glob(f"{seq}_*.png"))
        sets[f"camvid-{seq}"] = (files, cv, {"labels": lab(files, DATA / "trainannot"), "label_format": "camvid"})
    if CITYSCAPES.is_dir():
        files = sorted((CITYSCAPES / "images").glob("*.jpg"))
        sets["cityscapes"] = (files, load_camera(CITYSCAPES / "camera.yaml"),
                              {"source_size": (2048, 1024), "labels": [CITYSCAPES / "labels" / (f.stem + ".png")
                                                                       for f in files], "label_format": CS_FORMAT})
    if quick:
        sets = {k: (v[0][:12], v[1], {**v[2], **({"labels": v[2]["labels"][:12]} if "labels" in v[2] else {})})
                for k, v in sets.items()}
    return sets


def _road_width_m(labels: list[Path], fmt: str, cam: Camera) -> tuple[float, int]:
    """The median visible road width (metres) of labelled frames under their TRUE calibration, and
    the number of frames it was measurable in: what ROAD_WIDTH (CamVid train's) stands for."""
    w = road_widths(labels, get_label_format(fmt), cam, cam.ego_rows)
    return (float(np.median(w)) * cam.height if len(w) else float("nan")), len(w)


def _depth_scale_err(c: Camera, truth: Camera) -> float:
    """% error of fy * height, the road plane's depth scale (depth = fy h / (v - v_horizon) for a
    level camera): how much too far (>0) or near the estimated camera puts each road row; the
    vertical stretch of the road in the virtual image is its inverse."""
    return 100 * (c.fy * c.height / (truth.fy * truth.height) - 1)


def _stats(rows: list[dict], key: str) -> tuple[float, float]:
    x = np.abs([r[key] for r in rows])
    return float(np.median(x)), float(np.max(x))


def _estimate_row(files: list[Path], truth: Camera, kw: dict, clock: dict) -> dict:
    """One set's errors with fx given and with nothing given, or {"failed": why} where the estimator
    refuses the camera; ``clock`` adds the seconds and frames of each estimate."""
    row = {}
    for with_fx in (True, False):
        t0 = time.perf_counter()
        # fx given: what the frames say of the pose; nothing given: the labels (where there are) give
        # the height, from the road footprint
        given = {"fx": truth.fx, "pixel_aspect": truth.fy / truth.fx} if with_fx else {
            "labels": kw.get("labels"), "label_format": get_label_format(kw["label_format"])
            if kw.get("labels") else None}
        try:
            est = estimate_camera(files, source_size=kw.get("source_size") if with_fx else None, **given)
        except InputError as e:  # reported, never hidden: a camera the estimator refuses
            return {"failed": f"{e.problem} ({'fx given' if with_fx else 'fx assumed'})"}
        clock["seconds"] += time.perf_counter() - t0
        clock["frames"] += len(files)
        row["fx_given" if with_fx else "fx_assumed"] = _errors(est, truth, with_fx)
        if not with_fx:
            e = row["fx_assumed"]
            e["height"] = est.camera.height
            e["height_source"] = est.values["height"].source
            e["depth_scale_err_pct"] = _depth_scale_err(est.camera, truth)
            # the same camera with the height assumed (what a user got without labels)
            e["depth_scale_err_pct_height_assumed"] = _depth_scale_err(replace(est.camera, height=ASSUMED_HEIGHT),
                                                                       truth)
    return row


def estimate_sets(groups: dict) -> tuple[dict, dict, float, float]:
    """Every set's row (printed as it comes), the refused sets, and seconds per 100 frames inside
    estimate_vp and besides it."""
    results: dict[str, dict[str, dict]] = {}
    failed: dict[str, str] = {}
    clock = {"seconds": 0.0, "frames": 0}
    with _VPTimer() as vt:
        for g, sets in groups.items():
            for name, (files, truth, kw) in sets.items():
                row = _estimate_row(files, truth, kw, clock)
                if "failed" in row:
                    failed[f"{g} {name}"] = row["failed"]
                    print(f"{g:10s} {name:24s} NO ESTIMATE: {row['failed']}", flush=True)
                    continue
                results.setdefault(g, {})[name] = row
                e = row["fx_given"]
                print(f"{g:10s} {name:24s} tilt err {e['tilt_err']:+6.2f} deg, horizon {e['horizon_err_pct']:+6.2f} %, "
                      f"pan {e['pan_err']:+6.2f}; fx assumed: horizon {row['fx_assumed']['horizon_err_pct']:+6.2f} %, "
                      f"tilt {row['fx_assumed']['tilt_err']:+6.2f}, fx {row['fx_assumed']['fx_err_pct']:+6.1f} % "
                      f"({e['accepted']}/{e['frames']} VPs)", flush=True)
    return (results, failed, 100 * vt.seconds / clock["frames"],
            100 * (clock["seconds"] - vt.seconds) / clock["frames"])


def visible_road_width(quick: bool) -> dict:
    """What ROAD_WIDTH stands for: the median visible road width under the TRUE calibrations."""
    cv = PRESETS["camvid"].for_image_size((480, 360))
    train_labels = sorted((DATA / "trainannot").glob("*.png"))
    widths = {"camvid-train": _road_width_m(train_labels[:12] if quick else train_labels, "camvid", cv)}
    if CITYSCAPES.is_dir():
        cs_labels = sorted((CITYSCAPES / "labels").glob("*.png"))
        widths["cityscapes"] = _road_width_m(cs_labels[:12] if quick else cs_labels, CS_FORMAT,
                                             load_camera(CITYSCAPES / "camera.yaml"))
    return {k: {"median_m": round(m, 2), "frames": n} for k, (m, n) in widths.items()}


def headline(results: dict, failed: dict, road_width: dict, s_vp: float, s_rest: float) -> dict:
    """The figures the results page shows: errors over the synthetic cameras, the simulated and real sets."""
    syn = results["synthetic"]
    given = [r["fx_given"] for r in syn.values()]
    assumed = [r["fx_assumed"] for r in syn.values()]
    return {
        "tilt_abs_err_median": round(_stats(given, "tilt_err")[0], 3),
        "tilt_abs_err_max": round(_stats(given, "tilt_err")[1], 3),
        "horizon_err_pct_median": round(_stats(given, "horizon_err_pct")[0], 3),
        "horizon_err_pct_max": round(_stats(given, "horizon_err_pct")[1], 3),
        "tilt_abs_err_median_fx_assumed": round(_stats(assumed, "tilt_err")[0], 3),
        "tilt_abs_err_max_fx_assumed": round(_stats(assumed, "tilt_err")[1], 3),
        "horizon_err_pct_max_fx_assumed": round(_stats(assumed, "horizon_err_pct")[1], 3),
        "fx_err_pct_median_assumed": round(_stats(assumed, "fx_err_pct")[0], 1),
        "camvid_sim_tilt_abs_err_max": round(_stats([r["fx_given"] for r in results["camvid-sim"].values()],
                                                    "tilt_err")[1], 3),
        "camvid_sim_horizon_err_pct_max": round(_stats([r["fx_given"] for r in results["camvid-sim"].values()],
                                                       "horizon_err_pct")[1], 3),
        "real": {k: {"tilt_err": round(r["fx_given"]["tilt_err"], 3),
                     "horizon_err_pct": round(r["fx_given"]["horizon_err_pct"], 3)} for k, r in results["real"].items()},
        "kitti": "1 frame in ../shared/data: below the 5 frames an estimate needs",
        # nothing given, labels given: the road-footprint height; depth scale = fy * height (% error)
        "real_depth_scale_err_pct": {k: round(r["fx_assumed"]["depth_scale_err_pct"], 1)
                                     for k, r in results["real"].items()},
        "real_depth_scale_err_pct_height_assumed": {k: round(r["fx_assumed"]["depth_scale_err_pct_height_assumed"], 1)
                                                    for k, r in results["real"].items()},
        "road_width_constant_m": ROAD_WIDTH,
        "road_width_m": road_width,
        "no_estimate": failed,
        "s_per_100_frames_besides_vp": round(s_rest, 4),
        "s_per_100_frames_vp": round(s_vp, 3),
    }


def table(results: dict, road_width: dict) -> str:
    """Markdown: a row per set, and the visible road width."""
    lines = ["| set | camera | tilt err (deg) | horizon err (% h) | pan err (deg) | fx assumed: fx err (%) | "
             "fx assumed: tilt err | nothing given: height m (how) | depth scale err (%): labels / no labels | VPs |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for g, sets in results.items():
        for name, r in sets.items():
            e, s = r["fx_given"], r["fx_assumed"]
            lines.append(f"| {g} | {name} | {e['tilt_err']:+.2f} | {e['horizon_err_pct']:+.2f} | {e['pan_err']:+.2f} | "
                         f"{s['fx_err_pct']:+.1f} | {s['tilt_err']:+.2f} | {s['height']:.2f} ({s['height_source']}) | "
                         + (f"{s['depth_scale_err_pct']:+.1f} / " if s["height_source"] == "estimated" else "- / ")
                         + f"{s['depth_scale_err_pct_height_assumed']:+.1f} | {e['accepted']}/{e['frames']} |")
    lines.append("")
    lines.append("Visible road width under the true calibration (what ROAD_WIDTH = "
                 f"{ROAD_WIDTH:g} m stands for): " + ", ".join(f"{k} {v['median_m']:.2f} m ({v['frames']} frames)"
                                                             for k, v in road_width.items()) + ".")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--workdir", type=Path, default=ROOT / "benchmarks" / "out" / "camera_estimate")
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    cv2.setNumThreads(1)
    if not DATA.is_dir():
        raise SystemExit(f"needs {DATA} (../shared/data); not found")
    wd = a.workdir if not a.quick else Path(tempfile.mkdtemp(prefix="camest_"))
    groups = {"synthetic": _synthetic(wd, 6 if a.quick else a.frames), "camvid-sim": _camvid_sim(wd, a.quick),
              "real": _real(a.quick)}
    if a.quick:
        groups["synthetic"] = dict(list(groups["synthetic"].items())[::6])
    results, failed, s_vp, s_rest = estimate_sets(groups)
    road_width = visible_road_width(a.quick)
    print("visible road width under the true calibration: " + ", ".join(
        f"{k} {v['median_m']:.2f} m ({v['frames']} frames)" for k, v in road_width.items()), flush=True)
    head = headline(results, failed, road_width, s_vp, s_rest)
    text = table(results, road_width)
    print(text)
    res = results_dir(__file__) if not a.quick else wd
    res.mkdir(parents=True, exist_ok=True)
    (res / "camera_estimate.md").write_text(text)
    write_json(res / "camera_estimate.json",
               {"headline": head, "results": results, "frames_per_synthetic_camera": a.frames, "threads": 1,
                "machine": machine(), "date": today(), "command": f"benchmarks/camera_from_frames/camera_estimate.py --frames {a.frames}"})
    print(json.dumps(head))


if __name__ == "__main__":
    main()
