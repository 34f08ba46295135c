"""The int8 graph's road IoU on a shipped model's held-out splits, against the float graph and the
model itself (issue 69; run by ``benchmarks/speed/predict_e2e.py --quality`` or alone).

    .venv/bin/python benchmarks/speed/int8_quality.py [--threads 2] [--model shipped] [--tag NAME]

``--model``: a shipped model's name or a .pt (default ``shipped``: ``vctrain.shipped.SHIPPED``); results
``int8_quality.json`` (``road-multicamera``'s run, issue 69) or ``int8_quality_<tag>.json`` (issue 82:
``--tag road-street``, ``--tag road-all``).

Splits (never trained on by any shipped model: models/road-multicamera/README.md,
models/road-street/README.md, models/road-all/README.md): CamVid val (101 frames, 480x360),
the KITTI road frame (1242x375), Cityscapes cs_25xx-cs_29xx (43 frames, 256x256), LUMS captures 1-79
(640x640), BDD100K sources 0a3*/0a4* (15 frames, 1280x720), IDD-Lite's held-out drives (drive % 7 ==
3: 170 frames, 320x227), ``kitti_semantics`` 000100-000123 (19 frames, 1242x375; road-street's and road-all's
held-out KITTI frames, new to road-multicamera; not in the issue-69 run). Per split: road.pt through PyTorch (the model card's route), its float graph and its int8
graph (``vctrain export --size WxH [--int8]``, int8 calibrated on the shipped examples, never on the
split) at the split's frame size, the graphs in their default runtime (OpenVINO where installed, else
onnxruntime: the JSON's ``graph_runtime``); road IoU = sum TP / sum (TP + FP + FN) over the split, ignore
excluded (``vctrain eval``), and the share of pixels whose mask the int8 graph shares with the float
graph. Target (issue 69): int8 within 0.5 IoU points of the float model on every split, masks
identical on >= 99 % of pixels. Results: benchmarks/speed/results/int8_quality.json.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import CS_FORMAT, DATA, KITTI, KITTI_SEM, KITTI_SEM_FORMAT, LUMS_FORMAT, SHARED_DATA  # noqa: E402
from benchmarks.measure.report import machine, results_dir, today, write_json  # noqa: E402

BDD_HELD = ("0a3", "0a4")  # road-multicamera's held-out BDD100K sources (models/road-multicamera/README.md)
KITTI_SEM_HELD = (100, 123)  # road-street's and road-all's held-out kitti_semantics frames (their cards)


def splits() -> list[tuple[str, list[Path], Path, str]]:
    """(name, image files, label folder, label format) of each held-out split here."""
    cs, lums = SHARED_DATA / "cityscapes_pix2pix", SHARED_DATA / "lums_road"
    out = [("camvid_val", sorted((DATA / "val").glob("*.png")), DATA / "valannot", "camvid"),
           ("kitti", sorted((KITTI / "image_2").glob("*.png")), KITTI / "gt_image_2", "kitti"),
           ("cityscapes", [p for p in sorted((cs / "images").glob("cs_*")) if 2500 <= int(p.stem[3:7]) <= 2999],
            cs / "labels", CS_FORMAT)]
    lums_held = [p for p in sorted((lums / "images").glob("*")) if _capture(p) is not None and 1 <= _capture(p) <= 79]
    out.append(("lums", lums_held, lums / "labels", LUMS_FORMAT))
    bdd = SHARED_DATA / "bdd100k_drivable"
    out.append(("bdd", sorted(p for p in (bdd / "images").glob("*.jpg") if p.name.startswith(BDD_HELD)),
                bdd / "labels", "bdd"))
    out.append(("idd", [im for im, _, _ in idd_held()], None, "idd"))
    lo, hi = KITTI_SEM_HELD
    out.append(("kitti_semantics", [p for p in sorted((KITTI_SEM / "images").glob("*.jpg"))
                                    if lo <= int(p.stem.split("_")[0]) <= hi], KITTI_SEM / "labels", KITTI_SEM_FORMAT))
    return [s for s in out if s[1]]


def idd_held() -> list[tuple[Path, Path, str]]:
    """IDD-Lite's held-out drives (drive % 7 == 3: 45 drives, 170 frames): (image, label, flat name
    '<drive>_<frame>'), the frames' names being unique only within a drive."""
    from benchmarks.what_a_user_gets.own_frames import _idd

    return _idd()[1]


def _idd_labels(wd: Path) -> Path:
    """A flat folder of links to the held-out IDD-Lite labels under the images' flat names."""
    folder = wd / "idd" / "labels"
    folder.mkdir(parents=True, exist_ok=True)
    for _, lab, name in idd_held():
        if not (folder / f"{name}_label.png").exists():
            (folder / f"{name}_label.png").symlink_to(lab)
    return folder


def _capture(p: Path) -> int | None:
    """LUMS's capture number (file names 'color_<n>_png.rf.<hash>')."""
    parts = p.stem.split("_")
    return int(parts[1]) if len(parts) > 1 and parts[1].isdigit() else None


