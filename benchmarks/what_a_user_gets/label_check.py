"""Labels read as the wrong class, refused before training (issue 80 item 6): does ``vctrain fit``'s label
check (:func:`vctrain.training.check_labels`) let every real label set through with its right format, and
stop CamVid's labels read with ``'values:road=1;ignore=255'`` (1 is CamVid's building)?

    .venv/bin/python benchmarks/what_a_user_gets/label_check.py [--workdir benchmarks/out/label_check]

Data: the seven label sets of ../shared/data, whole (CamVid train, Cityscapes pix2pix, IDD-Lite train,
KITTI road's frame, KITTI semantics, LUMS, BDD100K), each with the format its README gives, and CamVid
train with the wrong one. Each set twice, as ``vctrain fit`` reads it: its frames as they are (the route
``fit --baseline resize --images/--labels``: the horizon is the frame's middle row) and a store of the
README's route (``vcprep warp --camera <its camera> ... --out <store>``: the designed virtual camera, each
frame's own road VP, whose row is the horizon). The check runs as fit runs it (up to 48 labels spread
over a source, at the working size); the table gives the share of labelled pixels read as road and the
share of road above the horizon, and the verdict. No threshold is fitted here: the rule's 50 % is
vcprep.labels.UPPER_ROAD. Threads: 1. Time: about 3 min on 2 shared cores (most of it the stores' VPs).
Results: ``results/label_check.{md,json}``.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import BIN, ROOT, SHARED_DATA, run
from benchmarks.measure.report import machine, results_dir, today, write_json

# set -> (camera, images, labels, the right format), as each folder's README gives them
SETS = {
    "camvid": ("camvid", "camvid/train", "camvid/trainannot", "camvid"),
    "cityscapes_pix2pix": ("cityscapes_pix2pix/camera.yaml", "cityscapes_pix2pix/images", "cityscapes_pix2pix/labels",
                           "values:road=1;ignore=255;max=255"),
    "idd_lite": ("idd_lite/camera.yaml", "idd_lite/leftImg8bit/train", "idd_lite/gtFine/train", "idd"),
    "kitti_road": ("kitti_road/training/calib", "kitti_road/training/image_2", "kitti_road/training/gt_image_2",
                   "kitti"),
    "kitti_semantics": ("kitti_semantics/camera.yaml", "kitti_semantics/images", "kitti_semantics/labels",
                        "values:road=1;ignore=255;max=255"),
    "lums_road": ("lums_road/camera.yaml", "lums_road/images", "lums_road/labels", "values:road=2;max=4"),
    "bdd100k_drivable": ("bdd100k_drivable/camera.yaml", "bdd100k_drivable/images", "bdd100k_drivable/labels", "bdd"),
}
WRONG = ("camvid", "values:road=1;ignore=255")  # CamVid's building (1) read as road: the case


def _checked(cfg) -> dict:
    """fit's label check on ``cfg``'s training data: the shares it found and whether it refused."""
    from vcprep.errors import VCError
    from vctrain.training import check_labels, label_shares, prepare_data, resolve_recipe, training_sets

    resolve_recipe(cfg)
    train, val, info = prepare_data(cfg)
    train_ds, _ = training_sets(cfg, train, val, info)
    (_, _, _, share), = label_shares(train_ds)
    try:
        check_labels(cfg, train_ds)
        error = None
    except VCError as e:
        error = str(e)
    return {"frames": share.frames, "road_share": share.road / max(share.labelled, 1),
            "above_horizon": share.upper / max(share.road, 1), "refused": error is not None, "error": error}


def main() -> None:
    from vctrain.training import TrainConfig

    ap = argparse.ArgumentParser()
    ap.add_argument("--workdir", type=Path, default=ROOT / "benchmarks" / "out" / "label_check")
    args = ap.parse_args()
    if not SHARED_DATA.is_dir():
        sys.exit(f"{SHARED_DATA} not found: this benchmark needs the label sets of ../shared/data")
    cases = [(name, fmt) for name, (_, _, _, fmt) in SETS.items()] + [WRONG]
    rows = []
    for name, fmt in cases:
        camera, images, labels, right = SETS[name]
        cam = camera if "/" not in camera else SHARED_DATA / camera
        images, labels = SHARED_DATA / images, SHARED_DATA / labels
        store = args.workdir / f"{name}{'' if fmt == right else '_wrong'}"
        run(BIN / "vcprep", "warp", "--camera", cam, "--images", images, "--labels", labels, "--label-format", fmt,
            "--out", store, "--jobs", "1", "--quiet")
        raw = _checked(TrainConfig(baseline="resize", images=str(images), labels=str(labels), label_format=fmt,
                                   val_fraction=0.0, out=str(store / "x.pt"), seed=0))
        warped = _checked(TrainConfig(stores=[str(store)], val_fraction=0.0, out=str(store / "x.pt"), seed=0))
        for route, got in (("frames", raw), ("store", warped)):
            rows.append({"set": name, "format": fmt, "right": fmt == right, "route": route, **got})
            print(f"{name:<18} {fmt:<34} {route:<6} {got['frames']:>3} frames  road {got['road_share']:6.1%}  "
                  f"above the horizon {got['above_horizon']:6.1%}  {'REFUSED' if got['refused'] else 'trains'}",
                  flush=True)
    held = all(r["refused"] != r["right"] for r in rows)
    md = ["| set | format | route | frames checked | road of the labelled | road above the horizon | fit |",
          "|---|---|---|---|---|---|---|"]
    md += [f"| {r['set']} | `{r['format']}` | {r['route']} | {r['frames']} | {r['road_share']:.1%} | "
           f"{r['above_horizon']:.1%} | {'refused' if r['refused'] else 'trains'} |" for r in rows]
    out = results_dir(__file__)
    (out / "label_check.md").write_text("\n".join(md) + "\n")
    head = {"all_right_formats_train": all(not r["refused"] for r in rows if r["right"]),
            "wrong_format_refused": all(r["refused"] for r in rows if not r["right"]), "held": held,
            "worst_right_above_horizon": max(r["above_horizon"] for r in rows if r["right"]),
            "least_wrong_above_horizon": min(r["above_horizon"] for r in rows if not r["right"])}
    write_json(out / "label_check.json", {"date": today(), "machine": machine(), **head, "rows": rows})
    print(json.dumps(head))


if __name__ == "__main__":
    main()
