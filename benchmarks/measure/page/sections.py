"""The results page's sections (benchmarks/results_page.py): one renderer per benchmark JSON (``RENDER``:
the JSON's stem, or a stem's beginning ending in "_", -> the Markdown lines of its figures; :func:`renderer`
picks; :func:`r_generic` for a JSON without one). Number formats: measure/page/format.py; the
multi-camera benchmarks' renderers: measure/page/multi_camera.py."""
from __future__ import annotations

import statistics
from typing import Callable

from .format import _mean_std, median3, ms, num, pct, r_generic, table
from .multi_camera import (r_adapt_loo, r_finetune, r_merged_estimated, r_multi_camera, r_low_camera, r_own_frames,
                           r_loo_diagnose, r_route_finetune, r_ship_geometry, r_shipped_model, r_shipped_screen)


# ---------------------------------------------------------------- one renderer per benchmark

def r_warp(d: dict) -> list[str]:
    rows = []
    for k, v in d["detail"].items():
        rows.append([num(v["store_size"]), num(v["frames"]), num(median3(v["bare_ms"]), 3),
                     num(median3(v["ours_ms"]), 3), num(v["ratio"], 3), num(v["cold_ms"], 1)])
    return table(["store size", "frames", "bare cv2.warpPerspective ms", "ours ms", "ours / bare",
                  "building the maps ms (once per camera)"], rows)


def r_completion(d: dict) -> list[str]:
    rows = []
    for k in ("eighth", "full"):
        v = d[k]
        lo, hi = v["ratio_spread"]
        bare = statistics.median(f["bare"]["median_ms"] for f in v["frames"])
        cpu = [num(v[c]) if c in v else "-" for c in ("ratio_cpu", "ratio_torch_cpu")]
        rows.append([num(v["store_size"]), num(v["source_size"]), num(len(v["frames"])), num(bare, 2),
                     f"{v['ratio']:.2f} ({lo:.2f}–{hi:.2f})", *cpu, num(v["back_ratio"]), num(v["cold_ratio"], 1)])
    load = f" 1-minute load average at the end: {num(d['loadavg_1min'])}." if "loadavg_1min" in d else ""
    return table(["store size", "source size", "frames", "bare warp ms", "warp + completion / bare warp, wall (spread)",
                  "the same, CPU time", "torch loaded, CPU time", "back-projection / bare", "cold maps / bare"],
                 rows) + [
        "Warp + completion as `vcprep` runs it (its fill gathers with cv2) and with torch loaded (vctrain: "
        "`torch.index_select`); one thread; medians, the candidates interleaved; the CPU time leaves out the "
        f"time other processes held the core. Target <= 1.3 (issue 81).{load}", ""]


def r_predict_whole(d: dict) -> list[str]:
    said = lambda r: "-" if r.get("load_s") is None else f"{num(r['load_s'], 1)} / {num(r['compile_s'], 1)}"  # noqa: E731
    rows = [[r["size"] + (f" (decoded {r['decoded']})" if r.get("decoded", r["size"]) != r["size"] else ""),
             r["engine"], "yes" if r["overlay"] else "no", " / ".join(num(t, 1) for t in r["wall_s"]),
             "-" if r["fps_steady"] is None else num(r["fps_steady"], 1),
             "-" if r["startup_s"] is None else num(r["startup_s"], 1), said(r), num(r["fps_whole"], 1)]
            for r in d["rows"]]
    n1, n2 = d["rows"][0]["frames"] if d["rows"] else ("?", "?")
    return table(["size", "engine", "overlay", f"wall s ({n1} / {n2} frames)", "steady frames/s", "start-up s",
                  "said: load / export+compile s", f"frames/s of the {n2}-frame run"], rows) + [
        "`vctrain predict MODEL VIDEO` as typed, a fresh process per run (engine `default`: no `--engine`); "
        "steady = the difference of the two lengths, start-up = the rest (imports included); said = what the "
        "longer run recorded in predict.json. Load average before / after: "
        + " / ".join(num(x, 1) for x in d.get("load_average", [])) + ".", ""]


