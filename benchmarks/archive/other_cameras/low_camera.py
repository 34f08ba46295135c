"""A camera lower than the training one (issue 60, item 3): where a virtual-camera model loses the
road near it, and the rule beyond the training rectangle that keeps it.

    .venv/bin/python benchmarks/archive/other_cameras/low_camera.py [--seeds 0,1,2] [--workdir benchmarks/out/user_route] [--quick]

The models are the README route's (benchmarks/what_a_user_gets/user_route.py, run it first with
the same --seeds and --workdir): ``vctrain fit stores/mine`` on CamVid train minus 0001TP (the
camvid camera, 1.21 m, level) and its resize twin, seed k, WORKDIR/seed<k>/{vc,resize}.pt.

A lower camera's near road lands in the virtual camera below the training rectangle: the ground
homography stretches the image vertically by (virtual height / camera height) about the horizon.
``vctrain predict`` grows the rectangle down to hold it and runs the network on rows no
training image ever filled. Rules, each a ``vctrain predict --beyond`` value, run on the same
models and frames:

* ``extend`` (the default): the network on the rectangle grown for the frames;
* ``rays``: the network on the training rectangle only; a source pixel that lands outside it takes
  P(road) where the ray from the road VP through it leaves the rectangle (the projective
  completion's rule run backwards: road edges are lines through the VP);
* ``hybrid``: the network on the grown rectangle (its context kept), the pixels beyond the
  training rectangle by rays from its edge;

Sets (labels are never used to choose anything):

* ``lums``: LUMS (144 frames, a low campus vehicle, about 0.8 m and 8 degrees down; its camera file);
* ``sim-<h>``: a simulated lower camera with the truth known exactly. CamVid val (101 frames of
  the training camera, unseen drives) with a camera file that says the camvid camera at height h
  (1.21 = the real file: the control). A pinhole image is unchanged when the world and the camera
  height scale together, so these frames ARE what a camera at h sees of a world scaled by
  h / 1.21, labels included; the homography into the virtual camera (1.21 m) stretches them
  vertically by 1.21 / h, exactly as it stretches a real camera that much lower. The resize twin
  sees the same pixels at every h (one figure, the baseline).

Per set and rule: road IoU (sum over frames) per seed and the mean; for LUMS also the IoU in the
four bands of the lower half of the frame. Outputs benchmarks/other_cameras/results/low_camera.{md,json}
(``--quick``: 6 frames a set, seed 0, into WORKDIR/low_camera/results). The last stdout line is the
JSON summary.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import BIN, DATA, LUMS, LUMS_FORMAT, ROOT, link_files, require_data, run
from benchmarks.measure.report import machine, results_dir, today
from vcprep.camera import load_camera
from vcprep.labels import decode_label, get_label_format

HEIGHTS = (1.21, 0.9, 0.7, 0.55)  # sim-<h>: the camvid camera declared at h metres (1.21: its own file)
RULES = ("extend", "rays", "hybrid")
BANDS = 4  # bands of the lower half of the frame


def sets(wd: Path, quick: bool) -> dict[str, tuple[Path, Path, Path, str]]:
    """name -> (camera file, images, labels, label format); the simulated cameras' files in WORKDIR."""
    lums_img, lums_lab = LUMS / "images", LUMS / "labels"
    val_img, val_lab = DATA / "val", DATA / "valannot"
    if quick:
        names = sorted(p.name for p in lums_img.iterdir())[:6]
        lums_img = link_files(names, lums_img, wd / "quick" / "lums" / "images")
        lums_lab = link_files([Path(n).stem + ".png" for n in names], LUMS / "labels", wd / "quick" / "lums" / "labels")
        names = sorted(p.name for p in val_img.iterdir())[:6]
        val_img = link_files(names, val_img, wd / "quick" / "val" / "images")
        val_lab = link_files(names, val_lab, wd / "quick" / "val" / "labels")
    out = {"lums": (LUMS / "camera.yaml", lums_img, lums_lab, LUMS_FORMAT)}
    base = load_camera("camvid").to_dict()
    for h in HEIGHTS:
        cam = wd / "cameras" / f"camvid_at_{h:g}m.yaml"
        cam.parent.mkdir(parents=True, exist_ok=True)
        cam.write_text(yaml.safe_dump({**base, "name": f"camvid_at_{h:g}m", "height": h}, sort_keys=False))
        out[f"sim-{h:g}"] = (cam, val_img, val_lab, "camvid")
    return out


