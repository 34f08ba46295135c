"""The route a user follows, as the README writes it (issues 52, 60): does ``vcprep warp`` + ``vctrain fit``,
with no flag set by hand, deliver what ``vctrain crossval`` measured for the same frames, and beat its
resize twin on cameras it never saw?

    .venv/bin/python benchmarks/what_a_user_gets/user_route.py [--seeds 0] [--epochs N] [--model NET] [--rules extend,rays]
                                                               [--workdir benchmarks/out/user_route] [--quick]

"My camera" is CamVid train minus sequence 0001TP (305 frames, links in WORKDIR/mine/; the frames
benchmarks/other_cameras/as_shipped.py trains its crossval models on). Exactly the README's commands, run as
subprocesses of the installed tools:

    vcprep warp --camera camvid --images mine/images --labels mine/labels --label-format camvid --out stores/mine
    vctrain fit stores/mine --out seed<k>/vc.pt --seed k                      # the virtual camera
    vctrain fit stores/mine --baseline resize --out seed<k>/resize.pt --seed k  # its resize twin
    vctrain predict MODEL --camera <the set's camera file> <images> --out seed<k>/<model>/<set>
    vctrain eval seed<k>/<model>/<set> --labels <labels> --label-format <format> --json

(``--seed`` only where k > 0; ``--epochs``, ``--model`` only when given; the virtual-camera model's
predictions in seed<k>/vc-<rule>/, the rule named: the default ``--beyond`` and each of ``--rules``, a row
each), on the real other cameras of ``../shared/data`` with the camera files they ship: Cityscapes (400),
IDD-Lite (1,403), the KITTI road frame, BDD100K (41), LUMS (144) (IDD-Lite's drive tree as links named
``<drive>_<file>``), and on the training camera's unseen frames: CamVid val (101) and train's sequence
0001TP (62, never trained on). Road IoU per set (sum over its frames), the mean over the five other
cameras, and virtual camera - resize per seed; beside it crossval's figures for the same frames, training
and seeds (benchmarks/other_cameras/results/as_shipped.json: ``within``, scored with the rule before issue
60, ``--beyond extend``; ``resize``). Targets (issue 60, checked, not asserted): route virtual camera >=
route resize + 5 on the mean; no camera below its resize twin - 2; the extend row within 1 point of
crossval's. Outputs: benchmarks/what_a_user_gets/results/user_route[_NET].{md,json} (``--quick``: a few
frames, 1 epoch, into WORKDIR/results). The last stdout line is the JSON summary.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import (BIN, CS_FORMAT, DATA, KITTI, LUMS_FORMAT, ROOT, SHARED_DATA, link_files, require_data, run)
from benchmarks.measure.report import machine, results_dir, today
from vctrain.predict import DEFAULT_BEYOND

SETS = {  # name: (camera file, images, labels, label format)
    "cityscapes": (SHARED_DATA / "cityscapes_pix2pix" / "camera.yaml", SHARED_DATA / "cityscapes_pix2pix" / "images",
                   SHARED_DATA / "cityscapes_pix2pix" / "labels", CS_FORMAT),
    "idd": (SHARED_DATA / "idd_lite" / "camera.yaml", SHARED_DATA / "idd_lite" / "leftImg8bit" / "train",
            SHARED_DATA / "idd_lite" / "gtFine" / "train", "idd"),
    "kitti": (KITTI / "calib", KITTI / "image_2", KITTI / "gt_image_2", "kitti"),
    "bdd": (SHARED_DATA / "bdd100k_drivable" / "camera.yaml", SHARED_DATA / "bdd100k_drivable" / "images",
            SHARED_DATA / "bdd100k_drivable" / "labels", "bdd"),
    "lums": (SHARED_DATA / "lums_road" / "camera.yaml", SHARED_DATA / "lums_road" / "images",
             SHARED_DATA / "lums_road" / "labels", LUMS_FORMAT),
}
OWN = {  # the training camera's unseen frames: CamVid val, and train's sequence 0001TP (never trained on)
    "camvid_val": ("camvid", DATA / "val", DATA / "valannot", "camvid"),
    "0001TP": ("camvid", None, None, "camvid"),
}
MODELS = ("vc", "resize")
EXTEND = "vc-extend"  # the virtual-camera model predicted with --beyond extend (the rule before issue 60)
AS_SHIPPED = ROOT / "benchmarks" / "other_cameras" / "results" / "as_shipped.json"  # crossval's figures
TARGET_GAIN, TARGET_CROSSVAL, TARGET_WORST = 5.0, 1.0, 2.0  # issue 60: vc >= resize + 5, no camera below resize - 2


def my_frames(wd: Path, quick: bool) -> tuple[Path, Path]:
    """WORKDIR/mine/{images,labels}: links to CamVid train minus 0001TP (a smoke run: 24 of them)."""
    names = [p.name for p in sorted((DATA / "train").iterdir()) if not p.name.startswith("0001TP_")]
    names = names[::12][:24] if quick else names
    return link_files(names, DATA / "train", wd / "mine" / "images"), link_files(names, DATA / "trainannot",
                                                                                 wd / "mine" / "labels")


def flat_drives(images: Path, dst: Path) -> Path:
    """dst: links to a drive tree's frames named ``<drive>_<file>`` (IDD's file names repeat from drive to
    drive, and ``vctrain predict`` names its outputs by file stem; ``vctrain eval`` matches
    ``<drive>_<id>`` to ``<drive>/<id>_label.png``), the frames of a drive one VP sequence by name."""
    dst.mkdir(parents=True, exist_ok=True)
    for f in sorted(images.rglob("*.jpg")):
        link = dst / f"{f.parent.name}_{f.name}"
        if not link.exists():
            link.symlink_to(f.resolve())
    return dst


def test_set(wd: Path, name: str, quick: bool) -> tuple[Path, Path, Path, str]:
    """(camera, images, labels, format) of a test set; a smoke run: links to a few of its frames."""
    if name in OWN:
        return own_set(wd, name, quick)
    cam, images, labels, fmt = SETS[name]
    if name == "idd":
        return cam, flat_drives(images / "0" if quick else images, wd / "flat" / "idd"), labels, fmt
    if not quick or name == "kitti":
        return cam, images, labels, fmt
    picked = sorted(images.iterdir())[:6]
    dst = wd / "quick" / name
    link_files([p.name for p in picked], images, dst / "images")
    label_names = [p.name for p in sorted(labels.iterdir())[:6]]
    link_files(label_names, labels, dst / "labels")
    return cam, dst / "images", dst / "labels", fmt


def own_set(wd: Path, name: str, quick: bool) -> tuple[str, Path, Path, str]:
    """(camera, images, labels, format) of a set of the training camera's unseen frames (links)."""
    cam, images, labels, fmt = OWN[name]
    if images is not None and not quick:
        return cam, images, labels, fmt
    src = DATA / "val" if images is not None else DATA / "train"
    names = sorted(p.name for p in src.iterdir() if images is not None or p.name.startswith("0001TP_"))
    names = names[:6] if quick else names
    dst = wd / "own" / name
    return (cam, link_files(names, src, dst / "images"),
            link_files(names, DATA / ("valannot" if images is not None else "trainannot"), dst / "labels"), fmt)