def r_store(d: dict) -> list[str]:
    own = d.get("process_cpu_ms_per_item", {})
    rows = [[k, num(v["median_s"], 3), num(d["items_s"].get(k), 1) if k in d["items_s"] else "-",
             num(d["cores_busy"].get(k)), num(d["machine_busy_ms_per_item"].get(k), 1),
             num(own.get(k), 1) if k not in ("jobs2", "cpu2") else "-"]  # (a pool's workers are other processes)
            for k, v in d["stages"].items()]
    out = table(["stage", "median s", "items/s", "cores busy", "machine busy ms per item",
                 "this process's CPU ms per item"], rows)
    tg = d.get("targets", {})
    ratios = [[k, num(d[k]), tg.get(k, "reported")] for k in
              ("jobs2_speedup", "ratio_vs_png_io", "ratio_vs_png_io_paired", "ratio_vs_png_io_cpu", "ratio_vs_same_encoder",
               "control_cpu_speedup") if k in d]
    return out + table(["figure", "measured", "target"], ratios) + [
        f"{d['frames']} frames {num(d['source_size'])} → store {num(d['store_size'])}, completion "
        f"{d['completion']}, {d['repeats']} repeats; 1-minute load average recorded: "
        f"{', '.join(num(x) for x in d.get('loadavg_1min', []))}."
        + (f" PNG deflate: {d['deflate']}." if d.get("deflate") else ""), ""]


def r_png_deflate(d: dict) -> list[str]:
    """The PNG writer's deflate candidates per content kind (benchmarks/speed/png_deflate.py)."""
    t = d["ms_kb"]
    kinds = list(t)
    rows = [[name] + [f"{num(t[k][name]['ms'])} / {num(t[k][name]['kb'], 1)}" for k in kinds] for name in t[kinds[0]]]
    det = [[n, num(v["processes"]), num(v["items"]), ",".join(map(str, v["levels"])), num(v["max_distinct_streams"]),
            num(v["threads_agree"])] for n, v in d["determinism"].items()]
    w = d["writer"]["kinds"]
    return table(["encoder: ms / KB per image"] + [f"{k} {d['shapes'][k][1]}×{d['shapes'][k][0]}" for k in kinds], rows) + table(
        ["deflate", "fresh processes", "items", "levels", "distinct streams per item (max)", "threads agree"], det) + [
        f"Writer: {d['writer']['deflate']}, (filter, level) per kind {', '.join(f'{k} {v[0]} {v[1]}' for k, v in w.items())}; "
        f"versions {', '.join(f'{k} {v}' for k, v in d['versions'].items())}; items {', '.join(f'{k} {v}' for k, v in d['items'].items())}; "
        f"1-minute load average {num(d['loadavg_1min'])} at the end (other jobs on the machine can slow some "
        f"encoders far more than others: compare within one run).", ""]


def r_stages(d: dict) -> list[str]:
    h, paper = d["headline"], d["paper_ms"]
    rows = [[k, num(h[f"{k}_ms"]), num(paper.get(k))] for k in
            ("line_detection", "vp", "projection", "completion", "inference", "back_projection")]
    rows.append(["completion (cached, one H for all frames)", num(h["completion_cached_ms"]), "-"])
    rows.append(["total", num(h["total_ms"]), "-"])
    return table(["stage", "ours ms per image", "paper ms (other hardware, not comparable)"], rows) + [
        f"Store size {num(h['store_size'])}, threads {h['threads']}.", ""]


def r_train(d: dict) -> list[str]:
    h, det = d["headline"], d["detail"]
    rows = [[name, pct(v["val_iou"]), pct(v["val_f1"]), pct(v["maxf"]), num(v["train_images_per_s"], 1),
             num(v["fit_seconds"] / 60, 1)] for name, v in det.items()]
    return table(["model", "val road IoU %", "val F1 %", "MaxF %", "train images/s", "fit minutes"], rows) + [
        f"{h['model']}, {h['epochs']} epochs, threads: {h['threads']}.", ""]


