"""The results page's sections of the multi-camera benchmarks (issue 34): leave one camera out, the
shipped model, fine-tuning, the LOO diagnosis and adaptation without labels."""
from __future__ import annotations

from .format import _mean_std, num, pct, r_generic, table


def r_multi_camera(d: dict) -> list[str]:
    """Leave one real camera out (benchmarks/other_cameras/multi_camera.py): cells are IoU points per seed (None: not run yet)."""
    c, seeds = d["cells"], d.get("seeds", [])
    have = lambda v: [x for x in (v or []) if x is not None]  # noqa: E731
    pair = lambda t: [w - r for w, r in zip(c.get(f"{t}|within") or [], c.get(f"{t}|resize") or [])  # noqa: E731
                      if w is not None and r is not None]
    out = [f"Road IoU (%), mean ± std over the seeds finished of {seeds}; each fold trained on the other four real "
           f"datasets merged into one virtual camera (`balance: datasets`, {d.get('steps_per_epoch')} steps an "
           "epoch), tested on all frames of the held-out camera in that camera"
           + (f"; {', '.join(d['test_only'])} by the model trained on all five" if d.get("test_only") else "")
           + ". within − resize paired per seed.",
           ""]
    out += table(["held out", "within", "resize", "within − resize", "seeds done (within, resize)"],
                 [[t, _mean_std(have(c.get(f"{t}|within"))), _mean_std(have(c.get(f"{t}|resize"))),
                   _mean_std(pair(t), signed=True),
                   f"{len(have(c.get(f'{t}|within')))}, {len(have(c.get(f'{t}|resize')))}"]
                  for t in d.get("held_out", []) + d.get("test_only", [])])
    h = d["headline"]
    if h.get("loo_within_minus_resize") is not None:
        out += [f"Mean over the {len(d.get('held_out') or [])} held-out cameras (per seed, seeds {h.get('loo_complete_seeds')}): "
                f"**{h['loo_within_minus_resize']:+.1f} ± {h['loo_within_minus_resize_std']:.1f}**.", ""]
    if h.get("folds_missing"):
        out += [f"Not finished yet: {', '.join(h['folds_missing'])}.", ""]
    if d.get("targets"):
        out += table([f"target (issue {d.get('issue', 34)})", "met"], [[k, "not measured" if v is None else num(v)]
                                                   for k, v in d["targets"].items()])
    return out + r_generic({"headline": {k: v for k, v in h.items() if k != "folds_missing"}})


def r_merged_estimated(d: dict) -> list[str]:
    """Leave one camera out with the guessed cameras estimated (benchmarks/archive/other_cameras/merged_estimated.py)."""
    cams = [[k, num(v["fx"], 1), num(v["height"], 2), num(v["tilt"], 1), num(v["pan"], 1), num(v["ego_rows"]),
             "x".join(map(str, v["size"]))] for k, v in d.get("cameras", {}).items()]
    return (["The guessed camera files (" + ", ".join(d.get("guessed", [])) + ") replaced by estimates: a training "
             "set's from its frames and labels, the held-out set's from its frames only (as `vctrain predict --camera "
             f"estimate`); network {d.get('model')}, rectangle rule {d.get('extent')}.", ""]
            + r_multi_camera(d) + table(["estimated camera", "fx px", "height m", "tilt deg", "pan deg",
                                         "own-vehicle rows", "size"], cams))


