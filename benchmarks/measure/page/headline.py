"""The README's headline, made from the results JSON (benchmarks/results_page.py writes it between the
README's markers): one small table, a row a regime (one training camera, several cameras merged, the
shipped model) with what wins, by how much and on which held-out cameras; then which model to use and
when the virtual camera pays. And where each figure the README states comes from (:func:`readme_figures`).

Every function takes ``data``: a results JSON's stem -> its content (the stems are unique over the
question folders).
"""
from __future__ import annotations

import statistics
from dataclasses import dataclass

from .format import _mean_std, table
from .sections import AS_SHIPPED_REAL, _real_mean

MAX_LINES = 12  # the headline block, the lines between the README's markers
NAMES = {"camvid": "CamVid", "cityscapes": "Cityscapes", "idd": "IDD-Lite", "bdd": "BDD100K", "lums": "LUMS",
         "kitti": "KITTI", "kitti_semantics": "KITTI"}
HEADER = ["regime", "what wins", "by how much (road IoU points; mean ± std over seeds)",
          "on which cameras (held out of training)"]
SHIP_NAME = "road-all"        # what `shipped` names (vctrain.shipped.SHIPPED; issue 82)
SHIP_RESULT = "ship_mix_six"   # its run beside the models shipped before (benchmarks/what_a_user_gets/ship_mix.py)
SHIP_LOO = "ship_loo"          # the candidates judged on cameras held out of training (benchmarks/other_cameras/ship_loo.py)
SHIPPED = f"[`models/{SHIP_NAME}`](models/{SHIP_NAME}/README.md)"
SPLIT_NAMES = {"kitti_semantics": "`kitti_semantics`", "kitti": "the KITTI road frame"}
GUESSED = ("idd", "bdd", "lums")  # the development sets whose camera files are assumed (their READMEs)


@dataclass(frozen=True)
class Row:
    """One regime of the headline's table; ``figure`` is what ``--check`` looks for in its third cell."""
    key: str        # the regime cell starts with it
    regime: str
    wins: str
    by: str
    cameras: str
    figure: str
    source: str     # the stem of the JSON the figure comes from


def _seeds(v: list) -> str:
    return f"{len(v)} seed{'s' if len(v) != 1 else ''}"


WINNER = {"within": "the virtual camera (`within`)", "resize": "resize"}


def _winner(within_minus_resize: str) -> str:
    """What a within − resize figure ('+4.3 ± 1.2') says wins."""
    return WINNER["within" if within_minus_resize.startswith("+") else "resize"]


def worst_merged(m: dict) -> list[tuple[str, str]]:
    """The held-out cameras of a leave-one-camera-out result (benchmarks/other_cameras/multi_camera.py),
    worst first, as (name, 'mean ± std' of within − resize paired per seed)."""
    c, per = m["cells"], []
    for t in m.get("held_out", []):
        pair = [w - r for w, r in zip(c.get(f"{t}|within") or [], c.get(f"{t}|resize") or [])
                if w is not None and r is not None]
        if pair:
            per.append((sum(pair) / len(pair), NAMES.get(t, t), _mean_std(pair, signed=True)))
    return [(name, fig) for _, name, fig in sorted(per)]


def one_camera(a: dict) -> Row:
    """Trained on CamVid, tested on the real other cameras (benchmarks/other_cameras/as_shipped.py)."""
    fig = _mean_std(_real_mean(a["cells"], AS_SHIPPED_REAL), signed=True)
    return Row("one training camera", "one training camera (CamVid)", _winner(fig),
               f"within − resize **{fig}** ({_seeds(a['seeds'])})",
               f"{len(AS_SHIPPED_REAL)} real other cameras: " + ", ".join(NAMES[t] for t in AS_SHIPPED_REAL),
               fig, "as_shipped")