def r_vp(d: dict) -> list[str]:
    per = d["headline"]["per_set"]
    rows = []
    for name, v in per.items():
        s = d["sets"][name]
        rows.append([name, num(v["n"]), f"{v['median_pct_width']:.2f} / {v['p90_pct_width']:.2f}",
                     f"{v['baseline_median_pct_width']:.2f} / {v['baseline_p90_pct_width']:.2f}",
                     f"{v['accepted']} of {v['n']}", num(s["ours"]["ms_per_image"], 1),
                     num(s["baseline"]["ms_per_image"], 1), num(v.get("scenes")),
                     "[{:.2f}, {:.2f}]".format(*v["p90_minus_baseline_ci90"]) if "p90_minus_baseline_ci90" in v
                     else "-"])
    out = ["Error in % of the image width, median / p90; ms per image on one thread.", ""]
    out += table(["set", "frames", "ours", "baseline (LSD + RANSAC)", "accepted", "ours ms", "baseline ms",
                  "scenes", "p90 ours − baseline, 90 % scene-bootstrap interval"], rows)
    cons = [[name, f"{v['median_pct_width']:.2f} / {v['p90_pct_width']:.2f}",
             f"{v['consistency_median_pct_width']:.2f} / {v['consistency_p90_pct_width']:.2f}",
             f"{v['inherited_median_pct_width']:.2f} / {v['inherited_p90_pct_width']:.2f}"]
            for name, v in per.items() if "consistency_median_pct_width" in v]
    if cons:
        out += ["Simulated cameras: our VP against our VP on the source frame carried over by the exact homography "
                "(consistency), and the source frame's own error carried over (inherited):", ""]
        out += table(["set", "error vs reference", "consistency", "inherited"], cons)
    loo = d.get("fallback_loo")
    if loo:
        out += ["Fallback VP, leave-one-out (each referenced frame treated as rejected):", ""]
        out += table(["split", "frames detected", "rejected", "mean of its sequence", "mean of the dataset"],
                     [[k, num(v["frames_detected"]), num(v["rejected_in_split"]),
                       f"{v['sequence_mean']['median_pct_width']:.2f} / {v['sequence_mean']['p90_pct_width']:.2f}",
                       f"{v['dataset_mean']['median_pct_width']:.2f} / {v['dataset_mean']['p90_pct_width']:.2f}"]
                      for k, v in loo.items()])
    spread = d.get("reference_spread")
    if spread:
        out += ["Spread of the reference VP itself (its fitting band changed):", ""]
        out += table(["split", "frames", "median / p90"],
                     [[k, num(v["n"]), f"{v['median_pct_width']:.2f} / {v['p90_pct_width']:.2f}"]
                      for k, v in spread.items()])
    return out


def r_cross_camera(d: dict) -> list[str]:
    return table(["condition", "mean road IoU % over the held-out cameras"], [[k, pct(v)] for k, v in d.items()]) + [
        "Per held-out camera: [`cross_camera.md`](../benchmarks/other_cameras/results/cross_camera.md).", ""]