def r_shipped_model(d: dict) -> list[str]:
    """The shipped model (benchmarks/what_a_user_gets/shipped_model.py): one model, each development set's held-out split."""
    h, t = d["headline"], d.get("targets", {})
    out = [f"One model trained on the five development sets' training splits (`balance: datasets`, "
           f"{d.get('epochs')} epochs of {d.get('steps_per_epoch')} steps, seed {d.get('seed')}), road IoU (%) on each "
           "set's held-out split in its own camera; KITTI never trained on. The resize twin: the same network, "
           "frames, steps and sampling, the images resized.", ""]
    sh = h.get("shipped_condition", "within")
    pr = any(k.startswith("precision_") for k in h)  # precision and recall beside the IoU (issue 59; later runs)
    out += table(["held-out split", "within" + (" (shipped)" if sh == "within" else ""),
                  "resize twin" + (" (shipped)" if sh == "resize" else ""), "within − resize"]
                 + (["precision / recall (shipped)"] if pr else []),
                 [[k, num(h.get(f"within_{k}")), num(h.get(f"resize_{k}")), num(h.get(f"within_minus_resize_{k}"))]
                  + ([f"{num(h.get(f'precision_{sh}_{k}'))} / {num(h.get(f'recall_{sh}_{k}'))}"] if pr else [])
                  for k in d.get("sets", [])])
    out += [f"Mean over the splits: within {num(h.get('mean_within'))}, resize {num(h.get('mean_resize'))}; shipped "
            f"(the higher mean): **{sh}**. Checkpoint {num(h.get('checkpoint_mb'))} MB; predict per 1280×720 frame "
            f"(1 / 2 threads): within (warp, network, back-projection) {num(h.get('predict_ms_1280x720_within_t1'))} / "
            f"{num(h.get('predict_ms_1280x720_within_t2'))} ms, resize {num(h.get('predict_ms_1280x720_resize_t1'))} / "
            f"{num(h.get('predict_ms_1280x720_resize_t2'))} ms.", ""]
    return out + table(["target (issue 34)", "met"], [[k, "not measured" if v is None else num(v)] for k, v in t.items()])


def r_shipped_screen(d: dict) -> list[str]:
    """The shipped model's appearance levers (benchmarks/archive/what_a_user_gets/shipped_screen.py): each variant's resize
    twin against today's recipe (the baseline) trained in the same run; the script writes its .md with this."""
    rows, base, sets = d["rows"], d["baseline"], d["sets"]
    pr = lambda r, t: f"{num(r['iou'][t], 1)} ({num(r['precision'][t], 1)} / {num(r['recall'][t], 1)})"  # noqa: E731
    out = [f"The shipped recipe's resize twin, one model a variant on the five development sets' training splits "
           f"({d['epochs']} epochs, seed {d['seed']}); road IoU % (precision / recall) on each held-out split; baseline "
           f"`{base}` (today's recipe) in the same run.", ""]
    out += table(["variant"] + sets + ["mean", "− baseline", "predict ms (1 thread)", "minutes"],
                 [[v] + [pr(r, t) for t in sets] + [f"**{num(r['mean'], 1)}**",
                  "-" if v == base else f"{r['mean'] - rows[base]['mean']:+.1f}", num(r["predict_ms_t1"], 1),
                  num(r["minutes"], 1)] for v, r in rows.items()])
    names = next(iter(d["targets"].values()), {})
    return out + table(["variant"] + list(names), [[v] + [num(ok) for ok in t.values()] for v, t in d["targets"].items()])


def r_ship_geometry(d: dict) -> list[str]:
    """Ship geometry if it wins (benchmarks/what_a_user_gets/ship_geometry.py): the recipe trained both ways on the
    six development sets against today's shipped model on the same test stores; the script writes its .md with this."""
    cells, h = d["cells"], d["headline"]
    f = lambda v: "-" if not v else (_mean_std(v) if len(v) > 1 else f"{v[0]:.1f}")  # noqa: E731
    g = lambda a, b: "-" if not a or not b else f"{sum(a) / len(a) - sum(b) / len(b):+.1f}"  # noqa: E731
    out = [f"Ship geometry (issue 73 item 4): `{d['model']}` trained on the six development sets' training splits "
           f"({d['epochs']} epochs, seeds {', '.join(map(str, d['seeds']))}), road IoU % on each held-out split in its "
           "own camera; today's shipped model scored on the same test stores in the same run.", ""]
    rows = []
    for t in d["sets"] + d.get("estimated", []):
        w, r, s = (cells[k].get(t) for k in ("within", "resize", "shipped"))
        rows.append([t, f(w), f(r), f(s), g(w, s), g(w, r)])
    out += table(["held-out split", "within", "resize twin", "shipped today", "within − shipped", "within − resize"], rows)
    out += [f"Mean over the {len(d['sets'])} held-out splits (the `-est` rows beside, not in it): " + ", ".join(
        f"{k} {h.get(f'mean_{k}', '-')}" for k in ("within", "resize", "shipped")) + ".", ""]
    out += table(["rule", "met"], [[k, num(v)] for k, v in h["rule"].items()])
    return out + [f"Decision: {h['decision']}."]


