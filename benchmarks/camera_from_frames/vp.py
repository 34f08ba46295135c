"""Road vanishing-point benchmark: our detector vs a plain LSD + RANSAC baseline, on synthetic
frames, real CamVid frames, CamVid val through three simulated cameras, and KITTI.

Run (one thread, as the figures below are stated):

    .venv/bin/python benchmarks/camera_from_frames/vp.py                 # synthetic + CamVid (if ../shared/data exists)
    .venv/bin/python benchmarks/camera_from_frames/vp.py --n-synthetic 40 --repeats 3
    .venv/bin/python benchmarks/camera_from_frames/vp.py --dev           # development sets only (see "Development")

This script runs the measurement and writes its results; the measuring code is in the ``measure``
package: the baseline and the reference rule in ``measure.vp_reference``, the sets in
``measure.vp_sets``, the errors and the scene bootstrap in ``measure.vp_scoring``.

Data
----
* **synthetic**: ``vcprep.synthetic.render_road`` through the camvid camera at 480x360 (and a
  few at 960x720 for the timing), pan uniform in [-20, 20] deg, tilt uniform in [-15, 15] deg,
  random road offset/width, Gaussian noise (sigma 5 grey levels) and 10 clutter segments
  (random position, direction and colour, 20-160 px long, 1-3 px thick; some near-vertical
  "poles"). Seed 0. Ground truth: ``vp_from_pose(cam, pan, tilt)`` (exact).
* **real**: CamVid (SegNet release, 480x360) ``val`` (101 frames) and ``train`` (367 frames) from
  ``../shared/data/camvid`` with the camvid camera scaled by 1/2. Reference VP from the
  ground-truth road mask (label 3), rule:

  1. road = largest 8-connected component of label 3;
  2. per image row (below the top 15 % of the road's rows, road width >= 12 px), the leftmost and
     rightmost road pixel are boundary points if they are at least 3 px from the image border
     and the pixel just outside is a static class (building 1, pavement 4, tree 5, fence 7,
     sky 0) - not a car, pedestrian, cyclist, pole, sign or unlabelled pixel (occluders);
  3. per side, a line x = a*y + b is fitted by deterministic RANSAC (all point pairs up to 4000,
     inlier band 2 px) and refined by least squares on the inliers; a side is good if it has
     >= 25 inliers, >= 60 % of its points are inliers, the inliers span >= 40 rows, and the
     inlier RMS is <= 1.2 px;
  4. both sides good, the two lines meet at >= 8 deg, the intersection lies above every fitted
     point and inside the camera's prior window (pan +/-20, tilt +/-15): keep the frame with
     that intersection as the reference VP; otherwise the frame is skipped (counted).

  The reference itself is uncertain (hand-drawn polygons, real kerbs): errors near its spread
  are at the reference's noise, not the detector's. Measured, not guessed (``train``, 42 frames):

  * *parameter spread*: recomputing it with rule 3's inlier band at 1.5 px and at 3 px (the rule
    uses 2 px) moves the reference VP by median 0.22 %, p90 0.54 % of the width (``val``: 0.16 %,
    0.35 %). The run prints this spread per split and writes it as ``reference_spread``
    (headline: ``reference_spread_*`` for ``val``);
  * *straight-kerb assumption*: the rule assumes both mask boundaries are straight lines parallel
    to the lane. Fitting the near half and the far half of each boundary separately gives VPs
    that differ by median 1.6 % of the width; where a kerb bends (bus lay-by, widening, side
    road) the reference is wrong by several percent while the lane markings are unambiguous -
    e.g. train 0016E5_00780 (9 %) and 0016E5_00870 (7 %), checked by eye on the drawings
    (``vcprep figure vp`` plus the fitted boundary lines). The rule was NOT changed to drop such
    frames: any straightness threshold strict enough to catch them also drops most good frames
    (measured), and a rule chosen by looking at the detector's errors would not be independent.

  * *what the image lines say*: an oracle measured on ``train`` (development only, not part of
    the run) keeps only the detector's segments that have ground-truth road (label 3) on at
    least one side - lane markings and road edges, no facades - and refines the VP on them: the
    median error is 0.81 % (vs 0.80 % with all segments); refining from the reference VP itself
    instead of from the detection gives median 0.59 %, p90 1.1 % (see the band note below;
    an earlier 0.46 % / 1.0 % was with a narrower band). So on most frames the road's
    own lines (markings, kerb tops, kerb faces) meet about 0.5-1 % of the width away from the
    mask-boundary intersection: the disagreement is between two definitions of the road VP,
    not clutter the detector could learn to ignore; 7 of 42 ``train`` frames (00780, 00870,
    07500, 07530, 01170, 01050, 00750) have two modes (e.g. lane markings vs kerbs of a
    slightly curving road) and the detector takes the better-supported one. With the
    detector's own refinement (inlier band 2 deg) the refinement from the reference gives
    0.59 % / 1.10 %, and the figure follows the band (1 deg: 0.50 % median, 3 deg: 0.70 %):
    a narrow band stays near wherever it starts, so it measures a basin, not a better optimum.
    Refined from the reference, 32 of 42 ``train`` frames end within 0.3 % of the detection
    (27 within 0.1 %), 17 of them frames with error > 0.5 %: there the detection already IS the
    image lines' optimum nearest the reference.

  * *what did not help* (``train`` median / p90 %, from 0.75 / 2.39; development only): scoring
    candidates by bilateral support below the VP - min(left, right) 0.94 / 2.16, geometric mean
    0.78 / 2.64, left + right + min 0.78 / 2.37; weighting segments by how low their lower end
    lies ((y / h) ** p, p = 1: 0.78 / 2.37, p = 2: 0.81 / 2.66); refining the best k = 6-24
    finalists and keeping the best refined one 0.74-0.75 / 2.39-2.67; refinement on segments
    below the VP 0.73 / 2.45, with left/right balanced weights 0.75 / 2.28; minimising
    point-line distance instead of angle 0.71-0.73 / 2.4-2.5 (synthetic median 0.11 -> 0.12-0.13);
    single-field sweeps of max/min_angle_deg, inlier_deg, above_weight, length_power,
    refine_power, lsd_scale, min_length, n_finalists, max_segments: medians 0.73-0.93. None
    was kept.

  So the targets (median 0.5 %, p90 1 %) are within about 2x of the reference's own parameter
  spread, and a bent kerb in 1 frame of 20 puts that frame's error above any p90 target; the
  synthetic set (exact ground truth) is where the detector's own precision shows.
  No parameter of the detector was tuned on ``val``; ``train`` (and synthetic) was used during
  development; ``val`` was run once at the end.

* **other cameras** (issue 17): the CamVid ``val`` frames that have a reference VP, through the
  simulated cameras of the cross-camera benchmarks (``measure.data.SIMULATED``: ``tele`` 35 deg
  HFOV tilted 3 deg down, 320x240; ``band`` 480x146; ``dashcam`` 40 deg, 400x225, per-image pan
  +/-8 and tilt +/-4 deg), made by ``vcprep simulate --vps`` so that each frame's reference VP is
  moved by the same exact homography as its pixels (in ``--workdir``). The detector gets the
  simulated camera at its nominal pose. Plus the KITTI road frames in ../shared/data with the
  same rule on their road ground truth (magenta road; an edge counts where the pixel outside is
  red) and each frame's own calibration; the one frame shipped (um_000000) is skipped by the
  rule (its left road boundary fails rule 3's goodness tests), so it is counted, not scored.

Development (``--dev``; issue 17's second round): CamVid ``train`` and the same 42 ``train``
frames through the same three simulated cameras (same arguments and seeds, in
``--workdir``/sim/train-*), plus synthetic; results in ``benchmarks/camera_from_frames/results/vp.dev.json``. Every
detector change of that round was chosen on these sets only; ``val``, val-simulated and KITTI
were run once, after the choice. Dev figures, median / p90 % width, train | tele | band | dashcam
| synthetic (the detector's own VP, before the reliability rule, unless said):

* before: 0.75/2.38 | 2.21/12.3 | 1.00/18.4 | 1.72/13.6 | 0.11/0.26;
* pose prior, Gaussian in pan/tilt around the camera's average pose, sigma = k x the window
  (20, 15 deg): k = 1.5 0.75/2.38 | 1.90/5.65 | 1.00/8.51 | 1.72/13.6 | 0.11/0.26; k = 1.25
  0.75/2.38 | 1.90/5.48 | 1.00/6.71 | 1.72/13.6 | 0.11/0.26; k = 1 breaks synthetic (p90 16.9,
  its poses are uniform up to the window's edge); a data-driven prior (train reference poses:
  pan sd 4.7, tilt sd 1.5 deg) at sigma 10/7.5 deg or tighter breaks train (p90 6.7-13.8: real
  frames with pan 15 deg exist);
* two-sided factor (score x (f + (1 - f) 2 min(L, R) / (L + R)), L/R = support below the
  candidate left/right of its vertical): f = 0.8 0.78/2.37 | 1.86/12.3 | 0.94/8.12 | 1.72/10.3;
  f = 0.67 0.78/2.37 | 1.86/12.3 | 0.85/9.52 | 1.79/10.3; f = 0.5 0.81/2.90 | .. | 0.91/6.54 |
  1.72/14.7; additive (+ 0.5 min(L, R)) 0.78/2.37 | 1.86/11.7 | 0.94/8.12 | 1.72/10.3;
* multi-scale vote (+ 0.5-1 x the vote with a 4-10 deg band): tele or dashcam p90 worse
  (16-42, 14.8-22.4); not kept;
* temporal smoothing (``--smooth N`` over all 367 train frames, then scored on the 42): N = 1
  0.79/2.49, N = 2 1.58/5.88, N = 3 2.11/6.86 - CamVid's labelled frames are 1 s apart and the
  VP moves in 1-2 s; the option is for real video rates, not for these sets; not used;
* kept: prior k = 1.25 and two-sided f = 0.8 together: 0.78/2.37 | 1.86/5.71 | 0.94/4.15 |
  1.69/10.3 | 0.10/0.23 (``pose_sigma``, ``one_sided``; ~3 % slower, same run);
* reliability (with the kept score): a margin rule (second-best mode more than 3 deg away >=
  0.92-0.95 of the best) and a both-sides rule did not separate good from bad (AUC 0.5-0.8);
  ``min_support`` did, with a knee at 7: over the 168 dev frames, n_support < 7 rejects 9, 5 of
  them more than 10 % of the width off, and the accepted p90 falls to tele 5.65, band 2.47,
  dashcam 5.16 (from 5.72, 3.92, 10.3); train rejects none. Kept (``min_support`` 4 -> 7). The
  fallback is no better than a detection for most rejected frames (camera-pose VP: train
  4.2/13.3 % error, tele 7.4/23.4), so with the rule applied (a rejected VP counted as the
  camera's average-pose VP, as in the table of a run) the all-frames figures are 0.78/2.37 |
  1.86/12.3 | 0.94/3.84 | 1.72/10.8 | 0.10/0.23 (tele's p90 is three rejected frames whose
  detections were 2.6 % off and whose fallback is 20 % off: the rule's price on that set).

Camera consistency (simulated sets; reference-free): our VP on each simulated frame vs our VP on
its source frame carried into the simulated camera by the frame's exact homography (as the
simulation recorded it), % of the simulated width: a camera-independent detector
finds the same road direction in both, whatever the reference says. Beside it, ``inherited``: the
source frame's own error carried over by the same homography, i.e. the simulated set's error if the
detector did on every simulated frame exactly as on its source; a crop or zoom enlarges it in % of
the narrower width (tele: about 1.8x), so a simulated set's median near its inherited median is the
source set's reference disagreement, magnified, not a camera dependence.

Scenes (what a set's p90 can say): frames of one sequence whose frame numbers are at most 30
apart (1 s at CamVid's 30 fps), chained, are one scene - they see the same road. Val's 29
referenced frames are 3 scenes of one 6.7-second clip (0016E5_07959-08159); train's 42 are 22.
Per set, a paired scene-block bootstrap (whole scenes resampled with replacement, 2000 draws,
seed 0) gives 90 % intervals of ours' and the baseline's median and p90 and of their difference
(``scenes`` per set, ``p90_minus_baseline_ci90`` in the headline), and the CamVid sets are listed
scene by scene.

The tail, split (``tail`` per set): every frame with an error above 1 % of the width is a
*search miss* if the reference VP scores higher than the detection under the detector's own score
(``vcprep.vp.score_vps``), else *lines elsewhere*: the image's lines, as the detector
weighs them, converge away from the reference. First run: 99 of 100 tail frames over all sets are
lines-elsewhere (reference / detection score 0.61-0.67, median per set), one tele frame a miss.

Round 3 (2026-11-24), development sets only, none kept (median / p90 % width, train | tele |
band | dashcam | synthetic, from 0.78/2.37 | 1.86/12.3 | 0.94/3.84 | 1.72/10.8 | 0.10/0.23):
CLAHE before LSD (clip 2, 8x8 tiles) 0.68/2.34 | 1.83/5.54 | 0.98/9.34 | 1.65/9.92 | 0.11/13.5,
(clip 1.5, 2x2) 0.67/2.16 | 1.72/4.00 | 0.88/9.45 | 1.52/10.9 | 0.10/9.31, (1.5, 4x4) 0.71/2.27 |
1.71/6.44 | 0.93/6.98 | 1.50/15.0 | 0.13/3.49: it fixes the dusk frames (tele 0001TP 19-24 % ->
0.4-1.9 %) but grass texture, shadows and parking-bay lines give new near-horizontal modes
(synthetic syn000 0.1 -> 12.6 %, train 0006R0_f03900 1.0 -> 26.9 %); a global stretch or
histogram equalisation alike;
a tilt-only pose prior at 5 / 7.5 deg breaks synthetic (p90 39 / 34); refinement weight x
1 / distance ** p, p = -1..3: within 0.03 of the medians, p90 unchanged or worse; max_angle_deg
75 / 80 and min_angle_deg 15: no set better on both figures; an angular working resolution
(fx capped at 431 / 380 px, min_length relative to fx): tele p90 15.0 / 19.1; merging collinear
segments (1.5 deg, 0.4 % width; one physical line votes once; min_support 4): 0.79/2.53 |
1.69/11.1 | 0.86/2.93 | 1.71/14.7 | 0.09/0.26 (mixed). Diagnosis of val's tail (looked at on val,
nothing changed because of it): in 0016E5_08149-08159 the near-vertical lane dashes ahead
(> 75 deg) give our VP 21 votes and the reference 0; with 15-75 deg lines only the two nearly tie.

Baseline (issue 17's plain vote, no camera, no prior): OpenCV LSD with default settings on the
grey image; segments 15-75 deg from horizontal, longer than 15 px, midpoint in the lower 60 % of
the image; 500 seeded RANSAC pairs, each intersection scored by the summed length of segments
whose line passes within 3 px; the best intersection, unrefined.

Fallback, leave-one-out (``fallback_loo``, CamVid splits): the detector runs on every frame of the
split; each referenced frame in turn is marked rejected and ``apply_reliability`` replaces it by
its sequence's mean of accepted VPs (the tool's rule) or, as before, by the whole split's mean;
both scored against the frame's reference. What a rejection costs, on real frames.

Reliability (ours): ``estimate_vp`` accepts or rejects each VP (pose outside pan +/-20 / tilt
+/-15 deg of the camera, or fewer than ``min_support`` segments); a rejected VP is replaced by
the mean of the set's accepted VPs (``apply_reliability``, what ``vcprep warp`` does). Reported
per set: the error of the accepted VPs, and of the rejected ones (their detection, and the
fallback that replaces them), so a user can see what ``accepted`` is worth.

Metrics: error = |VP - reference| in pixels / image width * 100 (median, 90th percentile),
time = wall ms per image for detection from the decoded image (grey conversion, downscale,
line detection, voting), median over ``--repeats`` passes, single thread (``cv2.setNumThreads(1)``).
Results: ``benchmarks/camera_from_frames/results/vp.json``; the last stdout line is one JSON object with the headline
figures (``median_pct_width``, ``p90_pct_width``, ``ms_per_image_480`` for ours on real val frames,
``baseline_*`` for the baseline, and ``per_set``: ours, the baseline and the reliability split
for every set, and for the simulated sets ``consistency_*`` and ``inherited_*``).
"""
from __future__ import annotations