def r_real_cameras(d: dict) -> list[str]:
    conds = d["conditions"]
    groups = set(d.get("groups", {}))
    wmr = d.get("within_minus_resize", {})
    rows = []
    for name, cells in d["cells"].items():
        label = f"**{name}** (mean)" if name in groups else name
        rows.append([label, num(d.get("test_frames", {}).get(name, "")) if name not in groups else ""]
                    + [ms(cells.get(c)) for c in conds] + ([ms(wmr.get(name), signed=True)] if wmr else []))
    out = [f"Road IoU (%) in each test set's own camera, mean ± std over seeds {','.join(map(str, d['seeds']))}.", ""]
    out += table(["test set", "frames"] + conds + (["within − resize"] if wmr else []), rows)
    ns = d.get("no_shift", {})
    if ns.get("cost"):
        sets = list(ns["cost"])
        out += ["The camera change alone: each model's score on the simulated camera minus its score on the same "
                "pixels without a camera change (its prediction on the CamVid val frame carried over by the exact "
                "homography), IoU points:", ""]
        out += table(["simulated set"] + [f"{c}: no change" for c in conds] + [f"{c}: cost" for c in conds],
                     [[s] + [ms(ns.get("reference", {}).get(s, {}).get(c)) for c in conds]
                      + [ms(ns["cost"][s].get(c), signed=True) for c in conds] for s in sets])
    if ns.get("exact_vp"):
        out += ["`within` with each simulated frame's exact pose instead of its estimated road VP (same models):", ""]
        out += table(["simulated set", "exact pose", "estimated − exact"],
                     [[s, ms(v.get("exact")), ms(v.get("cost"), signed=True)] for s, v in ns["exact_vp"].items()])
    tg = d.get("targets", {})
    if tg:
        out += table(["target", "met", "value"],
                     [[k, "yes" if v.get("pass") else "no",
                       "; ".join(f"{kk} {pct(vv) if isinstance(vv, float) and kk in ('value',) else num(vv, 3)}"
                                 for kk, vv in v.items() if kk not in ("pass", "values"))
                       or ", ".join(f"{kk} {pct(vv)}" for kk, vv in v.get("values", {}).items())]
                      for k, v in tg.items()])
    models = d.get("models", [])
    if models:
        out += table(["seed", "condition", "train minutes", "best epoch", "input size", "crop", "images/s",
                      "data pipeline ratio"],
                     [[num(m["seed"]), m["condition"], num(m["train_minutes"], 1),
                       f"{m['best_epoch']} of {m['epochs']}", num(m["input_size"]), num(m.get("crop_size")),
                       num(m["train_images_per_s"], 1), num(m["pipeline_ratio"])] for m in models])
    ts, st = d.get("train_settings", {}), d.get("study", {})
    if ts:
        out += [f"Training: recipe {ts.get('recipe')}, {ts.get('arch')}, {ts.get('epochs')} epochs, "
                f"{ts.get('optimizer')} lr {ts.get('lr')}, batch {ts.get('batch_size')}, crop {num(ts.get('crop'), 4)}. "
                f"Virtual camera: {st.get('virtual')}, pan ±{st.get('pan_range')}°, tilt ±{st.get('tilt_range')}°, "
                f"{st.get('above')}° above the horizon, {num(d.get('virtual', {}).get('image_size'))} at scale "
                f"{num(d.get('scale'), 4)}; store pixels {st.get('store_pixels')}. Threads {d.get('threads')}.", ""]
    return out


def r_camera_estimate(d: dict) -> list[str]:
    h = d["headline"]
    split = ("real", "no_estimate", "real_depth_scale_err_pct", "real_depth_scale_err_pct_height_assumed", "road_width_m")
    out = r_generic({"headline": {k: v for k, v in h.items() if k not in split}})
    real = h.get("real", {})
    if real:
        depth, assumed = h.get("real_depth_scale_err_pct", {}), h.get("real_depth_scale_err_pct_height_assumed", {})
        out += ["Real cameras against their given calibration (tilt error in degrees, horizon error in % of "
                "the height, both with fx given); with nothing given but the labels, the error of the road "
                "plane's depth scale fy x height (%) with the height from the road footprint and with the "
                "height assumed:", ""]
        out += table(["set", "tilt error", "horizon error %", "depth scale % (road footprint)",
                      "depth scale % (height assumed)"],
                     [[k, num(v.get("tilt_err")), num(v.get("horizon_err_pct")), num(depth.get(k)), num(assumed.get(k))]
                      for k, v in real.items()])
    if h.get("road_width_m"):
        out += ["", "Median visible road width under the true calibration (what the footprint height's "
                f"{h.get('road_width_constant_m')} m stands for): " + ", ".join(
                    f"{k} {v['median_m']} m ({v['frames']} frames)" for k, v in h["road_width_m"].items()) + ".", ""]
    return out


