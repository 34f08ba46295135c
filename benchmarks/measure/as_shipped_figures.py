"""The one-training-camera verdict's figures (benchmarks/other_cameras/as_shipped.py): its test sets,
what a run measured (:class:`Runs`: IoU points per test set, condition and seed), the headline
figures (:func:`headline_studies`, :func:`headline_more`), the targets (:func:`targets_met`) and the
markdown page it prints and writes (:func:`tables`). The script defines and runs the studies and
writes the results; this reads them.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from vctrain.study import DEFAULT_CANVAS

from .data import SIM
from .stats import format_stat, seed_stats
from .studies import camvid_steps_per_epoch

REAL_OTHER = ["cityscapes", "idd", "kitti", "bdd", "lums"]  # real cameras other than CamVid: the headline
EGO = ["cityscapes", "camvid-0001TP"]                       # real cameras that show their own vehicle
ESTIMATED = ["cityscapes", "idd", "bdd"]                    # also with camera: estimate
SIMULATED_SETS = ["sim-" + n for n in SIM]                  # CamVid val through exactly simulated cameras: a
                                                            # known camera to hide from the estimate (default canvas)
TESTS = (["camvid-val", "camvid-0001TP", "camvid-0001TP-noego"] + REAL_OTHER + ["cityscapes-noego"]
         + [c + "-est" for c in ESTIMATED] + [x for n in SIMULATED_SETS for x in (n, n + "-est")])
LOO = ["camvid", "cityscapes", "idd"]                       # leave-one-real-dataset-out
TARGET_GAIN, TARGET_WORST, TARGET_IN_DOMAIN, TARGET_MINUTES = 10.0, -2.0, 85.0, 15.0
ABLATION_TESTS = ["camvid-val", "camvid-0001TP"] + ["cityscapes", "idd", "kitti", "bdd", "lums"]


def stat(v: list[float] | None) -> dict | None:
    """:func:`measure.stats.seed_stats` of IoU points (None without values)."""
    return seed_stats(v) if v else None


def fmt(s: dict | None, signed: bool = False) -> str:
    return format_stat(s, scale=1.0, signed=signed)


def diff(x: list[float] | None, y: list[float] | None) -> list[float] | None:
    """x - y per seed (None unless both have the same seeds)."""
    return [p - q for p, q in zip(x, y)] if x and y and len(x) == len(y) else None


def r2(x: float) -> float:
    return round(float(x), 2)


@dataclass
class Runs:
    """The seeds, conditions and rectangle rules of the three studies, and what they measured: IoU
    points per (test set, condition) and seed (``cell``: study 1, crossval's DEFAULT canvas under the
    plain condition name, every canvas under 'condition@canvas'; ``loo``: study 2; ``abl``: the
    ablation), training minutes, and the own vehicles and cameras crossval found."""
    seeds: list[int]
    loo_seeds: list[int]
    abl_seeds: list[int]
    conds: list[str]
    canvases: list[str]
    cell: dict = field(default_factory=dict)
    loo: dict = field(default_factory=dict)
    abl: dict = field(default_factory=dict)
    minutes: list = field(default_factory=list)
    loo_minutes: list = field(default_factory=list)
    found: dict = field(default_factory=dict)
    estimated: dict = field(default_factory=dict)

    def c(self, t: str, k: str = "within") -> list[float] | None:
        """Study 1's values of test set ``t`` under condition ``k``."""
        return self.cell.get((t, k))

    def pick(self, v: list[float] | None) -> list[float] | None:
        """A study-1 cell's values of the ablation's seeds (None unless study 1 ran every one of them)."""
        return [v[self.seeds.index(k)] for k in self.abl_seeds] if v and all(k in self.seeds for k in self.abl_seeds) \
            else None

    def others(self) -> list[str]:
        """Study 1's 'condition@canvas' columns besides crossval's default canvas."""
        return [f"{k}@{cv}" for cv in self.canvases if cv != DEFAULT_CANVAS for k in self.conds if k != "resize"]

    def loo_diff(self) -> dict:
        """Study 2's within - resize per held-out set."""
        return {t: diff(self.loo.get((t, "within")), self.loo.get((t, "resize"))) for t in LOO}


