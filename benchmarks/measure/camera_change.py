"""The camera change alone, on the simulated cameras: each model's score without the change
(:func:`no_shift_reference`), with each frame's exact pose (:func:`exact_vp_scores`), and their
statistics over seeds (:func:`shift_costs`, :func:`vp_costs`).
"""
from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np

from .data import SIM
from .stats import UNTRAINED, seed_stats


def no_shift_reference(sd: Path, wd: Path, source: dict, conditions: list[str], sets: list[str]) -> dict:
    """{(simulated set, condition): {"iou", "test_items"}}: each trained model's prediction on the
    simulations' SOURCE frames in their own camera (the in-domain test set, e.g. CamVid val),
    carried into the simulated camera by the simulation's exact homography (each frame's
    ``out_H_src`` as the simulation recorded it, :func:`vcprep.simulate.recorded_homographies`;
    P(road) bilinear, like the images) and scored against the simulated labels. Same frames, same
    pixels, no camera change: the score the model would get on that camera if the change cost
    nothing, so (simulated score - this) is the cost of the camera change alone. Checked against
    the files: every source label carried over must equal the simulated label, or the benchmark
    stops. Kept in runs/_all/<condition>/no_shift.json (keyed by the training and the simulations)."""
    from vcprep.dataset import list_dataset
    from vcprep.io import read_image
    from vcprep.labels import decode_label, get_label_format
    from vcprep.simulate import recorded_homographies, simulate_arrays
    from vcprep.store import Store
    from vctrain.study import CONDITIONS as MODES
    from vctrain.metrics import RoadMetrics
    from vctrain.predict import Predictor

    sims = [n for n in SIM if n in sets]
    fmt = get_label_format("camvid")
    jobs = {j.id: j for j in list_dataset(source["images"], source["labels"], fmt)}
    Hs, sizes, labels = {}, {}, {}
    for n in sims:
        Hs[n] = recorded_homographies(wd / "sim" / n)
        sizes[n] = tuple(json.loads((wd / "sim" / n / "simulate.json").read_text())["camera"]["image_size"])
        for iid in Hs[n]:  # the exact-geometry check: the recorded H reproduces the simulated label
            raw = read_image(jobs[iid].label, label=True).array
            mine = simulate_arrays(raw, raw, Hs[n][iid], sizes[n])[1]
            sim_file = wd / "sim" / n / "labels" / jobs[iid].label.name
            theirs = read_image(sim_file, label=True).array
            if not np.array_equal(mine, theirs):
                sys.exit(f"{sim_file}: the recorded homography does not reproduce this label; "
                         f"delete {wd / 'sim'} and run again")
            labels[n, iid] = decode_label(theirs, fmt, sim_file)
    out: dict[tuple[str, str], dict] = {}
    key_sims = json.dumps({n: (wd / "sim" / n / "simulate.json").read_text() for n in sims}, sort_keys=True)
    for c in conditions:
        run_dir = sd / "runs" / "_all" / c
        if c in UNTRAINED or not (run_dir / "train.json").exists():
            continue
        key = hashlib.sha256(((run_dir / "train.json").read_text() + key_sims).encode()).hexdigest()[:16]
        cache = run_dir / "no_shift.json"
        old = json.loads(cache.read_text()) if cache.exists() else {}
        if old.get("key") != key:
            store = Store.open(sd / "stores" / source["dataset"] / "test" / MODES[c][0])
            pred = Predictor(run_dir / "model.pt", device="cpu")
            probs = {rec["id"]: pred.store_item(store, rec).astype(np.float32) for rec in store}
            res = {}
            for n in sims:
                m = RoadMetrics()
                for iid, H in Hs[n].items():
                    m.add(simulate_arrays(probs[iid], None, H, sizes[n])[0] >= 0.5, labels[n, iid])
                res[n] = {**m.result(), "test_items": len(Hs[n])}
            old = {"key": key, "results": res}
            cache.write_text(json.dumps(old, indent=1) + "\n")
        for n, r in old["results"].items():
            out[n, c] = r
    return out