def split_quality(model: Path, name: str, files: list[Path], labels: Path, fmt: str, wd: Path) -> dict:
    from collections import Counter

    from vcprep.io import image_size
    from vcprep.labels import get_label_format
    from vctrain.deploy import export_onnx
    from vctrain.evaluate import evaluate_folder
    from vctrain.predict import PredictOptions, predict_inputs

    size = Counter(image_size(f) for f in files).most_common(1)[0][0]
    files = [f for f in files if image_size(f) == size]  # a graph takes one size
    folder = wd / name / "images"
    folder.mkdir(parents=True, exist_ok=True)
    flat = {im: f"{n}_image.jpg" for im, _, n in idd_held()} if name == "idd" else {}
    for f in files:
        if not (folder / flat.get(f, f.name)).exists():
            (folder / flat.get(f, f.name)).symlink_to(f)
    files = [folder / flat.get(f, f.name) for f in files]
    labels = _idd_labels(wd) if labels is None else labels
    row = {"frames": len(files), "size": list(size)}
    graphs = {"float_graph": wd / name / "float.onnx", "int8_graph": wd / name / "int8.onnx"}
    export_onnx(model, None, graphs["float_graph"], size=size)
    row["int8_export"] = export_onnx(model, None, graphs["int8_graph"], size=size, int8=True)["int8"]
    for key, path, engine in (("torch", model, "torch"), ("float_graph", graphs["float_graph"], "auto"),
                              ("int8_graph", graphs["int8_graph"], "auto")):
        predict_inputs(PredictOptions(path, (folder,), wd / name / key, progress=False, engine=engine))
        row[f"iou_{key}"] = 100 * evaluate_folder(wd / name / key, labels, get_label_format(fmt), progress=False)[0]["iou"]
    same = total = 0
    from vcprep.io import read_image

    for f in files:
        a, b = (read_image(wd / name / k / f"{f.stem}_mask.png").array for k in ("float_graph", "int8_graph"))
        same, total = same + int((a == b).sum()), total + a.size
    row["int8_same_mask_pct"] = 100 * same / total
    row["int8_minus_float"] = row["iou_int8_graph"] - row["iou_torch"]
    print(f"{name}: {len(files)} frames {size[0]}x{size[1]}: IoU torch {row['iou_torch']:.2f}, float graph "
          f"{row['iou_float_graph']:.2f}, int8 {row['iou_int8_graph']:.2f}; int8 masks = float's on "
          f"{row['int8_same_mask_pct']:.2f} % of pixels", file=sys.stderr)
    return row


def _default_runtime() -> str:
    from vctrain.deploy.runtime import graph_runtime, runtime_name

    return runtime_name(graph_runtime(None))


def held_out_quality(model: Path, wd: Path) -> dict:
    rows = {name: split_quality(model, name, files, labels, fmt, wd) for name, files, labels, fmt in splits()}
    headline = {f"int8_minus_float_{k}": round(r["int8_minus_float"], 2) for k, r in rows.items()}
    headline.update({f"int8_same_mask_pct_{k}": round(r["int8_same_mask_pct"], 2) for k, r in rows.items()})
    targets = {"int8 within 0.5 IoU points of the float model on every split":
               all(abs(r["int8_minus_float"]) <= 0.5 for r in rows.values()),
               "int8 masks = float graph's on >= 99 % of pixels": all(r["int8_same_mask_pct"] >= 99 for r in rows.values())}
    return {"splits": rows, "headline": headline, "targets": targets}


def main() -> None:
    from vctrain.threads import use_threads

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--model", default="shipped", help="a shipped model's name or a .pt (default: shipped)")
    ap.add_argument("--tag", default="", help="results file suffix (results/int8_quality_<tag>.json)")
    args = ap.parse_args()
    from vctrain.shipped import resolve_model

    model = resolve_model(args.model)
    use_threads(args.threads)
    with tempfile.TemporaryDirectory(prefix="int8_quality-") as tmp:
        q = held_out_quality(model, Path(tmp))
    print("split | frames | size | IoU road.pt (PyTorch) | float graph | int8 graph | int8 - float | int8 mask = float (%)")
    for k, r in q["splits"].items():
        print(f"{k} | {r['frames']} | {r['size'][0]}x{r['size'][1]} | {r['iou_torch']:.2f} | {r['iou_float_graph']:.2f} | "
              f"{r['iou_int8_graph']:.2f} | {r['int8_minus_float']:+.2f} | {r['int8_same_mask_pct']:.2f}")
    write_json(results_dir(__file__) / f"int8_quality{'_' + args.tag if args.tag else ''}.json",
               {"command": "python " + " ".join(["benchmarks/speed/int8_quality.py"] + sys.argv[1:]), "date": today(),
                "machine": machine(), "threads": args.threads, "load_average": os.getloadavg()[0],
                "graph_runtime": _default_runtime(),
                "model": str(model.resolve().relative_to(Path(__file__).resolve().parents[2]))
                if model.resolve().is_relative_to(Path(__file__).resolve().parents[2]) else str(model), **q})
    print(json.dumps(q["headline"]))


if __name__ == "__main__":
    main()
