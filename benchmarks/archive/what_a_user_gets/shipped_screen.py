"""Screening the shipped model's appearance levers (issue 59, item 2): today's recipe and each candidate
trained by benchmarks/what_a_user_gets/shipped_model.py with the same seed, epochs and frames, back to back
on this machine (the baseline in the same run), scored on the six held-out splits, in shipped_model.py's
work folders (a budget's runs are its own there).

    .venv/bin/python benchmarks/archive/what_a_user_gets/shipped_screen.py [--epochs 15] [--seed 0]
                                                                   [--candidates lite1fpn,lite2fpn,lite0fpn@px307200] [--quick]

**Variants** ``NET[@pxN]``: the network (``--model NET``: lite0fpn today, lite1fpn, lite2fpn) and the
working resolution's pixel budget (``--store-pixels N``; default 172,800, 480x360's; 307,200 is
640x480's). The baseline ``--baseline`` (default ``lite0fpn``, today's shipped recipe: the resize twin)
runs first. Each variant is one ``shipped_model.py --conditions resize --model NET [--store-pixels N]
--epochs E --seed S`` run (resumed where it stopped), its figures read from the headline it prints last.

Reported per variant: road IoU, precision and recall (%) per held-out split, the mean IoU over the six,
the predict time of a 1280x720 frame at 1 thread (shipped_model.py's, one process a model: noisier than
benchmarks/speed/networks.py's interleaved figures) and the training minutes. **Targets** (issue 59,
checked, not asserted; a screen points, the full budget decides): the mean above the baseline's; no
split below the baseline's; KITTI's precision above the baseline's; predict at most 1.5x the baseline's.
Outputs benchmarks/what_a_user_gets/results/shipped_screen_e<E>[_s<S>].{md,json} (``_s<S>`` for a seed
other than 0; ``--quick``: the work folder's); the table is the results page's
:func:`~benchmarks.measure.page.multi_camera.r_shipped_screen`;
the last stdout line is one JSON object. Time: about 17 minutes a lite0fpn model at 15 epochs on 2
cores, more for the larger networks and resolutions.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import ROOT, run
from benchmarks.measure.page.multi_camera import r_shipped_screen
from benchmarks.measure.report import machine, results_dir, today, write_json
from benchmarks.what_a_user_gets.shipped_model import SETS

SCRIPT = Path(__file__).resolve().parents[2] / "what_a_user_gets" / "shipped_model.py"
WORKDIR = ROOT / "benchmarks" / "out" / "shipped_model"


def parse(variant: str) -> tuple[str, int | None]:
    """``NET[@pxN]`` -> (network, pixel budget or None)."""
    net, _, px = variant.partition("@")
    if px and not (px.startswith("px") and px[2:].isdigit()):
        raise SystemExit(f"--candidates: '{variant}': write NET or NET@pxN (e.g. lite0fpn@px307200)")
    return net, int(px[2:]) if px else None


def measure(variant: str, a: argparse.Namespace) -> dict:
    """One variant's shipped_model.py run (resumed) and its figures."""
    net, px = parse(variant)
    args = ["--conditions", "resize", "--model", net, "--epochs", a.epochs, "--seed", a.seed, "--threads", a.threads]
    args += ["--store-pixels", px] if px else []
    args += ["--quick"] if a.quick else []
    h = json.loads(run(sys.executable, SCRIPT, *args, stream=True).strip().splitlines()[-1])  # its headline
    row = {"iou": {t: h[f"resize_{t}"] for t in SETS}, "precision": {t: h.get(f"precision_resize_{t}") for t in SETS},
           "recall": {t: h.get(f"recall_resize_{t}") for t in SETS}, "mean": h.get("mean_resize"),
           "predict_ms_t1": h.get("predict_ms_1280x720_resize_t1"), "minutes": h["minutes_per_model"].get("resize")}
    print(f"{variant}: {json.dumps(row)}", flush=True)
    return row


def targets(base: dict, row: dict) -> dict[str, bool]:
    return {"mean above the baseline's": row["mean"] > base["mean"],
            "no split below the baseline's": all(row["iou"][t] >= base["iou"][t] for t in SETS),
            "KITTI precision above the baseline's": (row["precision"]["kitti"] or 0) > (base["precision"]["kitti"] or 0),
            "predict <= 1.5x the baseline's": row["predict_ms_t1"] <= 1.5 * base["predict_ms_t1"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--candidates", default="lite1fpn,lite2fpn,lite0fpn@px307200", help="NET[@pxN], comma list")
    ap.add_argument("--baseline", default="lite0fpn", help="today's recipe, run first")
    ap.add_argument("--epochs", type=int, default=15)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="smoke run: shipped_model.py --quick for every variant")
    a = ap.parse_args()
    variants = [a.baseline] + [v for v in a.candidates.split(",") if v and v != a.baseline]
    for v in variants:
        parse(v)  # every name checked before the first hour of training
    rows = {v: measure(v, a) for v in variants}
    out = WORKDIR / "quick" / "results" if a.quick else results_dir(__file__)
    out.mkdir(parents=True, exist_ok=True)
    head = {f"{k}_{v}": r[k] for v, r in rows.items() for k in ("mean", "predict_ms_t1", "minutes")}
    head.update({f"{v}_minus_baseline": round(r["mean"] - rows[a.baseline]["mean"], 2) for v, r in rows.items()})
    result = {"headline": head, "rows": rows, "targets": {v: targets(rows[a.baseline], r) for v, r in rows.items()
                                                         if v != a.baseline},
              "baseline": a.baseline, "epochs": a.epochs, "seed": a.seed, "sets": SETS, "machine": machine(),
              "date": today(), "command": f"benchmarks/archive/what_a_user_gets/shipped_screen.py --candidates "
                                          f"{a.candidates} --baseline {a.baseline} --epochs {a.epochs} --seed {a.seed}"}
    text = "\n".join(r_shipped_screen(result))
    print(text)
    stem = f"shipped_screen_e{a.epochs}" + (f"_s{a.seed}" if a.seed else "")  # each budget and seed its own file
    (out / f"{stem}.md").write_text(text)
    write_json(out / f"{stem}.json", result)
    print(json.dumps(head))


if __name__ == "__main__":
    main()