def several_merged(m: dict, stem: str = "multi_camera_median") -> Row:
    """Each real dataset held out in turn, trained on the others (benchmarks/other_cameras/multi_camera.py)."""
    h, n = m["headline"], len(m["held_out"])
    fig = f"{h['loo_within_minus_resize']:+.1f} ± {h['loo_within_minus_resize_std']:.1f}"
    worst = ", ".join(f"{name} {f}" for name, f in worst_merged(m)[:2])
    guessed = sum(t in GUESSED for t in m["held_out"])
    return Row("several cameras merged", f"several cameras merged ({n} real datasets, {guessed} cameras guessed)", _winner(fig),
               f"within − resize **{fig}** ({_seeds(m['seeds'])})",
               f"each dataset held out in turn, trained on the other {n - 1}; worst {worst}", fig, stem)


def calibrated_merged(c: dict, stem: str = "calibrated_loo_lite0fpn") -> Row:
    """Each calibrated camera held out in turn, trained on the other two (benchmarks/other_cameras/calibrated_loo.py)."""
    h, folds = c["headline"], c["held_out"]
    fig = f"{h['loo_within_minus_resize']:+.1f} ± {h['loo_within_minus_resize_std']:.1f}"
    per = sorted((h[f"loo_within_minus_resize_{f}"], NAMES.get(f, f)) for f in folds)
    return Row("several calibrated cameras", f"several calibrated cameras merged ({len(folds)}, `{c['model']}`)",
               _winner(fig), f"within − resize **{fig}** ({_seeds(c['seeds'])})",
               f"each held out in turn, trained on the other {len(folds) - 1}; best {per[-1][1]} {per[-1][0]:+.1f}, "
               f"worst {per[0][1]} {per[0][0]:+.1f}", fig, stem)


def shipped(data: dict[str, dict]) -> Row:
    """The model that ships (benchmarks/what_a_user_gets/results/ship_mix_six.json): its mean over the held-out
    splits beside the models shipped before in the same run, and the candidates' leave-one-dataset-out
    (ship_loo.json) where finished."""
    d = data[SHIP_RESULT]
    h, cand = d["headline"], d["candidate"]
    fig = f"{h[f'mean_{cand}']:.1f}"
    before = [f"{h[f'mean_{w}']:.1f} for `{w}`" for w in d.get("also", {})] + [f"{h['mean_shipped']:.1f} for `road-multicamera`"]
    by = (f"held-out mean **{fig}** ({_seeds(d['seeds'])}, {d['epochs']} epochs) against {' and '.join(before)}, "
          "shipped before")
    loo = data.get(SHIP_LOO, {}).get("headline", {})
    if loo.get(f"{cand}_mean") is not None and loo.get("today_mean") is not None:
        by += (f"; held out ({len(data[SHIP_LOO]['held_out'])} folds, {data[SHIP_LOO]['epochs']} epochs): "
               f"{loo[f'{cand}_mean']:.1f} against {loo['today_mean']:.1f}")
        factors = data[SHIP_LOO].get("budget_factor", {})  # the same at longer budgets, where measured
        for tail in ("long", "30"):
            longer, factor = loo.get(f"{cand}-{tail}_minus_today-{tail}"), factors.get(f"{cand}-{tail}", 2)
            if longer is not None:
                done = _done(data[SHIP_LOO], (f"{cand}-{tail}", f"today-{tail}"))
                by += f"; {factor * data[SHIP_LOO]['epochs']} epochs, {_seeds(done)}: {longer:+.1f}"
    return Row("the shipped model", f"the shipped model, {SHIPPED}", WINNER["resize"], by,
               f"{len(d['splits'])} held-out splits: " + ", ".join(SPLIT_NAMES.get(s, NAMES.get(s, s)) for s in d["splits"]), fig,
               SHIP_RESULT)


def rows(data: dict[str, dict]) -> list[Row]:
    """The three regimes, as measured."""
    cal = [calibrated_merged(data["calibrated_loo_lite0fpn"])] if "calibrated_loo_lite0fpn" in data else []
    return [one_camera(data["as_shipped"]), several_merged(data["multi_camera_median"]), *cal, shipped(data)]


