"""Scoring VPs: errors in % of the width (:func:`vp_errors`, :func:`error_summary`), scenes and the
paired scene-block bootstrap (:func:`scenes`, :func:`scene_bootstrap`), ours against the baseline
on one set (:func:`evaluate_vps`), the reliability rule's fallback (:func:`fallback_loo`) and
camera independence (:func:`camera_consistency`).
"""
from __future__ import annotations

import math
import re
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from .data import DATA
from .vp_reference import baseline_vp
from vcprep.vp import VPConfig, apply_reliability, estimate_vp, score_vps, sequence_key

TAIL_PCT = 1.0  # the tail: errors above this (% width), split into search misses and lines-elsewhere
SCENE_GAP = 30  # frames of one sequence at most this many frame numbers apart are one scene (1 s at 30 fps)


def vp_errors(vps, items, cams) -> np.ndarray:
    """|VP - reference| of each item in % of its camera's width."""
    return np.array([math.hypot(v[0] - r[0], v[1] - r[1]) / c.size[0] * 100
                     for v, (_, _, r), c in zip(vps, items, cams)])


def error_summary(e: np.ndarray) -> dict:
    return {"n": int(len(e)), "median_pct_width": round(float(np.median(e)), 3) if len(e) else None,
            "p90_pct_width": round(float(np.percentile(e, 90)), 3) if len(e) else None,
            "mean_pct_width": round(float(np.mean(e)), 3) if len(e) else None}


_FRAME_RE = re.compile(r"^(.*?)(\d+)$")


def scenes(ids, gap: int = SCENE_GAP) -> list[int]:
    """Scene index of each frame id: frames of one sequence (:func:`sequence_key`) whose frame
    numbers (the id's trailing digits) are at most ``gap`` apart, chained, are one scene (CamVid
    is 30 fps: 30 = one second of driving); an id without a frame number is a scene of its own.
    Consecutive frames of one drive see the same road, so their errors are not independent."""
    keyed = []
    for k, iid in enumerate(ids):
        m = _FRAME_RE.match(iid.rsplit("_", 1)[-1]) if "_" in iid else None
        keyed.append((sequence_key(iid), int(m.group(2)) if m else None, k))
    out = [0] * len(ids)
    scene, last = -1, None
    for seq, num, k in sorted(keyed, key=lambda t: (t[0], -1 if t[1] is None else t[1], t[2])):
        if num is None or last is None or seq != last[0] or num - last[1] > gap:
            scene += 1
        out[k] = scene
        last = None if num is None else (seq, num)
    return out


def _scene_groups(scene: list[int]) -> list[np.ndarray]:
    """Frame indices of each scene, in scene order."""
    scene = np.asarray(scene)
    return [np.flatnonzero(scene == s) for s in np.unique(scene)]


def scene_bootstrap(ours: np.ndarray, base: np.ndarray, groups: list[np.ndarray], n_boot: int = 2000,
                    seed: int = 0) -> dict:
    """Paired scene-block bootstrap (whole scenes resampled with replacement, ``n_boot`` draws,
    seeded): 90 % intervals (5th-95th percentile) of the median and p90 error of ours, of the
    baseline, and of their differences (ours - baseline; negative = ours better), in % width.
    With few scenes the intervals are wide: that is what the set can say. ``groups``: the frame
    indices of each scene (:func:`_scene_groups`)."""
    rng = np.random.default_rng(seed)
    stats = {k: [] for k in ("median", "p90", "baseline_median", "baseline_p90", "median_minus_baseline",
                             "p90_minus_baseline")}
    for _ in range(n_boot):
        idx = np.concatenate([groups[g] for g in rng.integers(0, len(groups), len(groups))])
        mo, po = np.median(ours[idx]), np.percentile(ours[idx], 90)
        mb, pb = np.median(base[idx]), np.percentile(base[idx], 90)
        for k, v in (("median", mo), ("p90", po), ("baseline_median", mb), ("baseline_p90", pb),
                     ("median_minus_baseline", mo - mb), ("p90_minus_baseline", po - pb)):
            stats[k].append(v)
    ci = {k: [round(float(np.percentile(v, 5)), 3), round(float(np.percentile(v, 95)), 3)] for k, v in stats.items()}
    return {"scenes": len(groups), "n_boot": n_boot, "seed": seed, "ci90": ci,
            "frames_per_scene": [int(len(g)) for g in groups]}