def exact_vp_scores(sd: Path, wd: Path, sets: list[str], threads: int) -> dict:
    """{simulated set: {"iou", "test_items"}}: the seed's within model on each simulated camera's
    test frames warped with each frame's EXACT camera pose (the simulation's vps.csv, status
    'given': the source camera's nominal pose through the frame's simulated rotation, what a
    perfect per-frame calibration gives) instead of its estimated road VP, into the same virtual
    camera and scale (stores under ``exact_vp/<set>``). Kept in runs/_all/within/exact_vp.json
    (keyed by the training and the VP files)."""
    from vcprep.store import WarpSettings, warp_dataset
    from vcprep.dataset import list_dataset
    from vcprep.camera import camera_from_dict, load_camera
    from vcprep.labels import get_label_format
    from vcprep.vp import ItemPose, vps_for_items
    from vctrain.study import evaluate_heldout

    run_dir = sd / "runs" / "_all" / "within"
    sims = [n for n in SIM if n in sets]
    if not sims or not (run_dir / "train.json").exists():
        return {}
    key = hashlib.sha256(((run_dir / "train.json").read_text() + json.dumps(
        {n: (wd / "sim" / n / "vps.csv").read_text() for n in sims}, sort_keys=True)).encode()).hexdigest()[:16]
    cache = run_dir / "exact_vp.json"
    old = json.loads(cache.read_text()) if cache.exists() else {}
    if old.get("key") == key:
        return old["results"]
    study = json.loads((sd / "study.json").read_text())
    virtual, fmt = camera_from_dict(study["virtual"]), get_label_format("camvid")
    res = {}
    for n in sims:
        d = wd / "sim" / n
        jobs = list_dataset(d / "images", d / "labels", fmt)
        cam = load_camera(str(d / "camera.yaml"))
        vps = vps_for_items([j.image for j in jobs], [j.id for j in jobs], cam, str(d / "vps.csv"))
        poses = {j.id: ItemPose((r.vp[0], r.vp[1]), r.status) for j, r in zip(jobs, vps)}
        store = sd / "exact_vp" / n
        warp_dataset(jobs, store, WarpSettings(cam, virtual, study["scale"], fmt, completion="projective", poses=poses,
                                               workers=threads, progress=False))
        res[n] = evaluate_heldout(run_dir / "model.pt", store)
    cache.write_text(json.dumps({"key": key, "results": res}, indent=1) + "\n")
    return res


def shift_costs(per_seed: dict[int, dict], no_shift: dict[int, dict], sets: list[str], conditions: list[str],
                others: list[str]) -> dict:
    """The camera change alone, per simulated set and condition (mean, std, per seed): ``reference``
    (:func:`no_shift_reference`: the same pixels seen by the model in the source camera), ``cost``
    = score on the simulated camera - reference (and per group), and ``zero_cost``: within -
    resize if the within model lost nothing to the camera change (within's reference - resize's
    score; what these test sets allow at this network quality), per simulated set, over the
    simulated sets, and over the other cameras ``others`` with the real ones (no reference) as measured."""
    seeds = [k for k in sorted(per_seed) if no_shift.get(k)]
    sims = [n for n in SIM if n in sets]
    trained = [c for c in conditions if c not in UNTRAINED]
    ref: dict[str, dict] = {n: {} for n in sims}
    cost: dict[str, dict] = {n: {} for n in sims}
    for n in sims:
        for c in trained:
            ks = [k for k in seeds if (n, c) in no_shift[k] and (n, c) in per_seed[k]]
            if ks:
                ref[n][c] = seed_stats([no_shift[k][n, c]["iou"] for k in ks])
                cost[n][c] = seed_stats([per_seed[k][n, c]["iou"] - no_shift[k][n, c]["iou"] for k in ks])
    if sims:
        cost["simulated"] = {c: seed_stats([float(np.mean([per_seed[k][n, c]["iou"] - no_shift[k][n, c]["iou"]
                                                       for n in sims])) for k in seeds])
                             for c in trained if all(c in cost[n] for n in sims)}
    zero: dict[str, dict] = {}
    if {"within", "resize"} <= set(trained) and sims and all("within" in ref[n] for n in sims):
        def gap(k: int, n: str) -> float:
            if n in sims:
                return no_shift[k][n, "within"]["iou"] - per_seed[k][n, "resize"]["iou"]
            return per_seed[k][n, "within"]["iou"] - per_seed[k][n, "resize"]["iou"]

        for n in sims:
            zero[n] = seed_stats([gap(k, n) for k in seeds])
        zero["simulated"] = seed_stats([float(np.mean([gap(k, n) for n in sims])) for k in seeds])
        if all((n, c) in per_seed[k] for k in seeds for n in others for c in ("within", "resize")):
            zero["other cameras"] = seed_stats([float(np.mean([gap(k, n) for n in others])) for k in seeds])
    return {"reference": ref, "cost": cost, "zero_cost": zero, "seeds": seeds}


def vp_costs(per_seed: dict[int, dict], exact: dict[int, dict]) -> dict:
    """Per simulated set (and their mean): within with each frame's exact pose (``exact``, mean,
    std, per seed) and ``cost`` = within with estimated road VPs - that."""
    seeds = [k for k in sorted(exact) if exact[k]]
    sims = [n for n in SIM if all(n in exact[k] and (n, "within") in per_seed[k] for k in seeds)] if seeds else []
    out = {n: {"exact": seed_stats([exact[k][n]["iou"] for k in seeds]),
               "cost": seed_stats([per_seed[k][n, "within"]["iou"] - exact[k][n]["iou"] for k in seeds])} for n in sims}
    if sims:
        out["simulated"] = {"exact": seed_stats([float(np.mean([exact[k][n]["iou"] for n in sims])) for k in seeds]),
                            "cost": seed_stats([float(np.mean([per_seed[k][n, "within"]["iou"] - exact[k][n]["iou"]
                                                          for n in sims])) for k in seeds])}
    return out