def r_finetune(d: dict) -> list[str]:
    """Fine-tuning on 20 labelled frames of a camera the model has not seen (benchmarks/archive/what_a_user_gets/finetune.py)."""
    c, seeds, h = d["cells"], d.get("seeds", []), d["headline"]
    split = d.get("split", "LUMS: captures 400–466; scored on the 118 frames of the other captures")
    out = [f"{d.get('n_train')} labelled frames, {split}; model `{d.get('model')}`; recipe {str(d.get('epochs')).split(',')[0]} "
           f"epochs, fine-tuned at lr ×{str(d.get('lr_factors', '0.1')).split(',')[0]}; road IoU (%) per seed {seeds}.", ""]
    out += table(["condition"] + [f"seed {s}" for s in seeds] + ["mean"],
                 [[k] + [num(x) for x in v] + [num(h.get(k, sum(v) / len(v)))] for k, v in c.items()])
    if d.get("base_heldout"):
        out += ["The model as it is, on the shipped model's held-out splits (road IoU %): "
                + ", ".join(f"{k} {v:.1f}" for k, v in d["base_heldout"].items()) + ".", ""]
    return out + table(["target (issue 34)", "met"], [[k, num(v)] for k, v in d.get("targets", {}).items()])


def r_own_frames(d: dict) -> list[str]:
    """A user's own labelled frames: zero-shot, fine-tuned, the card's old command, from ImageNet
    (benchmarks/what_a_user_gets/own_frames.py)."""
    h, frames = d["headline"], d["frames"].split(",")
    out = [f"{d['split']}; model `{d['model']}` ({'a camera it never saw' if d.get('unseen') else 'a camera it knows'}); "
           f"seeds {d['seeds']}" + (f" ({d['large_seeds']} for the frame counts beyond the controls')"
                                     if d.get("large_seeds") not in (None, d["seeds"]) else "")
           + f"; road IoU % (precision / recall) as the mean over seeds, and the minutes a fit took on 2 cores."
           + (f" Fine-tuned with `{d['fit_args']}`." if d.get("fit_args") else ""), ""]
    rows = []
    for cond, by_n in d["cells"].items():
        row = [cond]
        for n in frames:
            row.append("-" if n not in by_n else
                       f"**{num(h[f'{cond}_n{n}_iou'])}** ({h[f'{cond}_n{n}_precision']:.0f} / {h[f'{cond}_n{n}_recall']:.0f}; "
                       f"{h[f'{cond}_n{n}_minutes']:.1f} min)")
        rows.append(row)
    out += table(["condition"] + [f"{n} frames" for n in frames], rows)
    gains = [f"{n} frames {h[f'fine-tuned_minus_zero-shot_n{n}']:+.1f} ± {h[f'fine-tuned_minus_zero-shot_n{n}_std']:.1f} "
             f"(worst seed {h[f'fine-tuned_minus_zero-shot_n{n}_min']:+.1f})" for n in frames
             if f"fine-tuned_minus_zero-shot_n{n}" in h]
    if gains:
        out += ["Fine-tuned − zero-shot, paired per seed: " + "; ".join(gains) + ".", ""]
    return out + table(["target (issue 60)", "met"], [[k, num(v)] for k, v in d.get("targets", {}).items()])


def r_route_finetune(d: dict) -> list[str]:
    """Fine-tuning the README route's own model: in its virtual camera or the new camera's design,
    against the model as it is and the route on the new frames alone (route_finetune.py)."""
    h, frames = d["headline"], [str(n) for n in d["frames"]]
    out = [f"{d['split']}; the README route's model (CamVid train minus 0001TP) of each seed {d['seeds']}; road IoU % "
           "(precision / recall; per seed; minutes a fit on 2 cores; the gain over zero-shot paired per seed).", ""]
    rows = []
    for cond, by_n in d["cells"].items():
        rows.append([cond] + [
            f"**{num(h[f'{cond}_n{n}_iou'])}** ({h[f'{cond}_n{n}_precision']:.0f} / {h[f'{cond}_n{n}_recall']:.0f}; "
            + " / ".join(f"{r['iou']:.1f}" for r in by_n[n]) + f"; {h[f'{cond}_n{n}_minutes']:.1f} min"
            + (f"; {h[f'{cond}_minus_zero_n{n}']:+.1f}" if f"{cond}_minus_zero_n{n}" in h else "") + ")"
            for n in frames])
    out += table(["condition"] + [f"{n} frames" for n in frames], rows)
    if d["set"] == "camvid":  # the model's virtual camera is the design from this very camera
        out += ["On the camera the model was trained on both warps build the same store: the model's virtual "
                "camera is the design from that camera.", ""]
    return out + table(["target (issue 60)", "met"], [[k, num(v)] for k, v in d.get("targets", {}).items()])