def evaluate_vps(items, cams, cfg: VPConfig, repeats: int):
    """Errors (% width) and median ms/image for ours and the baseline, same images, same run;
    ``cams``: one camera per item (or one for all). For ours also the reliability rule's split:
    the error of the VPs it accepts, and of those it rejects (their detection, and the dataset
    mean of the accepted VPs that replaces them: what ``vcprep warp`` uses)."""
    cams = list(cams) if isinstance(cams, (list, tuple)) else [cams] * len(items)
    ids = [iid for iid, _, _ in items]
    res = {}
    for name, fn in (("ours", lambda im, c: estimate_vp(im, c, cfg)),
                     ("baseline", lambda im, c: baseline_vp(im))):
        per_pass, out = [], []
        for rep in range(repeats):
            t0 = time.perf_counter()
            got = [fn(im, c) for (_, im, _), c in zip(items, cams)]
            per_pass.append((time.perf_counter() - t0) * 1000 / max(1, len(items)))
            if rep == 0:
                out = got
        vps = [r.vp for r in out] if name == "ours" else out
        e = vp_errors(vps, items, cams)
        res[name] = {**error_summary(e), "ms_per_image": round(float(np.median(per_pass)), 2),
                     "ms_spread": [round(float(min(per_pass)), 2), round(float(max(per_pass)), 2)],
                     "errors": [round(float(x), 4) for x in e],
                     "vps": {iid: [round(float(v[0]), 4), round(float(v[1]), 4)] for (iid, _, _), v in zip(items, vps)}}
        if name == "ours":
            acc = np.array([r.status == "accepted" for r in out], bool)
            final = apply_reliability(out, cams, ids)
            det = [(r.detected or r.vp) for r in out]
            # the tail, split by the detector's own score (score_vps): a reference VP scoring higher
            # than the detection is a search miss; lower, the image's lines converge elsewhere
            tail = np.flatnonzero(e > TAIL_PCT)
            split = {"search_miss": [], "lines_elsewhere": []}
            for k in tail:
                (iid, im, ref), c = items[k], cams[k]
                s_det, s_ref = score_vps(im, c, [out[k].detected or out[k].vp, ref], cfg)
                split["search_miss" if s_ref > s_det else "lines_elsewhere"].append(
                    {"id": iid, "error_pct_width": round(float(e[k]), 3),
                     "score_reference_over_detection": round(float(s_ref / s_det), 3) if s_det > 0 else None})
            res[name]["tail"] = {"threshold_pct_width": TAIL_PCT, "n": int(len(tail)), **split}
            res[name]["reliability"] = {
                "accepted": error_summary(e[acc]),
                "rejected_detection": error_summary(vp_errors(det, items, cams)[~acc]),
                "rejected_fallback": error_summary(vp_errors([r.vp for r in final], items, cams)[~acc]),
                "reasons": sorted({r.reason for r in out if r.status != "accepted"}),
            }
    e_o, e_b = np.array(res["ours"]["errors"]), np.array(res["baseline"]["errors"])
    groups = _scene_groups(scenes(ids))
    res["scenes"] = scene_bootstrap(e_o, e_b, groups)
    res["scenes"]["per_scene"] = [
        {"first": ids[g[0]], "last": ids[g[-1]], "n": int(len(g)),
         "median_pct_width": round(float(np.median(e_o[g])), 3), "max_pct_width": round(float(e_o[g].max()), 3),
         "baseline_median_pct_width": round(float(np.median(e_b[g])), 3),
         "baseline_max_pct_width": round(float(e_b[g].max()), 3)}
        for g in groups]
    return res


def fallback_loo(split: str, cam, items, cfg: VPConfig) -> dict:
    """What the reliability rule's fallback is worth on real frames, leave-one-out: the detector
    runs on EVERY frame of the split (as ``vcprep warp --within estimate`` would), then each
    referenced frame in turn is marked rejected and ``apply_reliability`` replaces it - with its
    sequence's mean (ids given, the tool's rule) and with the whole split's mean (no ids, the
    rule before) - and the replacement is scored against the frame's reference (% width)."""
    paths = sorted((DATA / split).glob("*.png"))
    ids = [p.stem for p in paths]
    res = [estimate_vp(cv2.imread(str(p), cv2.IMREAD_COLOR), cam, cfg) for p in paths]
    cams = [cam] * len(res)
    where = {iid: k for k, iid in enumerate(ids)}
    out = {"sequence": [], "dataset": []}
    for iid, _, ref in items:
        k = where[iid]
        trial = list(res)
        trial[k] = replace(res[k], status="rejected")
        for name, fb in (("sequence", apply_reliability(trial, cams, ids)[k]),
                         ("dataset", apply_reliability(trial, cams)[k])):
            out[name].append(math.hypot(fb.vp[0] - ref[0], fb.vp[1] - ref[1]) / cam.size[0] * 100)
    return {"frames_detected": len(res), "rejected_in_split": sum(r.status != "accepted" for r in res),
            **{f"{k}_mean": error_summary(np.array(v)) for k, v in out.items()}}


def camera_consistency(source_vps: dict, sim_items, sim_vps: dict, sim_dir: Path, width: int) -> dict:
    """Reference-free camera independence of our detector on one simulated set: its VP on each
    simulated frame vs its VP on the SOURCE frame carried into the simulated camera by that
    frame's exact homography (``out_H_src`` recorded by the simulation), in % of the simulated
    width. A camera-independent detector finds the same road direction in both (0 up to
    resampling), whatever the reference says. ``inherited``: the source frame's own error
    carried over (its VP vs its reference, both through the same homography), i.e. the simulated
    set's error if the detector did exactly as well on every simulated frame as on its source;
    a crop/zoom makes it larger in % of the (narrower) width."""
    from vcprep.warp import apply_homography
    from vcprep.simulate import recorded_homographies

    H = recorded_homographies(sim_dir)
    cons, inh = [], []
    for iid, _, ref in sim_items:
        mapped = apply_homography(H[iid], np.array([source_vps[iid]], float))[0]
        cons.append(math.hypot(*(np.asarray(sim_vps[iid]) - mapped)) / width * 100)
        inh.append(math.hypot(mapped[0] - ref[0], mapped[1] - ref[1]) / width * 100)
    return {"consistency": error_summary(np.array(cons)), "inherited": error_summary(np.array(inh)),
            "consistency_errors": [round(x, 4) for x in cons]}