def render(data: dict[str, dict]) -> str:
    """The headline block: a sentence, the table, which model to use and when the virtual camera pays."""
    rs = rows(data)
    one, several = rs[0], rs[1]
    cal = [r for r in rs if r.key == "several calibrated cameras"]
    sets = ", ".join(NAMES[t] for t in data[SHIP_RESULT]["datasets"])
    lines = ["On real cameras held out of training, the virtual camera (`within`: per-image correction) against "
             "the same network on resized images (`resize`):", ""]
    lines += table(HEADER, [[r.regime, r.wins, r.by, r.cameras] for r in rs])
    lines += [f"- **Which model to use**: the shipped one, {SHIPPED}, a lite0fpn trained on {sets} with the frames "
              f"read as they are, chosen on cameras held out of training{_before(data)}.",
              f"- **When the virtual camera pays**: a model trained on one camera and used on others "
              f"({one.figure} IoU points over resize)" + (f", or on several calibrated cameras ({cal[0].figure})" if cal else "")
              + ": your labelled frames, each camera described by a file (calibrated, or `--camera estimate`, which beat "
              "a guessed file on a camera new to the model), trained with `vcprep warp` + `vctrain fit`; with guessed "
              "cameras merged, train the resize twin (`--baseline resize`); camera by camera: "
              "[docs/training.md](docs/training.md#which-model-for-which-camera).",
              "- **Every figure**, with the script and the results file it comes from: [docs/results.md](docs/results.md)."]
    return "\n".join(lines)


def _done(loo: dict, cands: tuple[str, ...]) -> list[int]:
    """The seeds of ship_loo.json on which every one of ``cands`` has every fold."""
    cells, folds = loo["cells"], loo["held_out"]
    return [s for i, s in enumerate(loo["seeds"]) if all(cells[f"{c}|{f}|iou"][i] is not None for c in cands for f in folds)]


def _before(data: dict[str, dict]) -> str:
    """The models shipped before, by name, and where each is ahead of the shipped one (measured)."""
    d, loo = data[SHIP_RESULT], data.get(SHIP_LOO, {}).get("headline", {})
    h, cand = d["headline"], d["candidate"]
    street, bdd = loo.get(f"{cand}-30_minus_four-30"), (h.get("shipped_bdd"), h.get(f"{cand}_bdd"))
    if cand != "six" or street is None or None in bdd:  # (a figure not measured is not written as 0)
        return ""
    dash = bdd[0] - bdd[1]
    seeds = _seeds(_done(data[SHIP_LOO], (f"{cand}-30", "four-30")))
    return (f"; by name, `road-street` is {-street:.1f} ahead on held-out datasets (30 epochs, {seeds}) and "
            f"`road-multicamera` {dash:.1f} on BDD100K's dashcams")


def _table_rows(block: str) -> list[list[str]]:
    """The body rows of the first Markdown table in ``block``, as cells."""
    body = [ln for ln in block.splitlines() if ln.startswith("|")][2:]
    return [[c.strip() for c in ln.strip().strip("|").split("|")] for ln in body]


def problems(block: str, data: dict[str, dict]) -> list[str]:
    """What a headline block gets wrong: too long, a regime's figure missing from its row, no shipped model."""
    lines = block.strip("\n").splitlines()
    out = [f"the headline has {len(lines)} lines, at most {MAX_LINES}"] if len(lines) > MAX_LINES else []
    cells = _table_rows(block)
    for r in rows(data):
        row = next((c for c in cells if c and c[0].startswith(r.key)), None)
        if row is None or len(row) < 3 or r.figure not in row[2]:
            out.append(f"the headline's table leaves out the '{r.key}' figure ({r.figure}, from {r.source}.json)")
    if f"models/{SHIP_NAME}" not in block:
        out.append(f"the headline does not name the shipped model (models/{SHIP_NAME})")
    return out


