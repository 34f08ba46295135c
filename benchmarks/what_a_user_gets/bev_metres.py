"""The road in metres a planner gets from a model (issue 80 item 5): `free_m` and `width_m` (10 and
20 m ahead) from the model's masks against the same from the labels, the rules before issue 80
against today's, on the same BEV masks.

    .venv/bin/python benchmarks/what_a_user_gets/bev_metres.py [--model shipped] [--tag NAME] [--frames LO-HI]

``--frames 100-123``: only those kitti_semantics frames (road-street's held-out frames: it trained on the
others; issue 82 ran ``--model road-street --tag road-street --frames 100-123``).

Data: the 98 frames of `../shared/data/kitti_semantics` (camera.yaml, its labels: 0 not road, 1 road,
255 void) and the KITTI road frame of `../shared/data/kitti_road` (`um_000000`, its calibration file:
the devkit's transform; KITTI's `gt_image_2`, whose bottom 4 pixel rows are marked not road). The
model's masks: `vctrain predict MODEL FRAMES --camera CAM --threads 1` (cached in
`benchmarks/out/bev_metres/<model sha256[:12]>/`). Each frame's label and mask go onto the default
grid (x -10..10, z 6..46 m, 0.05 m cells) with one view, the pose `vcprep bev` and `vctrain predict
--bev` give it by default (kitti_semantics: each frame's road VP; `--pose nominal`: the camera's
nominal pose; the KITTI frame: its calibration); only the rules that read metres from them differ:

  before   the rules up to issue 80: free_m stops at the first corridor row holding a not-road or
           unseen cell; width_m counts every road cell of the row (null where any reaches the grid's
           side or an unseen cell)
  after    vcprep.bev.road_in_metres: blobs under 0.5 m passed over, the corridor starting past a
           label's border rows; width_m the road runs under the corridor, holes under 0.5 m filled

Reported: the median absolute error (metres) of the model's value against the label's, over the
frames where both rules give both numbers (n: the same frames before and after), and after "all"
over the frames where that rule gives both; and the number of frames where the label's free_m ends in the grid's
first 0.3 m. One thread. Target (issue 80): after below before (the newcomer measured 2.3 m at 10 m on
60 KITTI road frames before). Results: `results/bev_metres[_<tag>].{json,md}`. Last line: JSON.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.report import machine, results_dir, today, write_json
from vctrain.study.hashing import file_sha256
from vcprep.bev import BevGrid, BevSource, bev_maps, frame_views, road_in_metres, to_bev
from vcprep.bev.border import frame_hidden, label_border_rows
from vcprep.dataset import list_dataset
from vcprep.labels import decode_label, get_label_format

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT.parent / "shared" / "data"
OUT = ROOT / "benchmarks" / "out" / "bev_metres"
SETS = {  # name -> (images, labels, label format, camera)
    "kitti_semantics": (DATA / "kitti_semantics" / "images", DATA / "kitti_semantics" / "labels",
                        "values:road=1;ignore=255;max=255", DATA / "kitti_semantics" / "camera.yaml"),
    "kitti_road": (DATA / "kitti_road" / "training" / "image_2", DATA / "kitti_road" / "training" / "gt_image_2",
                   "kitti", DATA / "kitti_road" / "training" / "calib"),
}
GRID = BevGrid()
CORRIDOR = 1.8
DISTANCES = (10, 20)
UNSEEN = 255


# ---- the rules up to issue 80 (vcprep/bev/metres.py as it was), kept here to measure against ----
def old_free(bev: np.ndarray, grid: BevGrid, corridor: float, origin_z: float) -> float | None:
    x = grid.x_min + (np.arange(grid.shape[1]) + 0.5) * grid.res
    cols = np.flatnonzero(np.abs(x) <= corridor / 2 + 1e-9)
    c = bev[:, cols][::-1]
    blocked, unknown = (c == 0).any(axis=1), (c == UNSEEN).any(axis=1)
    start = np.flatnonzero(blocked | ~unknown)
    if start.size == 0:
        return None
    stops = np.flatnonzero((blocked | unknown)[start[0]:])
    if stops.size == 0:
        return round(float(grid.z_max - origin_z), 6)
    return round(float(grid.z_max - grid.shape[0] * grid.res + (start[0] + stops[0]) * grid.res - origin_z), 6)


def old_width(bev: np.ndarray, grid: BevGrid, distance: float, origin_z: float) -> float | None:
    row = grid.row_at(origin_z + distance)
    if row is None or not (bev[row] != UNSEEN).any():
        return None
    r = bev[row]
    road = np.flatnonzero(r == 1)
    if road.size == 0:
        return 0.0
    last = r.size - 1
    left, right = road - 1, road + 1
    clipped = (road == 0).any() or (road == last).any()
    clipped = clipped or (r[left[left >= 0]] == UNSEEN).any() or (r[right[right <= last]] == UNSEEN).any()
    return None if clipped else round(float(road.size * grid.res), 6)


def old_rules(bev: np.ndarray, origin_z: float) -> dict:
    return {"free_m": old_free(bev, GRID, CORRIDOR, origin_z),
            "width_m": {f"{d:g}": old_width(bev, GRID, d, origin_z) for d in DISTANCES}}


def new_rules(bev: np.ndarray, view, hidden=None, why=None) -> dict:
    r = road_in_metres(bev, GRID, view, CORRIDOR, DISTANCES, hidden=hidden, hidden_why=why)
    return {k: r[k] for k in ("free_m", "width_m", "free_to_edge", "start_why")}


# ---- the model's masks ----
def model_path(model: str) -> Path:
    from vctrain.cli.common import model_arg

    return Path(model_arg(Path(model)))


def predict(model: Path, name: str, images: Path, camera: Path) -> Path:
    """The model's masks of a set (``vctrain predict``, one thread), cached by the model's SHA-256."""
    out = OUT / file_sha256(model)[:12] / name
    n = len([p for p in images.iterdir() if p.suffix.lower() in (".png", ".jpg")])
    if out.is_dir() and len(list(out.glob("*_mask.png"))) == n:
        return out
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(ROOT)}
    cmd = [sys.executable, "-m", "vctrain.cli", "predict", str(model), str(images), "--camera", str(camera),
           "--out", str(out), "--threads", "1", "--quiet"]
    subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL)
    return out


# ---- per frame ----
def in_range(frame_id: str, frames: tuple[int, int] | None) -> bool:
    """Whether a kitti_semantics frame ('000105_10') is in ``frames`` (lo, hi inclusive; None: all)."""
    return frames is None or frames[0] <= int(frame_id.split("_")[0]) <= frames[1]


def measure_set(name: str, preds: Path, pose: str, frames: tuple[int, int] | None = None) -> list[dict]:
    images, labels, fmt_name, camera = SETS[name]
    fmt = get_label_format(fmt_name)
    jobs = [j for j in list_dataset(images, labels, fmt) if name != "kitti_semantics" or in_range(j.id, frames)]
    source = BevSource.from_spec(str(camera))
    within = "none" if source.calibrated or pose == "nominal" else "estimate"
    views = frame_views(jobs, source, within)
    rows = []
    for job in jobs:
        view = views[job.id]
        maps = bev_maps(view, GRID, job.image)
        label = decode_label(cv2.imread(str(job.label), cv2.IMREAD_UNCHANGED), fmt, job.label)
        mask = cv2.imread(str(preds / f"{job.id}_mask.png"), cv2.IMREAD_UNCHANGED)
        bev_label = to_bev(label, maps, "label")
        bev_mask = to_bev((mask != 0).astype(np.uint8), maps, "label")
        hidden, why = frame_hidden(maps, view.size, 0, label_border_rows(label))
        rows.append({"id": job.id,
                     "before": {"label": old_rules(bev_label, view.origin_z),
                                "model": old_rules(bev_mask, view.origin_z)},
                     "after": {"label": new_rules(bev_label, view, hidden, why), "model": new_rules(bev_mask, view)}})
    return rows


def _value(r: dict, rule: str, who: str, key: str, dist: str | None):
    v = r[rule][who][key]
    return v[dist] if dist is not None else v


def summary(rows: list[dict]) -> dict:
    """Per rule and measure: the median (and mean) |model - label| over the frames where both rules
    give all four numbers (``n``: the same frames before and after), and over the frames where this
    rule gives both (``n_all``)."""
    out = {"before": {}, "after": {}}
    for what, key, dist in (("free_m", "free_m", None), ("width_10", "width_m", "10"), ("width_20", "width_m", "20")):
        both = [r for r in rows if all(_value(r, ru, w, key, dist) is not None
                                       for ru in ("before", "after") for w in ("label", "model"))]
        for rule in ("before", "after"):
            e = [abs(_value(r, rule, "label", key, dist) - _value(r, rule, "model", key, dist)) for r in both]
            pairs = [(_value(r, rule, "label", key, dist), _value(r, rule, "model", key, dist)) for r in rows]
            e_all = [abs(a - b) for a, b in pairs if a is not None and b is not None]
            out[rule][what] = {"median_abs_err": round(float(np.median(e)), 3) if e else None,
                               "mean_abs_err": round(float(np.mean(e)), 3) if e else None, "n": len(e),
                               "median_abs_err_all": round(float(np.median(e_all)), 3) if e_all else None,
                               "n_all": len(e_all)}
    for rule in ("before", "after"):
        first = [r[rule]["label"]["free_m"] for r in rows]
        out[rule]["label_free_at_first_rows"] = sum(1 for f in first if f is not None and f < GRID.z_min + 0.3)
    out["frames"] = len(rows)
    return out


COLUMNS = [f"{who}_{rule}_{what}" for rule in ("before", "after") for who in ("label", "model")
           for what in ("free_m", "width_10", "width_20")]


def compact(rows: list[dict]) -> dict:
    """Each frame's numbers as one line 'id v v ...' (columns: :data:`COLUMNS`; '-': null)."""
    def line(r: dict) -> str:
        vals = [_value(r, rule, who, key, dist) for rule in ("before", "after") for who in ("label", "model")
                for key, dist in (("free_m", None), ("width_m", "10"), ("width_m", "20"))]
        return " ".join([r["id"]] + ["-" if v is None else f"{v:g}" for v in vals])

    return {"columns": ["id"] + COLUMNS, "frames": [line(r) for r in rows]}