def road_iou(wd: Path, model: Path, name: str, out: Path, quick: bool, flags: list[str] = ()) -> float:
    """Predict ``name``'s frames with ``model`` as the README says, score them with ``vctrain eval``."""
    cam, images, labels, fmt = test_set(wd, name, quick)
    if not (out / "eval.json").exists():
        run(BIN / "vctrain", "predict", model, "--camera", cam, images, "--out", out, "-q", *flags)
        (out / "eval.json").write_text(run(BIN / "vctrain", "eval", out, "--labels", labels, "--label-format", fmt,
                                           "--json", "-q"))
    return 100.0 * float(json.loads((out / "eval.json").read_text())["iou"])


def crossval_figures(seeds: list[int]) -> dict[str, dict[str, list[float]]] | None:
    """crossval's road IoU of the same frames and training (as_shipped.json): {model: {set: per seed}}."""
    path = AS_SHIPPED
    if not path.exists():
        return None
    d = json.loads(path.read_text())
    if d.get("epochs") is not None:
        return None
    at = [d["seeds"].index(s) for s in seeds if s in d["seeds"]]
    if len(at) != len(seeds):
        return None
    cells = d["cells"]
    return {m: {n: [cells[f"{n}|{c}"][i] for i in at] for n in SETS} for m, c in (("vc", "within"), ("resize", "resize"))}