import argparse
import json
import platform
import sys
from dataclasses import asdict, replace
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: `benchmarks.` imports in a file run
from benchmarks.measure.data import DATA, KITTI, ROOT
from benchmarks.measure.report import results_dir, write_json
from benchmarks.measure.vp_scoring import TAIL_PCT, camera_consistency, evaluate_vps, fallback_loo
from benchmarks.measure.vp_sets import camvid_vp_set, kitti_vp_set, simulated_vp_sets, synthetic_vp_set
from vcprep.camera import PRESETS
from vcprep.vp import VPConfig


def _row(label, size, r):
    return (f"{label:<26} {size:>8} {r['n']:>4}  {r['median_pct_width']!s:>7} {r['p90_pct_width']!s:>7} "
            f"{r['ms_per_image']:>8.2f}")


def parse_args(argv=None) -> argparse.Namespace:
    """The options (--dev: the train split, its own output file)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n-synthetic", type=int, default=40)
    ap.add_argument("--n-synthetic-960", type=int, default=8, help="960x720 renders (timing + error)")
    ap.add_argument("--repeats", type=int, default=3, help="timing passes (median reported)")
    ap.add_argument("--splits", default="val,train")
    ap.add_argument("--no-other-cameras", action="store_true", help="skip the simulated cameras and KITTI")
    ap.add_argument("--set", action="append", default=[], help="override a VPConfig field, e.g. work_width=360")
    ap.add_argument("--workdir", default=str(ROOT / "benchmarks" / "out" / "vp"), help="simulated frames go here")
    ap.add_argument("--dev", action="store_true",
                    help="development sets only: CamVid train, and train through the simulated cameras "
                         "(no val, no KITTI); writes benchmarks/camera_from_frames/results/vp.dev.json")
    ap.add_argument("--out", default=None, help="default benchmarks/camera_from_frames/results/vp.json (--dev: vp.dev.json)")
    args = ap.parse_args(argv)
    if args.dev:
        args.splits = "train"
    if args.out is None:
        args.out = str(results_dir(__file__) / ("vp.dev.json" if args.dev else "vp.json"))
    return args


def vp_config(overrides: list[str]) -> VPConfig:
    """The detector's configuration with ``--set`` overrides (field=value)."""
    cfg = VPConfig()
    for kv in overrides:
        k, v = kv.split("=")
        t = type(getattr(cfg, k))
        cfg = replace(cfg, **{k: v.strip().lower() in ("1", "true", "yes") if t is bool else t(v)})
    return cfg