def r_focal_from_verticals(d: dict) -> list[str]:
    out = r_generic(d)
    cell = lambda e: "-" if not e else f"{e['err_pct']:+.1f} [{e['interval_pct'][0]:+.0f}, {e['interval_pct'][1]:+.0f}]"
    out += ["", "fy from the road VP and the vertical VP (error %, [68 % bootstrap interval]); information: the "
            "pooled cost curve's relative depth (0: the frames say nothing about fy):", ""]
    out += table(["set", "tilt°", "true fy", "horizon exact", "information", "detected VPs", "information",
                  "VPs", "60° assumed: fx err %", "fy err %"],
                 [[k, f"{r['tilt']:+.1f}", f"{r['true_fy']:.0f}", cell(r["exact_horizon"]),
                   f"{r['exact_horizon']['information']:.2f}", cell(r["detected_vp"]),
                   "-" if not r["detected_vp"] else f"{r['detected_vp']['information']:.2f}",
                   f"{r['vps_accepted']}/{r['frames']}", f"{r['assumed_fx_err_pct']:+.1f}",
                   f"{r['assumed_fy_err_pct']:+.1f}"] for k, r in d.get("sets", {}).items()])
    return out


AS_SHIPPED_ROWS = [  # (test set, what it is)
    ("camvid-val", "CamVid val (in domain)"),
    ("camvid-0001TP", "CamVid 0001TP (unseen rig), own vehicle found from the labels"),
    ("camvid-0001TP-noego", "CamVid 0001TP, own vehicle not said"),
    ("cityscapes", "Cityscapes, its calibration, own vehicle found from the labels"),
    ("idd", "IDD-Lite, the dataset's assumed camera"),
    ("kitti", "KITTI road, its calibration file"),
    ("bdd", "BDD100K (27 dashcams), the dataset's assumed camera"),
    ("lums", "LUMS (low campus vehicle), the dataset's assumed camera"),
    ("cityscapes-noego", "Cityscapes, own vehicle not said"),
    ("cityscapes-est", "Cityscapes, camera estimated from its frames"),
    ("idd-est", "IDD-Lite, camera estimated from its frames"),
    ("bdd-est", "BDD100K, camera estimated from its frames"),
]
AS_SHIPPED_REAL = ["cityscapes", "idd", "kitti", "bdd", "lums"]  # the real other cameras of the headline


def _diff(a: list[float] | None, b: list[float] | None) -> list[float] | None:
    return [x - y for x, y in zip(a, b)] if a and b and len(a) == len(b) else None


def _base(test: str) -> str:
    """The frame set a variant row (-noego, -est) shares its resize score with."""
    return test.rsplit("-", 1)[0] if test.endswith(("-noego", "-est")) else test


def _real_mean(cells: dict, tests: list[str]) -> list[float] | None:
    """Per seed, the mean over ``tests`` of within - resize (points)."""
    per = [_diff(cells.get(f"{t}|within"), cells.get(f"{t}|resize")) for t in tests]
    return [statistics.fmean(v) for v in zip(*per)] if all(per) else None