def band_counts(pred: Path, labels: Path, fmt: str) -> np.ndarray:
    """(BANDS, 2): intersection and union of road in each band of the lower half, summed over frames."""
    f = get_label_format(fmt)
    acc = np.zeros((BANDS, 2))
    for m in sorted(pred.glob("*_mask.png")):
        lab = decode_label(cv2.imread(str(labels / (m.name[:-9] + ".png")), cv2.IMREAD_UNCHANGED), f)
        p, t, ok = cv2.imread(str(m), cv2.IMREAD_GRAYSCALE) > 127, lab == 1, lab != 255
        h = t.shape[0]
        for b in range(BANDS):
            rows = slice(h // 2 + b * h // (2 * BANDS), h // 2 + (b + 1) * h // (2 * BANDS))
            acc[b] += ((p & t & ok)[rows].sum(), ((p | t) & ok)[rows].sum())
    return acc


def score(model: Path, rule: str | None, spec: tuple[Path, Path, Path, str], out: Path) -> dict:
    """Predict the set with ``model`` under ``rule`` (None: a resize model) and score it; cached in out."""
    cam, images, labels, fmt = spec
    done = out / "score.json"
    if not done.exists():
        run(BIN / "vctrain", "predict", model, "--camera", cam, images, "--out", out, "-q",
            *(["--beyond", rule] if rule else []))
        ev = json.loads(run(BIN / "vctrain", "eval", out, "--labels", labels, "--label-format", fmt, "--json", "-q"))
        done.write_text(json.dumps({"iou": 100 * float(ev["iou"]), "bands": band_counts(out, labels, fmt).tolist()}))
    return json.loads(done.read_text())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--workdir", type=Path, default=ROOT / "benchmarks" / "out" / "user_route")
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    require_data(DATA, LUMS)
    seeds = [0] if a.quick else [int(s) for s in a.seeds.split(",") if s.strip()]
    wd = a.workdir / "low_camera" / ("quick" if a.quick else "")
    tests = sets(wd, a.quick)
    cells: dict[str, dict[str, list]] = {}
    for seed in seeds:
        sd = a.workdir / ("quick" if a.quick else "") / (f"seed{seed}-e1" if a.quick else f"seed{seed}")
        for m in ("vc.pt", "resize.pt"):
            if not (sd / m).exists():
                sys.exit(f"{sd / m}: missing: run benchmarks/what_a_user_gets/user_route.py --seeds {a.seeds} first")
        for name, spec in tests.items():
            for rule in (*RULES, "resize"):
                if rule == "resize" and name.startswith("sim-") and name != f"sim-{HEIGHTS[0]:g}":
                    cells.setdefault(f"{name}|{rule}", []).append(cells[f"sim-{HEIGHTS[0]:g}|resize"][-1])
                    continue  # the same pixels at every declared height
                model = sd / ("resize.pt" if rule == "resize" else "vc.pt")
                r = score(model, None if rule == "resize" else rule, spec, wd / f"seed{seed}" / rule / name)
                cells.setdefault(f"{name}|{rule}", []).append(r)
                print(f"seed {seed} {name} {rule}: {r['iou']:.1f}", flush=True)
    report(a, wd, seeds, list(tests), cells)


def report(a: argparse.Namespace, wd: Path, seeds: list[int], names: list[str], cells: dict) -> None:
    """The table (rule x set, mean over seeds and per seed), LUMS's bands, the JSON."""
    rules = (*RULES, "resize")
    iou = {k: [r["iou"] for r in v] for k, v in cells.items()}
    rows = [f"| road IoU %, seeds {','.join(map(str, seeds))} | " + " | ".join(names) + " |",
            "|---|" + "---|" * len(names)]
    for rule in rules:
        rows.append(f"| {rule} | " + " | ".join(
            f"{np.mean(iou[f'{n}|{rule}']):.1f} ({' / '.join(f'{x:.1f}' for x in iou[f'{n}|{rule}'])})"
            for n in names) + " |")
    band_rows = ["| LUMS, road IoU % in the lower half's bands (top to bottom) | " +
                 " | ".join(f"rows {4 + b}/8" for b in range(BANDS)) + " |", "|---|" + "---|" * BANDS]
    for rule in rules:
        acc = np.sum([np.asarray(r["bands"]) for r in cells[f"lums|{rule}"]], axis=0)
        band_rows.append(f"| {rule} | " + " | ".join(f"{100 * i / max(u, 1):.1f}" for i, u in acc) + " |")
    head = {f"{n}_{rule}": round(float(np.mean(iou[f"{n}|{rule}"])), 2) for n in names for rule in rules}
    for rule in RULES:
        head[f"lums_{rule}_minus_resize"] = round(float(np.mean(iou[f"lums|{rule}"]) - np.mean(iou["lums|resize"])), 2)
    cmd = "benchmarks/archive/other_cameras/low_camera.py " + ("--quick" if a.quick else f"--seeds {a.seeds}")
    res = {"headline": head, "iou": iou, "bands": {k: [r["bands"] for r in v] for k, v in cells.items() if k.startswith("lums|")},
           "seeds": seeds, "heights": list(HEIGHTS), "rules": list(RULES), "machine": machine(), "date": today(),
           "command": cmd}
    res_dir = wd / "results" if a.quick else results_dir(__file__)
    res_dir.mkdir(parents=True, exist_ok=True)
    (res_dir / "low_camera.json").write_text(json.dumps(res, indent=1) + "\n")
    table = "\n".join(rows) + "\n\n" + "\n".join(band_rows)
    (res_dir / "low_camera.md").write_text(f"# A camera lower than the training one (benchmarks/archive/other_cameras/low_camera.py)"
                                           f"\n\n{today()}, {machine()}; `{cmd}`\n\n{table}\n")
    print(table)
    print(json.dumps(head))


if __name__ == "__main__":
    main()