def camvid_sets(args: argparse.Namespace, cfg: VPConfig, cam480, results: dict, sets: list) -> list | None:
    """The CamVid splits' sets (appended to ``sets``), their reference spread, fallback and skipped
    frames (into ``results``); the items of the split the simulated cameras are made from."""
    val_items = None
    if DATA.is_dir():
        for split in args.splits.split(","):
            items, skipped, spread = camvid_vp_set(split, cam480)
            sp = np.array(spread)
            sp = sp[np.isfinite(sp)]
            ref_noise = {"n": int(len(sp)), "median_pct_width": round(float(np.median(sp)), 3) if len(sp) else None,
                         "p90_pct_width": round(float(np.percentile(sp, 90)), 3) if len(sp) else None}
            print(f"camvid/{split}: {len(items)} frames with a good reference VP, {skipped} skipped by the rule; "
                  f"reference spread (band 1.5 vs 3 px) median {ref_noise['median_pct_width']} % "
                  f"p90 {ref_noise['p90_pct_width']} % of the width", file=sys.stderr)
            results.setdefault("reference_spread", {})[f"camvid/{split}"] = ref_noise
            sets.append((f"camvid/{split}", "480x360", items, cam480))
            loo = fallback_loo(split, cam480, items, cfg)
            results.setdefault("fallback_loo", {})[f"camvid/{split}"] = loo
            print(f"camvid/{split}: fallback if each referenced frame were rejected (leave-one-out over the "
                  f"{loo['frames_detected']} frames; {loo['rejected_in_split']} rejected in the split), median / "
                  f"p90 % width: sequence mean {loo['sequence_mean']['median_pct_width']} / "
                  f"{loo['sequence_mean']['p90_pct_width']}, whole-split mean {loo['dataset_mean']['median_pct_width']}"
                  f" / {loo['dataset_mean']['p90_pct_width']}", file=sys.stderr)
            results.setdefault("skipped", {})[f"camvid/{split}"] = skipped
            if split == ("train" if args.dev else "val"):
                val_items = items
    else:
        print(f"NOTE: {DATA} is absent: real-frame figures are NOT measured (synthetic only).", file=sys.stderr)
    return val_items