def r_as_shipped(d: dict) -> list[str]:
    c = d["cells"]
    out = [f"Road IoU (%), mean ± std over seeds {d.get('seeds')}; one model per condition trained on CamVid train "
           "minus 0001TP with `vctrain crossval`'s defaults, scored in each test set's own camera. "
           "within − resize is paired per seed (the resize baseline reads the frames as they are, so a variant "
           "row is compared with its frame set's resize score).", ""]
    rows = [[t, what, _mean_std(c.get(f"{t}|within")), _mean_std(c.get(f"{_base(t)}|resize")),
             _mean_std(_diff(c.get(f"{t}|within"), c.get(f"{_base(t)}|resize")), signed=True)]
            for t, what in AS_SHIPPED_ROWS]
    out += table(["test set", "what", "within", "resize", "within − resize"], rows)
    real = _real_mean(c, AS_SHIPPED_REAL)
    out += [f"Real other cameras ({', '.join(AS_SHIPPED_REAL)}), within − resize, per seed the mean over them: "
            f"**{_mean_std(real, signed=True)}**.", ""]
    default = d["headline"].get("canvas_default", "shared")
    for cv in d.get("canvases", []):
        key = f"within@{cv}"
        if cv == default or not any(k.endswith("|" + key) for k in c):
            continue
        out += [f"The virtual camera's rectangle (`canvas`): crossval's default `{default}` against `{cv}` "
                "(within, paired per seed):", ""]
        out += table(["test set", f"within ({default})", f"within ({cv})", f"{default} − {cv}"],
                     [[t, _mean_std(c.get(f"{t}|within")), _mean_std(c.get(f"{t}|{key}")),
                       _mean_std(_diff(c.get(f"{t}|within"), c.get(f"{t}|{key}")), signed=True)]
                      for t, _ in AS_SHIPPED_ROWS])
    loo = d.get("loo_cells") or {}
    if loo:
        out += [f"Leave one real dataset out (trained on the other two at the CamVid model's "
                f"{d.get('loo_steps_per_epoch')} steps an epoch; seeds {d.get('loo_seeds')}):", ""]
        names = list(dict.fromkeys(k.split("|")[0] for k in loo))
        out += table(["held out", "within", "resize", "within − resize"],
                     [[t, _mean_std(loo.get(f"{t}|within")), _mean_std(loo.get(f"{t}|resize")),
                       _mean_std(_diff(loo.get(f"{t}|within"), loo.get(f"{t}|resize")), signed=True)] for t in names])
        out += [f"Mean over the held-out datasets: **{_mean_std(_real_mean(loo, names), signed=True)}**.", ""]
    abl = d.get("ablation_cells") or {}
    if abl:
        seeds, a_seeds = d.get("seeds", []), d.get("ablation_seeds", [])
        sub = lambda v: [v[seeds.index(k)] for k in a_seeds] if v and all(k in seeds for k in a_seeds) else None
        names = list(dict.fromkeys(k.split("|")[0] for k in abl))
        out += [f"Without geometric augmentation (random scale about the VP and shift off, both conditions; seeds "
                f"{a_seeds}), against the default recipe's models of the same seeds (paired per seed):", ""]
        out += table(["test set", "within", "resize", "within − resize", "within: noaug − aug", "resize: noaug − aug"],
                     [[t, _mean_std(abl.get(f"{t}|within")), _mean_std(abl.get(f"{t}|resize")),
                       _mean_std(_diff(abl.get(f"{t}|within"), abl.get(f"{t}|resize")), signed=True),
                       _mean_std(_diff(abl.get(f"{t}|within"), sub(c.get(f"{t}|within"))), signed=True),
                       _mean_std(_diff(abl.get(f"{t}|resize"), sub(c.get(f"{t}|resize"))), signed=True)]
                      for t in names])
        aug = {f"{t}|{k}": sub(c.get(f"{t}|{k}")) for t in AS_SHIPPED_REAL for k in ("within", "resize")}
        out += [f"Real other cameras, within − resize: without geometric augmentation "
                f"**{_mean_std(_real_mean(abl, AS_SHIPPED_REAL), signed=True)}**, with it (same seeds) "
                f"{_mean_std(_real_mean(aug, AS_SHIPPED_REAL), signed=True)}.", ""]
    found = d["headline"].get("ego_rows_found", {})
    out += ["Own vehicle rows found from the labels: " + ", ".join(f"{k} {v}" for k, v in found.items()) + ".", ""]
    given = [k.split("|")[0][:-len("-est")] for k in c if k.endswith("-est|within")]
    if given:
        out += ["`camera: estimate` against the given camera file, same frames (within, paired per seed; the "
                "simulated cameras' files are exact, CamVid val made into them by `vcprep simulate`; the IDD and "
                "BDD files are themselves assumptions):", ""]
        out += table(["frames", "within, given camera", "within, estimated", "estimated − given"],
                     [[t, _mean_std(c.get(f"{t}|within")), _mean_std(c.get(f"{t}-est|within")),
                       _mean_std(_diff(c.get(f"{t}-est|within"), c.get(f"{t}|within")), signed=True)]
                      for t in given])
    est = d.get("cameras_estimated", {})
    if est:
        out += ["Cameras estimated from their frames (tilt, pan from the road VPs; fx assumed from a 60° field of "
                "view; height from the labelled road footprint):", ""]
        out += table(["dataset", "fx", "fy", "tilt", "pan", "height", "ego_rows"],
                     [[k, num(e.get("fx"), 1), num(e.get("fy"), 1), num(e.get("tilt")), num(e.get("pan")),
                       num(e.get("height")), num(e.get("ego_rows", 0))] for k, e in est.items()])
    if d.get("targets"):
        out += table(["target (issue 24)", "met"], [[k, num(v)] for k, v in d["targets"].items()])
    out += r_generic({"headline": {k: v for k, v in d["headline"].items() if k != "ego_rows_found"}})
    return out