def table(results: dict) -> list[str]:
    lines = ["| set | pose | frames | rule | free_m | width_m 10 m | width_m 20 m | label free_m in the first 0.3 m |",
             "|---|---|---|---|---|---|---|---|"]
    cell = lambda m: ("-" if m["median_abs_err"] is None else f"{m['median_abs_err']:.2f} (n {m['n']})") + \
        ("" if m["median_abs_err_all"] is None else f"; all {m['median_abs_err_all']:.2f} (n {m['n_all']})")
    for key, s in results.items():
        name, pose = key.split("/")
        for rule in ("before", "after"):
            r = s[rule]
            lines.append(f"| {name} | {pose} | {s['frames']} | {rule} | {cell(r['free_m'])} | {cell(r['width_10'])} | "
                         f"{cell(r['width_20'])} | {r['label_free_at_first_rows']} |")
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="shipped", help="a model file or a shipped model's name (default: shipped)")
    ap.add_argument("--tag", default="", help="results file suffix (results/bev_metres_<tag>.json)")
    ap.add_argument("--frames", default="", metavar="LO-HI",
                    help="kitti_semantics frames LO..HI only (by number; e.g. 100-123, road-street's held-out frames)")
    args = ap.parse_args()
    frames = tuple(int(v) for v in args.frames.split("-")) if args.frames else None
    cv2.setNumThreads(1)
    model = model_path(args.model)
    results, detail = {}, {}
    for name in SETS:
        images, _, _, camera = SETS[name]
        preds = predict(model, name, images, camera)
        for pose in (("calibration",) if name == "kitti_road" else ("vp", "nominal")):
            rows = measure_set(name, preds, pose, frames)
            results[f"{name}/{pose}"] = summary(rows)
            detail[f"{name}/{pose}"] = compact(rows)
    lines = table(results)
    print(f"model {model} (sha256 {file_sha256(model)[:12]}); grid x -10..10, z 6..46 m, 0.05 m; corridor {CORRIDOR} m; "
          "median |model - label| in metres over the frames where both rules give both numbers (n), and where this "
          "rule does (all)")
    print("\n".join(lines))
    stem = "bev_metres" + (f"_{args.tag}" if args.tag else "")
    command = "python " + " ".join(["benchmarks/what_a_user_gets/bev_metres.py"] + sys.argv[1:])
    headline = {f"{k} {m} {r}": v[r][m]["median_abs_err"] for k, v in results.items()
                for m in ("free_m", "width_10", "width_20") for r in ("before", "after")}
    doc = {"headline": headline,
           "command": command, "date": today(), "machine": machine(), "model": str(model),
           "model_sha256": file_sha256(model), "kitti_semantics_frames": list(frames) if frames else "all", "threads": 1, "results": results, "detail": detail}
    write_json(results_dir(__file__) / f"{stem}.json", doc)
    (results_dir(__file__) / f"{stem}.md").write_text(
        f"# The road in metres: the model's against the labels' ({today()})\n\n`{command}`; model `{model.parent.name}/{model.name}` "
        f"(sha256 {file_sha256(model)[:12]}). Median absolute error in metres (n: the frames where both rules give both "
        "numbers; all: where this rule does).\n\n"
        + "\n".join(lines) + "\n")
    print(json.dumps(doc["headline"]))


if __name__ == "__main__":
    main()