def other_camera_sets(args: argparse.Namespace, val_items: list | None, results: dict, sets: list) -> dict:
    """The simulated cameras' and KITTI's sets (appended to ``sets``): {simulated set: (its folder,
    the source set, items, camera)}."""
    sims = {}
    if val_items:
        sim_split = "train" if args.dev else "val"
        wd = Path(args.workdir)
        for name, cam, items in simulated_vp_sets(val_items, wd, sim_split):
            label, size = f"sim/{name}" if not args.dev else f"sim-train/{name}", f"{cam.size[0]}x{cam.size[1]}"
            sims[f"{label}@{size}"] = (wd / "sim" / (name if sim_split == "val" else f"{sim_split}-{name}"),
                                       f"camvid/{sim_split}@480x360", items, cam)
            sets.append((label, size, items, cam))
    kcams, kitems, kskipped = kitti_vp_set() if not args.dev else ([], [], 0)
    if kitems:
        w, h = kcams[0].size
        sets.append(("kitti", f"{w}x{h}", kitems, kcams))
        results.setdefault("skipped", {})["kitti"] = kskipped
    elif not args.dev:
        print(f"NOTE: no KITTI road frame with a usable reference in {KITTI}", file=sys.stderr)
    return sims


def evaluate_sets(sets: list, cfg: VPConfig, repeats: int, results: dict) -> None:
    """Ours and the baseline on every set (into ``results["sets"]``), a table row each."""
    print(f"{'set':<26} {'size':>8} {'n':>4}  {'med %w':>7} {'p90 %w':>7} {'ms/img':>8}   accepted: n med p90 | "
          "rejected: n, detection med, fallback med")
    for name, size, items, cam in sets:
        r = evaluate_vps(items, cam, cfg, repeats)
        results["sets"][f"{name}@{size}"] = r
        rel = r["ours"]["reliability"]
        print(_row(f"{name} ours", size, r["ours"]) +
              f"   {rel['accepted']['n']} {rel['accepted']['median_pct_width']} {rel['accepted']['p90_pct_width']} | "
              f"{rel['rejected_detection']['n']}, {rel['rejected_detection']['median_pct_width']}, "
              f"{rel['rejected_fallback']['median_pct_width']}")
        print(_row(f"{name} baseline", size, r["baseline"]))