def readme_figures(data: dict[str, dict]) -> list[tuple[str, list[str], str]]:
    """Each figure the README states: (where and what, the figure as the README writes it (in parts),
    the results file it comes from). The headline's are generated; the others are written by hand."""
    rs = rows(data)
    s = data[SHIP_RESULT]
    cells = {t: s["headline"][f"{s['candidate']}_{t}"] for t in s["splits"] if t != "kitti_semantics"}
    out = [(f"headline, {r.key}", [r.figure], f"{r.source}.json") for r in rs]
    out.insert(2, ("headline, several cameras merged: the worst held-out cameras",
                   [f"{n} {f}" for n, f in worst_merged(data["multi_camera_median"])[:2]], "multi_camera_median.json"))
    out += [("Three routes, 1: the shipped model's held-out road IoU", [
                f"{'CamVid val' if t == 'camvid' else NAMES[t]} {cells[t]:.1f}" for t in cells if t != "kitti"]
             + [f"the KITTI road frame {cells['kitti']:.1f}"], f"{SHIP_RESULT}.json"),
            ("Your first hour, 2: the shipped model on held-out frames (the figure)", ["shipped_model.png"],
             "shipped_model.png"),
            ("Your first hour, 5 and Concepts: minutes a model, 305 CamVid frames on 2 cores (the route's fits, median)",
             [f"{round(statistics.median(sum(data['user_route']['fit_seconds'].values(), [])) / 60)} min"],
             "user_route.json"),
            ("Your first hour, 5: minutes a `--model lite0fpn` model, the same frames (the route's fits, median)",
             [f"takes {round(statistics.median(data['user_route_lite0fpn']['fit_seconds']['vc']) / 60)}"],
             "user_route_lite0fpn.json")]
    out += [("Three routes, 2: your own model in the virtual camera against its resize twin, on other cameras",
             [f"{rs[0].figure} over its resize twin"], f"{rs[0].source}.json"),
            ("Three routes, 3: several cameras merged, the virtual camera against resize",
             [f"{rs[1].figure} for the virtual camera"], f"{rs[1].source}.json")]
    if "finetune_guard" in data:  # route 2: fine-tuning the shipped model by default, 3 seeds (issue 72)
        out.append(("Three routes, 2: fine-tuning the shipped model by default, gain and worst seed",
                    finetune_figures(data["finetune_guard"]), "finetune_guard.json"))
    if "route_finetune_idd" in data:  # your own model fine-tuned on a new camera's store
        h = data["route_finetune_idd"]["headline"]
        out.append(("Your first hour, 5: your own model fine-tuned on a new camera's store, over it as it is",
                    [f"{h[f'own virtual camera_minus_zero_n{n}']:+.1f} with {n} frames"
                     for n in data["route_finetune_idd"]["frames"]]
                    + [f"about {round(h['own virtual camera_n60_minutes'])} min"], "route_finetune_idd.json"))
    if "route_finetune_camvid" in data:  # ... and where it loses: a new drive of the camera the model knows
        h = data["route_finetune_camvid"]["headline"]
        out.append(("Your first hour, 5: your own model fine-tuned on a new drive of its own camera, over it as it is",
                    [f"a new drive of its own camera: {h['own virtual camera_minus_zero_n20']:+.1f} with 20 frames"],
                    "route_finetune_camvid.json"))
    return out


FINETUNE_CASES = {"kitti": "a camera it never saw (KITTI", "dusk": "in other light (CamVid dusk -> daylight",
                  "idd": "a camera it knows (IDD-Lite"}


def signed_points(x: float) -> str:
    """A gain in points, signed: to a tenth, and to a hundredth below one point (-0.03, not -0.0)."""
    return f"{x:+.2f}" if abs(x) < 1 else f"{x:+.1f}"


def finetune_figures(guard: dict) -> list[str]:
    """Route 2's figures from finetune_guard.json: per case its start, then per frame count the mean
    gain over the model as it is and the worst seed, as the README writes them."""
    h, out = guard["headline"], [f"{len(guard['seeds'])} seeds"]
    for case, name in FINETUNE_CASES.items():
        ns = sorted((int(k.split("_n")[1].split("_")[0]) for k in h
                     if k.startswith(f"{case}_default_n") and k.endswith("_gain")))
        if not ns:
            continue
        out.append(f"{name}, {h[f'{case}_zero-shot']:.1f})")
        gain = lambda n, what: signed_points(h[f"{case}_default_n{n}_{what}"])
        out += [f"{gain(n, 'gain')} (worst {gain(n, 'worst')}) with {n}" for n in ns]
    return out