def headline_studies(r: Runs) -> dict:
    """Study 1's and 2's figures: within - resize on the real other cameras, in domain, per canvas."""
    conds, canvases, loo, c = r.conds, r.canvases, r.loo, r.c
    head: dict = {}
    # within - resize over the real other cameras: per seed the mean over cameras, then over seeds
    per_cam = {t: diff(c(t), c(t, "resize")) for t in REAL_OTHER}
    if all(per_cam.values()):
        real = stat([float(np.mean(v)) for v in zip(*per_cam.values())])
        head["real_within_minus_resize"], head["real_within_minus_resize_std"] = r2(real["mean"]), r2(real["std"])
    for t, v in per_cam.items():
        head[f"real_within_minus_resize_{t}"] = r2(stat(v)["mean"]) if v else None
    lo = r.loo_diff()
    if loo and all(lo.values()):
        s = stat([float(np.mean(v)) for v in zip(*lo.values())])
        head["loo_within_minus_resize"], head["loo_within_minus_resize_std"] = r2(s["mean"]), r2(s["std"])
        for t, v in lo.items():
            head[f"loo_within_minus_resize_{t}"] = r2(stat(v)["mean"])
    for k in conds:
        head[f"in_domain_{k}"] = r2(stat(c("camvid-val", k))["mean"]) if c("camvid-val", k) else None
        head[f"in_domain_0001TP_{k}"] = r2(stat(c("camvid-0001TP", k))["mean"]) if c("camvid-0001TP", k) else None
    head["canvas_default"] = DEFAULT_CANVAS
    for canvas in canvases:  # every canvas against the resize baseline, and footprint against shared
        pc = {t: diff(c(t, f"within@{canvas}"), c(t, "resize")) for t in REAL_OTHER}
        if all(pc.values()):
            head[f"real_within_minus_resize@{canvas}"] = r2(stat([float(np.mean(v)) for v in zip(*pc.values())])["mean"])
        if canvas != "shared":
            pd = {t: diff(c(t, f"within@{canvas}"), c(t, "within@shared")) for t in REAL_OTHER + ["camvid-val",
                                                                                                   "camvid-0001TP"]}
            real = [pd[t] for t in REAL_OTHER]
            if all(real):
                s_ = stat([float(np.mean(v)) for v in zip(*real)])
                head[f"real_{canvas}_minus_shared"], head[f"real_{canvas}_minus_shared_std"] = r2(s_["mean"]), r2(s_["std"])
            for t, v in pd.items():
                head[f"{canvas}_minus_shared_{t}"] = r2(stat(v)["mean"]) if v else None
    return head


def headline_more(r: Runs, head: dict) -> None:
    """Into ``head``: the own vehicle, the estimated cameras, the ablation and the training minutes."""
    abl, c, pick = r.abl, r.c, r.pick
    found = r.found
    for cam in EGO:
        g = diff(c(cam), c(cam + "-noego"))
        head[f"ego_gain_{cam}"] = r2(stat(g)["mean"]) if g else None
    head["ego_rows_found"] = {k: found.get(k, {}).get("ego_rows_at_camera_size", found.get(k, {}).get("ego_rows"))
                              for k in EGO + ["camvid-val"]}
    for cam in ESTIMATED + SIMULATED_SETS:
        e = diff(c(cam + "-est"), c(cam))
        head[f"estimated_minus_given_{cam}"] = r2(stat(e)["mean"]) if e else None
        if cam in ESTIMATED:  # (the simulated sets are test-only: no resize row of their own)
            w = diff(c(cam + "-est"), c(cam, "resize"))
            head[f"within_estimated_minus_resize_{cam}"] = r2(stat(w)["mean"]) if w else None
    sim_e = [diff(c(n + "-est"), c(n)) for n in SIMULATED_SETS]
    if all(sim_e):  # per seed the mean over the simulated cameras, then over seeds
        s_ = stat([float(np.mean(v)) for v in zip(*sim_e)])
        head["estimated_minus_given_simulated"], head["estimated_minus_given_simulated_std"] = (r2(s_["mean"]),
                                                                                                r2(s_["std"]))
    if abl:  # paired per seed over the ablation's seeds (the augmented models of the same seeds)
        ab = lambda t, k="within": abl.get((t, k))
        for name, per in (("noaug_real_within_minus_resize", {t: diff(ab(t), ab(t, "resize")) for t in REAL_OTHER}),
                          ("aug_real_within_minus_resize", {t: diff(pick(c(t)), pick(c(t, "resize"))) for t in REAL_OTHER}),
                          ("noaug_minus_aug_real_within", {t: diff(ab(t), pick(c(t))) for t in REAL_OTHER}),
                          ("noaug_minus_aug_real_resize", {t: diff(ab(t, "resize"), pick(c(t, "resize"))) for t in REAL_OTHER})):
            if all(per.values()):
                s_ = stat([float(np.mean(v)) for v in zip(*per.values())])
                head[name], head[name + "_std"] = r2(s_["mean"]), r2(s_["std"])
        for t in REAL_OTHER:
            v = diff(ab(t), ab(t, "resize"))
            head[f"noaug_within_minus_resize_{t}"] = r2(stat(v)["mean"]) if v else None
    all_minutes = r.minutes + r.loo_minutes
    head["minutes_per_model"] = round(float(np.mean(all_minutes)), 2) if all_minutes else None
    head["minutes_per_model_max"] = round(float(np.max(all_minutes)), 2) if all_minutes else None