def print_scenes_and_consistency(S: dict, sims: dict) -> None:
    """The scene bootstrap, the per-scene errors, the tail split, and the camera consistency of the
    simulated sets (added to their results)."""
    print("scenes (frames of one drive <= 1 s apart; paired scene-block bootstrap, 2000 draws, seed 0; 90 % "
          "intervals, % width): p90 ours | p90 baseline | p90 ours - baseline | median ours - baseline")
    for key, r in S.items():
        c = r["scenes"]["ci90"]
        print(f"{key:<26} {r['scenes']['scenes']:>3} scenes  [{c['p90'][0]}, {c['p90'][1]}] | "
              f"[{c['baseline_p90'][0]}, {c['baseline_p90'][1]}] | [{c['p90_minus_baseline'][0]}, "
              f"{c['p90_minus_baseline'][1]}] | [{c['median_minus_baseline'][0]}, {c['median_minus_baseline'][1]}]")
    for key in [k for k in S if k.startswith("camvid/")]:
        print(f"{key} per scene: first..last (n): ours median / max | baseline median / max")
        for ps in S[key]["scenes"]["per_scene"]:
            print(f"  {ps['first']}..{ps['last']} ({ps['n']}): {ps['median_pct_width']} / {ps['max_pct_width']} | "
                  f"{ps['baseline_median_pct_width']} / {ps['baseline_max_pct_width']}")
    print(f"tail (errors > {TAIL_PCT} % width), split by the detector's own score (score_vps): n | search misses "
          "(the reference scores higher: the search missed it) | lines elsewhere (the detection scores higher); "
          "median score(reference) / score(detection)")
    for key, r in S.items():
        t = r["ours"]["tail"]
        ratios = [x["score_reference_over_detection"] for x in t["search_miss"] + t["lines_elsewhere"]
                  if x["score_reference_over_detection"] is not None]
        print(f"{key:<26} {t['n']:>3} | {len(t['search_miss']):>3} | {len(t['lines_elsewhere']):>3} | "
              f"{round(float(np.median(ratios)), 2) if ratios else None}")
    if sims:
        print("camera consistency (ours on the simulated frame vs ours on its source frame carried over exactly; "
              "% width): median p90 | inherited (the source frame's own error carried over): median p90")
    for key, (sim_dir, src_key, items, cam) in sims.items():
        c = camera_consistency(S[src_key]["ours"]["vps"], items, S[key]["ours"]["vps"], sim_dir, cam.size[0])
        S[key]["ours"]["camera_consistency"] = c
        print(f"{key:<26} {c['consistency']['median_pct_width']!s:>7} {c['consistency']['p90_pct_width']!s:>7} | "
              f"{c['inherited']['median_pct_width']!s:>7} {c['inherited']['p90_pct_width']!s:>7}")