def r_deploy(d: dict) -> list[str]:
    rows = []
    for name, v in d["detail"].items():
        for t, r in v["threads"].items():
            st = r["torch_stages"]
            m = lambda k: f"{r[k]['median']:.1f} ({r[k]['min']:.1f}–{r[k]['max']:.1f})"  # noqa: E731
            label = t if t != "default" else f"default ({r.get('threads')})"  # vctrain predict's default then
            rows.append([f"{name} {num(v['frame_size'])}", label, m("net_torch"), m("net_ort"),
                         f"{m('torch_path')}: {st['warp']:.1f} / {st['network']:.1f} / {st['backproject']:.1f}",
                         m("onnx_fixed"), m("torch_path_vp") if "torch_path_vp" in r else "–", m("onnx_vp"),
                         m("resize_torch"), m("resize_onnx"),
                         num(r["geometry_share_torch"], 3), num(r["geometry_share_graph"], 3),
                         num(r["onnx_over_torch"], 2), num(r.get("onnx_vp_over_torch_vp"), 2)])
    out = table(["frame", "threads", "network torch ms", "network onnxruntime ms",
                 "torch path ms: warp / network / back-projection", "graph (mount) ms",
                 "torch path, VP per frame ms", "graph (--vp-input) ms",
                 "resize twin torch ms", "resize twin graph ms", "geometry / network, torch path",
                 "geometry / network, graph", "graph / torch path", "--vp-input graph / torch path, VP per frame"],
                rows)
    agree = [[name, num(v["store_size"]), num(v["working_size"]), f"{v['agreement_fixed']['max_abs_diff']:.1e}",
              f"{100 * v['agreement_fixed']['mask_agreement']:.3f}", f"{v['agreement_vp']['max_abs_diff']:.1e}",
              f"{100 * v['agreement_vp']['mask_agreement']:.3f}",
              f"{v['graph_mb']['']:.1f}", f"{v['graph_mb']['_vp']:.1f}"] for name, v in d["detail"].items()]
    return out + table(["frame", "store", "working size", "graph vs torch path: max abs dP", "masks agree %",
                        "--vp-input graph: max abs dP", "masks agree %", "graph MB", "--vp-input graph MB"], agree)