def targets_met(head: dict) -> dict:
    """Each target: met (True/False), or None where not measured."""
    worst = min((v for k, v in head.items() if k.startswith("real_within_minus_resize_") and v is not None),
                default=None)
    return {
        "real_within_minus_resize >= +10": head.get("real_within_minus_resize") is not None
        and head["real_within_minus_resize"] >= TARGET_GAIN,
        "no real camera below resize - 2": worst is not None and worst >= TARGET_WORST,
        "loo_within_minus_resize >= +10": None if head.get("loo_within_minus_resize") is None
        else head["loo_within_minus_resize"] >= TARGET_GAIN,  # (None: not measured, --loo-seeds '')
        "camvid-val within >= 85": (head.get("in_domain_within") or 0) >= TARGET_IN_DOMAIN,
        "0001TP within (own vehicle found) >= 85": (head.get("in_domain_0001TP_within") or 0) >= TARGET_IN_DOMAIN,
        "<= 15 minutes per model": head["minutes_per_model_max"] is not None
        and head["minutes_per_model_max"] <= TARGET_MINUTES,
    }


def tables(r: Runs, head: dict, targets: dict) -> str:
    """The markdown page: study 1's table, the canvases, the estimated cameras, study 2 and the ablation."""
    seeds, loo_seeds, abl_seeds, conds, canvases = r.seeds, r.loo_seeds, r.abl_seeds, r.conds, r.canvases
    loo, abl, c, pick = r.loo, r.abl, r.c, r.pick
    lo = r.loo_diff()
    others = r.others()
    lines = [f"Road IoU (%), mean ± std over seeds {seeds}; one model per condition trained on CamVid train minus "
             f"0001TP with `vctrain crossval`'s defaults, scored in each test set's own camera.", "",
             f"`within` is crossval's default rectangle ('canvas: {DEFAULT_CANVAS}'); `within@<canvas>` the others.", "",
             "| test set | " + " | ".join(conds + others) + " | within − resize |",
             "|---|" + "---|" * (len(conds) + len(others) + 1)]
    for t in TESTS:
        res = "resize" if not t.endswith(("-noego", "-est")) else None
        base = t.rsplit("-", 1)[0] if t.endswith(("-noego", "-est")) else t
        if t.startswith("sim-") and not c(t):
            continue  # (study 1 without the default rectangle: no simulated sets)
        lines.append(f"| {t} | " + " | ".join(fmt(stat(c(t, k))) for k in conds + others) + " | "
                     + fmt(stat(diff(c(t), c(base if res is None else t, "resize"))), signed=True) + " |")
    for canvas in canvases:
        if canvas != "shared" and f"real_{canvas}_minus_shared" in head:
            lines += ["", f"Rectangle '{canvas}' against 'shared' (within, paired per seed), real other cameras: "
                          f"{head[f'real_{canvas}_minus_shared']:+.1f} ± {head[f'real_{canvas}_minus_shared_std']:.1f}."]
    est = [(t, stat(diff(c(t + "-est"), c(t)))) for t in ESTIMATED + SIMULATED_SETS]
    if any(v for _, v in est):
        lines += ["", "Estimated camera against the given one (within, paired per seed; the simulated cameras' "
                      "files are exact, the IDD and BDD files are assumptions): "
                  + ", ".join(f"{t} {fmt(v, signed=True)}" for t, v in est if v) + "."]
    if "real_within_minus_resize" in head:
        lines += ["", f"Real other cameras ({', '.join(REAL_OTHER)}): within − resize "
                      f"{head['real_within_minus_resize']:+.1f} ± {head['real_within_minus_resize_std']:.1f} "
                      "(per seed the mean over the cameras)."]
    if loo:
        lines += ["", f"Leave one real dataset out (trained on the other two, {camvid_steps_per_epoch()} steps an "
                      f"epoch; seeds {loo_seeds}):", "", "| held out | " + " | ".join(conds) + " | within − resize |",
                  "|---|" + "---|" * (len(conds) + 1)]
        for t in LOO:
            lines.append(f"| {t} | " + " | ".join(fmt(stat(loo.get((t, k)))) for k in conds) + " | "
                         + fmt(stat(lo.get(t)), signed=True) + " |")
    if abl:
        lines += ["", f"Without geometric augmentation (random scale about the VP and shift off, both conditions; "
                      f"seeds {abl_seeds}), against the default recipe's models of the same seeds:", "",
                  "| test set | within | resize | within − resize | within: noaug − aug | resize: noaug − aug |",
                  "|---|---|---|---|---|---|"]
        for t in ABLATION_TESTS:
            ab_w, ab_r = abl.get((t, "within")), abl.get((t, "resize"))
            lines.append(f"| {t} | {fmt(stat(ab_w))} | {fmt(stat(ab_r))} | {fmt(stat(diff(ab_w, ab_r)), signed=True)} | "
                         f"{fmt(stat(diff(ab_w, pick(c(t)))), signed=True)} | "
                         f"{fmt(stat(diff(ab_r, pick(c(t, 'resize')))), signed=True)} |")
    lines += ["", "| target | met |", "|---|---|"] + [f"| {k} | {'not measured' if v is None else 'yes' if v else 'no'} |"
                                                         for k, v in targets.items()]
    return "\n".join(lines) + "\n"