def headline(results: dict, dev: bool) -> dict:
    """The figures the results page shows."""
    S = results["sets"]
    real = S.get("camvid/train@480x360" if dev else "camvid/val@480x360")
    head_src = real or S["synthetic@480x360"]
    return {
        "data": ("camvid/train (--dev)" if dev else "camvid/val") if real else "synthetic (../shared/data absent)",
        "n": head_src["ours"]["n"],
        "median_pct_width": head_src["ours"]["median_pct_width"],
        "p90_pct_width": head_src["ours"]["p90_pct_width"],
        "ms_per_image_480": head_src["ours"]["ms_per_image"],
        "ms_per_image_960": S.get("synthetic@960x720", {}).get("ours", {}).get("ms_per_image"),
        "reference_spread_median_pct_width": results.get("reference_spread", {}).get("camvid/val", {}).get("median_pct_width"),
        "reference_spread_p90_pct_width": results.get("reference_spread", {}).get("camvid/val", {}).get("p90_pct_width"),
        "baseline_median_pct_width": head_src["baseline"]["median_pct_width"],
        "baseline_p90_pct_width": head_src["baseline"]["p90_pct_width"],
        "baseline_ms_per_image_480": head_src["baseline"]["ms_per_image"],
        "fallback_loo": {k: {"sequence_median_pct_width": v["sequence_mean"]["median_pct_width"],
                             "sequence_p90_pct_width": v["sequence_mean"]["p90_pct_width"],
                             "dataset_median_pct_width": v["dataset_mean"]["median_pct_width"],
                             "dataset_p90_pct_width": v["dataset_mean"]["p90_pct_width"]}
                         for k, v in results.get("fallback_loo", {}).items()},
        "per_set": {k: {"n": v["ours"]["n"], "median_pct_width": v["ours"]["median_pct_width"],
                        "p90_pct_width": v["ours"]["p90_pct_width"],
                        "baseline_median_pct_width": v["baseline"]["median_pct_width"],
                        "baseline_p90_pct_width": v["baseline"]["p90_pct_width"],
                        "accepted": v["ours"]["reliability"]["accepted"]["n"],
                        "accepted_median_pct_width": v["ours"]["reliability"]["accepted"]["median_pct_width"],
                        "accepted_p90_pct_width": v["ours"]["reliability"]["accepted"]["p90_pct_width"],
                        "scenes": v["scenes"]["scenes"],
                        "p90_ci90": v["scenes"]["ci90"]["p90"],
                        "baseline_p90_ci90": v["scenes"]["ci90"]["baseline_p90"],
                        "p90_minus_baseline_ci90": v["scenes"]["ci90"]["p90_minus_baseline"],
                        "median_minus_baseline_ci90": v["scenes"]["ci90"]["median_minus_baseline"],
                        "tail_n": v["ours"]["tail"]["n"],
                        "tail_search_misses": len(v["ours"]["tail"]["search_miss"]),
                        "rejected": v["ours"]["reliability"]["rejected_detection"]["n"],
                        "rejected_fallback_median_pct_width":
                            v["ours"]["reliability"]["rejected_fallback"]["median_pct_width"],
                        **({f"{m}_{q}_pct_width": v["ours"]["camera_consistency"][m][f"{q}_pct_width"]
                            for m in ("consistency", "inherited") for q in ("median", "p90")}
                           if "camera_consistency" in v["ours"] else {})}
                    for k, v in S.items()},
    }


