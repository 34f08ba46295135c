"""One model for every camera: leave one real camera out over all five real development sets (issue 34).

    .venv/bin/python benchmarks/other_cameras/multi_camera.py [--seeds 0,1] [--conditions within,resize] [--epochs N]
                                                              [--workdir benchmarks/out/multi_camera] [--threads 2]
                                                              [--quick] [--collect] [--extent max|median]
                                                              [--held-out idd,bdd] [--train-on camvid,cityscapes]
                                                              [--train-extra KEY=VALUE,...] [--camera-estimate bdd,lums]
                                                              [--model lite0fpn]

**Data** (../shared/data, each with the camera it ships with), every one ``role: both``:
``camvid`` (CamVid train + val, 468 frames of the SegNet release, the camvid preset scaled to 480x360;
sequence 0001TP shows its own vehicle: crossval's default ``ego: auto`` finds it from the labels),
``cityscapes`` (400 frames of cityscapes_pix2pix, its camera.yaml), ``idd`` (1,403 IDD-Lite frames, label
format idd, its ASSUMED camera.yaml), ``bdd`` (41 BDD100K frames, label format bdd, its ASSUMED camera.yaml)
and ``lums`` (144 frames of a low (0.8 m) campus vehicle, ``values:road=2;max=4``, its camera.yaml); the
KITTI road frame (its own calibration) is ``role: test`` only.

**Split**: one ``vctrain crossval`` study per seed (WORKDIR/seed<k>/, ``--seed k``; an interrupted study
resumes where it stopped, and the stores are built once and shared by the seeds). Each fold trains on
four of the five datasets merged into one virtual camera (crossval's default rectangle rule) and is
tested on ALL frames of the fifth, scored in that camera (back-projected; road IoU = sum TP / sum
(TP+FP+FN) over the set, ignore excluded); one more model per condition trained on all five is tested on
KITTI. Training: crossval's defaults plus ``balance: datasets`` (each training store drawn equally often
an epoch: 41 BDD frames weigh as much as 1,403 IDD frames) and the step budget of the single-camera
CamVid model of benchmarks/other_cameras/as_shipped.py (``max_steps`` per epoch = its steps per epoch, 305 frames less
the 10 % validation share at batch 8), so every fold costs one model's time whatever its union's size.
``shading_aug: 0.4`` (``--shading-aug``; vctrain.training.data: half the items get a smooth per-channel colour
gain field, the lens shading of cheap cameras: LUMS's bottom corners are tinted green and magenta, which
a model trained without it reads as "not road"; both conditions). The checkpoint of each model is
chosen on its training frames' validation share, never on a test set.

**Baseline**: condition ``resize``, the same network on the same training frames simply resized (the
resize twin draws exactly the same items, steps and sampling: same stores, seed and balance). Reported:
road IoU per held-out camera and condition, within - resize paired per seed, per camera and the mean
over the five held-out cameras (per seed, then mean +/- sample std over seeds).

**Targets** (issue 34, checked, not asserted): LOO mean within >= resize + 5; no held-out camera below
resize - 1.

**Threads**: ``--threads`` (default 2) is crossval's ``--jobs`` and OMP_NUM_THREADS; the minutes per model
are wall-clock training minutes on this machine at that thread count.

**Rectangle rule** (``--extent``): ``max`` (default) designs the virtual camera's rectangle to hold every
camera; ``median`` sizes it by the median camera (IDD-Lite's assumed 90 deg and LUMS's low, tilted view no
longer shrink every other camera's images; each test split extended to hold its own camera): the
virtual-camera conditions run in WORKDIR/median, ``resize`` (which no rectangle touches) is read from
WORKDIR's studies of the same seeds, results in multi_camera_median.{md,json}.

**Issue 44 options**: ``--held-out`` runs some folds only (crossval ``--heldout``; no all-five model, results
in WORKDIR[/median]/results). Condition ``average`` (crossval's: the within and resize models' probabilities
averaged in the held-out camera's pixels, no training of its own) makes the median study train its own
``resize`` (same frames, steps and sampling; it reads the frames as they are). ``--train-on camvid,cityscapes``
trains the virtual-camera conditions on those datasets only (the calibrated cameras: IDD-Lite's, BDD100K's
and LUMS's files are assumed), one model per seed tested on every held-out set (WORKDIR[/median]/train-<names>),
against the resize model of each fold (trained on the other four, in WORKDIR[/median]); ``average`` there is
that within model averaged with the fold's resize model (:func:`mixed_average`). ``--train-extra KEY=VALUE``
trains the virtual-camera conditions with extra settings (WORKDIR[/median]/extra-<settings>, sharing the stores).
``--camera-estimate bdd,lums`` gives those datasets ``camera: estimate`` (estimated from their own frames and
labels instead of their assumed files; WORKDIR[/median]/estimate-<names>, its own stores): for folds that hold
out another set only, since a held-out set's estimate would read its test labels. Condition ``resize-vp``
(resize plus each frame's road VP as a 4th channel) trains its paired ``resize`` in the same study.

**Network** (``--model``, issue 53): every condition of the study, resize included, trains that
architecture (study ``train: arch``; ``lite0fpn`` starts from its ImageNet weights), in
WORKDIR/model-<name>[/median] with its own stores, results in that folder's results/.

Outputs: benchmarks/other_cameras/results/multi_camera.{md,json} (``--quick``: a smoke run, a few frames, 2 steps, into
WORKDIR/results). ``--collect`` runs nothing: it reports the folds finished so far (a cut-off run's) and
names the missing ones. The last stdout line is one JSON object: ``loo_within_minus_resize`` (and
``_std``), ``loo_within_minus_resize_<dataset>``, ``loo_within_<dataset>``, ``loo_resize_<dataset>``,
``test_within_kitti``/``test_resize_kitti`` (the all-five model), ``loo_<condition>_minus_resize_<dataset>``
(every other condition), ``minutes_per_model``, ``seeds`` and ``folds_missing``.
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import (BDD, CITYSCAPES, CS_FORMAT, DATA, IDD, KITTI, KITTI_SEM, KITTI_SEM_FORMAT, LUMS,
                                     LUMS_FORMAT, ROOT, native_camera, require_data)
from benchmarks.measure.studies import camvid_steps_per_epoch, link_stores, run_study
from benchmarks.measure.report import machine, results_dir, today, write_json
from benchmarks.measure.stats import seed_stats
from vctrain.training import RECIPES

LOO = ["lums", "bdd", "camvid", "cityscapes", "idd"]  # held out in turn (LUMS first: the camera in question)
TEST_ONLY = ["kitti"]                                  # tested by the model trained on all five
TARGET_GAIN, TARGET_WORST = 5.0, -1.0
QUICK_FRAMES = 6
SHADING_AUG = RECIPES["multicamera"]["shading_aug"]  # the multi-camera recipe's colour shading (vctrain.training.data), both conditions


def _link_all(dst: Path, parts: list[tuple[Path, Path]], n: int | None = None) -> dict[str, str]:
    """dst/{images,labels} afresh: links to the frames (and labels) of every (image folder, label
    folder) in ``parts`` (the first ``n`` of each in a smoke run); a study split."""
    if dst.exists():
        shutil.rmtree(dst)
    for sub in ("images", "labels"):
        (dst / sub).mkdir(parents=True)
    for images, labels in parts:  # (each folder's first n in name order: a label named otherwise sorts alike)
        for sub, src in (("images", images), ("labels", labels)):
            for p in sorted(src.iterdir())[:n]:
                (dst / sub / p.name).symlink_to(p)
    return {"images": str(dst / "images"), "labels": str(dst / "labels")}


def study_file(wd: Path, quick: bool, epochs: int | None, shading_aug: float = SHADING_AUG,
               extent: str = "max", train_on: list[str] | None = None, extra: dict | None = None,
               home: Path | None = None, estimate: list[str] | None = None, model: str | None = None,
               names: list[str] | None = None) -> Path:
    """The study: the five real datasets held out in turn, KITTI a test set; ``extent`` the designed
    rectangle's rule (study key ``extent``). ``train_on``: only these datasets trained on (role
    train), every other one a test set (one model, runs/_all/). ``extra``: training settings added.
    ``home``: the study whose CamVid frames and camera file this one names (default ``wd``: its
    own), so that a study sharing its stores names the very same source files. ``estimate``: these
    datasets get ``camera: estimate`` (their camera estimated from their own frames and labels).
    ``model``: every condition's architecture (study ``train: arch``; default the recipe's). ``names``:
    the datasets written, in that order (default: the five of LOO and the KITTI road frame as a test
    set); ``kitti_semantics`` (98 calibrated KITTI frames, role both) is one of them only when named."""
    n = QUICK_FRAMES if quick else None
    home = home or wd
    camvid = ({"images": str(home / "frames" / "camvid" / "images"), "labels": str(home / "frames" / "camvid" / "labels")}
              if home != wd and (home / "frames" / "camvid" / "images").is_dir() else
              _link_all(home / "frames" / "camvid", [(DATA / "train", DATA / "trainannot"),
                                                     (DATA / "val", DATA / "valannot")], n))
    split = lambda src: ({"images": str(src / "images"), "labels": str(src / "labels")} if not quick else
                         _link_all(wd / "frames" / src.name, [(src / "images", src / "labels")], n))
    idd = {"images": str(IDD / "leftImg8bit" / "train"), "labels": str(IDD / "gtFine" / "train"),
           **({"include": "1[0-9]_*"} if quick else {})}
    both = lambda name, camera, fmt, s: {"name": name, "role": "both", "camera": str(camera), "label_format": fmt,
                                         "train": s, "test": s}
    datasets = {"camvid": both("camvid", native_camera(home), "camvid", camvid),
                "cityscapes": both("cityscapes", CITYSCAPES / "camera.yaml", CS_FORMAT, split(CITYSCAPES)),
                "idd": both("idd", IDD / "camera.yaml", "idd", idd),
                "bdd": both("bdd", BDD / "camera.yaml", "bdd", split(BDD)),
                "lums": both("lums", LUMS / "camera.yaml", LUMS_FORMAT, split(LUMS))}
    if "kitti_semantics" in (names or ()):
        datasets["kitti_semantics"] = both("kitti_semantics", KITTI_SEM / "camera.yaml", KITTI_SEM_FORMAT, split(KITTI_SEM))
    kitti = {"name": "kitti", "role": "test", "camera": str(KITTI / "calib"), "label_format": "kitti",
             "test": {"images": str(KITTI / "image_2"), "labels": str(KITTI / "gt_image_2")}}
    train = ({"epochs": 1, "max_steps": 2} if quick else
             {"max_steps": camvid_steps_per_epoch(), **({"epochs": epochs} if epochs else {})})
    for k in estimate or ():
        datasets[k]["camera"] = "estimate"
    for k, d in datasets.items() if train_on else ():
        d["role"] = "train" if k in train_on else "test"
        del d["test" if k in train_on else "train"]
    path = wd / "study.yaml"
    picked = [datasets[k] for k in names] if names else [datasets[k] for k in LOO] + [kitti]
    path.write_text(yaml.safe_dump({"datasets": picked,
                                    **({"extent": extent} if extent != "max" else {}),
                                    "train": {**train, "balance": "datasets", "shading_aug": shading_aug,
                                              **({"arch": model} if model else {}), **(extra or {})}},
                                   sort_keys=False))
    return path


def result_files(sd: Path, cond: str, held: list[str] = LOO, pooled: bool = False) -> dict[str, Path]:
    """{test set: its result file} of one seed's study and condition (crossval's layout); ``held`` the
    held-out cameras (a subset of LOO: no test-only set then); ``pooled``: one model (--train-on)."""
    if pooled:
        return {t: sd / "runs" / "_all" / cond / f"result-{t}.json" for t in held}
    out = {t: sd / "runs" / t / cond / "result.json" for t in held}
    if held != LOO:
        return out
    out.update({t: sd / "runs" / "_all" / cond / f"result-{t}.json" for t in TEST_ONLY})
    return out


def collect(wd: Path, seeds: list[int], conds: list[str], base: Path | None = None,
            held: list[str] = LOO, pooled: bool = False) -> tuple[dict[str, list], list[str], list[float]]:
    """(cells {'<test>|<cond>': road IoU points per seed, None where not finished}, the missing
    '<test>|<cond>|seed<k>' folds, the training minutes of every finished model). ``base``: the
    workdir whose studies hold ``resize`` (another rectangle rule's: resize meets no rectangle)."""
    cells: dict[str, list] = {}
    missing, minutes = [], {}
    for i, seed in enumerate(seeds):
        for cond in conds:
            sd = (base if base is not None and cond == "resize" else wd) / f"seed{seed}"
            for t, f in result_files(sd, cond, held, pooled and sd.parent == wd).items():
                cell = cells.setdefault(f"{t}|{cond}", [None] * len(seeds))
                if not f.is_file():
                    missing.append(f"{t}|{cond}|seed{seed}")
                    continue
                row = json.loads(f.read_text())
                cell[i] = 100 * row["iou"]
                if "averaged" not in row:  # (condition average trains nothing: its models are within's, resize's)
                    minutes[(seed, cond, row.get("run", t))] = row["train_seconds"] / 60  # one model per run
    return cells, missing, list(minutes.values())


def summarise(cells: dict[str, list], seeds: list[int], conds: list[str],
              held: list[str] = LOO) -> tuple[dict, dict]:
    """(headline, targets) of the cells; a figure over seeds uses the seeds that have both of its values."""
    r2 = lambda x: round(float(x), 2)
    head: dict = {}

    def paired(t: str) -> list[float]:
        w, r = cells.get(f"{t}|within", []), cells.get(f"{t}|resize", [])
        return [a - b for a, b in zip(w, r) if a is not None and b is not None]

    for t in held:
        for k in conds:
            v = [x for x in cells.get(f"{t}|{k}", []) if x is not None]
            head[f"loo_{k}_{t}"] = r2(np.mean(v)) if v else None
        d = paired(t)
        head[f"loo_within_minus_resize_{t}"] = r2(np.mean(d)) if d else None
        for k in conds:  # every other condition against resize, paired per seed
            if k not in ("within", "resize"):
                d = [a - b for a, b in zip(cells.get(f"{t}|{k}", []), cells.get(f"{t}|resize", []))
                     if a is not None and b is not None]
                head[f"loo_{k}_minus_resize_{t}"] = r2(np.mean(d)) if d else None
    for t in TEST_ONLY if held == LOO else []:
        for k in conds:
            v = [x for x in cells.get(f"{t}|{k}", []) if x is not None]
            head[f"test_{k}_{t}"] = r2(np.mean(v)) if v else None
    # the LOO mean: per seed over the five held-out cameras (seeds with every fold of both conditions)
    per_seed = []
    for i in range(len(seeds)):
        d = [cells.get(f"{t}|within", [None] * len(seeds))[i] is not None
             and cells.get(f"{t}|resize", [None] * len(seeds))[i] is not None for t in held]
        if all(d):
            per_seed.append(float(np.mean([cells[f"{t}|within"][i] - cells[f"{t}|resize"][i] for t in held])))
    if per_seed:
        s = seed_stats(per_seed)
        head["loo_within_minus_resize"], head["loo_within_minus_resize_std"] = r2(s["mean"]), r2(s["std"] or 0.0)
    else:
        head["loo_within_minus_resize"] = head["loo_within_minus_resize_std"] = None
    head["loo_complete_seeds"] = [seeds[i] for i in range(len(seeds)) if len(per_seed) and all(
        cells.get(f"{t}|{k}", [None] * len(seeds))[i] is not None for t in held for k in ("within", "resize"))]
    worst = [head[f"loo_within_minus_resize_{t}"] for t in held]
    targets = {
        f"LOO mean within >= resize + {TARGET_GAIN:g}": None if head["loo_within_minus_resize"] is None
        else head["loo_within_minus_resize"] >= TARGET_GAIN,
        f"no held-out camera below resize - {-TARGET_WORST:g}": None if any(v is None for v in worst)
        else min(worst) >= TARGET_WORST,
    }
    return head, targets


def render(cells: dict[str, list], head: dict, targets: dict, seeds: list[int], conds: list[str],
           missing: list[str], steps: int, held: list[str] = LOO) -> str:
    f = lambda v: "-" if v is None else f"{v:.1f}"
    others = [k for k in conds if k not in ("within", "resize")]
    lines = [f"Leave one real camera out: road IoU (%) per seed {seeds}; each fold trained on the other four real "
             f"datasets (balance: datasets, {steps} steps an epoch), tested on all frames of the held-out one in "
             "its own camera; KITTI by the model trained on all five.", "",
             "| held out | seed | " + " | ".join(conds) + " | within − resize |"
             + "".join(f" {k} − resize |" for k in others),
             "|---|---|" + "---|" * (len(conds) + 1 + len(others))]
    for t in held + (TEST_ONLY if held == LOO else []):
        for i, s in enumerate(seeds):
            v = [cells.get(f"{t}|{k}", [None] * len(seeds))[i] for k in conds]
            w, r = (cells.get(f"{t}|within", [None] * len(seeds))[i], cells.get(f"{t}|resize", [None] * len(seeds))[i])
            lines.append(f"| {t} | {s} | " + " | ".join(f(x) for x in v) + " | "
                         + ("-" if w is None or r is None else f"{w - r:+.1f}") + " |"
                         + "".join(" - |" if x is None or r is None else f" {x - r:+.1f} |"
                                   for x in (cells.get(f"{t}|{k}", [None] * len(seeds))[i] for k in others)))
    m, sd = head.get("loo_within_minus_resize"), head.get("loo_within_minus_resize_std")
    lines += ["", f"LOO mean within − resize (per seed the mean over the {len(held)} held-out cameras): "
              + ("not complete for any seed" if m is None
                 else f"{m:+.1f} ± {sd:.1f} (seeds {head['loo_complete_seeds']})")
              + "."]
    if missing:
        lines += ["", f"Missing (not finished): {', '.join(missing)}."]
    lines += ["", "| target | met |", "|---|---|"] + [
        f"| {k} | {'not measured' if v is None else 'yes' if v else 'no'} |" for k, v in targets.items()]
    return "\n".join(lines) + "\n"


def mixed_average(wd: Path, rd: Path, seeds: list[int], held: list[str]) -> None:
    """Condition average across two studies (``--train-on``): the mean of WORKDIR's one within model
    (trained on the --train-on sets) and each fold's resize model in ``rd`` (trained on the other four),
    scored as crossval's condition average on this study's within test store of the held-out camera;
    written where collect reads it (runs/_all/average/result-<t>.json; kept while it exists)."""
    from vctrain.predict import Predictor
    from vctrain.study.conditions import AveragePredictor
    from vctrain.study import score_store

    for seed in seeds:
        sd = wd / f"seed{seed}"
        within = sd / "runs" / "_all" / "within" / "model.pt"
        for t in held:
            resize = rd / f"seed{seed}" / "runs" / t / "resize" / "model.pt"
            out = sd / "runs" / "_all" / "average" / f"result-{t}.json"
            if out.is_file() or not (within.is_file() and resize.is_file()):
                continue
            pred = AveragePredictor([Predictor(within, device="cpu"), Predictor(resize, device="cpu")])
            m = score_store(pred, sd / "stores" / t / "test" / "within")
            out.parent.mkdir(parents=True, exist_ok=True)
            write_json(out, {**m, "heldout": t, "condition": "average", "averaged": [str(within), str(resize)]})


def _args() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--conditions", default="within,resize")
    ap.add_argument("--epochs", type=int, default=None, help="default: crossval's (the recipe's)")
    ap.add_argument("--workdir", type=Path, default=ROOT / "benchmarks" / "out" / "multi_camera")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--shading-aug", type=float, default=SHADING_AUG, help="study train: shading_aug (0: off)")
    ap.add_argument("--no-test-only", action="store_true", help="skip the all-five model tested on KITTI "
                    "(benchmarks/what_a_user_gets/shipped_model.py scores KITTI too)")
    ap.add_argument("--quick", action="store_true", help="smoke run: a few frames, 2 steps, seed 0")
    ap.add_argument("--collect", action="store_true", help="run nothing: report what is finished and what is missing")
    ap.add_argument("--extent", choices=("max", "median"), default="max",
                    help="the designed rectangle's rule (study 'extent'); median: the virtual-camera conditions "
                    "in WORKDIR/median, resize taken from WORKDIR's studies of the same seeds, results "
                    "multi_camera_median.{md,json}")
    ap.add_argument("--held-out", default=",".join(LOO), help="the folds to run, a comma-separated subset of "
                    f"{','.join(LOO)} (a subset: no test-only model, results in WORKDIR/results)")
    ap.add_argument("--train-on", default="", help="the virtual-camera conditions trained on these datasets only "
                    "(e.g. camvid,cityscapes: the calibrated cameras; one model, every held-out set a test set), in "
                    "WORKDIR[/median]/train-<names>; resize (and condition average's resize model) from the "
                    "study of all four (WORKDIR[/median], run there with --conditions within,resize,average)")
    ap.add_argument("--train-extra", default="", help="training settings added to the virtual-camera conditions' "
                    "study, KEY=VALUE[,KEY=VALUE] (e.g. shading_aug=0.2; issue 44's candidates), in "
                    "WORKDIR[/median]/extra-<settings> with the stores of WORKDIR[/median]; resize from there")
    ap.add_argument("--model", default=None, help="every condition's network (study train: arch), e.g. lite0fpn; "
                    "WORKDIR/model-<name>, its own stores")
    ap.add_argument("--camera-estimate", default="",
                    help="these datasets' cameras estimated from their frames and labels (camera: estimate), e.g. "
                    "bdd,lums: the assumed cameras of the TRAINING sets (issue 44; hold out a set whose camera is "
                    "not estimated, or its test geometry reads its labels), in WORKDIR[/median]/estimate-<names> "
                    "with its own stores; resize from WORKDIR[/median]")
    return ap.parse_args()


def train_extra(text: str) -> dict:
    """--train-extra 'blur_aug=1.5,seen_only=true' -> {'blur_aug': 1.5, 'seen_only': True} (YAML values)."""
    out = {}
    for part in filter(None, text.split(",")):
        k, _, v = part.partition("=")
        out[k.strip()] = yaml.safe_load(v)
    return out


def main() -> None:
    a = _args()
    held = [t for t in LOO if t in a.held_out.split(",")]
    train_on = [t for t in LOO if t in a.train_on.split(",")]
    require_data(CITYSCAPES, IDD, DATA, KITTI, BDD, LUMS)
    seeds = [0] if a.quick else [int(s) for s in a.seeds.split(",") if s]
    conds = a.conditions.split(",")
    base = a.workdir / "quick" if a.quick else a.workdir
    if a.model:  # another network for every condition: its own studies (and stores)
        base = base / f"model-{a.model}"
    rd = wd = base / "median" if a.extent == "median" else base  # rd: the study that trains resize
    extra = train_extra(a.train_extra)
    estimate = [t for t in LOO if t in a.camera_estimate.split(",")]
    if estimate and (set(estimate) & set(held)):
        raise SystemExit(f"--camera-estimate {a.camera_estimate}: a held-out set's camera would be estimated from "
                         "its test labels; hold out only sets whose camera is not estimated (--held-out)")
    if estimate:  # other cameras: another virtual camera, its own stores; resize (no rectangle) from the plain one
        wd = wd / ("estimate-" + "-".join(estimate) + "".join(f"-{k}-{v}" for k, v in extra.items()))
    elif train_on:
        wd = wd / ("train-" + "-".join(train_on))
    elif extra:  # the candidate's own study beside the plain one, sharing its stores; resize from the plain one
        wd = wd / ("extra-" + "-".join(f"{k}-{v}" for k, v in extra.items()))
        for seed in seeds:
            link_stores(wd / f"seed{seed}", rd / f"seed{seed}")
    else:  # resize meets no rectangle: from WORKDIR's studies, unless average or resize-vp (paired) needs it here
        rd = wd if a.extent == "max" or a.model or {"average", "resize-vp"} & set(conds) else base
    wd.mkdir(parents=True, exist_ok=True)
    steps = 2 if a.quick else camvid_steps_per_epoch()
    run_conds = [k for k in conds if rd == wd or k not in ("resize", "average")]

    if not a.collect:
        study = study_file(wd, a.quick, a.epochs, a.shading_aug, a.extent, train_on or None, extra,
                           rd if extra or estimate else None, estimate, a.model)
        for seed in seeds:
            if seed != seeds[0]:
                link_stores(wd / f"seed{seed}", wd / f"seed{seeds[0]}")
            run_study(study, wd / f"seed{seed}", run_conds, seed, a.threads,
                      held if a.no_test_only or held != LOO or train_on else None)
        if train_on and "average" in conds:
            mixed_average(wd, rd, seeds, held)

    cells, missing, minutes = collect(wd, seeds, conds, None if rd == wd else rd, held, bool(train_on))
    head, targets = summarise(cells, seeds, conds, held)
    head["minutes_per_model"] = round(float(np.mean(minutes)), 2) if minutes else None
    head["minutes_per_model_max"] = round(float(np.max(minutes)), 2) if minutes else None
    head["seeds"] = seeds
    head["folds_missing"] = missing
    table = render(cells, head, targets, seeds, conds, missing, steps, held)
    print(table)
    _write(a, wd, table, {"headline": head, "targets": targets, "cells": cells, "seeds": seeds, "conditions": conds,
                          "held_out": held, "train_on": train_on or None}, held, steps)
    print(json.dumps(head))
    sys.stdout.flush()


def _write(a: argparse.Namespace, wd: Path, table: str, out: dict, held: list[str], steps: int) -> None:
    """The table and the JSON (benchmarks/other_cameras/results, or WORKDIR's results for a smoke run or some folds)."""
    own = a.quick or held != LOO or a.train_on or a.train_extra or a.camera_estimate or a.model
    res_dir = (wd / "results") if own else results_dir(__file__)
    res_dir.mkdir(parents=True, exist_ok=True)
    name = "multi_camera" + ("_median" if a.extent != "max" else "")
    (res_dir / f"{name}.md").write_text(table)
    command = (f"benchmarks/other_cameras/multi_camera.py {'--quick' if a.quick else '--seeds ' + a.seeds} "
               f"--conditions {a.conditions} --threads {a.threads}"
               + (f" --epochs {a.epochs}" if a.epochs else "") + f" --shading-aug {a.shading_aug:g}"
               + (f" --extent {a.extent}" if a.extent != "max" else "") + (" --collect" if a.collect else "")
               + (f" --held-out {','.join(held)}" if held != LOO else "")
               + (f" --train-on {a.train_on}" if a.train_on else "")
               + (f" --train-extra {a.train_extra}" if a.train_extra else "")
               + (f" --camera-estimate {a.camera_estimate}" if a.camera_estimate else "")
               + (f" --model {a.model}" if a.model else ""))
    write_json(res_dir / f"{name}.json", {
        **out, "test_only": TEST_ONLY, "steps_per_epoch": steps, "epochs": a.epochs, "balance": "datasets",
        "shading_aug": a.shading_aug, "extent": a.extent, "model": a.model,
        "threads": a.threads, "machine": machine(), "date": today(), "command": command})


if __name__ == "__main__":
    main()