def r_video(d: dict) -> list[str]:
    h, e2e, st = d["headline"], d["end_to_end"], d["stages_ms"]
    v = d["video"]
    rows = [[n, num(e2e[n]["wall_s"], 1), num(e2e[n]["fps"]), num(e2e[n]["ms_per_frame"], 1)]
            for n in ("between", "within")]
    out = table(["one command, whole video", "wall s", "frames/s", "ms per frame"], rows)
    cell = lambda c: f"{c['median']:.1f} ({c['min']:.1f}–{c['max']:.1f})"
    out += table([f"stage, ms per frame (first {d['stage_frames']} frames; median, range of 2)", "between", "within"],
                 [[k, cell(st["between"][k]), cell(st["within"][k])] for k in st["between"]])
    return out + [
        f"Video: {v['frames']} frames {num(v['size'])} at {v['fps']:g} fps ({v['source']}); model: {d['model']}; "
        f"threads {d['cpu_threads']}. within / between (time per frame): **{h['within_over_between']:.2f}** end to "
        f"end (target ≤ 1.3), {d['stages_within_over_between']:.2f} over the stages. The own-vehicle search "
        f"(48 frames spread over the video; part of every command) took {d['ego_search_s']:.1f} s and found "
        f"{d['ego_rows']} rows."
        + (f" 1-minute load average before and after: {', '.join(num(x) for x in d['loadavg_1min'])} (other "
           f"jobs on the 2 cores slow both conditions)." if d.get("loadavg_1min") else ""), ""]


def r_predict_threads(d: dict) -> list[str]:
    """vctrain predict per frame at 1, 2 threads and the default beside busy processes (benchmarks/speed/predict_threads.py)."""
    cell = lambda c: f"{c['median']:.0f} ({c['min']:.0f}–{c['max']:.0f})"  # noqa: E731
    rows = [[k, num(r["busy_besides"]), cell(r["1"]), cell(r["2"]), f"{cell(r['default'])} ({r['default']['threads']})",
             num(r["default_over_1"]), num(r["2_over_1"])] for k, r in d["loads"].items()]
    out = [f"ms per frame, median (range) over {d.get('repeats')} passes, the settings alternated pass by pass; "
           f"load average {num(d.get('load_average_start'), 1)} at the start (other jobs on the machine).", ""]
    out += table(["busy processes started", "processes running besides (busy_cpus)", "1 thread", "2 threads",
                  "default (its threads)", "default / 1", "2 / 1"], rows)
    return out + table(["target (issue 45)", "met"], [[k, "not measured" if v is None else num(v)]
                                                      for k, v in d.get("targets", {}).items()])


RENDER: dict[str, Callable[[dict], list[str]]] = {
    "warp": r_warp, "video": r_video, "completion": r_completion, "predict_e2e.whole": r_predict_whole, "deploy": r_deploy, "store": r_store, "store.zlib": r_store, "png_deflate": r_png_deflate, "stages": r_stages, "train": r_train,
    "camera_estimate": r_camera_estimate, "focal_from_verticals": r_focal_from_verticals, "as_shipped": r_as_shipped, "vp": r_vp, "vp.dev": r_vp, "cross_camera": r_cross_camera, "real_cameras": r_real_cameras,
    "real_cameras_within_seq_fallback": r_real_cameras, "multi_camera": r_multi_camera, "multi_camera_median": r_multi_camera,
    "shipped_model": r_shipped_model, "shipped_model_e60": r_shipped_model, "finetune": r_finetune, "finetune_cityscapes": r_finetune, "adapt_loo": r_adapt_loo,
    "predict_threads": r_predict_threads, "own_frames_idd_unseen": r_own_frames, "own_frames_idd_shipped": r_own_frames,
    "own_frames_camvid_shipped": r_own_frames, "low_camera": r_low_camera, "merged_estimated": r_merged_estimated,
    "ship_geometry": r_ship_geometry, "route_finetune_idd": r_route_finetune, "route_finetune_camvid": r_route_finetune,
    # a name ending in "_": every stem it begins (loo_diagnose_<set>, shipped_screen_e<epochs>)
    "loo_diagnose_": r_loo_diagnose, "shipped_screen_": r_shipped_screen,
}


def renderer(stem: str) -> Callable[[dict], list[str]]:
    """The section renderer of a results JSON's stem: its own, else a prefix's, else :func:`r_generic`."""
    return RENDER.get(stem) or next((f for k, f in RENDER.items() if k.endswith("_") and stem.startswith(k)), r_generic)