def r_low_camera(d: dict) -> list[str]:
    """A camera lower than the training one: each ``--beyond`` rule on LUMS and on CamVid val declared
    lower (benchmarks/archive/other_cameras/low_camera.py)."""
    iou, seeds = d["iou"], d["seeds"]
    names = list(dict.fromkeys(k.split("|")[0] for k in iou))
    rules = list(dict.fromkeys(k.split("|")[1] for k in iou))
    out = [f"The README route's models (CamVid train minus 0001TP, the camvid camera at 1.21 m), seeds {seeds}; "
           "road IoU % as the mean over seeds (per seed in brackets). `sim-<h>`: CamVid val with the camera "
           "declared at h metres (exact: the same frames from a camera at h in a world scaled by h / 1.21); the "
           "resize twin sees the same pixels at every h.", ""]
    out += table(["`--beyond`"] + names, [[r] + [f"{num(sum(iou[f'{n}|{r}']) / len(iou[f'{n}|{r}']))} ("
                                                  + " / ".join(f"{x:.1f}" for x in iou[f"{n}|{r}"]) + ")"
                                                  for n in names] for r in rules])
    rows = []
    for r in rules:
        per_seed = d["bands"].get(f"lums|{r}")
        if per_seed:
            acc = [[sum(s[b][k] for s in per_seed) for k in (0, 1)] for b in range(len(per_seed[0]))]
            rows.append([r] + [num(100 * i / max(u, 1)) for i, u in acc])
    if rows:
        out += ["LUMS, road IoU % in the bands of the lower half of the frame (top to bottom):", ""]
        out += table(["`--beyond`"] + [f"rows {4 + b}/8" for b in range(len(rows[0]) - 1)], rows)
    return out


def r_loo_diagnose(d: dict) -> list[str]:
    h = d["headline"]
    out = [f"Held out {d['heldout']}, seed {d['seed']}, {h['frames']} frames: road IoU within {pct(h['iou']['within'])} "
           f"(precision {pct(h['precision']['within'])}, recall {pct(h['recall']['within'])}), resize "
           f"{pct(h['iou']['resize'])} ({pct(h['precision']['resize'])}, {pct(h['recall']['resize'])}). Road pixels no "
           f"store pixel reaches: {pct(h['road_uncovered_share'])} %; road within misses inside the covered part: "
           f"{pct(h['road_missed_inside_coverage_share'])} %. Within at a multiple of its working size: "
           + ", ".join(f"{s}x {pct(v)}" for s, v in h["within_iou_by_scale"].items()) + ".", ""]
    n = len(h["fn_share_by_band"]["within"])
    rows = [[f"{what}, {k} (%)"] + [pct(v) for v in h[key][k]]
            for what, key in (("missed road", "fn_share_by_band"), ("false road", "fp_share_by_band"))
            for k in ("within", "resize")]
    return out + table(["band, top to bottom"] + [str(i + 1) for i in range(n)], rows)


def r_adapt_loo(d: dict) -> list[str]:
    """Adapting without labels on LOO folds (benchmarks/archive/other_cameras/adapt_loo.py): per seed, and the mean."""
    conds = ["resize", "resize-self", "resize-fuse", "within", "adapt", "adapt-fuse", "adapt-self"]
    seeds = d.get("seeds", [d.get("seed")])
    per = d.get("per_seed") or {str(seeds[0]): d["cells"]}
    out = [f"Leave-one-camera-out folds, seeds {seeds}; every adaptation on the held-out frames it is scored on, "
           f"without their labels (tri-mask {d['lo']:g}/{d['hi']:g}); road IoU (%).", ""]
    rows = []
    for f in d["folds"]:
        rows += [[f, str(s)] + [num(per[str(s)][f].get(k)) for k in conds] for s in seeds]
        if len(seeds) > 1:
            rows.append([f, "mean"] + [num(d["cells"][f].get(k)) for k in conds])
    return out + table(["held out", "seed"] + conds, rows)