def main(argv=None) -> int:
    args = parse_args(argv)
    cv2.setNumThreads(1)
    cfg = vp_config(args.set)
    cam480 = PRESETS["camvid"].for_image_size((480, 360))
    cam960 = PRESETS["camvid"]
    results = {"config": asdict(cfg), "threads": 1, "opencv": cv2.__version__, "python": platform.python_version(),
               "seed": 0, "sets": {}}
    print(f"threads: 1 (cv2.setNumThreads(1)); opencv {cv2.__version__}; repeats {args.repeats}", file=sys.stderr)
    sets = [("synthetic", "480x360", synthetic_vp_set(args.n_synthetic, cam480), cam480)]
    if args.n_synthetic_960:
        sets.append(("synthetic", "960x720", synthetic_vp_set(args.n_synthetic_960, cam960, seed=1), cam960))
    val_items = camvid_sets(args, cfg, cam480, results, sets)
    sims = {} if args.no_other_cameras else other_camera_sets(args, val_items, results, sets)
    evaluate_sets(sets, cfg, args.repeats, results)
    print_scenes_and_consistency(results["sets"], sims)
    results["headline"] = headline(results, args.dev)
    out = write_json(Path(args.out), results)
    print(f"wrote {out}", file=sys.stderr)
    print(json.dumps(results["headline"]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