def crossval_seeds() -> list[int]:
    """The seeds benchmarks/other_cameras/results/as_shipped.json holds."""
    path = AS_SHIPPED
    return json.loads(path.read_text())["seeds"] if path.exists() else []


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--epochs", type=int, default=None, help="vctrain fit --epochs (default: the recipe's)")
    ap.add_argument("--workdir", type=Path, default=ROOT / "benchmarks" / "out" / "user_route")
    ap.add_argument("--model", default=None, help="vctrain fit --model for both fits (default: the recipe's)")
    ap.add_argument("--rules", default="",
                    help="also these vctrain predict --beyond rules for the virtual-camera model, a row each "
                         "(e.g. extend,rays: the rule before issue 60 and the rays alone)")
    ap.add_argument("--models", default=",".join(MODELS),
                    help="which of the route's two models to train and score (vc, resize); the report needs both "
                         "for its route rows' gain")
    ap.add_argument("--tag", default="", help="predictions in seed<k>/<model><TAG>/ (a rerun of predict alone, the models kept)")
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    require_data(DATA, *(s[1] for s in SETS.values()))
    seeds = [int(s) for s in a.seeds.split(",") if s.strip()]
    wd = a.workdir / "quick" if a.quick else a.workdir
    wd.mkdir(parents=True, exist_ok=True)
    epochs = 1 if a.quick else a.epochs
    images, labels = my_frames(wd, a.quick)
    t0 = time.perf_counter()
    store = wd / "stores" / "mine"
    warp = ["vcprep", "warp", "--camera", "camvid", "--images", images, "--labels", labels, "--label-format", "camvid",
            "--out", store]
    run(BIN / warp[0], *warp[1:], "-q")
    warp_s = time.perf_counter() - t0
    rules = [r for r in a.rules.split(",") if r.strip() and r != DEFAULT_BEYOND]
    trained = [m for m in MODELS if m in a.models.split(",")]
    models = (*trained, *(f"vc-{r}" for r in rules))
    iou: dict[str, dict[str, list[float]]] = {m: {n: [] for n in (*SETS, *OWN)} for m in models}
    fit_s: dict[str, list[float]] = {m: [] for m in MODELS}
    for seed in seeds:
        sd = wd / (f"seed{seed}" + ("" if epochs is None else f"-e{epochs}") + (f"-{a.model}" if a.model else ""))
        for m in trained:
            ckpt = sd / f"{m}.pt"
            if not ckpt.exists():
                t = time.perf_counter()
                run(BIN / "vctrain", "fit", store, *(["--baseline", "resize"] if m == "resize" else []), "--out", ckpt,
                    *(["--model", a.model] if a.model else []),
                    *(["--seed", seed] if seed else []), *(["--epochs", epochs] if epochs else []), "-q")
                fit_s[m].append(time.perf_counter() - t)
        for m in models:
            for n in (*SETS, *OWN):
                rule = DEFAULT_BEYOND if m == "vc" else m[3:] if m.startswith("vc-") else None
                out = sd / (f"vc-{rule}{a.tag}" if rule else f"{m}{a.tag}") / n  # each rule named: no default unsaid
                iou[m][n].append(road_iou(wd, sd / f"{m.split('-')[0]}.pt", n, out, a.quick,
                                          ["--beyond", rule] if rule else []))
                print(f"seed {seed} {m} {n}: {iou[m][n][-1]:.1f}", flush=True)
    report(a, wd, seeds, epochs, iou, fit_s, warp, warp_s)


def report(a: argparse.Namespace, wd: Path, seeds: list[int], epochs: int | None, iou: dict, fit_s: dict,
           warp: list, warp_s: float) -> None:
    """The summary against resize and crossval: user_route.{md,json}, the table and the JSON line on stdout."""
    models = tuple(iou)
    mean = {m: [float(np.mean([iou[m][n][i] for n in SETS])) for i in range(len(seeds))] for m in models}
    twin = "resize" in mean  # (--models vc: the virtual-camera model alone, no gain to report)
    gain = [v - r for v, r in zip(mean["vc"], mean["resize"])] if twin else []
    ref = None if (a.quick or epochs is not None or a.model) else crossval_figures(seeds)
    ref_mean = None if ref is None else {m: [float(np.mean([ref[m][n][i] for n in SETS])) for i in range(len(seeds))]
                                         for m in MODELS}
    every = None if ref is None else crossval_figures(crossval_seeds())  # (crossval's seed spread, for scale)
    every_mean = None if every is None else {m: [float(np.mean([every[m][n][i] for n in SETS]))
                                                 for i in range(len(every[m][next(iter(SETS))]))] for m in MODELS}
    head = {"route_vc_mean": round(float(np.mean(mean["vc"])), 2),
            "route_vc_mean_per_seed": [round(x, 2) for x in mean["vc"]],
            **{f"route_{m}_{n}": round(float(np.mean(iou[m][n])), 2) for m in models for n in (*SETS, *OWN)}}
    worst = min(float(np.mean(iou["vc"][n]) - np.mean(iou["resize"][n])) for n in SETS) if twin else None
    if twin:
        head.update(route_resize_mean=round(float(np.mean(mean["resize"])), 2),
                    route_vc_minus_resize=round(float(np.mean(gain)), 2), route_vc_minus_resize_worst_camera=round(worst, 2))
    if EXTEND in iou:
        head["route_vc_extend_mean"] = round(float(np.mean(mean[EXTEND])), 2)
    if ref_mean is not None:
        head.update({"crossval_vc_mean": round(float(np.mean(ref_mean["vc"])), 2),
                     "crossval_resize_mean": round(float(np.mean(ref_mean["resize"])), 2),
                     "route_vc_minus_crossval": round(float(np.mean(mean[EXTEND if EXTEND in mean else "vc"])
                                                         - np.mean(ref_mean["vc"])), 2)})
    if every_mean is not None:
        head.update({f"crossval_{m}_mean_every_seed": round(float(np.mean(every_mean[m])), 2) for m in MODELS})
        head.update({f"crossval_{m}_mean_every_seed_std": round(float(np.std(every_mean[m], ddof=1)), 2)
                     for m in MODELS if len(every_mean[m]) > 1})
        head["crossval_seeds"] = crossval_seeds()
    targets = {f"route vc >= route resize + {TARGET_GAIN:g}": bool(head["route_vc_minus_resize"] >= TARGET_GAIN),
               f"no camera: route vc below route resize - {TARGET_WORST:g}": bool(worst >= -TARGET_WORST)} if twin else {}
    if ref_mean is not None:
        targets[f"route vc ({'--beyond extend, ' if EXTEND in mean else ''}crossval's rule) within {TARGET_CROSSVAL:g} of crossval's"] = bool(abs(head["route_vc_minus_crossval"])
                                                                              <= TARGET_CROSSVAL)
    rows = ["| road IoU % (CamVid train minus 0001TP, " + f"seeds {a.seeds}) | " + " | ".join(SETS) + " | mean | "
            + " | ".join(OWN) + " |", "|---|" + "---|" * (len(SETS) + 1 + len(OWN))]
    label = {"vc": "README route: virtual camera", "resize": "README route: resize twin",
             EXTEND: "the same virtual-camera model, `--beyond extend` (the rule before issue 60)",
             "vc-rays": "the same virtual-camera model, `--beyond rays`",
             "vc-hybrid": "the same virtual-camera model, `--beyond hybrid`"}
    for m in models:
        rows.append(f"| {label[m]} | " + " | ".join(f"{np.mean(iou[m][n]):.1f}" for n in SETS)
                    + f" | {np.mean(mean[m]):.1f} | " + " | ".join(f"{np.mean(iou[m][n]):.1f}" for n in OWN) + " |")
    if ref is not None:
        for m, what in (("vc", "within"), ("resize", "resize")):
            rows.append(f"| `vctrain crossval` (as_shipped.json), {what}, the same seeds | "
                        + " | ".join(f"{np.mean(ref[m][n]):.1f}" for n in SETS) + f" | {np.mean(ref_mean[m]):.1f} |"
                        + " – |" * len(OWN))
    if every is not None:
        for m, what in (("vc", "within"), ("resize", "resize")):
            rows.append(f"| `vctrain crossval`, {what}, seeds {','.join(map(str, crossval_seeds()))} (mean ± std) | "
                        + " | ".join(f"{np.mean(every[m][n]):.1f} ± {np.std(every[m][n], ddof=1):.1f}" for n in SETS)
                        + f" | {np.mean(every_mean[m]):.1f} ± {np.std(every_mean[m], ddof=1):.1f} |" + " – |" * len(OWN))
    table = "\n".join(rows)
    cmd = "benchmarks/what_a_user_gets/user_route.py " + " ".join(
        x for x in (f"--seeds {a.seeds}", f"--epochs {a.epochs}" if a.epochs else "", f"--model {a.model}" if a.model else "",
                    f"--tag {a.tag}" if a.tag else "",
                    "--quick" if a.quick else "") if x)
    result = {"headline": head, "targets": targets, "iou": iou, "seeds": seeds, "epochs": epochs,
              "fit_seconds": {m: [round(s, 1) for s in v] for m, v in fit_s.items()}, "warp_seconds": round(warp_s, 1),
              "route": [" ".join(map(str, warp)).replace(str(wd) + "/", "")], "machine": machine(), "date": today(),
              "command": cmd}
    res_dir = wd / "results" if a.quick else results_dir(__file__)
    res_dir.mkdir(parents=True, exist_ok=True)
    stem = "user_route" + "".join(f"_{x}" for x in (a.model, a.tag.strip("-_")) if x)
    (res_dir / f"{stem}.json").write_text(json.dumps(result, indent=1) + "\n")
    (res_dir / f"{stem}.md").write_text(
        f"# The README route (benchmarks/what_a_user_gets/user_route.py)\n\n{today()}, {machine()}; `{cmd}`\n\n{table}\n\n"
        + "\n".join(f"- {k}: {'met' if v else 'missed'}" for k, v in targets.items()) + "\n")
    print(table)
    print(json.dumps(head))


if __name__ == "__main__":
    main()
